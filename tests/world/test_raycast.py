"""The ToF cone against hand-computed distances, and its error model."""

from __future__ import annotations

import math
from collections.abc import Callable

import numpy as np
import pytest

from coffeebot.floorplan import FloorPlan
from coffeebot.messages import ReadingStatus
from coffeebot.sim.world import ObstacleSpec, Pose, RobotSpec, SensorMount, ToFModel, World
from coffeebot.sim.world.geometry import Surfaces
from coffeebot.sim.world.obstacles import obstacle_surfaces
from coffeebot.sim.world.tof import SensorArray

HALF_FOV = math.radians(13.5)  # a 27 degree cone
FRONT = SensorMount(x_mm=0, y_mm=0, yaw_deg=0, height_mm=250, fov_deg=27)


def _segment(x0: float, y0: float, x1: float, y1: float, z=(0.0, 2700.0)) -> Surfaces:
    return Surfaces(np.array([[x0, y0, x1, y1, *z]]), ("wall",), np.zeros((0, 5)), ())


def _cylinder(x: float, y: float, r: float, z=(0.0, 1000.0)) -> Surfaces:
    return Surfaces(np.zeros((0, 6)), (), np.array([[x, y, r, *z]]), ("pole",))


def _read(
    surfaces: Surfaces, model: ToFModel | None = None, seed: int = 0, mount: SensorMount = FRONT
) -> int | None:
    """One reading of a sensor at the origin facing +x; None when there is no target."""
    array = SensorArray([mount], model or ToFModel.exact())
    ranges = array.ranges(0.0, 0.0, 0.0, surfaces.segments, surfaces.cylinders)
    reading = array.measure(ranges, np.random.default_rng(seed))[0]
    return reading.distance_mm if reading.status is ReadingStatus.VALID else None


def _wall_through(distance: float, normal_deg: float) -> Surfaces:
    """A long wall whose nearest point to the origin is ``distance`` away at ``normal_deg``."""
    n = math.radians(normal_deg)
    cx, cy = distance * math.cos(n), distance * math.sin(n)
    tx, ty = -math.sin(n) * 5000, math.cos(n) * 5000
    return _segment(cx - tx, cy - ty, cx + tx, cy + ty)


def test_perpendicular_wall() -> None:
    assert _read(_wall_through(1200, 0)) == 1200


def test_wall_at_a_known_angle_centre_ray() -> None:
    # A single ray meets a wall whose normal is 30 degrees off at D / cos(30).
    single = ToFModel.exact(rays_per_axis=1)
    assert _read(_wall_through(866.0254, 30), single) == 1000


def test_wall_at_a_known_angle_whole_cone() -> None:
    # The nearest ray in the cone is its edge, 13.5 degrees towards the wall's normal.
    expected = 866.0254 / math.cos(math.radians(30 - 13.5))
    assert _read(_wall_through(866.0254, 30)) == round(expected)


def test_door_recess_reads_deeper_than_the_wall(
    tiny_plan: FloorPlan, one_sensor: Callable[..., RobotSpec]
) -> None:
    # Sensor at the robot centre, 300 mm right of the axis, looking right (-y).
    robot = one_sensor(yaw_deg=-90)
    exact = ToFModel.exact()
    at_wall = World(tiny_plan, robot, floor=1, pose=Pose(3000, -300, 0), tof=exact)
    at_door = World(tiny_plan, robot, floor=1, pose=Pose(5000, -300, 0), tof=exact)
    assert at_wall.tof_reading(0).distance_mm == 850 - 300
    assert at_door.tof_reading(0).distance_mm == 850 + 100 - 300


def test_pole_at_the_edge_of_the_cone_is_hit_by_the_edge_ray() -> None:
    edge = HALF_FOV
    pole = _cylinder(800 * math.cos(edge), 800 * math.sin(edge), 15)
    assert _read(pole) == 800 - 15


def test_pole_just_outside_the_cone_is_missed() -> None:
    outside = HALF_FOV + math.asin(15 / 800) + math.radians(0.5)
    assert _read(_cylinder(800 * math.cos(outside), 800 * math.sin(outside), 15)) is None


