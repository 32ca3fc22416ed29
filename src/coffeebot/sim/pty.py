"""A simulated UART device on the master side of a pseudo-terminal.

The driver opens :attr:`PtyDevice.port`, a symlink to the pty's slave side, like a real
``/dev/serial/by-id/...`` link: unplugging removes the link and hangs up the line (the
driver's reads fail), replugging makes a fresh pty behind the same path.
"""

from __future__ import annotations

import contextlib
import os
import select
import tempfile
import threading
import time
import tty
from abc import ABC, abstractmethod
from collections.abc import Callable
from pathlib import Path


class PtyDevice(ABC):
    """Base class: a thread that feeds received bytes to :meth:`on_data` and calls
    :meth:`on_tick` every ``tick_s`` (or, once :meth:`stop_serving` has been called, the same
    from :meth:`poll`, called by whoever owns time). Subclasses speak the protocol."""

    def __init__(
        self,
        name: str,
        *,
        tick_s: float = 0.005,
        clock: Callable[[], float] = time.monotonic,
    ) -> None:
        self.clock = clock
        self.tick_s = tick_s
        self._dir = tempfile.TemporaryDirectory(prefix="coffeebot-sim-")
        self.port = str(Path(self._dir.name) / name)
        self._lock = threading.RLock()  # also guards subclass state
        self._master: int | None = None
        self._slave: int | None = None
        self._stop = threading.Event()
        self._thread = threading.Thread(target=self._serve, name=f"sim-{name}", daemon=True)
        self.replug()

    # --- for tests ----------------------------------------------------------------------

    def start(self) -> None:
        self._thread.start()

    def stop_serving(self) -> None:
        """Stop the device's own thread and leave the line open: whoever owns time calls
        :meth:`poll` from now on (the simulator does, once per world step, so the device
        answers in simulated time however busy the machine is)."""
        self._stop.set()
        if self._thread.is_alive():
            self._thread.join()

    def close(self) -> None:
        self.stop_serving()
        self.unplug()
        self._dir.cleanup()

    def __enter__(self) -> PtyDevice:
        self.start()
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()

    def unplug(self) -> None:
        """Hang up: the driver's open port fails and the path disappears."""
        with self._lock:
            for fd in (self._master, self._slave):
                if fd is not None:
                    os.close(fd)
            self._master = self._slave = None
            Path(self.port).unlink(missing_ok=True)

    def replug(self) -> None:
        self.unplug()
        master, slave = os.openpty()
        tty.setraw(slave)  # no echo or line editing before the driver configures the port
        os.set_blocking(master, False)
        with self._lock:
            self._master, self._slave = master, slave
            os.symlink(os.ttyname(slave), self.port)
        self.on_plugged()

    @property
    def plugged(self) -> bool:
        return self._master is not None

    def inject(self, data: bytes) -> None:
        """Raw bytes on the line: garbage, a partial line, noise."""
        self.send(data)

    # --- for subclasses -----------------------------------------------------------------

    def send(self, data: bytes) -> None:
        """Write to the line; bytes nobody reads are lost once the pty buffer is full, like
        a UART transmitting to an unplugged host."""
        with self._lock:
            if self._master is None:
                return
            with contextlib.suppress(OSError):  # BlockingIOError: the buffer is full
                os.write(self._master, data)

    def on_plugged(self) -> None:  # noqa: B027 - an optional hook, empty by default
        """Called when the device is (re)connected, before any byte is exchanged."""

    @abstractmethod
    def on_data(self, data: bytes) -> None: ...

    @abstractmethod
    def on_tick(self, now: float) -> None: ...

    def poll(self, now: float) -> None:
        """One turn without waiting: take what the driver wrote, then tick at ``now``."""
        self._receive(0.0)
        self.on_tick(now)

    def _receive(self, wait_s: float) -> None:
        master = self._master
        if master is None:
            return
        try:
            readable, _, _ = select.select([master], [], [], wait_s)
            data = os.read(master, 4096) if readable else b""
        except OSError:
            data = b""  # unplugged under our feet, or nobody has the slave open
        if data:
            self.on_data(data)

    def _serve(self) -> None:
        while not self._stop.is_set():
            if self._master is None:
                self._stop.wait(self.tick_s)
            else:
                self._receive(self.tick_s)
            self.on_tick(self.clock())
