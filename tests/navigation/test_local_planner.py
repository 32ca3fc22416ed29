"""The costmap's marking and clearing, its wall gaps and the dynamic window's way out of a
lethal zone."""

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
from coffeebot.navigation.dwa import DwaChoice, DynamicWindow, rollout
from coffeebot.perception.geometry import sensor_origin

FLOOR = PLAN.floor(2)
HALF_WIDTH = FLOOR.hallway.width_mm / 2


def costmap_at(x: float, y: float):
    costmap = MotionModule(CONFIG, PLAN).costmap
    costmap.reset(FLOOR, x, y)
    return costmap


def one_sensor_scan(sensor: int, distance_mm: float | None) -> RangeScan:
    """A scan of one sensor: a reading at ``distance_mm``, or nothing in range."""
    reading = (
        RangeReading(sensor=sensor, status=ReadingStatus.OUT_OF_BOUNDS)
        if distance_mm is None
        else RangeReading(sensor=sensor, status=ReadingStatus.VALID, distance_mm=distance_mm)
    )
    return RangeScan(cycle_start_s=0.0, cycle_time_s=0.05, readings=[reading])


def marked_near(costmap, x: float, y: float, now: float) -> bool:
    xs, ys, _, _ = costmap.obstacles(now)
    return bool(np.any(np.hypot(xs - x, ys - y) < costmap.res))


def test_an_empty_cone_clears_only_where_it_looks_whatever_the_heading_error() -> None:
    """The pose's heading may be a few degrees off, so a cone that sees nothing clears only
    the part it looks through whatever the error: an obstacle near the edge of where the
    cone is thought to look may be just outside where it really looks (a box beside the
    robot, turning away from it, was forgotten that way and the robot turned back into
    it)."""
    x, y = FLOOR.from_hallway(13000.0, 0.0)
    heading = FLOOR.hallway.heading_deg
    costmap = costmap_at(x, y)
    sensor = next(s for s in CONFIG.tof.sensors if s.id == 3)
    costmap.update(one_sensor_scan(3, 700), FLOOR, x, y, heading, 0.0)
    sx, sy, look = sensor_origin(x, y, heading, sensor)
    ahead = (sx + 700 * math.cos(math.radians(look)), sy + 700 * math.sin(math.radians(look)))
    assert marked_near(costmap, *ahead, 0.0)
    marked = costmap.obstacles(0.0)[0].size
    # Turned 8 degrees away with the heading known to 4 degrees: what was straight ahead is
    # now inside the 13.5 degree cone as placed, but the cone may really look 4 degrees
    # further away, past it.
    sx, sy, look = sensor_origin(x, y, heading + 8.0, sensor)
    off_axis = abs(math.degrees(math.atan2(ahead[1] - sy, ahead[0] - sx)) - look)
    half_fov = CONFIG.tof.cone_half_deg
    assert half_fov - 4.0 < off_axis < half_fov
    costmap.update(one_sensor_scan(3, None), FLOOR, x, y, heading + 8.0, 0.1, 4.0)
    assert marked_near(costmap, *ahead, 0.1)
    assert costmap.obstacles(0.1)[0].size < marked  # the middle of the cone was cleared
    # Known to a degree, the whole cone clears: the edge of an arc marked by one reading is
    # no obstacle for good.
    costmap.update(one_sensor_scan(3, None), FLOOR, x, y, heading + 8.0, 0.2, 1.0)
    assert not marked_near(costmap, *ahead, 0.2)


def test_planned_arcs_turn_the_body_about_its_axle() -> None:
    """A quarter turn on the spot swings the centre round the axle 150 mm ahead of it (the
    rear corners sweep that much further out than a turn about the centre would take
    them); a straight line at 400 mm/s moves it 400 mm in a second."""
    xs, ys, thetas = rollout(
        (0.0, 0.0, 0.0), np.array([0.0, 400.0]), np.array([math.pi / 2, 0.0]), np.ones(1), 150.0
    )
    assert (xs[0, 0], ys[0, 0]) == (pytest.approx(150.0), pytest.approx(-150.0))
    assert thetas[0, 0] == pytest.approx(math.pi / 2)
    assert (xs[1, 0], ys[1, 0], thetas[1, 0]) == (pytest.approx(400.0), 0.0, 0.0)


def test_a_turned_body_reaches_the_wall_with_a_corner() -> None:
    """Parallel to the wall the gap is the centre distance less half the width; turned 45
    degrees, a front corner is far nearer the wall than that."""
    s, d = 13000.0, -HALF_WIDTH + 500.0
    x, y = FLOOR.from_hallway(s, d)
    costmap = costmap_at(x, y)
    travel = math.radians(FLOOR.hallway.heading_deg)
    parallel = costmap.wall_gaps(np.array([x]), np.array([y]), np.array([travel]))[0]
    turned = costmap.wall_gaps(np.array([x]), np.array([y]), np.array([travel - math.pi / 4]))[0]
    assert abs(parallel - (500.0 - CONFIG.geometry.width_mm / 2)) < 1.0
    corner = math.hypot(CONFIG.geometry.length_mm / 2, CONFIG.geometry.width_mm / 2)
    expected = 500.0 - corner * math.sin(math.pi / 4 + math.atan2(255.0, 305.0))
    assert abs(turned - expected) < 1.0
    assert turned < parallel - 100.0


