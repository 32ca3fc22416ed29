"""One injectable clock for the whole daemon.

Every module reads time and sleeps through a :class:`Clock`, never through ``time`` or
``asyncio.sleep`` directly, so the simulator can run the daemon faster than wall-clock time
and tests can reason about time without racing the machine.
"""

from __future__ import annotations

import asyncio
import time
from typing import Protocol


class Clock(Protocol):
    """Monotonic seconds and a sleep that agrees with them."""

    def now(self) -> float: ...

    async def sleep(self, seconds: float) -> None: ...


class MonotonicClock:
    """Wall-clock time: what runs on the robot."""

    def now(self) -> float:
        return time.monotonic()

    async def sleep(self, seconds: float) -> None:
        await asyncio.sleep(max(0.0, seconds))


class ScaledClock:
    """Simulated time running ``speed`` times faster than the machine's monotonic clock.

    Simulated seconds start at ``start`` (zero, or a recording's first stamp when replaying)
    when the clock is made. Sleeping ``dt`` simulated seconds sleeps ``dt / speed`` real
    seconds, so every module keeps its rates in simulated time.
    """

    def __init__(self, speed: float = 1.0, start: float = 0.0) -> None:
        if speed <= 0:
            raise ValueError(f"clock speed must be positive, got {speed}")
        self.speed = speed
        self.start = start
        self._origin = time.monotonic()

    def now(self) -> float:
        return self.start + (time.monotonic() - self._origin) * self.speed

    def restart(self, start: float) -> None:
        """Read ``start`` from this moment on; replay uses it to line up with a recording."""
        self.start = start
        self._origin = time.monotonic()

    async def sleep(self, seconds: float) -> None:
        await asyncio.sleep(max(0.0, seconds) / self.speed)
