"""A simulated UART device: its firmware on one end of a serial line.

Subclasses speak the protocol (:meth:`UartDevice.on_data`, :meth:`UartDevice.on_tick`); the
line is either a pseudo-terminal (:class:`~coffeebot.sim.pty.PtyLine`, the drivers open it
through pyserial) or in-process (:class:`~coffeebot.sim.serial_line.MemoryLine`, in step
with simulated time). The device runs in a thread of its own that feeds it received bytes and
ticks it every ``tick_s``, until :meth:`UartDevice.stop_serving`; from then on whoever owns
time calls :meth:`UartDevice.poll` (the simulator does, once per world step, so the device
answers in simulated time however busy the machine is).
"""

from __future__ import annotations

import threading
import time
from abc import ABC, abstractmethod
from collections.abc import Callable
from typing import Protocol

from coffeebot.sim.pty import PtyLine


class Line(Protocol):
    """The device's end of a serial line."""

    @property
    def port(self) -> str:
        """What the driver opens."""

    @property
    def plugged(self) -> bool: ...

    def plug(self) -> None:
        """(Re)connect: a fresh line behind the same port name."""

    def unplug(self) -> None:
        """Hang up: the driver's open port fails and the port cannot be opened."""

    def send(self, data: bytes) -> None: ...

    def receive(self, wait_s: float) -> bytes:
        """What the driver wrote, waiting up to ``wait_s`` of the machine's time for it."""

    def close(self) -> None: ...


class UartDevice(ABC):
    def __init__(
        self,
        name: str,
        *,
        tick_s: float = 0.005,
        clock: Callable[[], float] = time.monotonic,
        line: Line | None = None,
    ) -> None:
        """``line``: the serial line (a new pty named ``name`` by default)."""
        self.clock = clock
        self.tick_s = tick_s
        self.line: Line = line if line is not None else PtyLine(name)
        self._lock = threading.RLock()  # also guards subclass state
        self._stop = threading.Event()
        self._thread = threading.Thread(target=self._serve, name=f"sim-{name}", daemon=True)
        self.replug()

    @property
    def port(self) -> str:
        return self.line.port

    # --- for tests and faults -----------------------------------------------------------

    def start(self) -> None:
        self._thread.start()

    def stop_serving(self) -> None:
        """Stop the device's own thread and leave the line open: whoever owns time calls
        :meth:`poll` from now on."""
        self._stop.set()
        if self._thread.is_alive():
            self._thread.join()

    def close(self) -> None:
        self.stop_serving()
        self.line.close()

    def __enter__(self) -> UartDevice:
        self.start()
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()

    def unplug(self) -> None:
        """Hang up: the driver's open port fails and the port disappears."""
        self.line.unplug()

    def replug(self) -> None:
        self.line.plug()
        self.on_plugged()

    @property
    def plugged(self) -> bool:
        return self.line.plugged

    def inject(self, data: bytes) -> None:
        """Raw bytes on the line: garbage, a partial line, noise."""
        self.send(data)

    # --- for subclasses -----------------------------------------------------------------

    def send(self, data: bytes) -> None:
        self.line.send(data)

    def on_plugged(self) -> None:  # noqa: B027 - an optional hook, empty by default
        """Called when the device is (re)connected, before any byte is exchanged."""

    @abstractmethod
    def on_data(self, data: bytes) -> None: ...

    @abstractmethod
    def on_tick(self, now: float) -> None: ...

    def poll(self, now: float) -> None:
        """One turn without waiting: take what the driver wrote, then tick at ``now``."""
        data = self.line.receive(0.0)
        if data:
            self.on_data(data)
        self.on_tick(now)

    def _serve(self) -> None:
        while not self._stop.is_set():
            if not self.line.plugged:
                self._stop.wait(self.tick_s)
            else:
                data = self.line.receive(self.tick_s)
                if data:
                    self.on_data(data)
            self.on_tick(self.clock())
