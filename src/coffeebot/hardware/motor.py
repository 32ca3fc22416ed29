"""Robot side of the motor controller line protocol (``docs/motor-protocol.md``)."""

from __future__ import annotations

from dataclasses import dataclass

from coffeebot.hardware.serial_port import LineReader, SerialPort
from coffeebot.messages import Odometry

WATCHDOG_MS = 200
MAX_LINE = 80
WATCHDOG_FLAG = 0x01
FIELD_COUNTS = {"T": 8, "I": 3, "B": 1, "V": 2, "S": 0, "?": 0}


def checksum(payload: bytes) -> str:
    value = 0
    for byte in payload:
        value ^= byte
    return f"{value:02X}"


def encode(kind: str, *fields: int | str) -> bytes:
    payload = ",".join([kind, *map(str, fields)]).encode("ascii")
    return payload + b"*" + checksum(payload).encode("ascii") + b"\n"


def decode(line: bytes) -> tuple[str, list[str]]:
    """``(type, fields)`` of a checked line; ``ValueError`` for anything malformed."""
    payload, star, cc = line.rstrip(b"\r").rpartition(b"*")
    if not star or cc.decode("ascii", errors="replace") != checksum(payload):
        raise ValueError(f"bad checksum: {line[:40]!r}")
    kind, *fields = payload.decode("ascii").split(",")
    if FIELD_COUNTS.get(kind) != len(fields):
        raise ValueError(f"bad line type or field count: {line[:40]!r}")
    return kind, fields


@dataclass(frozen=True, slots=True)
class Identity:
    firmware: str
    watchdog_ms: int
    telemetry_hz: int


@dataclass(frozen=True, slots=True)
class Boot:
    firmware: str


def parse(line: bytes) -> Odometry | Identity | Boot:
    """A controller line as a typed event; ``ValueError`` for garbage or host-side types."""
    kind, f = decode(line)
    if kind == "T":
        ms, lt, rt, gz, lv, rv, flags, _rx_errors = map(int, f)
        return Odometry(
            controller_time_ms=ms,
            left_ticks=lt,
            right_ticks=rt,
            gyro_z_dps=gz / 1000.0,
            left_mm_s=lv,
            right_mm_s=rv,
            watchdog_tripped=bool(flags & WATCHDOG_FLAG),
        )
    if kind == "I":
        return Identity(f[0], int(f[1]), int(f[2]))
    if kind == "B":
        return Boot(f[0])
    raise ValueError(f"not a controller line: {line[:40]!r}")


class MotorController:
    """Blocking driver; reads and writes may run in two different threads (pyserial allows
    one reader and one writer at a time), which keeps commands flowing while a read waits."""

    def __init__(self, port: SerialPort) -> None:
        self.port = port
        self.lines = LineReader(port, max_line=MAX_LINE)

    def set_speeds(self, left_mm_s: float, right_mm_s: float) -> None:
        self.port.write(encode("V", round(left_mm_s), round(right_mm_s)))

    def stop(self) -> None:
        self.port.write(encode("S"))

    def request_identity(self) -> None:
        self.port.write(encode("?"))

    def readline(self) -> bytes | None:
        return self.lines.readline()

    def identify(self, max_lines: int = 20) -> Identity:
        """Ask for and wait for the ``I`` reply, skipping telemetry in between."""
        self.request_identity()
        for _ in range(max_lines):
            line = self.readline()
            if line is None:
                self.request_identity()
                continue
            try:
                event = parse(line)
            except ValueError:
                continue
            if isinstance(event, Identity):
                return event
        raise TimeoutError(f"motor controller: no identity reply within {max_lines} lines")