def test_pole_at_the_edge_flickers_like_a_weak_target() -> None:
    """Seed 000, Figure 5: a pole at the edge alternates between seen and not seen."""
    pole = _cylinder(800 * math.cos(HALF_FOV), 800 * math.sin(HALF_FOV), 15)
    flicker = ToFModel.exact(weak_target_detect_probability=0.5)
    readings = [_read(pole, flicker, seed) for seed in range(200)]
    seen = sum(r == 785 for r in readings)
    assert readings.count(None) + seen == 200
    assert 60 < seen < 140


def _cart_in_front(near_face_mm: float) -> Surfaces:
    """The mail cart broadside on: its lower shelf (z 100..230) spans x from near_face_mm
    to near_face_mm + 500, its corner bars at y = +/-435 are outside the cone."""
    cart = ObstacleSpec(
        id="cart", kind="mail_cart", floor=1, x_mm=near_face_mm + 250, y_mm=0, heading_deg=90
    )
    return obstacle_surfaces(cart)


def test_cart_shelf_below_sensor_height_is_missed_up_close() -> None:
    # 60 mm away the steepest ray (-13.5 deg) is still at 250 - 60 tan(13.5) = 235.6 mm
    # at the near face, above the shelf's 230 mm top: the near face is missed. Rays dip
    # into the open shelf and meet its far side at x = 560, first the -6.75 deg ray.
    reading = _read(_cart_in_front(60))
    assert reading == round(560 / math.cos(HALF_FOV / 2))


def test_cart_shelf_is_seen_from_further_away() -> None:
    # At 500 mm the -6.75 deg ray is at 250 - 500 tan(6.75) = 190.8 mm: on the shelf face.
    assert _read(_cart_in_front(500)) == round(500 / math.cos(HALF_FOV / 2))


def test_narrow_cone_misses_the_shelf_for_longer() -> None:
    # A 15 degree cone's steepest ray reaches 230 mm only 152 mm out (20 / tan 7.5 deg).
    narrow = SensorMount(x_mm=0, y_mm=0, yaw_deg=0, height_mm=250, fov_deg=15)
    # At 120 mm it sees past the near face into the shelf: the -3.75 deg ray meets the far
    # side at x = 620 at 250 - 620 tan(3.75) = 209 mm.
    assert _read(_cart_in_front(120), mount=narrow) == round(620 / math.cos(math.radians(3.75)))
    assert _read(_cart_in_front(200), mount=narrow) == round(200 / math.cos(math.radians(7.5)))


def test_surface_above_the_cone_is_missed() -> None:
    # A table top edge from 700 mm up, 1000 mm away: the top ray is at 250 + 240 = 490 mm.
    assert _read(_segment(1000, -2000, 1000, 2000, z=(700, 750))) is None


def test_nothing_in_range() -> None:
    assert _read(_wall_through(4500, 0)) is None


def test_noise_is_within_5_mm_up_close_and_grows_beyond_1000() -> None:
    model = ToFModel()
    array = SensorArray([FRONT], model)
    rng = np.random.default_rng(7)
    near = _wall_through(600, 0)
    far = _wall_through(2500, 0)
    ranges_near = array.ranges(0, 0, 0, near.segments, near.cylinders)
    ranges_far = array.ranges(0, 0, 0, far.segments, far.cylinders)
    close = [array.measure(ranges_near, rng)[0] for _ in range(500)]
    distant = [array.measure(ranges_far, rng)[0] for _ in range(500)]
    close_mm = np.array([r.distance_mm for r in close if r.status is ReadingStatus.VALID])
    far_mm = np.array([r.distance_mm for r in distant if r.status is ReadingStatus.VALID])
    assert np.mean(np.abs(close_mm - 600) <= 5) > 0.9
    assert 1.5 < close_mm.std() < 3.5
    assert far_mm.std() > 20
    invalid_far = sum(r.status is ReadingStatus.SIGMA_FAIL for r in distant)
    invalid_near = sum(r.status is ReadingStatus.SIGMA_FAIL for r in close)
    assert invalid_far > invalid_near


@pytest.mark.parametrize("fov", [14.9, 27.1])
def test_field_of_view_is_limited_to_the_sensor_range(fov: float) -> None:
    with pytest.raises(ValueError, match="fov_deg"):
        SensorMount(x_mm=0, y_mm=0, yaw_deg=0, fov_deg=fov)


def test_rays_per_axis_must_be_odd() -> None:
    with pytest.raises(ValueError, match="odd"):
        ToFModel(rays_per_axis=4)
