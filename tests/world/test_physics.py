"""Drive kinematics, encoders and gyro against ground truth; collisions; UWB; determinism."""

from __future__ import annotations

import math
from collections.abc import Callable

import numpy as np
import pytest

from coffeebot.floorplan import FloorPlan
from coffeebot.sim.world import ObstacleSpec, Pose, RobotSpec, UwbModel, World
from coffeebot.sim.world.geometry import Surfaces, footprint_contacts


def _drive(world: World, seconds: float, left: float, right: float, dt: float = 0.02) -> None:
    world.robot.command_wheels(left, right)
    for _ in range(round(seconds / dt)):
        world.step(dt)


def test_equal_motors_drive_straight(tiny_plan: FloorPlan) -> None:
    robot = RobotSpec(right_motor_gain=1.0, slip_sigma=0.0)
    world = World(tiny_plan, robot, floor=1, pose=Pose(1000, 0, 0))
    _drive(world, 4.0, 500, 500)
    assert world.robot.pose.heading_deg == pytest.approx(0.0, abs=1e-9)
    assert world.robot.pose.y_mm == pytest.approx(0.0, abs=1e-6)
    # Reaching 500 mm/s at 500 mm/s^2 takes 1 s and 250 mm, then 3 s at full speed.
    assert world.robot.pose.x_mm == pytest.approx(1000 + 250 + 500 * 3.0, abs=1.0)


def test_the_motor_controllers_watchdog_stops_the_wheels_within_one_long_step(
    tiny_plan: FloorPlan,
) -> None:
    """A set-point holds only until its watchdog deadline, in the world's own time: a world
    stepped late by two seconds (the firmware's thread starved on a loaded machine) must not
    drive on for those two seconds."""
    robot = RobotSpec(right_motor_gain=1.0, slip_sigma=0.0)
    world = World(tiny_plan, robot, floor=1, pose=Pose(1000, 0, 0))
    _drive(world, 1.0, 300, 300)
    start = world.robot.pose.x_mm
    world.robot.command_wheels(300, 300, until_s=world.t_s + 0.2)
    world.step(2.0)
    # 0.2 s at 300 mm/s, then braking at 500 mm/s^2: 60 + 90 mm, not 600.
    assert world.robot.pose.x_mm - start == pytest.approx(150.0, abs=2.0)
    assert world.robot.wheel_speeds_mm_s == (0.0, 0.0)


def test_unequal_motors_drift_towards_the_weaker_side(tiny_plan: FloorPlan) -> None:
    robot = RobotSpec(right_motor_gain=0.98, slip_sigma=0.0)
    world = World(tiny_plan, robot, floor=1, pose=Pose(1000, 0, 0))
    _drive(world, 4.0, 500, 500)
    state = world.robot.body.state
    left_mm, right_mm = state.left_turned_mm, state.right_turned_mm
    # Arc model: the heading change is the difference of wheel travel over the wheel base.
    expected = math.degrees((right_mm - left_mm) / robot.wheel_base_mm)
    assert expected == pytest.approx(math.degrees(-0.02 * left_mm / 450))
    assert world.robot.pose.heading_deg == pytest.approx(expected, rel=1e-9)
    assert world.robot.pose.heading_deg < -4
    assert world.robot.pose.y_mm < -30


def test_encoders_and_gyro_agree_with_ground_truth(tiny_plan: FloorPlan) -> None:
    """An S-bend with slip: the encoders' and the bias-corrected gyro's headings track the
    true heading within their noise (0.1 deg tick quantisation, sub-degree random walks)."""
    robot = RobotSpec(slip_sigma=0.005, gyro_bias_dps=0.5, gyro_noise_dps=0.2)
    world = World(tiny_plan, robot, floor=1, pose=Pose(2000, 0, 0), seed=3)
    dt = 0.02
    gyro_heading = 0.0
    start_ticks = world.robot.encoder_ticks
    start_heading = world.robot.pose.heading_deg
    travelled = 0.0
    for i in range(400):
        turn = 120 * math.sin(i * dt * 2 * math.pi / 4)
        world.robot.command_wheels(300 - turn, 300 + turn)
        before = world.robot.pose
        world.step(dt)
        after = world.robot.pose
        travelled += math.dist(before[:2], after[:2])
        gyro_heading += (world.robot.gyro_z_dps() - robot.gyro_bias_dps) * dt
    assert world.robot.collisions == []
    true_change = after.heading_deg - start_heading
    assert abs(true_change) > 1.0
    ticks_l = world.robot.encoder_ticks[0] - start_ticks[0]
    ticks_r = world.robot.encoder_ticks[1] - start_ticks[1]
    per_mm = robot.ticks_per_mm
    encoder_heading = math.degrees((ticks_r - ticks_l) / per_mm / robot.wheel_base_mm)
    assert encoder_heading == pytest.approx(true_change, abs=0.5)
    assert gyro_heading == pytest.approx(true_change, abs=0.5)
    encoder_distance = (ticks_l + ticks_r) / 2 / per_mm
    assert encoder_distance == pytest.approx(travelled, rel=0.02)


