"""Obstacles scripted against the robot: a walk that starts as it approaches, a dropped box."""

from __future__ import annotations

import pytest

from coffeebot.floorplan import FloorPlan
from coffeebot.sim.world import ObstacleSpec, Pose, RobotSpec, World

ROBOT = RobotSpec(right_motor_gain=1.0, slip_sigma=0.0)


def _drive(world: World, seconds: float, speed: float, dt: float = 0.01) -> None:
    world.robot.command_wheels(speed, speed)
    for _ in range(round(seconds / dt)):
        world.step(dt)


def test_a_walk_starts_when_the_robot_comes_within_the_trigger_distance(
    tiny_plan: FloorPlan,
) -> None:
    walker = ObstacleSpec(
        id="walker",
        kind="person",
        floor=1,
        x_mm=6000,
        y_mm=600,
        path=[(6000, -600)],
        speed_mm_s=1000,
        path_mode="once",
        trigger_mm=1000,
        trigger_at=(4000, 0),
    )
    world = World(tiny_plan, ROBOT, floor=1, pose=Pose(1000, 0, 0), obstacles=[walker])
    _drive(world, 1.0, 500)  # the centre reaches 1250 mm: 2750 mm from the trigger point
    assert world.obstacle_start_s == [None]
    assert world.obstacle_clock_s(0) is None
    # Standing at its start facing along its path (-y), so the legs are side by side in x.
    legs_and_torso = world.obstacle_at(0).cylinders[:, :2]
    assert legs_and_torso.tolist() == [[6100, 600], [5900, 600], [6000, 600]]
    _drive(world, 5.0, 500)
    (started,) = world.obstacle_start_s
    assert started is not None
    # 250 mm to reach speed, then at 500 mm/s to 3000 mm: within 1000 mm of (4000, 0).
    assert started == pytest.approx(1.0 + (3000 - 1250) / 500, abs=0.02)
    # It has walked for (6.0 - started) s since, and the path ends 1200 mm on: it stands there.
    assert world.obstacle_clock_s(0) == pytest.approx(6.0 - started)
    assert world.obstacle_clock_s(0, t_s=started - 0.1) is None
    assert world.obstacle_at(0).cylinders[2, 1] == pytest.approx(-600.0)


def test_a_dropped_box_is_absent_until_it_appears_and_can_then_be_hit(
    tiny_plan: FloorPlan,
) -> None:
    box = ObstacleSpec(
        id="box", kind="cardboard_box", floor=1, x_mm=3000, y_mm=0, trigger_mm=1500, appear_s=0.0
    )
    world = World(tiny_plan, ROBOT, floor=1, pose=Pose(1000, 0, 0), obstacles=[box])
    assert world.obstacle_at(0).segment_ids == ()
    assert not any("box" in e for e in world.robot.surfaces().segment_ids)
    _drive(world, 6.0, 400)
    assert world.obstacle_start_s[0] is not None
    assert len(world.obstacle_at(0).segment_ids) == 4
    (hit,) = world.robot.collisions
    assert hit.element == "box box"
    assert hit.body is not None and hit.body.speed_mm_s == pytest.approx(400.0, abs=1.0)
    # Before it appeared, the world at that time had no box.
    assert world.obstacle_at(0, t_s=0.5).segment_ids == ()


def test_a_walk_before_its_clock_starts_stands_at_its_start_point() -> None:
    spec = ObstacleSpec(
        id="p", kind="person", floor=1, x_mm=0, y_mm=0, path=[(1000, 0)], speed_mm_s=500
    )
    assert spec.pose_at(-3.0)[:2] == (0.0, 0.0)
    assert spec.pose_at(1.0)[:2] == pytest.approx((500.0, 0.0))


def test_a_cart_wheeled_away_is_there_until_it_is_gone(tiny_plan: FloorPlan) -> None:
    cart = ObstacleSpec(
        id="cart", kind="mail_cart", floor=1, x_mm=3000, y_mm=0, appear_s=1.0, gone_s=4.0
    )
    world = World(tiny_plan, ROBOT, floor=1, pose=Pose(1000, 0, 0), obstacles=[cart])
    for t_s, there in ((0.5, False), (1.0, True), (3.9, True), (4.0, False), (9.0, False)):
        assert bool(world.obstacle_at(0, t_s=t_s).segment_ids) is there, t_s
    with pytest.raises(ValueError, match="gone_s must come after appear_s"):
        ObstacleSpec(id="c", kind="mail_cart", floor=1, x_mm=0, y_mm=0, appear_s=5.0, gone_s=5.0)
