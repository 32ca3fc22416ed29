"""A turn on the spot is begun only with room for its sweep.

The robot turns about its axle, 150 mm ahead of the body's centre, so its rear corners swing
522 mm out, where no sensor looks. A quarter turn begun in a lane 300 mm from a wall, away
from it, puts a rear corner 33 mm from the wall; begun beside another robot, it swings into
it, the collision monitor stops it halfway, and the two stand askew in each other's way.
"""

from __future__ import annotations

import math

import numpy as np
import pytest
from helpers import CONFIG, PLAN, estimate_at

from coffeebot.messages import (
    MotionState,
    MoveInstruction,
    RangeReading,
    RangeScan,
    ReadingStatus,
)
from coffeebot.modules.motion import MotionModule
from coffeebot.navigation.dwa import axle_point, rollout
from coffeebot.perception.geometry import wrap_deg

FLOOR = PLAN.floor(2)
HALF_WIDTH = FLOOR.hallway.width_mm / 2
S_MM = 20000.0
"""A stretch of plain wall on both sides."""
KEEP_RIGHT_D = -HALF_WIDTH + CONFIG.motion.wall_distance_mm + CONFIG.geometry.width_mm / 2
"""The keep-right lane travelling east: the body's right side 300 mm from the wall."""
EAST = FLOOR.hallway.heading_deg


def module_at(
    d_mm: float, readings: dict[int, float] | None = None, s_mm: float = S_MM
) -> MotionModule:
    """The motion module of a robot standing at ``s_mm``, ``d_mm`` facing east, whose
    sensors have read ``readings`` (sensor id: mm; nothing in range on the others)."""
    module = MotionModule(CONFIG, PLAN)
    x, y = FLOOR.from_hallway(s_mm, d_mm)
    module.costmap.reset(FLOOR, x, y)
    seen = readings or {}
    scan = RangeScan(
        cycle_start_s=0.0,
        cycle_time_s=0.05,
        readings=[
            RangeReading(sensor=s.id, status=ReadingStatus.VALID, distance_mm=seen[s.id])
            if s.id in seen
            else RangeReading(sensor=s.id, status=ReadingStatus.OUT_OF_BOUNDS)
            for s in CONFIG.tof.sensors
        ],
    )
    for t in np.arange(0.0, 1.0, 0.05):
        module.costmap.update(scan, FLOOR, x, y, EAST, float(t))
    return module


def turn_to(
    module: MotionModule,
    d_mm: float,
    heading_deg: float,
    periods: int = 10,
    s_mm: float = S_MM,
    from_deg: float = EAST,
):
    """The commands of ``periods`` control periods turning from ``from_deg`` towards
    ``heading_deg``."""
    x, y = FLOOR.from_hallway(s_mm, d_mm)
    pose = estimate_at(2, x, y, from_deg)
    instruction = MoveInstruction(id=1, action="turn", floor=2, heading_deg=heading_deg)
    return [
        module.controller.step(instruction, pose, 1.0 + 0.05 * k, 0.05, 500.0)
        for k in range(periods)
    ]


def closest_wall_mm(module: MotionModule, d_mm: float, heading_deg: float) -> float:
    """The least gap between the body and a plan wall along the turn."""
    x, y = FLOOR.from_hallway(S_MM, d_mm)
    turn = math.radians(heading_deg - EAST)
    times = np.linspace(0.0, abs(turn), 37)
    xs, ys, headings = rollout(
        (x, y, math.radians(EAST)),
        np.zeros(1),
        np.array([math.copysign(1.0, turn)]),
        times,
        module.costmap.footprint.axle_x_mm,
    )
    return float(module.costmap.wall_gaps(xs, ys, headings).min())


def test_a_corner_past_the_wall_reads_as_a_negative_gap() -> None:
    """Facing across the hallway 200 mm from the wall, the rear corners lie 105 mm past it:
    a turn checked every few degrees can land a corner there, and measured only as a
    distance it would read as clear of the wall as a lane 105 mm from it."""
    module = module_at(KEEP_RIGHT_D)
    x, y = FLOOR.from_hallway(S_MM, -HALF_WIDTH + 200.0)
    north = math.radians(EAST + 90.0)
    gap = module.costmap.wall_gaps(np.array([x]), np.array([y]), np.array([north]))[0]
    assert gap == pytest.approx(-(CONFIG.geometry.length_mm / 2 - 200.0), abs=1.0)


