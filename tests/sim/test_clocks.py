"""The simulator's clocks: simulated time only the world moves on, and the replay's scaled
wall clock. (The lockstep between the world and the worker threads: test_lockstep.py.)"""

from __future__ import annotations

import asyncio

import pytest

from coffeebot.clock import ScaledClock, SteppedClock


def test_scaled_rate_change_keeps_time_continuous_and_monotonic() -> None:
    clock = ScaledClock(speed=8.0, start=100.0)
    before = clock.now()
    clock.set_rate(2.0)
    after = clock.now()
    assert before <= after < before + 0.05
    assert clock.rate == 2.0


def test_scaled_rate_is_clamped_to_the_requested_speed() -> None:
    clock = ScaledClock(speed=4.0)
    clock.set_rate(10.0)
    assert clock.rate == 4.0
    clock.set_rate(0.0)
    assert 0 < clock.rate < 0.01


async def test_stepped_time_moves_only_when_stepped_and_wakes_sleepers_in_order() -> None:
    clock = SteppedClock(speed=4.0, start=10.0)
    woke: list[tuple[str, float]] = []

    async def sleeper(name: str, seconds: float) -> None:
        await clock.sleep(seconds)
        woke.append((name, clock.now()))

    tasks = [asyncio.create_task(sleeper("late", 0.03)), asyncio.create_task(sleeper("soon", 0.01))]
    await asyncio.sleep(0.05)  # wall time passes, simulated time does not
    assert clock.now() == 10.0 and woke == []
    for _ in range(4):
        clock.advance(0.01)
        await asyncio.sleep(0)
    await asyncio.gather(*tasks)
    assert woke == [("soon", pytest.approx(10.01)), ("late", pytest.approx(10.03))]
