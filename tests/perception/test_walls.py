"""The plan's walls along rays, and the pose the walls are placed from, carried on by the
wheels through a heading-sigma spike."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest

from coffeebot.floorplan import load_floorplan
from coffeebot.messages import PoseEstimate
from coffeebot.perception.tracking import Odometry2D
from coffeebot.perception.walls import carried, trusted, wall_ranges

PLAN = load_floorplan(Path(__file__).resolve().parents[2] / "floorplans" / "cs-building.toml")


def pose(heading_deg: float, sigma_heading_deg: float = 1.0) -> PoseEstimate:
    return PoseEstimate(
        x_mm=1000.0,
        y_mm=-300.0,
        heading_deg=heading_deg,
        floor=2,
        sigma_x_mm=20.0,
        sigma_y_mm=20.0,
        sigma_heading_deg=sigma_heading_deg,
    )


def test_a_pose_with_a_wide_heading_sigma_is_not_trusted() -> None:
    assert trusted(pose(0.0, 2.0))
    assert not trusted(pose(0.0, 35.8))


def test_odometry_since_a_snapshot_is_in_the_robot_frame_of_then() -> None:
    odometry = Odometry2D()
    odometry.advance(0.0, 90.0, 1.0)  # turn to face +y in the odometry frame
    then = odometry.snapshot()
    odometry.advance(500.0, 0.0, 1.0)  # 500 mm straight ahead
    forward, left, turned = odometry.since(then)
    assert forward == pytest.approx(500.0)
    assert left == pytest.approx(0.0, abs=1e-9)
    assert turned == pytest.approx(0.0)


def test_a_carried_pose_moves_along_its_own_heading_and_keeps_its_sigmas() -> None:
    start = pose(90.0)
    moved = carried(start, 200.0, 50.0, math.radians(10.0))
    assert moved.x_mm == pytest.approx(1000.0 - 50.0)
    assert moved.y_mm == pytest.approx(-300.0 + 200.0)
    assert moved.heading_deg == pytest.approx(100.0)
    assert moved.sigma_heading_deg == start.sigma_heading_deg
    assert carried(pose(175.0), 0.0, 0.0, math.radians(10.0)).heading_deg == pytest.approx(-175.0)


def test_walls_within_reach_are_where_the_whole_floor_puts_them_and_none_beyond() -> None:
    floor = PLAN.floor(2)
    origins = np.array([floor.from_hallway(12000.0, 300.0), floor.from_hallway(30000.0, -600.0)])
    angles = np.radians(np.linspace(-180.0, 180.0, 721))[None, :].repeat(2, axis=0)
    everywhere = wall_ranges(floor, origins, angles)
    assert np.isfinite(everywhere).all()  # inside the hallway, every ray meets a wall
    for reach in (np.array([700.0, 1200.0]), np.array([3000.0, 500.0])):
        within = wall_ranges(floor, origins, angles, reach)
        close = everywhere <= reach[:, None]
        assert close.any(axis=1).all() and not close.all(axis=1).any()
        assert np.array_equal(within[close], everywhere[close])  # the same, to the bit
        assert np.isinf(within[~close]).all()
    # Each origin's rays alone give what they give together.
    alone = wall_ranges(floor, origins[1:], angles[1:], 3000.0)
    assert np.array_equal(alone[0], wall_ranges(floor, origins, angles, 3000.0)[1])