def test_a_turn_away_from_the_near_wall_is_not_begun_and_the_robot_says_so() -> None:
    module = module_at(KEEP_RIGHT_D)
    # Turning left, the rear swings right, into the wall the lane keeps 300 mm from.
    assert closest_wall_mm(module, KEEP_RIGHT_D, EAST + 90.0) < CONFIG.motion.turn_clearance_mm
    commands = turn_to(module, KEEP_RIGHT_D, EAST + 90.0)
    assert all(c.yaw_rate_dps == 0.0 and c.speed_mm_s == 0.0 for c in commands)
    assert commands[-1].status.state is MotionState.BLOCKED
    assert commands[-1].status.detail.startswith("no room to turn")


def test_the_same_turn_towards_the_near_wall_is_made() -> None:
    module = module_at(KEEP_RIGHT_D)
    assert closest_wall_mm(module, KEEP_RIGHT_D, EAST - 90.0) > CONFIG.motion.turn_clearance_mm
    commands = turn_to(module, KEEP_RIGHT_D, EAST - 90.0)
    assert commands[-1].status.state is MotionState.MOVING
    assert commands[-1].yaw_rate_dps < 0.0


def test_a_turn_whose_rear_swings_into_something_beside_the_robot_is_not_begun() -> None:
    """Another robot 150 mm off the left side (both left sensors see it): turning right
    swings the rear-left corner 267 mm out to the left, into it; in the middle of the hallway
    the walls alone would allow it."""
    module = module_at(0.0, readings={6: 150.0, 7: 150.0})
    blocked = turn_to(module, 0.0, EAST - 90.0)
    assert blocked[-1].status.state is MotionState.BLOCKED
    assert all(c.yaw_rate_dps == 0.0 for c in blocked)
    free = turn_to(module_at(0.0), 0.0, EAST - 90.0)
    assert free[-1].status.state is MotionState.MOVING and free[-1].yaw_rate_dps < 0.0


def test_a_turn_under_way_is_not_judged_again_each_period() -> None:
    """Once begun, the collision monitor guards the turn: a costmap that fills in beside the
    robot as it turns does not freeze it halfway, askew."""
    module = module_at(0.0)
    first = turn_to(module, 0.0, EAST - 90.0, periods=3)
    assert first[-1].yaw_rate_dps < 0.0
    module.controller.costmap = module_at(0.0, readings={6: 150.0, 7: 150.0}).costmap
    again = turn_to(module, 0.0, EAST - 90.0, periods=3)
    assert all(c.yaw_rate_dps < 0.0 for c in again)


def test_a_half_turn_with_no_room_beside_the_wall_is_made_after_driving_towards_the_middle() -> (
    None
):
    """A robot sent east stands facing west, 35 degrees into the left wall, its axle 399 mm
    from it: where one stood for good after going round past its stop in the fleet test (its
    half turn, begun there, was stopped by the collision monitor with the wall 224 mm ahead).
    It squares up, drives west towards the middle until any turn has room, stops, then turns
    east, keeping a turn's clearance to the walls all the way."""
    module = module_at(0.0)
    heading = math.radians(EAST + 145.0)
    axle_x, axle_y = FLOOR.from_hallway(S_MM, 451.0)
    axle = module.costmap.footprint.axle_x_mm
    pose = (axle_x - axle * math.cos(heading), axle_y - axle * math.sin(heading), heading)
    instruction = MoveInstruction(
        id=1, action="follow_lane", floor=2, target_s_mm=S_MM + 3000.0, stop=True
    )
    turned_at_d: float | None = None
    least_gap = math.inf
    for k in range(1200):
        estimate = estimate_at(2, pose[0], pose[1], math.degrees(pose[2]))
        command = module.controller.step(instruction, estimate, 1.0 + 0.05 * k, 0.05, 500.0)
        assert command.status.state is not MotionState.BLOCKED, command.status.detail
        if turned_at_d is None and command.status.detail == "turning into the lane":
            turned_at_d = FLOOR.to_hallway(*axle_point(*pose, axle))[1]
        if turned_at_d is not None and abs(wrap_deg(math.degrees(pose[2]) - EAST)) < 5.0:
            break
        xs, ys, headings = rollout(
            pose,
            np.array([command.speed_mm_s]),
            np.array([math.radians(command.yaw_rate_dps)]),
            np.array([0.05]),
            axle,
        )
        pose = (float(xs[0, -1]), float(ys[0, -1]), float(headings[0, -1]))
        least_gap = min(least_gap, gap_to_walls(module, pose))
    else:
        raise AssertionError(f"not turned east: {command.status.detail}")
    assert turned_at_d is not None
    reach = math.hypot(CONFIG.geometry.length_mm / 2 + axle, CONFIG.geometry.width_mm / 2)
    assert abs(turned_at_d) <= HALF_WIDTH - reach - CONFIG.motion.turn_clearance_mm
    assert least_gap >= CONFIG.motion.turn_clearance_mm


