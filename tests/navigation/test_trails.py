"""Marks another robot of the fleet left behind go once the traffic says it drove on; marks
made again after it left, or of a robot still there, stay; without traffic nothing changes."""

from __future__ import annotations

import math

import numpy as np
from helpers import CONFIG, PLAN, PLANNER, SETUP, reported, true_pose

from coffeebot.messages import RangeReading, RangeScan, ReadingStatus, Traffic
from coffeebot.modules.motion import MotionModule
from coffeebot.sim.world import Pose, RobotSpec, World
from coffeebot.sim.world.tof import as_range_reading

FLOOR = PLAN.floor(2)
HEADING = FLOOR.hallway.heading_deg
START_S = 20000.0
LANE = PLANNER.lane_mm(FLOOR, 1.0)
AHEAD_MM = 1200.0
"""What the front sensors read: something this far ahead of the robot's centre."""


def seeing_ahead(module: MotionModule, t0: float, t1: float) -> None:
    """The robot at ``START_S`` in its lane, its front sensors reading ``AHEAD_MM`` from
    ``t0`` to ``t1`` (the rest nothing in range)."""
    x, y = FLOOR.from_hallway(START_S, LANE)
    front = {s.id for s in CONFIG.tof.sensors if s.face == "front"}
    readings = [
        RangeReading(sensor=s.id, status=ReadingStatus.VALID, distance_mm=AHEAD_MM)
        if s.id in front
        else RangeReading(sensor=s.id, status=ReadingStatus.OUT_OF_BOUNDS)
        for s in CONFIG.tof.sensors
    ]
    for t in np.arange(t0, t1, 0.05):
        scan = RangeScan(cycle_start_s=float(t), cycle_time_s=0.05, readings=readings)
        module.costmap.update(scan, FLOOR, x, y, HEADING, float(t))


def other_at(s_mm: float, t: float, module: MotionModule, *, floor: int = 2) -> None:
    """The traffic at ``t``: robot-2 driving, at ``s_mm`` in the robot's lane."""
    x, y = FLOOR.from_hallway(s_mm, LANE)
    robot = reported(x, y, HEADING + 180, floor=floor, moving=True)
    module.controller.note_traffic(Traffic(robots=[robot]), t)


def marks(module: MotionModule, now: float) -> int:
    return module.costmap.obstacles(now).xs.size


def test_what_a_robot_that_drove_on_marked_is_forgotten() -> None:
    module = MotionModule(CONFIG, PLAN)
    where = START_S + AHEAD_MM + CONFIG.geometry.length_mm / 2
    for t in (0.0, 0.5, 1.0, 1.5):
        other_at(where, t, module)
    seeing_ahead(module, 0.0, 2.0)
    other_at(where, 2.0, module)
    assert marks(module, 2.0) > 0
    other_at(where + 2500.0, 3.0, module)  # it turned round and drove off
    assert marks(module, 3.0) == 0


def test_a_robot_still_there_keeps_its_marks() -> None:
    module = MotionModule(CONFIG, PLAN)
    where = START_S + AHEAD_MM + CONFIG.geometry.length_mm / 2
    seeing_ahead(module, 0.0, 2.0)
    for t in (0.0, 1.0, 2.0, 3.0):
        other_at(where, t, module)
    assert marks(module, 3.0) > 0


def test_marks_made_after_the_robot_left_stay() -> None:
    """Something seen where the robot was after it left is not the robot."""
    module = MotionModule(CONFIG, PLAN)
    where = START_S + AHEAD_MM + CONFIG.geometry.length_mm / 2
    other_at(where, 0.0, module)
    other_at(where + 2500.0, 1.0, module)
    seeing_ahead(module, 2.0, 3.0)
    other_at(where + 2500.0, 3.0, module)
    assert marks(module, 3.0) > 0


def test_marks_nowhere_near_the_robots_way_stay() -> None:
    module = MotionModule(CONFIG, PLAN)
    seeing_ahead(module, 0.0, 2.0)
    for t in (0.0, 1.0, 2.0, 3.0):
        other_at(START_S + 6000.0 + 500 * t, t, module)
    assert marks(module, 3.0) > 0


def test_a_robot_gone_to_another_floor_took_its_marks() -> None:
    module = MotionModule(CONFIG, PLAN)
    where = START_S + AHEAD_MM + CONFIG.geometry.length_mm / 2
    other_at(where, 0.0, module)
    seeing_ahead(module, 0.0, 2.0)
    other_at(where, 2.0, module)
    other_at(where, 3.0, module, floor=3)
    assert marks(module, 3.0) == 0


def trail_left(with_traffic: bool) -> list[tuple[float, float]]:
    """The marks (s, d) left in the costmap of a robot standing in its lane, turned 30
    degrees towards the hallway's middle, as another drives past it the other way in its
    passing lane at 800 mm/s, from 4 m ahead to 5 m behind."""
    spec = RobotSpec.from_config(CONFIG)
    x, y = FLOOR.from_hallway(13000.0, LANE)
    world = World(PLAN, spec, floor=2, pose=Pose(x, y, HEADING + 30), obstacles=[], seed=3)
    passing_lane = -LANE + math.copysign(150.0, -LANE)
    s = 17000.0
    other = world.add_robot(spec, 2, Pose(*FLOOR.from_hallway(s, passing_lane), HEADING + 180), "b")
    module = MotionModule(CONFIG, PLAN)
    pose = true_pose(world.robot)
    for step in range(round(9000 / 40)):
        if with_traffic and step % 10 == 0:  # twice a second
            bx, by = FLOOR.from_hallway(s, passing_lane)
            robot = reported(bx, by, HEADING + 180, moving=True)
            module.controller.note_traffic(Traffic(robots=[robot]), world.t_s)
        readings = [as_range_reading(k, r) for k, r in enumerate(world.robot.scan(SETUP))]
        scan = RangeScan(cycle_start_s=world.t_s, cycle_time_s=0.05, readings=readings)
        module.costmap.update(scan, FLOOR, pose.x_mm, pose.y_mm, pose.heading_deg, world.t_s)
        s -= 40.0
        other.place(Pose(*FLOOR.from_hallway(s, passing_lane), HEADING + 180), 2)
        world.step(0.05)
    xs, ys, _, _ = module.costmap.obstacles(world.t_s)
    return [FLOOR.to_hallway(x, y) for x, y in zip(xs, ys, strict=True)]


def test_a_passing_robots_trail_goes_with_the_traffic() -> None:
    assert trail_left(with_traffic=False)  # out of every cone since it was made
    assert not trail_left(with_traffic=True)
