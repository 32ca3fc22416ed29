"""Another robot of the fleet standing beside the lane, seen by a robot turned towards it
(as one coming out of the elevator turns): its cones' arcs reach into the passing lane; with
the robot's outline from the traffic, only the outline is marked."""

from __future__ import annotations

import math

import pytest
from helpers import CONFIG, PLAN, SETUP, reported, true_pose

from coffeebot.messages import OtherRobot, RangeScan, Traffic
from coffeebot.modules.motion import MotionModule
from coffeebot.navigation.others import standing_outlines
from coffeebot.navigation.passing import MAX_AGE_S
from coffeebot.sim.world import Pose, RobotSpec, World
from coffeebot.sim.world.tof import as_range_reading

FLOOR = PLAN.floor(2)
HEADING = FLOOR.hallway.heading_deg
STANDING_AT = (17000.0, -361.0)
"""s, d of the standing robot: by its passing lane on the right, facing +s."""
PASSING_D = 90.0
"""Cells beyond this d are in the passing lane (445 mm) of a robot going the other way."""


def standing(x_mm: float, y_mm: float, *, moving: bool = False, age_s: float = 0.0) -> OtherRobot:
    return reported(x_mm, y_mm, HEADING, floor=FLOOR.level, moving=moving, age_s=age_s)


def marked_d(with_traffic: bool) -> list[float]:
    """The d of every cell marked by a robot 1.3 m behind the standing one, in the keep-right
    lane of the other side, turned 40 degrees towards it, after two seconds of scans."""
    xa, ya = FLOOR.from_hallway(STANDING_AT[0] - 1300, 295.0)
    xb, yb = FLOOR.from_hallway(*STANDING_AT)
    spec = RobotSpec.from_config(CONFIG)
    world = World(PLAN, spec, floor=2, pose=Pose(xa, ya, HEADING - 40), obstacles=[], seed=3)
    world.add_robot(spec, 2, Pose(xb, yb, HEADING), "robot-2")
    module = MotionModule(CONFIG, PLAN)
    if with_traffic:
        module.controller.note_traffic(Traffic(robots=[standing(xb, yb)]), 0.0)
    pose = true_pose(world.robot)
    for _ in range(40):
        readings = [as_range_reading(k, r) for k, r in enumerate(world.robot.scan(SETUP))]
        scan = RangeScan(cycle_start_s=world.t_s, cycle_time_s=0.05, readings=readings)
        robots = module.controller.standing_robots(FLOOR.level, world.t_s)
        module.costmap.update(
            scan, FLOOR, pose.x_mm, pose.y_mm, pose.heading_deg, world.t_s, robots=robots
        )
        world.step(0.05)
    xs, ys, _, _ = module.costmap.obstacles(world.t_s)
    return [FLOOR.to_hallway(x, y)[1] for x, y in zip(xs, ys, strict=True)]


def test_without_traffic_the_arcs_reach_into_the_passing_lane() -> None:
    assert max(marked_d(with_traffic=False)) > PASSING_D


def test_with_traffic_only_the_outline_is_marked() -> None:
    marked = marked_d(with_traffic=True)
    half_width = CONFIG.geometry.width_mm / 2
    res = CONFIG.motion.costmap_resolution_mm
    assert marked
    assert max(marked) < STANDING_AT[1] + half_width + res
    assert min(marked) > STANDING_AT[1] - half_width - res


def test_only_fresh_reports_of_standing_robots_on_the_floor_count() -> None:
    length, width = CONFIG.geometry.length_mm, CONFIG.geometry.width_mm
    x, y = FLOOR.from_hallway(*STANDING_AT)
    (outline,) = standing_outlines([standing(x, y)], FLOOR.level, length, width)
    sides = [math.hypot(x1 - x0, y1 - y0) for x0, y0, x1, y1 in outline]
    assert sorted(sides) == pytest.approx([width, width, length, length])
    assert not standing_outlines([standing(x, y, moving=True)], FLOOR.level, length, width)
    assert not standing_outlines([standing(x, y)], FLOOR.level + 1, length, width)
    stale = standing(x, y, age_s=MAX_AGE_S / 2)
    assert standing_outlines([stale], FLOOR.level, length, width, age_s=MAX_AGE_S / 4)
    assert not standing_outlines([stale], FLOOR.level, length, width, age_s=MAX_AGE_S)
