"""One injectable clock for the whole daemon.

Every module reads time and sleeps through a :class:`Clock`, never through ``time`` or
``asyncio.sleep`` directly, so the simulator can run the daemon faster than wall-clock time
and tests can reason about time without racing the machine.
"""

from __future__ import annotations

import asyncio
import contextlib
import heapq
import itertools
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

    ``now`` is the world's time; the world module calls :meth:`advance` once per physics
    step, pacing itself to ``speed`` times the machine's clock when it can. A machine too
    busy to keep up (other processes, a loaded core) therefore makes a run slower, never
    different: while the daemon's process gets no CPU, simulated time does not pass either,
    so no sensor goes stale and no verdict gets old for lack of CPU. While any thread is
    inside the world (the chips asking for their cones' returns from the I2C worker), time
    does not move on either (:meth:`hold`): computing the world is not time the robot has.

    Sleeping waits until simulated time has passed, woken by the steps; :meth:`advance` must
    be called from the event loop the sleepers run on. Until the first step (the hardware
    self-check, before the daemon's modules start, talks to the simulated chips) time runs
    freely at ``speed``, as a :class:`ScaledClock` would.
    """

    def __init__(self, speed: float = 1.0, start: float = 0.0) -> None:
        if speed <= 0:
            raise ValueError(f"clock speed must be positive, got {speed}")
        self.speed = speed
        self._free = ScaledClock(speed, start)
        self._t: float | None = None
        """Simulated time once the world steps it; None while it still runs freely."""
        self._sleepers: list[tuple[float, int, asyncio.Future[None]]] = []
        self._count = itertools.count()
        self._lock = threading.Lock()
        self._holds = 0

    def now(self) -> float:
        t = self._t
        return self._free.now() if t is None else t

    @contextlib.contextmanager
    def hold(self) -> Iterator[None]:
        """Time does not move on while any thread is inside (threads may overlap)."""
        with self._lock:
            self._holds += 1
        try:
            yield
        finally:
            with self._lock:
                self._holds -= 1

    def advance(self, dt: float) -> bool:
        """Move time on by ``dt`` and wake whoever slept until then; refused (False) while
        held."""
        with self._lock:
            if self._holds:
                return False
            self._t = (self._free.now() if self._t is None else self._t) + dt
            t = self._t
        while self._sleepers and self._sleepers[0][0] <= t:
            _, _, waiter = heapq.heappop(self._sleepers)
            if not waiter.done():
                waiter.set_result(None)
        return True

    async def sleep(self, seconds: float) -> None:
        if self._t is None:
            await self._free.sleep(seconds)
            return
        if seconds <= 0:
            await asyncio.sleep(0)
            return
        waiter = asyncio.get_running_loop().create_future()
        heapq.heappush(self._sleepers, (self._t + seconds, next(self._count), waiter))
        await waiter
