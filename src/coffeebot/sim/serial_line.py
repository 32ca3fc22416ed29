"""A serial line inside the process, whose waits are in simulated time.

The simulated robot's UART devices (DWM1001, motor controller) talk to their drivers over
these instead of pseudo-terminals: the bytes are the same protocol, but a driver's read waits
for the *simulated* read timeout, in step with the world (:mod:`coffeebot.lockstep`), and
bytes the device sends are there for the driver at once, not when the kernel gets round to
moving them. A pty's timing follows the machine's load, which is what made two runs of the
same scenario differ.

The driver's end is a :class:`MemoryPort`, what :meth:`MemoryLine.open` returns for the
line's ``sim://`` port name: the :class:`~coffeebot.hardware.serial_port.SerialPort` subset
of ``serial.Serial``, failing with ``OSError`` as pyserial does when the line is unplugged.
"""

from __future__ import annotations

import errno
import os

from coffeebot.lockstep import Lockstep

BUFFER_BYTES = 4096
"""What the line holds for a reader that does not read (a pty's buffer); the rest is lost."""


class MemoryLine:
    """The device's end (see :class:`coffeebot.sim.uart.Line`); every buffer is guarded by
    the lockstep's lock, and every change wakes whoever waits for it (:meth:`Lockstep.wake`)."""

    def __init__(self, name: str, lockstep: Lockstep) -> None:
        self.port = f"sim://{name}"
        self.lockstep = lockstep
        self._lock = lockstep.lock
        self._to_driver = bytearray()
        self._to_device = bytearray()
        self._plugged = False
        self.generation = 0
        """Counts plug-ins: a port opened on an earlier one is hung up."""

    @property
    def plugged(self) -> bool:
        return self._plugged

    def plug(self) -> None:
        with self._lock:
            self.generation += 1
            self._plugged = True
            self._to_driver.clear()
            self._to_device.clear()
            self.lockstep.wake()

    def unplug(self) -> None:
        with self._lock:
            self._plugged = False
            self._to_driver.clear()
            self._to_device.clear()
            self.lockstep.wake()

    def send(self, data: bytes) -> None:
        with self._lock:
            if self._plugged:
                room = BUFFER_BYTES - len(self._to_driver)
                self._to_driver += data[: max(0, room)]
                self.lockstep.wake()

    def receive(self, wait_s: float) -> bytes:
        """What the driver wrote; waits up to ``wait_s`` simulated seconds for it."""
        if wait_s > 0:
            self.lockstep.block(lambda: bool(self._to_device), self.lockstep.now() + wait_s)
        with self._lock:
            data = bytes(self._to_device)
            self._to_device.clear()
            return data

    def close(self) -> None:
        self.unplug()

    def open(self, url: str, baudrate: int, timeout_s: float) -> MemoryPort:
        """The driver's end, as ``open_port(url, baudrate, timeout_s)`` would give it."""
        del baudrate  # bytes move whole; a UART's pace is not modelled
        with self._lock:
            if url != self.port or not self._plugged:
                why = os.strerror(errno.ENOENT)
                raise OSError(errno.ENOENT, f"could not open port {url}: {why}")
            self._to_driver.clear()  # pyserial flushes the input when it opens a port
            return MemoryPort(self, self.generation, timeout_s)

    # --- for MemoryPort (with the lock held) --------------------------------------------

    def _alive(self, generation: int) -> bool:
        return self._plugged and generation == self.generation


class MemoryPort:
    """The driver's end of a :class:`MemoryLine` (blocking calls: the port's worker thread)."""

    def __init__(self, line: MemoryLine, generation: int, timeout_s: float) -> None:
        self._line = line
        self._generation = generation
        self.timeout_s = timeout_s
        self._closed = False

    @property
    def in_waiting(self) -> int:
        with self._line.lockstep.lock:
            self._check()
            return len(self._line._to_driver)

    def read(self, size: int = 1) -> bytes:
        """Up to ``size`` bytes, waiting for all of them at most the simulated read timeout
        (``b""`` when nothing came), as pyserial's ``read`` does."""
        line = self._line
        lockstep = line.lockstep
        deadline = lockstep.now() + self.timeout_s
        lockstep.block(lambda: not self._usable() or len(line._to_driver) >= size, deadline)
        with lockstep.lock:
            self._check()
            data = bytes(line._to_driver[:size])
            del line._to_driver[:size]
            return data

    def write(self, data: bytes, /) -> int:
        line = self._line
        with line.lockstep.lock:
            self._check()
            line._to_device += data
        line.lockstep.wake()
        return len(data)

    def reset_input_buffer(self) -> None:
        with self._line.lockstep.lock:
            self._check()
            self._line._to_driver.clear()

    def close(self) -> None:
        self._closed = True

    def _usable(self) -> bool:
        return not self._closed and self._line._alive(self._generation)

    def _check(self) -> None:
        if self._closed:
            raise OSError(errno.EBADF, "port is closed")
        if not self._line._alive(self._generation):
            raise OSError(errno.EIO, f"{self._line.port}: {os.strerror(errno.EIO)} (line hung up)")
