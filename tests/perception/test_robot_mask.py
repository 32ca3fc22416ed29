"""The readings the particle filter leaves out because another robot of the fleet, standing
where the dispatcher says it stands, may have made them (the plan has no robots)."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest

from coffeebot.config import TofSensorConfig, load_robot_config
from coffeebot.floorplan import load_floorplan
from coffeebot.messages import (
    Odometry,
    OtherRobot,
    RangeReading,
    RangeScan,
    ReadingStatus,
    Traffic,
)
from coffeebot.navigation.passing import MAX_AGE_S
from coffeebot.perception.robot_mask import RobotMask
from coffeebot.perception.state import StateEstimator, make_fusion
from coffeebot.rectangles import corners, sides
from coffeebot.sim.world import Pose, RobotSpec, World
from coffeebot.sim.world.tof import as_range_reading, robot_setup

ROOT = Path(__file__).resolve().parents[2]
CONFIG = load_robot_config(ROOT / "boards" / "coffeebot-v1.toml")
PLAN = load_floorplan(ROOT / "floorplans" / "cs-building.toml")
AHEAD = TofSensorConfig(id=0, channel=0, face="front", x_mm=0, y_mm=0, yaw_deg=0)
"""One sensor at the body centre looking along +x."""
MASK = RobotMask([AHEAD], margin_mm=150.0)


def reads(distance_mm: int | None) -> RangeScan:
    status = ReadingStatus.VALID if distance_mm is not None else ReadingStatus.NO_TARGET
    reading = RangeReading(sensor=0, status=status, distance_mm=distance_mm)
    return RangeScan(cycle_start_s=0.0, cycle_time_s=0.02, readings=[reading])


def robot_at(x_mm: float, y_mm: float) -> np.ndarray:
    """Another robot's outline, 610 x 510 mm facing +y, grown by nothing."""
    return sides(corners(x_mm, y_mm, 610.0, 510.0, 90.0))


def test_a_reading_of_another_robot_ahead_is_left_out() -> None:
    # Its near side 1245 mm ahead; the reading says 1250.
    assert MASK.masked(reads(1250), (0.0, 0.0, 0.0), 2.0, [robot_at(1500.0, 0.0)]) == {0}


def test_something_in_front_of_the_other_robot_is_weighed() -> None:
    # A reading of 600 mm ends, with its margin, well short of the robot 1245 mm ahead:
    # something else is there (a person), which the range model judges as it judges people.
    assert not MASK.masked(reads(600), (0.0, 0.0, 0.0), 2.0, [robot_at(1500.0, 0.0)])


def test_a_robot_outside_the_cone_leaves_the_reading_in() -> None:
    # 1.5 m ahead and 1.2 m to the side: 39 degrees off the axis, outside the 13.5-degree
    # half cone even with the heading 10 degrees uncertain.
    assert not MASK.masked(reads(1600), (0.0, 0.0, 0.0), 10.0, [robot_at(1500.0, 1200.0)])
    # With the heading 30 degrees uncertain the widened cone may have met it.
    assert MASK.masked(reads(1600), (0.0, 0.0, 0.0), 30.0, [robot_at(1500.0, 1200.0)]) == {0}


def test_nothing_ranged_is_kept_and_no_robots_mask_nothing() -> None:
    assert not MASK.masked(reads(None), (0.0, 0.0, 0.0), 2.0, [robot_at(1500.0, 0.0)])
    assert not MASK.masked(reads(1250), (0.0, 0.0, 0.0), 2.0, [])


def other(**changes: object) -> OtherRobot:
    values: dict[str, object] = {
        "robot": "robot-2",
        "floor": 2,
        "x_mm": 43100.0,
        "y_mm": -3300.0,
        "heading_deg": 90.0,
        "moving": False,
        "reported_at_s": 0.0,
        "age_s": 0.2,
    }
    values.update(changes)
    return OtherRobot.model_validate(values)


def test_only_standing_robots_on_this_floor_with_a_fresh_report_count() -> None:
    state = StateEstimator(PLAN, CONFIG.motor, CONFIG.state, body=CONFIG.geometry)
    assert state.floor == 2
    assert state.other_robots(0.0) == []  # no fleet, no traffic
    robots = [
        other(),
        other(robot="robot-3", moving=True),
        other(robot="robot-4", floor=3),
        other(robot="robot-5", age_s=MAX_AGE_S + 0.1),
    ]
    state.on_traffic(Traffic(robots=robots), now=10.0)
    [outline] = state.other_robots(10.0)
    # Grown by the margin each side: 610 + 300 long (along y, the robot faces +y).
    margin = CONFIG.state.particles.robot_margin_mm
    xs, ys = outline[:, [0, 2]], outline[:, [1, 3]]
    assert ys.max() - ys.min() == pytest.approx(CONFIG.geometry.length_mm + 2 * margin)
    assert xs.max() - xs.min() == pytest.approx(CONFIG.geometry.width_mm + 2 * margin)
    # The traffic message itself ages: two seconds on, the report is stale.
    assert state.other_robots(10.0 + MAX_AGE_S) == []


