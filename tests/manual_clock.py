"""A clock that moves only when the test moves it, so time-dependent code is tested exactly."""

from __future__ import annotations

import asyncio
import heapq
import itertools


async def settle(rounds: int = 20) -> None:
    """Let every task that is ready run until it waits again."""
    for _ in range(rounds):
        await asyncio.sleep(0)


class ManualClock:
    """Satisfies ``coffeebot.clock.Clock``; sleepers wake when ``advance`` passes their deadline."""

    def __init__(self, start: float = 0.0) -> None:
        self._now = start
        self._sleepers: list[tuple[float, int, asyncio.Future[None]]] = []
        self._order = itertools.count()

    def now(self) -> float:
        return self._now

    def next_deadline(self) -> float | None:
        """When the earliest sleeper is due, or None if nothing sleeps on this clock."""
        return self._sleepers[0][0] if self._sleepers else None

    async def sleep(self, seconds: float) -> None:
        future: asyncio.Future[None] = asyncio.get_running_loop().create_future()
        heapq.heappush(self._sleepers, (self._now + max(0.0, seconds), next(self._order), future))
        await future

    async def advance(self, seconds: float) -> None:
        """Step through every deadline up to ``now + seconds``, each sleeper waking on time."""
        target = self._now + seconds
        await settle()  # tasks created just now get to register their sleeps first
        while self._sleepers and self._sleepers[0][0] <= target:
            deadline, _, future = heapq.heappop(self._sleepers)
            self._now = max(self._now, deadline)
            if not future.done():
                future.set_result(None)
            await settle()
        self._now = target
        await settle()

    async def stall(self, seconds: float) -> None:
        """Jump ``seconds`` at once, as if the event loop had been blocked: sleepers wake late."""
        self._now += seconds
        await self.advance(0.0)
