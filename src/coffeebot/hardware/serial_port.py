"""The serial port interface the UART drivers use, and line framing over it.

Ports are opened by URL with pyserial's ``serial_for_url`` (a device path, a pty path,
``socket://``...), so tests plug a pseudo-terminal in where the robot has a USB adapter.
"""

from __future__ import annotations

from typing import Protocol


class SerialPort(Protocol):
    """The subset of ``serial.Serial`` the drivers call."""

    @property
    def in_waiting(self) -> int: ...

    def read(self, size: int = 1) -> bytes: ...

    def write(self, data: bytes, /) -> int | None: ...

    def reset_input_buffer(self) -> None: ...

    def close(self) -> None: ...


def open_port(url: str, baudrate: int, timeout_s: float) -> SerialPort:
    """Open ``url`` 8N1 without flow control; reads return after ``timeout_s`` at the latest."""
    import serial

    return serial.serial_for_url(url, baudrate=baudrate, timeout=timeout_s)


class LineReader:
    """Reassembles lines from whatever chunks the port returns.

    A partial line survives a read timeout and is completed by the next chunk. A run of
    bytes longer than ``max_line`` without a terminator is junk (or a lost terminator); it is
    dropped and counted in ``overflows`` rather than growing without bound.
    """

    def __init__(self, port: SerialPort, max_line: int = 512) -> None:
        self.port = port
        self.max_line = max_line
        self.overflows = 0
        self._buf = bytearray()

    def read_until(self, terminator: bytes) -> bytes | None:
        """Bytes before the next ``terminator`` (which is consumed), or None if the port's
        read timeout passes first."""
        while True:
            at = self._buf.find(terminator)
            if at >= 0:
                out = bytes(self._buf[:at])
                del self._buf[: at + len(terminator)]
                return out
            if len(self._buf) > self.max_line:
                # Keep a tail that might be the start of the terminator.
                del self._buf[: len(self._buf) - len(terminator) + 1]
                self.overflows += 1
            chunk = self.port.read(max(1, self.port.in_waiting))
            if not chunk:
                return None
            self._buf += chunk

    def readline(self) -> bytes | None:
        """One line without its LF (and without a CR before it)."""
        line = self.read_until(b"\n")
        return None if line is None else line.removesuffix(b"\r")

    def clear(self) -> None:
        self._buf.clear()
        self.port.reset_input_buffer()
