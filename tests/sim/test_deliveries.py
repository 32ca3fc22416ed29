"""Whole deliveries: the scenarios in ``scenarios/`` run headless through the whole daemon.

The reliable ones must deliver (staff load the cup, the customer confirms pickup), touch
nothing, and stop at the ordered door; the others must touch nothing and, when held, say
why. Simulated time runs four times faster than the
wall clock (the fastest that keeps the sensor rates real, docs/scenarios.md), so each test
takes from a quarter to a full minute: they are marked ``slow`` to be skipped with
``-m "not slow"`` while working, and run in CI.
"""

from __future__ import annotations

from pathlib import Path

import pytest

from coffeebot.config import load_robot_config
from coffeebot.runtime import run_scenario
from coffeebot.sim.scenario import load_scenario

ROOT = Path(__file__).resolve().parents[2]
BOARD = ROOT / "boards" / "coffeebot-v1.toml"
SPEED = 4.0
DELIVERIES = [
    "floor2-delivery",  # 205, empty hallway
    "floor2-far",  # 202, the other wall, far end
    "floor3-elevator",  # 305, by elevator: the turns in the car and out of it
]
NOT_YET_RELIABLE = [
    "floor2-box-in-lane",  # 209, round a box: the detour does not get past it yet
]
"""Held by a front stop before the box in most runs (docs/navigation.md, "Known problems");
its test checks what must hold in every run: nothing touched, and a reason when held.

``floor3-walker`` is not a test yet: in some runs the walking person and the robot going
round it touch, or the robot is held by a front stop as it leaves the elevator, which is a
failure of the delivery, not a flaky test. It is kept in ``scenarios/`` and in
bench/delivery.py, which measures it."""
AT_THE_DOOR_MM = 200.0
"""Stopped at the ordered door rather than a neighbour (doors are metres apart). The
+/-50 mm precision target is measured by bench/delivery.py and not yet met everywhere."""


async def deliver(name: str) -> tuple[dict, dict]:
    config = load_robot_config(BOARD)
    scenario, plan = load_scenario(ROOT / "scenarios" / f"{name}.toml")
    report = await run_scenario(config, scenario, plan, speed=SPEED)
    [order] = report["orders"]
    return report, order


@pytest.mark.slow
@pytest.mark.parametrize("name", DELIVERIES)
async def test_delivers_without_touching_anything(name: str) -> None:
    report, order = await deliver(name)
    assert order["status"] == "delivered", order["detail"]
    assert report["collisions"] == []
    assert order["stop_error_mm"] <= AT_THE_DOOR_MM


@pytest.mark.slow
@pytest.mark.parametrize("name", NOT_YET_RELIABLE)
async def test_touches_nothing_and_a_held_robot_says_why(name: str) -> None:
    report, order = await deliver(name)
    assert report["collisions"] == []
    if order["status"] == "delivered":
        assert order["stop_error_mm"] <= AT_THE_DOOR_MM
    else:
        assert "blocked" in order["detail"] or "time limit" in order["detail"], order["detail"]
