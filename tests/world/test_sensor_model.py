"""The simulated VL53L1X's optics and ranging against hand-computed scenes and the chip's
published behaviour (docs/sensor-model.md)."""

from __future__ import annotations

import math
from collections.abc import Callable

import numpy as np
import pytest

from coffeebot.floorplan import FloorPlan
from coffeebot.hardware.vl53l1x import FULL_ROI, SpadRoi
from coffeebot.messages import ReadingStatus
from coffeebot.sim.world import ObstacleSpec, Pose, RobotSpec, SensorMount, World
from coffeebot.sim.world.geometry import Surfaces
from coffeebot.sim.world.obstacles import obstacle_surfaces
from coffeebot.sim.world.tof import (
    DEFAULT_SETUP,
    ConeOptics,
    RangingNoise,
    RangingSetup,
    Returns,
    SensorArray,
    field_of_view_deg,
    range_once,
)

OPTICS = ConeOptics()
ROBOT_HEIGHT = SensorMount(x_mm=0, y_mm=0, yaw_deg=0, height_mm=250)
LAB_HEIGHT = SensorMount(x_mm=0, y_mm=0, yaw_deg=0, height_mm=1500)
"""A sensor on a tripod: the floor stays out of the cone for the first few metres."""


def wall(distance: float, reflectance: float = 0.7, normal_deg: float = 0.0) -> Surfaces:
    """A long wall whose nearest point to the origin is ``distance`` away at ``normal_deg``."""
    n = math.radians(normal_deg)
    cx, cy = distance * math.cos(n), distance * math.sin(n)
    tx, ty = -math.sin(n) * 6000, math.cos(n) * 6000
    row = [[cx - tx, cy - ty, cx + tx, cy + ty, 0.0, 5000.0]]
    return Surfaces(np.array(row), ("wall",), np.zeros((0, 5)), (), np.array([reflectance]))


def pole(
    distance: float, radius: float = 15.0, reflectance: float = 0.5, y: float = 0.0
) -> Surfaces:
    row = [[distance + radius, y, radius, 0.0, 5000.0]]
    reflect = np.array([reflectance])
    return Surfaces(np.zeros((0, 6)), (), np.array(row), ("pole",), np.zeros(0), reflect)


def returns(surfaces: Surfaces, mount: SensorMount = LAB_HEIGHT, roi=FULL_ROI) -> Returns:
    array = SensorArray([mount], OPTICS)
    return array.returns(array.layers(0.0, 0.0, 0.0, surfaces), 0, roi)


def exact(surfaces: Surfaces, mount: SensorMount = LAB_HEIGHT, setup=DEFAULT_SETUP):
    """One noiseless ranging."""
    return range_once(returns(surfaces, mount), setup, None, np.random.default_rng(0))


def test_fitted_cone_has_the_datasheet_fields_of_view() -> None:
    assert field_of_view_deg(OPTICS) == pytest.approx(27.0, abs=0.5)
    assert field_of_view_deg(OPTICS, SpadRoi(4, 4)) == pytest.approx(15.0, abs=0.5)


def test_square_on_wall_reads_its_distance_within_the_cone_s_depth() -> None:
    # The photons of a wide cone travel a little further at its edge: the mean is ~1 % long.
    reading = exact(wall(1200))
    assert reading.status is ReadingStatus.VALID
    assert 1200 <= reading.distance_mm <= 1200 * 1.015


def test_signal_falls_with_distance_squared_and_rises_with_reflectance() -> None:
    near, far = returns(wall(500, 0.88)), returns(wall(1000, 0.88))
    assert near.signal_mcps / far.signal_mcps == pytest.approx(4.0, rel=0.05)
    dark = returns(wall(1000, 0.17))
    assert far.signal_mcps / dark.signal_mcps == pytest.approx(0.88 / 0.17, rel=0.01)


def test_a_wall_at_an_angle_reads_about_where_the_axis_meets_it() -> None:
    # Normal 30 degrees off: the axis meets it at 1000 mm, the cone's near edge at 903 mm.
    # The near half weighs more (nearer, less oblique), the far half's paths are longer:
    # the mean lands near the axis, not at the nearest return.
    d = 866.0254
    reading = exact(wall(d, normal_deg=30))
    edge = d / math.cos(math.radians(30 - 13.5))
    assert reading.distance_mm == pytest.approx(1000, rel=0.03)
    assert reading.distance_mm > edge + 50


