"""Shared fixtures: the shipped floor plans and board, and tiny hand-made worlds."""

from __future__ import annotations

from collections.abc import Callable
from pathlib import Path
from typing import Any

import pytest

from coffeebot.config import load_robot_config
from coffeebot.floorplan import FloorPlan, load_floorplan, parse_floorplan
from coffeebot.sim.world import RobotSpec, SensorMount

ROOT = Path(__file__).resolve().parents[2]
CS_BUILDING = ROOT / "floorplans" / "cs-building.toml"
EXAMPLE = ROOT / "floorplans" / "example.toml"
BOARD = ROOT / "boards" / "coffeebot-v1.toml"


@pytest.fixture(scope="session")
def cs_building() -> FloorPlan:
    return load_floorplan(CS_BUILDING)


@pytest.fixture(scope="session")
def board_robot() -> RobotSpec:
    return RobotSpec.from_config(load_robot_config(BOARD))


def _tiny_plan_dict(**hallway: Any) -> dict[str, Any]:
    """A 10 m hallway along +x, 1700 mm wide: one office door on the right at s = 5000 mm
    (900 wide, recessed 100 mm), the tea room door on the left at s = 8000 mm."""
    return {
        "name": "tiny",
        "floors": [
            {
                "level": 1,
                "hallways": [
                    {"id": "main", "start": [0, 0], "end": [10000, 0], "width_mm": 1700, **hallway}
                ],
                "doors": [
                    {"room": "101", "side": "right", "at_mm": 5000, "recess_mm": 100},
                    {"room": "Tea", "kind": "tea_room", "side": "left", "at_mm": 8000},
                ],
                "anchors": [
                    {"id": "0A01", "x_mm": 0, "y_mm": 800},
                    {"id": "0A02", "x_mm": 5000, "y_mm": -800},
                    {"id": "0A03", "x_mm": 10000, "y_mm": 800},
                ],
            }
        ],
    }


@pytest.fixture
def plan_dict() -> Callable[..., dict[str, Any]]:
    """Builds the tiny floor plan document; keyword arguments override hallway fields."""
    return _tiny_plan_dict


@pytest.fixture
def tiny_plan() -> FloorPlan:
    return parse_floorplan(_tiny_plan_dict())


@pytest.fixture
def one_sensor() -> Callable[..., RobotSpec]:
    return _one_sensor


def _one_sensor(yaw_deg: float = 0.0, **kw: float) -> RobotSpec:
    """A robot with a single sensor at its centre, no slip: geometry is easy to reason on."""
    mount = SensorMount(x_mm=0, y_mm=0, yaw_deg=yaw_deg, height_mm=250)
    return RobotSpec(sensors=(mount,), slip_sigma=0.0, **kw)