def test_gyro_at_rest_reads_its_bias(tiny_plan: FloorPlan) -> None:
    robot = RobotSpec(gyro_bias_dps=0.5, gyro_noise_dps=0.2)
    world = World(tiny_plan, robot, floor=1, pose=Pose(2000, 0, 0), seed=1)
    samples = np.array([world.robot.gyro_z_dps() for _ in range(400)])
    assert samples.mean() == pytest.approx(0.5, abs=3 * 0.2 / 20)
    assert samples.std() == pytest.approx(0.2, rel=0.2)


def test_acceleration_is_limited(tiny_plan: FloorPlan) -> None:
    world = World(tiny_plan, RobotSpec(slip_sigma=0.0), floor=1, pose=Pose(2000, 0, 0))
    _drive(world, 0.5, 800, 800)
    assert world.robot.wheel_speeds_mm_s[0] == pytest.approx(250.0)


def test_a_stop_line_brakes_harder_than_the_ramp(tiny_plan: FloorPlan) -> None:
    """From 500 mm/s a zero set-point ramps down in 1 s and 250 mm; the stop line brakes at
    1000 mm/s^2, standing in 0.5 s and 125 mm."""
    travelled = []
    for brake in (False, True):
        robot = RobotSpec(right_motor_gain=1.0, slip_sigma=0.0)
        world = World(tiny_plan, robot, floor=1, pose=Pose(500, 0, 0))
        _drive(world, 1.2, 500, 500)
        start = world.robot.pose.x_mm
        world.robot.command_wheels(0.0, 0.0, brake=brake)
        for _ in range(round(0.5 / 0.02)):
            world.step(0.02)
        standing = world.robot.wheel_speeds_mm_s == (0.0, 0.0)
        for _ in range(round(0.6 / 0.02)):
            world.step(0.02)
        travelled.append((standing, world.robot.pose.x_mm - start))
    (ramp_standing, ramp_mm), (brake_standing, brake_mm) = travelled
    assert not ramp_standing and ramp_mm == pytest.approx(250.0, abs=1.0)
    assert brake_standing and brake_mm == pytest.approx(125.0, abs=1.0)
    # The next set-point is followed on the ramp again.
    world.robot.command_wheels(800, 800)
    world.step(0.5)
    assert world.robot.wheel_speeds_mm_s[0] == pytest.approx(250.0)


def test_driving_into_the_end_wall_is_one_collision(tiny_plan: FloorPlan) -> None:
    robot = RobotSpec(right_motor_gain=1.0, slip_sigma=0.0)
    world = World(tiny_plan, robot, floor=1, pose=Pose(8500, 0, 0))
    _drive(world, 6.0, 400, 400)
    assert len(world.robot.collisions) == 1
    hit = world.robot.collisions[0]
    assert hit.element == "hallway end wall"
    assert hit.x_mm == pytest.approx(10000)
    assert abs(hit.y_mm) < 255
    assert hit.speed_mm_s == pytest.approx(400, rel=0.01)
    # 0.8 s and 160 mm to reach 400 mm/s, then the front edge closes the remaining gap.
    assert hit.t_s == pytest.approx(0.8 + (10000 - 305 - 8500 - 160) / 400, abs=0.01)
    # Pushing on keeps the body out of the wall and does not add collisions.
    assert world.robot.pose.x_mm + robot.length_mm / 2 <= 10000
    assert world.robot.body.state.speed_mm_s == 0.0
    # Backing off and driving in again is a second collision.
    _drive(world, 1.5, -300, -300)
    _drive(world, 3.0, 300, 300)
    assert [c.element for c in world.robot.collisions] == ["hallway end wall"] * 2


def test_collision_with_the_mail_cart_names_it(tiny_plan: FloorPlan) -> None:
    cart = ObstacleSpec(id="cart", kind="mail_cart", floor=1, x_mm=3000, y_mm=0, heading_deg=90)
    robot = RobotSpec(right_motor_gain=1.0, slip_sigma=0.0)
    world = World(tiny_plan, robot, floor=1, pose=Pose(1500, 0, 0), obstacles=[cart])
    _drive(world, 5.0, 300, 300)
    elements = {c.element for c in world.robot.collisions}
    assert "cart lower shelf" in elements
    assert all(c.x_mm == pytest.approx(2750) for c in world.robot.collisions)