@pytest.mark.parametrize("near", [500.0, 1000.0])
def test_a_pole_in_front_of_a_wall_reads_between_them(near: float) -> None:
    mixed = returns(wall(1500) + pole(near))
    assert near < mixed.mean_mm < 1500
    assert mixed.spread_mm > 100  # the blend reports a large sigma


def test_the_thinner_the_pole_the_nearer_the_wall() -> None:
    readings = [returns(wall(1500) + pole(1000, radius)).mean_mm for radius in (60, 30, 15, 7)]
    assert readings == sorted(readings)
    assert readings[-1] > 1400  # a 14 mm rod at 1 m barely moves a wall reading at 1.5 m


def test_a_narrow_roi_weighs_a_centred_pole_more() -> None:
    scene = wall(1500) + pole(1000)
    full = returns(scene).mean_mm
    narrow = returns(scene, roi=SpadRoi(4, 4)).mean_mm
    assert narrow < full


def test_a_narrow_roi_does_not_see_what_the_full_cone_sees_at_its_edge() -> None:
    # A pole 11 degrees off the axis: inside the full 27 degree cone, outside 15 degrees.
    at = math.radians(11)
    scene = pole(800 * math.cos(at), 30, y=800 * math.sin(at))
    full = returns(scene).signal_mcps
    assert full > 0.5
    assert returns(scene, roi=SpadRoi(4, 4)).signal_mcps < full / 100


def test_steering_the_roi_turns_the_cone() -> None:
    at = math.radians(8)
    scene = pole(800 * math.cos(at), 30, y=800 * math.sin(at))  # 8 degrees to the left
    left = returns(scene, roi=SpadRoi.steered(4, 4, column=2)).signal_mcps
    right = returns(scene, roi=SpadRoi.steered(4, 4, column=14)).signal_mcps
    assert left > 20 * right


def test_nothing_in_view_is_a_signal_fail_with_a_garbage_distance() -> None:
    empty = returns(Surfaces.empty())  # a tripod's sensor meets the floor only ~5 m out
    assert empty.signal_mcps < 0.01
    readings = [
        range_once(empty, DEFAULT_SETUP, RangingNoise(), np.random.default_rng(k))
        for k in range(20)
    ]
    assert {r.status for r in readings} == {ReadingStatus.SIGNAL_FAIL}
    assert len({r.distance_mm for r in readings}) > 3


def test_status_rules_follow_the_chip_thresholds() -> None:
    grey_far = returns(wall(2200, 0.17))  # ~0.5 Mcps
    assert exact(wall(2200, 0.17)).status is ReadingStatus.SIGNAL_FAIL
    lenient = RangingSetup(min_signal_mcps=0.25, sigma_limit_mm=500)
    rng = np.random.default_rng(0)
    assert range_once(grey_far, lenient, None, rng).status is ReadingStatus.VALID
    short = RangingSetup(max_range_mm=1300, short_mode=True)
    assert range_once(returns(wall(2000)), short, None, rng).status is (ReadingStatus.OUT_OF_BOUNDS)
    # A blend of a pole and a wall reports a larger sigma than the wall alone: a limit
    # between the two fails the blend only.
    blend, alone = returns(wall(1500) + pole(500)), returns(wall(950))
    blend_sigma = range_once(blend, DEFAULT_SETUP, RangingNoise(), rng).sigma_mm
    alone_sigma = range_once(alone, DEFAULT_SETUP, RangingNoise(), rng).sigma_mm
    assert blend_sigma > alone_sigma
    strict = RangingSetup(sigma_limit_mm=(blend_sigma + alone_sigma) / 2)
    assert range_once(blend, strict, RangingNoise(), rng).status is ReadingStatus.SIGMA_FAIL
    assert range_once(alone, strict, RangingNoise(), rng).status is ReadingStatus.VALID
    assert exact(wall(30)).status is ReadingStatus.TOO_CLOSE


