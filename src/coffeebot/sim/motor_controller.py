"""A simulated motor controller on a pseudo-terminal, obeying ``docs/motor-protocol.md``.

Wheels follow their set-points at once, each scaled by its own ``drift`` factor (the real
motors differ). Encoders count ``ticks_per_mm``; the gyro reports the yaw rate the wheel
speeds imply over ``track_mm``. Every accepted command is kept in :attr:`commands` with its
time, so tests can check what the robot asked for and when the watchdog stopped it.
"""

from __future__ import annotations

import math
import time
from collections.abc import Callable
from dataclasses import dataclass

from coffeebot.hardware.motor import MAX_LINE, WATCHDOG_FLAG, WATCHDOG_MS, decode, encode
from coffeebot.sim.pty import PtyDevice

FIRMWARE = "sim-1.0"
TELEMETRY_HZ = 50
MAX_SPEED_MM_S = 1000


@dataclass(frozen=True)
class Command:
    time_s: float
    kind: str  # "V" or "S"
    left_mm_s: int
    right_mm_s: int


class SimMotorController(PtyDevice):
    def __init__(
        self,
        *,
        ticks_per_mm: float = 1.2,
        track_mm: float = 440.0,
        drift: tuple[float, float] = (1.0, 1.0),
        clock: Callable[[], float] = time.monotonic,
    ) -> None:
        self.ticks_per_mm = ticks_per_mm
        self.track_mm = track_mm
        self.drift = drift
        self.commands: list[Command] = []
        self.watchdog_trips = 0
        self.rx_errors = 0
        super().__init__("motor", clock=clock)

    def on_plugged(self) -> None:
        self.reset()

    def reset(self) -> None:
        """Power-on state: counters at zero, watchdog tripped, a ``B`` line on the wire."""
        with self._lock:
            self._boot = self.clock()
            self._last = self._boot
            self._next_telemetry = self._boot
            self._last_command = -math.inf
            self._setpoint = (0, 0)
            self._distance_mm = [0.0, 0.0]
            self._tripped = True
            self._rx = bytearray()
            self.send(encode("B", FIRMWARE))

    @property
    def setpoint(self) -> tuple[int, int]:
        return self._setpoint

    @property
    def watchdog_tripped(self) -> bool:
        return self._tripped

    def on_data(self, data: bytes) -> None:
        with self._lock:
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
        self._integrate(now)
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
        self._setpoint = (left, right)
        self._last_command = now
        self._tripped = False

    def on_tick(self, now: float) -> None:
        with self._lock:
            self._integrate(now)
            if not self._tripped and now - self._last_command > WATCHDOG_MS / 1000.0:
                self._tripped = True
                self._setpoint = (0, 0)
                self.watchdog_trips += 1
            if now >= self._next_telemetry:
                self._next_telemetry = max(self._next_telemetry + 1.0 / TELEMETRY_HZ, now)
                self.send(self._telemetry(now))

    def wheel_speeds(self) -> tuple[float, float]:
        return self._setpoint[0] * self.drift[0], self._setpoint[1] * self.drift[1]

    def _integrate(self, now: float) -> None:
        dt = now - self._last
        self._last = now
        for i, v in enumerate(self.wheel_speeds()):
            self._distance_mm[i] += v * dt

    def _telemetry(self, now: float) -> bytes:
        left, right = self.wheel_speeds()
        yaw_mdps = math.degrees((right - left) / self.track_mm) * 1000.0
        return encode(
            "T",
            int((now - self._boot) * 1000) & 0xFFFFFFFF,
            round(self._distance_mm[0] * self.ticks_per_mm),
            round(self._distance_mm[1] * self.ticks_per_mm),
            round(yaw_mdps),
            round(left),
            round(right),
            WATCHDOG_FLAG if self._tripped else 0,
            self.rx_errors,
        )
