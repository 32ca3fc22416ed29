"""Whole deliveries: the scenarios in ``scenarios/`` run headless through the whole daemon.

Each must deliver every order (staff load the cup once the robot is back in the tea room,
the customer confirms pickup), touch nothing, and stop at the ordered door. Simulated time
runs as fast as the machine goes: the daemon runs in lockstep with the world, so a run is
the same run at any speed (docs/scenarios.md, "Speed"). Each test takes from a quarter of a
minute to a minute and a half: they are marked ``slow`` to be skipped with ``-m "not slow"``
while working, and run in CI.
"""

from __future__ import annotations

import math
from pathlib import Path

import pytest

from coffeebot.config import load_robot_config
from coffeebot.scenario.report import ScenarioReport
from coffeebot.scenario.run import run_scenario
from coffeebot.scenario.spec import load_scenario

ROOT = Path(__file__).resolve().parents[2]
BOARD = ROOT / "boards" / "coffeebot-v1.toml"
SPEED = math.inf
"""Flat out: the same run as at any pace, sooner."""
DELIVERIES = [
    "floor2-delivery",  # 205, empty hallway
    "floor2-far",  # 202, the other wall, far end
    "floor2-two-orders",  # 207, back into the tea room, then 204
    "floor2-box-in-lane",  # 209, round a cardboard box standing in the lane
    "floor3-elevator",  # 305 via the elevator
    "floor3-walker",  # 308 via the elevator, a person walking towards the robot
    # Linden Hall: hallways that bend and branch.
    "linden-bend",  # 112, round the L into the east wing
    "linden-junction",  # 121, right at the T into the south wing
    "linden-far-side",  # 104, past the south wing's mouth
    "linden-other-floor",  # 205, by the elevator, where floor 2's hallway narrows
    "linden-box-in-wing",  # 113, round a box in the east wing
    "linden-second-car",  # 202 from the east wing, by the nearer of two cars
]
EKF_DELIVERIES = [
    "floor3-elevator",  # turns in the car, a ride, another floor
]
"""With ``[state] fusion = "ekf"`` (the default is the particle filter): the scenario that
depends most on the estimate. All six run with each fusion in
``bench/deliveries_by_fusion.py`` (a second run of all six here would double the suite's
longest part)."""
AT_THE_DOOR_MM = 100.0
"""Stopped at the ordered door, well inside the door's width. The +/-50 mm precision
target is a 95th percentile, measured over many runs by bench/delivery.py."""


async def run(name: str, fusion: str) -> ScenarioReport:
    """The report of ``scenarios/NAME.toml`` run through the whole daemon."""
    config = load_robot_config(BOARD)
    config = config.model_copy(update={"state": config.state.model_copy(update={"fusion": fusion})})
    scenario, plan = load_scenario(ROOT / "scenarios" / f"{name}.toml")
    return await run_scenario(config, scenario, plan, speed=SPEED)


@pytest.mark.slow
@pytest.mark.parametrize(
    ("name", "fusion"),
    [(name, "particles") for name in DELIVERIES] + [(name, "ekf") for name in EKF_DELIVERIES],
)
async def test_delivers_without_touching_anything(name: str, fusion: str) -> None:
    report = await run(name, fusion)
    assert report.collisions == []
    assert report.orders, "the scenario placed no order"
    for order in report.orders:
        assert order.status == "delivered", f"{order.room}: {order.detail}"
        assert order.stop_error_mm is not None and order.stop_error_mm <= AT_THE_DOOR_MM, order.room
