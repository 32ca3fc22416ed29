"""One injectable clock for the whole daemon.

Every module reads time and sleeps through a :class:`Clock`, never through ``time`` or
``asyncio.sleep`` directly, so the simulator can run the daemon faster than wall-clock time
and tests can reason about time without racing the machine.
"""

from __future__ import annotations

import asyncio
import heapq
import itertools
import threading
import time
from collections.abc import Callable
from typing import Protocol

from coffeebot.lockstep import Lockstep


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

    @property
    def rate(self) -> float:
        return self._segment[2]

    def now(self) -> float:
        sim0, real0, rate = self._segment
        return sim0 + (time.monotonic() - real0) * rate

    def set_rate(self, rate: float) -> None:
        """Run at ``rate`` x real time from now on (clamped to ``(0, speed]``)."""
        with self._lock:
            self._segment = (self.now(), time.monotonic(), min(max(rate, 1e-3), self.speed))

    def restart(self, start: float) -> None:
        """Read ``start`` from this moment on; replay uses it to line up with a recording."""
        with self._lock:
            self._segment = (start, time.monotonic(), self.rate)

    async def sleep(self, seconds: float) -> None:
        await asyncio.sleep(max(0.0, seconds) / self.rate)


class SteppedClock:
    """Simulated time that only the simulated world moves on: what the simulator runs on.

    ``now`` is the world's time; the simulation calls :meth:`advance` once per physics step,
    and only once the daemon has settled (:mod:`coffeebot.lockstep`): the event loop has
    nothing left to run and every worker thread has finished or waits for a later step. The
    daemon's computing therefore takes no simulated time, and a run is the same however busy
    the machine is; the world paces itself to ``speed`` times the machine's clock when it
    can (``math.inf``: as fast as it can).

    Sleeping waits until simulated time has passed, woken by the steps; :meth:`advance` must
    be called from the event loop the sleepers run on.
    """

    def __init__(self, speed: float = 1.0, start: float = 0.0) -> None:
        if not speed > 0:
            raise ValueError(f"clock speed must be positive, got {speed}")
        self.speed = speed
        self._t = start
        self._sleepers: list[tuple[float, int, asyncio.Future[None]]] = []
        self._count = itertools.count()
        self.lockstep = Lockstep(self.now)
        """Worker threads' calls, so the world steps only once they are done."""

    def now(self) -> float:
        return self._t

    def advance(self, dt: float) -> None:
        """Move time on by ``dt`` and wake whoever slept until then."""
        self._t += dt
        while self._sleepers and self._sleepers[0][0] <= self._t:
            _, _, waiter = heapq.heappop(self._sleepers)
            if not waiter.done():
                waiter.set_result(None)
        self.lockstep.wake()

    async def sleep(self, seconds: float) -> None:
        if seconds <= 0:
            await asyncio.sleep(0)
            return
        waiter = asyncio.get_running_loop().create_future()
        heapq.heappush(self._sleepers, (self._t + seconds, next(self._count), waiter))
        await waiter


def blocking_sleep(clock: Clock) -> Callable[[float], None]:
    """A sleep for driver code in a worker thread that agrees with ``clock``."""
    if isinstance(clock, SteppedClock):
        return clock.lockstep.sleep
    if isinstance(clock, ScaledClock):
        return lambda seconds: time.sleep(max(0.0, seconds) / clock.rate)
    return time.sleep