def test_noise_grows_with_distance_and_ambient_and_shrinks_with_the_budget() -> None:
    def sd(distance: float, ambient: float = 0.02, budget: float = 20.0) -> float:
        r = returns(wall(distance, 0.88))._replace(ambient_mcps=ambient)
        setup = RangingSetup(timing_budget_ms=budget, sigma_limit_mm=10_000)
        rng = np.random.default_rng(1)
        values = [range_once(r, setup, RangingNoise(), rng).distance_mm for _ in range(400)]
        return float(np.std(values))

    assert sd(400) < 5.0  # a few mm up close (seed 000: +/-5 mm)
    assert sd(1500) > 3 * sd(400)
    assert sd(1000, ambient=1.0) > 2 * sd(1000)
    assert sd(1000, budget=100) < 0.6 * sd(1000)


def test_reads_short_up_close() -> None:
    rng = np.random.default_rng(2)
    near = returns(wall(150))
    readings = [range_once(near, DEFAULT_SETUP, RangingNoise(), rng) for _ in range(50)]
    assert 125 < np.mean([r.distance_mm for r in readings]) < 145


def test_the_floor_enters_a_low_sensor_s_cone_and_is_weak() -> None:
    # 250 mm up, the cone's lower edge meets the floor ~1 m out: a faint, grazing return.
    floor_only = returns(Surfaces.empty(), ROBOT_HEIGHT)
    assert 0.0 < floor_only.signal_mcps < 0.2
    assert 800 < floor_only.mean_mm < 2500


def test_surface_above_the_cone_is_missed() -> None:
    # A table top edge from 700 mm up, 1000 mm away: the cone reaches ~580 mm there.
    edge = np.array([[1000, -2000, 1000, 2000, 700, 750]])
    top = Surfaces(edge, ("table",), np.zeros((0, 5)), ())
    assert returns(top, ROBOT_HEIGHT).mean_mm > 1500 or returns(top, ROBOT_HEIGHT).signal_mcps < 0.1


def test_cart_shelf_below_sensor_height_is_missed_up_close() -> None:
    """Seed 000's mail cart: its lower shelf tops out 20 mm below the sensors. 60 mm away the
    cone's lower rays pass over its near face and meet the far side or the floor."""

    def cart(near_face_mm: float) -> Returns:
        spec = ObstacleSpec(
            id="cart", kind="mail_cart", floor=1, x_mm=near_face_mm + 250, y_mm=0, heading_deg=90
        )
        return returns(obstacle_surfaces(spec), ROBOT_HEIGHT)

    assert cart(60).mean_mm > 300
    assert cart(500).mean_mm == pytest.approx(560, abs=120)


def test_dark_and_white_obstacles_differ() -> None:
    white = returns(pole(800, 35, reflectance=0.88) + wall(2000))
    black = returns(pole(800, 35, reflectance=0.05) + wall(2000))
    assert white.mean_mm < black.mean_mm
    assert white.signal_mcps > black.signal_mcps


def test_door_recess_reads_deeper_than_the_wall(
    tiny_plan: FloorPlan, one_sensor: Callable[..., RobotSpec]
) -> None:
    # Sensor at the robot centre, 300 mm right of the axis, looking right (-y).
    robot = one_sensor(yaw_deg=-90)
    at_wall = World(tiny_plan, robot, floor=1, pose=Pose(3000, -300, 0), noise=None)
    at_door = World(tiny_plan, robot, floor=1, pose=Pose(5000, -300, 0), noise=None)
    wall_mm = at_wall.robot.tof_returns(0).mean_mm
    door_mm = at_door.robot.tof_returns(0).mean_mm
    assert wall_mm == pytest.approx(850 - 300, rel=0.02)
    assert door_mm - wall_mm == pytest.approx(100, abs=25)


def test_world_scan_uses_the_chip_model(
    tiny_plan: FloorPlan, one_sensor: Callable[..., RobotSpec]
) -> None:
    world = World(tiny_plan, one_sensor(yaw_deg=-90), floor=1, pose=Pose(3000, -300, 0))
    readings = world.robot.scan()
    assert len(readings) == 1 and readings[0].status is ReadingStatus.VALID
    assert readings[0].signal_mcps > 1.0 and readings[0].sigma_mm > 0
