"""A serial line on a pseudo-terminal: the simulated device holds the master side.

The driver opens :attr:`PtyLine.port`, a symlink to the pty's slave side, like a real
``/dev/serial/by-id/...`` link, through pyserial as on the robot: unplugging removes the link
and hangs up the line (the driver's reads fail), replugging makes a fresh pty behind the same
path. The hardware tests run the drivers over these; the simulated robot uses the in-process
:class:`~coffeebot.sim.serial_line.MemoryLine`, whose timing follows simulated time.
"""

from __future__ import annotations

import contextlib
import os
import select
import threading
import tty
from pathlib import Path

from coffeebot.sim.rundir import run_directory


class PtyLine:
    """The device's end of a pty (see :class:`coffeebot.sim.uart.Line`)."""

    def __init__(self, name: str) -> None:
        self._dir = run_directory()
        self.port = str(Path(self._dir.name) / name)
        self._lock = threading.Lock()
        self._master: int | None = None
        self._slave: int | None = None

    @property
    def plugged(self) -> bool:
        return self._master is not None

    def plug(self) -> None:
        self.unplug()
        master, slave = os.openpty()
        tty.setraw(slave)  # no echo or line editing before the driver configures the port
        os.set_blocking(master, False)
        with self._lock:
            self._master, self._slave = master, slave
            os.symlink(os.ttyname(slave), self.port)

    def unplug(self) -> None:
        with self._lock:
            for fd in (self._master, self._slave):
                if fd is not None:
                    os.close(fd)
            self._master = self._slave = None
            Path(self.port).unlink(missing_ok=True)

    def send(self, data: bytes) -> None:
        """Bytes nobody reads are lost once the pty buffer is full, like a UART transmitting
        to an unplugged host."""
        with self._lock:
            if self._master is None:
                return
            with contextlib.suppress(OSError):  # BlockingIOError: the buffer is full
                os.write(self._master, data)

    def receive(self, wait_s: float) -> bytes:
        master = self._master
        if master is None:
            return b""
        try:
            readable, _, _ = select.select([master], [], [], wait_s)
            return os.read(master, 4096) if readable else b""
        except OSError:
            return b""  # unplugged under our feet, or nobody has the slave open

    def close(self) -> None:
        self.unplug()
        self._dir.cleanup()