def gap_to_walls(module: MotionModule, pose: tuple[float, float, float]) -> float:
    """The least gap between the body at ``pose`` (x, y, heading rad) and a plan wall."""
    x, y, heading = (np.array([[v]]) for v in pose)
    return float(module.costmap.wall_gaps(x, y, heading).min())


def first_turn_rates(s_mm: float, d_mm: float, heading_deg: float, to_deg: float) -> list[float]:
    """The yaw rates of the first control periods of a robot standing ``s_mm`` along the
    hallway, ``d_mm`` left of its axis, facing ``heading_deg``, told to turn to ``to_deg``
    (nothing seen around it)."""
    module = module_at(d_mm, s_mm=s_mm)
    commands = turn_to(module, d_mm, to_deg, periods=3, s_mm=s_mm, from_deg=heading_deg)
    return [command.yaw_rate_dps for command in commands]


def test_a_half_turn_beside_a_wall_swings_the_front_through_the_hallways_middle() -> None:
    """Turning round at an office door, the robot turns the way that swings its front (near
    the axle) through the hallway's middle and its rear (corners half a metre from the
    axle) along the wall, into the door's recess: swung the other way (the shorter by a
    degree, or either at exactly 180), a robot turning round at 213's door swept its rear
    across the hallway into a robot that had come up beside the other wall, and the two
    stood pressed together for good in the fleet benchmark. On the centre line either way
    sweeps alike: the shorter."""
    west = FLOOR.hallway.heading_deg + 180.0
    east = FLOOR.hallway.heading_deg
    for room, side in (("213", 1.0), ("212", -1.0)):
        door = PLAN.find_room(room).door
        at_door = side * (HALF_WIDTH - 558.0)  # where a robot stands at a door (292 mm)
        for heading in (west, west - 1.0, west + 1.0):
            rates = first_turn_rates(door.at_mm, at_door, heading, east)
            # Left of the axis the front swings right (south) to the middle, and vice versa.
            assert all(rate * side > 0.0 for rate in rates), (room, heading, rates)
    # On the centre line: the shorter way, whichever side that is.
    assert all(rate < 0.0 for rate in first_turn_rates(S_MM, 0.0, west - 1.0, east))
    assert all(rate > 0.0 for rate in first_turn_rates(S_MM, 0.0, west + 1.0, east))


def test_a_turn_on_the_spot_waits_until_the_robot_stands() -> None:
    """Begun rolling, a turn sweeps from further on than its room was checked (in the
    elevator car a robot rolled 76 mm deeper as it began its half turn, and from there its
    sweep had no room): it begins once the robot stands."""
    module = module_at(KEEP_RIGHT_D)
    x, y = FLOOR.from_hallway(S_MM, KEEP_RIGHT_D)
    rolling = estimate_at(2, x, y, EAST).model_copy(update={"speed_mm_s": 120.0})
    instruction = MoveInstruction(id=1, action="turn", floor=2, heading_deg=EAST - 90.0)
    command = module.controller.step(instruction, rolling, 1.0, 0.05, 500.0)
    assert (command.speed_mm_s, command.yaw_rate_dps) == (0.0, 0.0)
    assert command.status.state is MotionState.MOVING
    standing = rolling.model_copy(update={"speed_mm_s": 0.0})
    assert module.controller.step(instruction, standing, 1.05, 0.05, 500.0).yaw_rate_dps < 0.0