# --- in the tea room among parked robots ----------------------------------------------------

SPEC = RobotSpec.from_config(CONFIG)
SETUP = robot_setup(CONFIG.tof)
LOADING_SPOT = Pose(42000.0, -1657.0, -90.0)
"""Facing into the room, on the door's axis."""
OWN_SPOT = (40900.0, -3300.0)
PARKED = [(43100.0, -3300.0), (40900.0, -5000.0), (43100.0, -5000.0)]
"""The fleet's other parking spots, each with a robot facing the door."""
ROOM_SPEED_MM_S = 300.0


def worst_error_to_own_spot(seed: int, *, traffic: bool) -> float:
    """From the loading spot along the door's axis to the spot's depth, a quarter turn, and
    across to its spot (as a fleet's robot parks), steered on the truth; the estimate's
    largest error on the way. The state estimator is fed as the daemon feeds it: odometry
    at 50 Hz, scans and UWB at 10 Hz, the dispatcher's traffic twice a second."""
    world = World(PLAN, SPEC, floor=2, pose=LOADING_SPOT, seed=seed)
    for k, (x, y) in enumerate(PARKED):
        world.add_robot(SPEC, 2, Pose(x, y, 90.0), f"parked-{k}")
    state = StateEstimator(
        PLAN, CONFIG.motor, CONFIG.state, make_fusion(CONFIG, PLAN), body=CONFIG.geometry
    )
    state.place(LOADING_SPOT.x_mm, LOADING_SPOT.y_mm, LOADING_SPOT.heading_deg, 2)
    parked = Traffic(
        robots=[other(robot=f"parked-{k}", x_mm=x, y_mm=y) for k, (x, y) in enumerate(PARKED)]
    )
    errors: list[float] = []
    tick = 0

    def step(left: float, right: float) -> None:
        nonlocal tick
        now, robot = world.t_s, world.robot
        tick += 1
        lt, rt = robot.encoder_ticks
        odometry = Odometry(
            controller_time_ms=round(now * 1000),
            left_ticks=lt,
            right_ticks=rt,
            gyro_z_dps=robot.gyro_z_dps(),
            left_mm_s=0.0,
            right_mm_s=0.0,
        )
        state.on_odometry(odometry, now)
        if traffic and tick % 25 == 0:
            state.on_traffic(parked, now)
        if tick % 5 == 0:
            fix = robot.uwb_fix()
            if fix is not None:
                state.on_uwb(fix, now)
            readings = [as_range_reading(i, r) for i, r in enumerate(robot.scan(SETUP))]
            state.on_scan(RangeScan(cycle_start_s=now, cycle_time_s=0.02, readings=readings), now)
        robot.command_wheels(left, right)
        world.step(0.02)
        estimate, truth = state.pose(), robot.pose
        errors.append(math.hypot(estimate.x_mm - truth.x_mm, estimate.y_mm - truth.y_mm))

    def ahead(heading_deg: float) -> tuple[float, float]:
        error = math.radians(math.remainder(heading_deg - world.robot.pose.heading_deg, 360.0))
        turn = 2.0 * error * SPEC.wheel_base_mm / 2
        return ROOM_SPEED_MM_S - turn, ROOM_SPEED_MM_S + turn

    for _ in range(50):
        step(0.0, 0.0)
    while world.robot.pose.y_mm > OWN_SPOT[1]:
        step(*ahead(-90.0))
    while abs(error := math.remainder(180.0 - world.robot.pose.heading_deg, 360.0)) > 2.0:
        rate = max(-150.0, min(150.0, 4.0 * error))
        step(-rate, rate)
    while world.robot.pose.x_mm > OWN_SPOT[0]:
        step(*ahead(180.0))
    for _ in range(50):
        step(0.0, 0.0)
    assert tick < 1500, "the robot should be at its spot in under 30 s"
    return max(errors)


@pytest.mark.parametrize("seed", range(1, 13))
def test_parking_past_the_fleets_parked_robots_keeps_the_estimate(seed: int) -> None:
    # Without the traffic the largest errors of these twelve runs were 76-450 mm (ten of
    # them over 110 mm); with the robots left out, but their scans still feeding the
    # recovery monitor, 41-86 mm and 249 mm in one (its fit fell, injected particles won);
    # as built, 39-86 mm.
    assert worst_error_to_own_spot(seed, traffic=True) < 110.0
