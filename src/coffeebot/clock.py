"""One injectable clock for the whole daemon.

Every module reads time and sleeps through a :class:`Clock`, never through ``time`` or
``asyncio.sleep`` directly, so the simulator can run the daemon faster than wall-clock time
and tests can reason about time without racing the machine.
"""

from __future__ import annotations

import asyncio
import contextlib
import threading
import time
from collections.abc import Iterator
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
    """Simulated time running up to ``speed`` times faster than the machine's monotonic clock.

    Simulated seconds start at ``start`` (zero, or a recording's first stamp when replaying)
    when the clock is made. Sleeping ``dt`` simulated seconds sleeps ``dt / rate`` real
    seconds, so every module keeps its rates in simulated time.

    ``rate`` starts at ``speed`` and may be lowered (never above ``speed``) by whoever paces
    the simulation when the machine cannot keep up: simulated time then slows down instead of
    running away from the sensors, as a physics simulator's real-time factor does. Time stays
    continuous and monotonic across a rate change.
    """

    def __init__(self, speed: float = 1.0, start: float = 0.0) -> None:
        if speed <= 0:
            raise ValueError(f"clock speed must be positive, got {speed}")
        self.speed = speed
        # One tuple, replaced whole: driver threads read it while the loop changes the rate.
        self._segment = (start, time.monotonic(), speed)
        self._lock = threading.Lock()
        self._holds = 0
        self._frozen: float | None = None

    @property
    def rate(self) -> float:
        return self._segment[2]

    def now(self) -> float:
        frozen = self._frozen
        if frozen is not None:
            return frozen
        sim0, real0, rate = self._segment
        return sim0 + (time.monotonic() - real0) * rate

    def set_rate(self, rate: float) -> None:
        """Run at ``rate`` x real time from now on (clamped to ``(0, speed]``)."""
        with self._lock:
            self._segment = (self.now(), time.monotonic(), min(max(rate, 1e-3), self.speed))

    @contextlib.contextmanager
    def hold(self) -> Iterator[None]:
        """Simulated time stands still inside: the simulated world's own computing (casting
        the sensors' cones, stepping the physics) takes no simulated time, as physics does
        not, so a busy machine makes a run slower, not different. Threads may hold at once;
        time moves on when the last lets go."""
        with self._lock:
            if self._holds == 0:
                self._frozen = self.now()
            self._holds += 1
        try:
            yield
        finally:
            with self._lock:
                self._holds -= 1
                if self._holds == 0 and self._frozen is not None:
                    self._segment = (self._frozen, time.monotonic(), self.rate)
                    self._frozen = None

    def restart(self, start: float) -> None:
        """Read ``start`` from this moment on; replay uses it to line up with a recording."""
        with self._lock:
            self._segment = (start, time.monotonic(), self.rate)

    async def sleep(self, seconds: float) -> None:
        await asyncio.sleep(max(0.0, seconds) / self.rate)