def choice_beside_the_wall(
    gap_mm: float, towards_deg: float, speed: float, lane_mm: float
) -> DwaChoice | None:
    """The window's choice for a robot driving +s at ``speed``, its side ``gap_mm`` from the
    right wall, heading ``towards_deg`` towards it, for ``lane_mm``."""
    d = -HALF_WIDTH + CONFIG.geometry.width_mm / 2 + gap_mm
    x, y = FLOOR.from_hallway(13000.0, d)
    return DynamicWindow(CONFIG.motion, CONFIG.motor.axle_x_mm).choose(
        costmap_at(x, y),
        FLOOR,
        (x, y, FLOOR.hallway.heading_deg - towards_deg),
        speed,
        0.0,
        lane_mm=lane_mm,
        direction=1.0,
        max_speed_mm_s=500.0,
        dt_s=0.05,
        now=0.0,
    )


def test_too_close_to_a_wall_the_window_steers_away_instead_of_giving_up() -> None:
    """60 mm from the wall is inside the side clearance, so every pose is "lethal"; arcs that
    end no nearer are still admissible. At speed, the best of them turns away from the wall
    (slowly: a turn first swings the rear corner towards it)."""
    choice = choice_beside_the_wall(gap_mm=60.0, towards_deg=0.0, speed=400.0, lane_mm=0.0)
    assert choice is not None
    assert choice.speed_mm_s > 0 and choice.yaw_rate_dps > 0  # forward, turning to the left


def test_placed_past_the_wall_the_window_still_steers_away() -> None:
    """The estimate puts the body's side 20 mm past the wall (a corner past a wall is a
    negative gap): an arc that goes no further past it still counts as getting out, or the
    robot could never move again."""
    choice = choice_beside_the_wall(gap_mm=-20.0, towards_deg=0.0, speed=100.0, lane_mm=0.0)
    assert choice is not None
    assert choice.speed_mm_s > 0 and choice.yaw_rate_dps > 0


@pytest.mark.parametrize(
    ("gap", "speed"), [(109.0, 0.0), (100.0, 0.0), (100.0, 100.0), (95.0, 50.0)]
)
def test_beside_the_wall_the_window_turns_away_swinging_the_rear_towards_it(
    gap: float, speed: float
) -> None:
    """At the edge of the side clearance, heading 1.7 degrees towards the wall, for the lane
    across the hallway: a turn away swings the rear corner (455 mm behind the axle) towards
    the wall first, which no sensor watches; it may come to the turn clearance, as in a turn
    on the spot. Held to the side clearance, the window found only creeping straight on (at
    100 mm/s no arc at all): a robot gone round something beside the wall crept 2.85 m
    along it in 115 s, to where its turn into the car had no room."""
    choice = choice_beside_the_wall(gap_mm=gap, towards_deg=1.7, speed=speed, lane_mm=295.0)
    assert choice is not None
    assert choice.speed_mm_s > 0 and choice.yaw_rate_dps > 0  # forward, turning to the left


def test_from_a_standstill_the_window_heads_for_the_lane_instead_of_swinging_the_centre() -> None:
    """Standing still 300 mm right of its lane in an empty hallway, the robot must not turn
    right, away from it. A turn to the right about the axle ahead swings the centre left,
    towards the lane, without getting anywhere: scored at the centre, that looked like the
    best way to the lane."""
    d = 0.0
    x, y = FLOOR.from_hallway(13000.0, d)
    choice = DynamicWindow(CONFIG.motion, CONFIG.motor.axle_x_mm).choose(
        costmap_at(x, y),
        FLOOR,
        (x, y, FLOOR.hallway.heading_deg),
        0.0,
        0.0,
        lane_mm=d + 300.0,
        direction=1.0,
        max_speed_mm_s=300.0,
        dt_s=0.05,
        now=0.0,
    )
    assert choice is not None
    assert choice.yaw_rate_dps >= 0  # never to the right


def test_seen_late_close_to_a_wide_obstacle_it_turns_out_instead_of_giving_up() -> None:
    """A mail cart seen late: the robot has stopped with the cart 480 mm ahead, inside the
    zone the planner keeps free, across the right half of its lane. Every arc from a
    standstill reaches further into that zone, so the robot first turns on the spot towards
    the free side (no forward speed), rather than reporting "no way past" for good."""
    lane_d = -HALF_WIDTH + CONFIG.motion.wall_distance_mm + CONFIG.geometry.width_mm / 2
    x, y = FLOOR.from_hallway(20000.0, lane_d)
    module = MotionModule(CONFIG, PLAN)
    module.costmap.reset(FLOOR, x, y)
    blocked = {2: 480, 3: 480, 4: 480}  # the front sensors on the right and the middle
    readings = [
        RangeReading(sensor=s.id, status=ReadingStatus.VALID, distance_mm=blocked[s.id])
        if s.id in blocked
        else RangeReading(sensor=s.id, status=ReadingStatus.OUT_OF_BOUNDS)
        for s in CONFIG.tof.sensors
    ]
    scan = RangeScan(cycle_start_s=0.0, cycle_time_s=0.05, readings=readings)
    heading = FLOOR.hallway.heading_deg
    for t in np.arange(0.0, 3.0, 0.05):  # seen for long enough to count as standing still
        module.costmap.update(scan, FLOOR, x, y, heading, float(t))
    pose = estimate_at(2, x, y, heading)
    instruction = MoveInstruction(
        id=1, action="follow_lane", floor=2, target_s_mm=30000.0, lane_mm=lane_d, avoid=True
    )
    states, rates = [], []
    for k in range(20):
        command = module.controller.step(instruction, pose, 3.0 + 0.05 * k, 0.05, 500.0)
        states.append(command.status.state)
        rates.append(command.yaw_rate_dps)
        assert command.speed_mm_s < 1.0  # nothing forward into the zone
    assert MotionState.BLOCKED not in states[-5:]
    assert rates[-1] > 0  # turning left, away from the cart on the right
