"""Whole deliveries: the scenarios in ``scenarios/`` run headless through the whole daemon.

Each one must deliver (staff load the cup, the customer confirms pickup), touch nothing, and
stop at the door within the stop tolerance. Simulated time runs four times faster than the
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
    "floor2-box-in-lane",  # 209, round a box
    "floor3-elevator",  # 305, by elevator
    "floor3-walker",  # 308, by elevator, past a person walking
]


@pytest.mark.slow
@pytest.mark.parametrize("name", DELIVERIES)
async def test_delivers_without_touching_anything(name: str) -> None:
    config = load_robot_config(BOARD)
    scenario, plan = load_scenario(ROOT / "scenarios" / f"{name}.toml")
    report = await run_scenario(config, scenario, plan, speed=SPEED)
    [order] = report["orders"]
    assert order["status"] == "delivered", order["detail"]
    assert report["collisions"] == []
    assert order["stop_error_mm"] <= 2 * config.motion.stop_tolerance_mm
