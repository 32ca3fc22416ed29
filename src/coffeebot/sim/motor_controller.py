"""A simulated motor controller on a serial line, obeying ``docs/motor-protocol.md``.

The controller drives a :class:`Drive`: the motors, encoders and gyro behind it. The default
:class:`IdealDrive` makes wheels follow their set-points at once, each scaled by its own
``drift`` factor (the real motors differ); encoders count ``ticks_per_mm`` and the gyro reports
the yaw rate the wheel speeds imply over ``track_mm``. The simulated world is the other drive,
with physics. Every accepted command is kept in :attr:`commands` with its time, so tests can
check what the robot asked for and when the watchdog stopped it.

Fault: ``silent`` makes the firmware hang: nothing is read or sent, and the watchdog (a
separate hardware timer on the real board) stops the motors 200 ms later.

Because that timer is hardware, each set-point reaches the drive with the moment it expires
(``until``) and the drive stops by itself then: the motors stop on time in the drive's own
time even when the thread running this firmware is late (on a loaded machine), and the tick
only reports the trip.
"""

from __future__ import annotations

import math
import time
from collections.abc import Callable
from dataclasses import dataclass
from typing import NamedTuple, Protocol

from coffeebot.hardware.motor import MAX_LINE, WATCHDOG_FLAG, WATCHDOG_MS, decode, encode
from coffeebot.sim.uart import Line, UartDevice

FIRMWARE = "sim-1.0"
TELEMETRY_HZ = 50
MAX_SPEED_MM_S = 1000


@dataclass(frozen=True)
class Command:
    time_s: float
    kind: str  # "V" or "S"
    left_mm_s: int
    right_mm_s: int


class DriveSample(NamedTuple):
    """What the controller measures: cumulative encoder counts, measured wheel speeds, gyro."""

    left_ticks: int
    right_ticks: int
    left_mm_s: float
    right_mm_s: float
    gyro_z_dps: float


class Drive(Protocol):
    """The motors and sensors behind the controller; ``now`` is the controller's clock."""

    def command(
        self,
        left_mm_s: float,
        right_mm_s: float,
        now: float,
        until: float = math.inf,
        brake: bool = False,
    ) -> None:
        """Drive towards the set-point from ``now``; at ``until`` the watchdog stops it.
        ``brake``: a stop line, braking actively rather than ramping down."""

    def sample(self, now: float) -> DriveSample: ...


class IdealDrive:
    """Wheels at their set-points at once, each scaled by its ``drift`` factor."""

    def __init__(
        self,
        ticks_per_mm: float = 1.2,
        track_mm: float = 440.0,
        drift: tuple[float, float] = (1.0, 1.0),
    ) -> None:
        self.ticks_per_mm = ticks_per_mm
        self.track_mm = track_mm
        self.drift = drift
        self._setpoint = (0.0, 0.0)
        self._until = math.inf
        self._distance_mm = [0.0, 0.0]
        self._last: float | None = None

    def _speeds(self) -> tuple[float, float]:
        return self._setpoint[0] * self.drift[0], self._setpoint[1] * self.drift[1]

    def _integrate(self, now: float) -> None:
        dt = 0.0 if self._last is None else min(now, self._until) - self._last
        self._last = now
        for i, v in enumerate(self._speeds()):
            self._distance_mm[i] += v * max(0.0, dt)
        if now >= self._until:
            self._setpoint, self._until = (0.0, 0.0), math.inf

    def command(
        self,
        left_mm_s: float,
        right_mm_s: float,
        now: float,
        until: float = math.inf,
        brake: bool = False,
    ) -> None:
        self._integrate(now)
        self._setpoint = (left_mm_s, right_mm_s)
        self._until = until

    def sample(self, now: float) -> DriveSample:
        self._integrate(now)
        left, right = self._speeds()
        return DriveSample(
            round(self._distance_mm[0] * self.ticks_per_mm),
            round(self._distance_mm[1] * self.ticks_per_mm),
            left,
            right,
            math.degrees((right - left) / self.track_mm),
        )


class SimMotorController(UartDevice):
    def __init__(
        self,
        drive: Drive | None = None,
        *,
        clock: Callable[[], float] = time.monotonic,
        tick_s: float = 0.005,
        line: Line | None = None,
    ) -> None:
        self.drive: Drive = drive or IdealDrive()
        self.commands: list[Command] = []
        self.watchdog_trips = 0
        self.rx_errors = 0
        self.silent = False
        super().__init__("motor", clock=clock, tick_s=tick_s, line=line)

    def on_plugged(self) -> None:
        self.reset()

    def reset(self) -> None:
        """Power-on state: counters at zero, watchdog tripped, a ``B`` line on the wire."""
        with self._lock:
            self._boot = self.clock()
            self._next_telemetry = self._boot
            self._last_command = -math.inf
            self._set(0, 0, self._boot)
            first = self.drive.sample(self._boot)
            self._ticks_at_boot = (first.left_ticks, first.right_ticks)
            self._tripped = True
            self._rx = bytearray()
            self.send(encode("B", FIRMWARE))

    @property
    def setpoint(self) -> tuple[int, int]:
        return self._setpoint

    @property
    def watchdog_tripped(self) -> bool:
        return self._tripped

    def _set(
        self, left: int, right: int, now: float, until: float = math.inf, brake: bool = False
    ) -> None:
        self._setpoint = (left, right)
        self.drive.command(left, right, now, until, brake)

    def on_data(self, data: bytes) -> None:
        with self._lock:
            if self.silent:
                return
            self._rx += data
            *lines, rest = self._rx.split(b"\n")
            self._rx = bytearray(rest)
            if len(self._rx) > MAX_LINE:  # no line end in sight: junk, like the firmware drops it
                self._rx.clear()
                self.rx_errors += 1
            for line in lines:
                self._handle(bytes(line))

    def _handle(self, line: bytes) -> None:
        now = self.clock()
        try:
            kind, fields = decode(line)
            if kind == "V":
                left, right = (max(-MAX_SPEED_MM_S, min(MAX_SPEED_MM_S, int(v))) for v in fields)
            elif kind in ("S", "?"):
                left, right = 0, 0
            else:
                raise ValueError(kind)
        except ValueError:
            self.rx_errors += 1
            return
        if kind == "?":
            self.send(encode("I", FIRMWARE, WATCHDOG_MS, TELEMETRY_HZ))
            return
        self.commands.append(Command(now, kind, left, right))
        self._set(left, right, now, until=now + WATCHDOG_MS / 1000.0, brake=kind == "S")
        self._last_command = now
        self._tripped = False

    def on_tick(self, now: float) -> None:
        with self._lock:
            if not self._tripped and now - self._last_command > WATCHDOG_MS / 1000.0:
                self._tripped = True
                self._set(0, 0, now)
                self.watchdog_trips += 1
            if now >= self._next_telemetry:
                self._next_telemetry = max(self._next_telemetry + 1.0 / TELEMETRY_HZ, now)
                sample = self.drive.sample(now)
                if not self.silent:
                    self.send(self._telemetry(now, sample))

    def _telemetry(self, now: float, sample: DriveSample) -> bytes:
        return encode(
            "T",
            int((now - self._boot) * 1000) & 0xFFFFFFFF,
            sample.left_ticks - self._ticks_at_boot[0],
            sample.right_ticks - self._ticks_at_boot[1],
            round(sample.gyro_z_dps * 1000.0),
            round(sample.left_mm_s),
            round(sample.right_mm_s),
            WATCHDOG_FLAG if self._tripped else 0,
            self.rx_errors,
        )
