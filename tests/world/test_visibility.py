"""Ground truth for the safety benchmark: what a cone sees, what is in the way, and when."""

from __future__ import annotations

import math

import numpy as np
import pytest

from coffeebot.sim.world import RobotSpec, SensorMount, Surfaces
from coffeebot.sim.world.visibility import (
    RobotPose,
    Trajectory,
    first_time,
    in_the_way,
    seeing_sensors,
    surface_points,
)

RANGE_MM = 4000.0
FRONT = SensorMount(x_mm=305.0, y_mm=0.0, yaw_deg=0.0, height_mm=250.0, fov_deg=27.0)
LEFT = SensorMount(x_mm=0.0, y_mm=255.0, yaw_deg=90.0, height_mm=250.0, fov_deg=27.0)
ROBOT = RobotSpec(sensors=(FRONT, LEFT))
AT_ORIGIN = RobotPose(0.0, 0.0, 0.0)


def pole(x: float, y: float, radius: float = 15.0, z: tuple[float, float] = (0, 450)) -> Surfaces:
    return Surfaces(np.zeros((0, 6)), (), np.array([[x, y, radius, *z]]), ("pole",))


def wall(x0: float, y0: float, x1: float, y1: float, top: float = 2700.0) -> Surfaces:
    return Surfaces(np.array([[x0, y0, x1, y1, 0.0, top]]), ("wall",), np.zeros((0, 5)), ())


def seen(target: Surfaces, scene: Surfaces | None = None, pose: RobotPose = AT_ORIGIN) -> list:
    scene = target if scene is None else scene + target
    return seeing_sensors(target, scene, ROBOT.sensors, pose, RANGE_MM)


def test_a_chair_leg_ahead_is_seen_by_the_front_cone_only_within_its_range() -> None:
    assert seen(pole(1500.0, 0.0)) == [0]
    assert seen(pole(305.0 + RANGE_MM + 20.0, 0.0)) == []


def test_the_cone_is_half_the_field_of_view_either_side_of_the_axis() -> None:
    # 1000 mm ahead of the sensor the cone's edge is 1000 * tan(13.5 deg) = 240 mm aside.
    edge = 1000.0 * math.tan(math.radians(13.5))
    assert seen(pole(1305.0, edge - 20.0, radius=10.0)) == [0]
    assert seen(pole(1305.0, edge + 20.0, radius=10.0)) == []


def test_a_side_cone_sees_what_stands_beside_the_body() -> None:
    assert seen(pole(0.0, 900.0)) == [1]


def test_a_wall_between_the_sensor_and_the_leg_hides_it() -> None:
    assert seen(pole(1500.0, 0.0), scene=wall(1000.0, -500.0, 1000.0, 500.0)) == []
    # A wall that ends short of the line of sight hides nothing.
    assert seen(pole(1500.0, 0.0), scene=wall(1000.0, 100.0, 1000.0, 500.0)) == [0]


def test_what_stands_above_every_cone_cannot_be_seen() -> None:
    """A table top 2 m up, 500 mm ahead: the cone reaches only ~250 + 0.24 x range there."""
    assert seen(pole(800.0, 0.0, radius=200.0, z=(2000.0, 2050.0))) == []


def test_surface_points_cover_segments_and_cylinders_up_to_a_height() -> None:
    target = wall(0.0, 0.0, 100.0, 0.0, top=100.0) + pole(500.0, 0.0, z=(0.0, 1000.0))
    points = surface_points(target, z_max_mm=400.0, step_mm=20.0)
    assert points[:, 2].max() == pytest.approx(400.0)
    on_wall = points[points[:, 1] == 0.0]
    assert on_wall[:, 0].min() == pytest.approx(0.0) and on_wall[:, 0].max() >= 100.0 - 1e-9
    radii = np.hypot(points[:, 0] - 500.0, points[:, 1])
    assert np.allclose(radii[np.abs(points[:, 0] - 500.0) < 20.0], 15.0)


def test_in_the_way_means_in_the_body_width_ahead_within_the_depth() -> None:
    front = ROBOT.length_mm / 2
    assert in_the_way(pole(front + 900.0, 0.0), AT_ORIGIN, ROBOT, 1000.0)
    assert not in_the_way(pole(front + 1100.0, 0.0), AT_ORIGIN, ROBOT, 1000.0)
    assert not in_the_way(pole(front + 500.0, ROBOT.width_mm / 2 + 40.0), AT_ORIGIN, ROBOT, 1000.0)
    # Reversing, the field lies behind the rear face.
    backwards = RobotPose(0.0, 0.0, 0.0, speed_mm_s=-300.0)
    assert in_the_way(pole(-front - 500.0, 0.0), backwards, ROBOT, 1000.0)
    assert not in_the_way(pole(front + 500.0, 0.0), backwards, ROBOT, 1000.0)


def test_a_part_above_the_body_is_not_in_the_way() -> None:
    assert not in_the_way(pole(800.0, 0.0, z=(1000.0, 1200.0)), AT_ORIGIN, ROBOT, 1000.0)


def _driving(speed: float, seconds: float, step_s: float = 0.005) -> Trajectory:
    times = np.arange(0.0, seconds, step_s)
    return Trajectory.from_samples([(t, speed * t, 0.0, 0.0, speed) for t in times])


def test_first_detectable_is_when_the_leg_comes_into_range() -> None:
    """Driving at 1 m/s towards a leg 6 m ahead of the front sensor: its near side (radius
    15 mm, at the sensor's height) comes within the 4 m range after (6000 - 15 - 4000) mm."""
    leg = pole(305.0 + 6000.0, 0.0)
    trajectory = _driving(1000.0, 4.0)
    t = first_time(
        trajectory,
        lambda _t, p: bool(seeing_sensors(leg, leg, ROBOT.sensors, p, RANGE_MM)),
    )
    assert t == pytest.approx((6000.0 - 15.0 - RANGE_MM) / 1000.0, abs=0.002)


def test_first_time_refines_between_samples_and_respects_the_start() -> None:
    trajectory = _driving(1000.0, 2.0, step_s=0.1)
    t = first_time(trajectory, lambda _t, p: p.x_mm >= 1234.0, resolution_s=0.0001)
    assert t == pytest.approx(1.234, abs=0.0002)
    assert first_time(trajectory, lambda _t, p: p.x_mm >= 1234.0, after_s=1.5) == 1.5
    assert first_time(trajectory, lambda _t, p: p.x_mm > 5000.0) is None


def test_the_trajectory_interpolates_the_heading_across_the_wrap() -> None:
    trajectory = Trajectory.from_samples(
        [(0.0, 0.0, 0.0, math.pi - 0.1, 0.0), (1.0, 0.0, 0.0, -math.pi + 0.1, 0.0)]
    )
    assert math.cos(trajectory.at(0.5).theta) == pytest.approx(-1.0)
