"""A clock for tests and benchmarks that runs on simulated time only."""

from __future__ import annotations

import asyncio


class SteppedClock:
    """Simulated time that moves only when someone sleeps.

    Every sleep returns at once with the clock advanced, so rates in simulated time are exact
    whatever the machine's load. Suited to one time-driven task plus simulated devices that
    read :meth:`now`; :meth:`advance` is the blocking sleep for driver threads.
    """

    def __init__(self) -> None:
        self.t = 0.0

    def now(self) -> float:
        return self.t

    def advance(self, seconds: float) -> None:
        self.t += max(0.0, seconds)

    async def sleep(self, seconds: float) -> None:
        self.advance(seconds)
        await asyncio.sleep(0)