def test_a_walking_person_bumps_into_a_parked_robot(tiny_plan: FloorPlan) -> None:
    person = ObstacleSpec(
        id="walker",
        kind="person",
        floor=1,
        x_mm=6000,
        y_mm=200,
        path=[(1000, 200)],
        speed_mm_s=1000,
        path_mode="once",
    )
    world = World(tiny_plan, RobotSpec(), floor=1, pose=Pose(3000, 0, 0), obstacles=[person])
    for _ in range(60):
        world.step(0.05)
    assert world.robot.collisions, "the person walked through the robot"
    first = world.robot.collisions[0]
    assert first.element.startswith("walker")
    assert first.speed_mm_s == 0.0
    assert first.t_s == pytest.approx((6000 - 3000 - 305 - 180) / 1000, abs=0.05)


def test_overhead_surfaces_do_not_collide() -> None:
    table = Surfaces(np.array([[-1000, 0, 1000, 0, 1000, 1050]]), ("table",), np.zeros((0, 5)), ())
    assert footprint_contacts(table, 0, 0, 0, 305, 255, (20, 900)) == []
    low = Surfaces(np.array([[-1000, 0, 1000, 0, 0, 50]]), ("rail",), np.zeros((0, 5)), ())
    assert [c.element for c in footprint_contacts(low, 0, 0, 0, 305, 255, (20, 900))] == ["rail"]


def test_turning_swings_the_rear_around_the_front_axle(tiny_plan: FloorPlan) -> None:
    robot = RobotSpec(right_motor_gain=1.0, slip_sigma=0.0)
    world = World(tiny_plan, robot, floor=1, pose=Pose(5000, 0, 0))
    _drive(world, 2.0, -100, 100)  # spin in place about the axle
    theta = math.radians(world.robot.pose.heading_deg)
    pose = world.robot.pose
    axle = (pose.x_mm + 150 * math.cos(theta), pose.y_mm + 150 * math.sin(theta))
    assert axle == pytest.approx((5150, 0), abs=1e-6)
    assert world.robot.pose.heading_deg > 20


def test_same_seed_same_world(cs_building: FloorPlan, board_robot: RobotSpec) -> None:
    def run(seed: int) -> tuple[list[object], Pose]:
        world = World(cs_building, board_robot, floor=2, pose=Pose(3000, -400, 0), seed=seed)
        scans = []
        world.robot.command_wheels(400, 410)
        for _ in range(20):
            world.step(0.1)
            scans.append(world.robot.scan())
        return scans, world.robot.pose

    assert run(5) == run(5)
    assert run(5) != run(6)


def test_uwb_fix_is_near_the_truth(tiny_plan: FloorPlan) -> None:
    world = World(tiny_plan, RobotSpec(), floor=1, pose=Pose(4000, -200, 90), seed=2)
    tag = world.robot.uwb_tag_position()
    assert tag == pytest.approx((4000, -200, 900))
    fixes = [world.robot.uwb_fix() for _ in range(200)]
    assert all(f is not None for f in fixes)
    errors = np.array([[f.x_mm - tag[0], f.y_mm - tag[1]] for f in fixes if f])
    assert np.abs(errors.mean(axis=0)).max() < 30
    assert errors.std(axis=0) == pytest.approx([100, 100], rel=0.25)
    first = fixes[0]
    assert first is not None and [a.anchor_id for a in first.anchors] == ["0A02", "0A01", "0A03"]


def test_uwb_needs_three_anchors(tiny_plan: FloorPlan) -> None:
    short = UwbModel(max_anchor_range_mm=5000)
    world = World(tiny_plan, RobotSpec(), floor=1, pose=Pose(9000, 0, 0), uwb=short)
    assert world.robot.uwb_fix() is None


def test_elevator_ride_changes_floor(cs_building: FloorPlan, board_robot: RobotSpec) -> None:
    world = World(cs_building, board_robot, floor=2, pose=Pose(41000, 0, 0))
    world.robot.place(Pose(42000, 300, -90), floor=3)
    assert world.robot.floor.level == 3
    assert world.robot.pose == Pose(42000, 300, -90)
    assert world.robot.uwb_fix() is not None
    assert len(world.robot.scan()) == 8


def test_obstacle_on_unknown_floor_is_refused(
    tiny_plan: FloorPlan, one_sensor: Callable[..., RobotSpec]
) -> None:
    box = ObstacleSpec(id="b", kind="cardboard_box", floor=7, x_mm=0, y_mm=0)
    with pytest.raises(KeyError, match="no floor 7"):
        World(tiny_plan, one_sensor(), floor=1, pose=Pose(2000, 0, 0), obstacles=[box])
