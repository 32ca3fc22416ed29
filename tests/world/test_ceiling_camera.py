"""The simulated ceiling camera: what it draws where, its noise and its faults."""

from __future__ import annotations

from collections.abc import Callable, Sequence
from typing import Any

import cv2
import numpy as np
import pytest
from pydantic import ValidationError

from coffeebot.cameras.geometry import mm_per_px, nominal_homography, project, to_plane
from coffeebot.floorplan import Camera, FloorPlan, parse_floorplan
from coffeebot.sim.world import ObstacleSpec, Pose, RobotSpec, World
from coffeebot.sim.world.ceiling_camera import CUP_HEIGHT_MM, CameraSimSettings, SimCeilingCamera

CAMERA = Camera(id="hall", x_mm=3000.0, y_mm=0.0)
"""The seed's camera over the middle of the hallway: it sees x 1000-5000, y -1500-1500 of
the floor at 12.5 mm a pixel."""

AWAY = Pose(9000.0, 0.0, 0.0)
"""Where the robot stands when the camera should not see it."""

ROBOT = RobotSpec(slip_sigma=0.0)
NOISELESS = CameraSimSettings(noise_sigma=0.0)
ROBOT_TOP_MM = ROBOT.height_mm
PERSON_TOP_MM = 1750.0
"""A person's torso ends at the top of the head (obstacles.py)."""


@pytest.fixture
def plan(plan_dict: Callable[..., dict[str, Any]]) -> FloorPlan:
    """The tiny plan's hallway widened to 2400 mm (y -1200 to 1200), so a robot fits 1.5 m
    off the camera's centre inside the image."""
    return parse_floorplan(plan_dict(width_mm=2400))


def _world(plan: FloorPlan, pose: Pose = AWAY, obstacles: Sequence[ObstacleSpec] = ()) -> World:
    return World(plan, ROBOT, floor=1, pose=pose, obstacles=obstacles)


def _frame(camera: SimCeilingCamera, t_s: float | None = None, **kw: Any) -> np.ndarray:
    frame = camera.frame(t_s, **kw)
    assert frame is not None
    return frame


def _blob(frame: np.ndarray, background: np.ndarray) -> tuple[np.ndarray, int]:
    """Centroid (image coordinates: pixel i's centre is at i + 0.5) and area in pixels of the
    largest region that differs from the background by more than the noise."""
    changed = (np.abs(frame.astype(int) - background.astype(int)) > 25).astype(np.uint8)
    count, _, stats, centroids = cv2.connectedComponentsWithStats(changed)
    assert count > 1, "nothing differs from the background"
    largest = 1 + int(np.argmax(stats[1:, cv2.CC_STAT_AREA]))
    return centroids[largest] + 0.5, int(stats[largest, cv2.CC_STAT_AREA])


def test_a_frame_has_the_cameras_shape_and_dtype(plan: FloorPlan) -> None:
    world = _world(plan)
    assert _frame(SimCeilingCamera(world, 1, CAMERA)).shape == (240, 320)
    small = CAMERA.model_copy(update={"width_px": 200, "height_px": 100})
    frame = _frame(SimCeilingCamera(world, 1, small))
    assert frame.shape == (100, 200)
    assert frame.dtype == np.uint8


def test_an_empty_hallway_changes_only_by_its_noise_over_a_textured_floor(
    plan: FloorPlan,
) -> None:
    world = _world(plan)
    sigma = 2.5
    camera = SimCeilingCamera(world, 1, CAMERA, CameraSimSettings(noise_sigma=sigma), seed=3)
    first, second = _frame(camera, 0.0), _frame(camera, 0.1)
    difference = np.abs(first.astype(float) - second.astype(float))
    # Two independent N(0, sigma^2) draws differ by 2 sigma / sqrt(pi) on average.
    assert difference.mean() == pytest.approx(2 * sigma / np.sqrt(np.pi), rel=0.15)
    assert difference.max() < 8 * sigma
    # Without noise the frames are equal, and the floor is not a flat colour.
    still = SimCeilingCamera(world, 1, CAMERA, NOISELESS, seed=3)
    np.testing.assert_array_equal(_frame(still, 0.0), _frame(still, 0.1))
    floor = _frame(still)[60:180, 40:280].astype(float)  # the hallway, between the walls
    assert floor.mean() == pytest.approx(NOISELESS.floor_grey, abs=1.5)
    assert 4.0 < floor.std() < 8.0


def test_walls_show_as_their_faces_from_the_floor_outwards(plan: FloorPlan) -> None:
    """The left wall (y = 1200) meets the floor on row 24 and its top, 2700 mm up, projects
    beyond the image: rows above 24 are wall. On the right, the office door's 100 mm recess
    at x 4550-5450 pushes the wall back where the door is."""
    frame = _frame(SimCeilingCamera(_world(plan), 1, CAMERA, NOISELESS)).astype(float)
    (_, left_foot_v), (right_foot_u, right_foot_v) = project(
        nominal_homography(CAMERA), np.array([[3000.0, 1200.0], [4550.0, -1200.0]])
    )
    assert (left_foot_v, right_foot_u, right_foot_v) == pytest.approx(
        (24.0, 284.0, 216.0), abs=0.01
    )
    wall, floor = NOISELESS.wall_grey, NOISELESS.floor_grey
    assert frame[:23].mean() == pytest.approx(wall, abs=0.5)
    assert frame[26:60].mean() == pytest.approx(floor, abs=1.5)
    assert frame[218:222, 180:270].mean() == pytest.approx(wall, abs=0.5)
    assert frame[218:222, 305:315].mean() == pytest.approx(floor, abs=6.0)  # the recess


@pytest.mark.parametrize(
    ("x_mm", "y_mm"), [(3000.0, 0.0), (4200.0, -900.0)], ids=["at nadir", "1.5 m off"]
)
def test_a_robot_shows_as_its_top_where_it_stands(
    plan: FloorPlan, x_mm: float, y_mm: float
) -> None:
    world = _world(plan)
    camera = SimCeilingCamera(world, 1, CAMERA, seed=5)
    background = _frame(camera)
    world.robot.place(Pose(x_mm, y_mm, 0.0))
    centroid, area = _blob(_frame(camera), background)
    top = to_plane(nominal_homography(CAMERA, ROBOT_TOP_MM), centroid)[0]
    assert np.hypot(*(top - (x_mm, y_mm))) < 15.0
    # The top, 900 mm nearer the lens than the floor, shows 1.67 times the footprint's area.
    top_area = ROBOT.length_mm * ROBOT.width_mm / mm_per_px(CAMERA, ROBOT_TOP_MM) ** 2
    assert area == pytest.approx(top_area, rel=0.08)
    # Read on the floor's plane instead, the robot would seem 29 % further from the nadir.
    on_floor = to_plane(nominal_homography(CAMERA), centroid)[0]
    off_nadir = np.hypot(x_mm - CAMERA.x_mm, y_mm - CAMERA.y_mm)
    seeming = np.hypot(on_floor[0] - CAMERA.x_mm, on_floor[1] - CAMERA.y_mm)
    assert seeming == pytest.approx(off_nadir * 4000 / 3100, abs=15.0)


def test_a_sub_pixel_move_changes_the_frame(plan: FloorPlan) -> None:
    """A robot's top moves 0.2 px for 2 mm: anti-aliased edges show it to the pipeline."""
    world = _world(plan, Pose(3000.0, 0.0, 0.0))
    camera = SimCeilingCamera(world, 1, CAMERA, NOISELESS)
    before = _frame(camera)
    world.robot.place(Pose(3002.0, 0.0, 0.0))
    assert np.abs(_frame(camera).astype(int) - before.astype(int)).max() >= 10


def test_a_cup_is_a_bright_disc_on_the_robots_centre(plan: FloorPlan) -> None:
    world = _world(plan, Pose(4000.0, -500.0, 30.0))
    camera = SimCeilingCamera(world, 1, CAMERA, NOISELESS)
    lid = project(
        nominal_homography(CAMERA, ROBOT_TOP_MM + CUP_HEIGHT_MM), np.array([[4000.0, -500.0]])
    )
    u, v = np.floor(lid[0]).astype(int)
    assert _frame(camera, cups={"robot": True})[v, u] == NOISELESS.cup_grey
    assert _frame(camera, cups={"robot": False})[v, u] == NOISELESS.robot_grey
    assert _frame(camera)[v, u] == NOISELESS.robot_grey


def test_a_walking_person_shows_as_the_top_of_their_head_where_they_are(
    plan: FloorPlan,
) -> None:
    walker = ObstacleSpec(
        id="walker",
        kind="person",
        floor=1,
        x_mm=500.0,
        y_mm=0.0,
        path=[(6000.0, 0.0)],
        speed_mm_s=1000.0,
        path_mode="once",
    )
    world = _world(plan, obstacles=[walker])
    camera = SimCeilingCamera(world, 1, CAMERA, seed=9)
    background = _frame(camera, 0.0)  # still at x = 500: out of sight
    head_plane = nominal_homography(CAMERA, PERSON_TOP_MM)
    head_area = np.pi * (180.0 / mm_per_px(CAMERA, PERSON_TOP_MM)) ** 2
    for t_s in (2.5, 2.7):
        centroid, area = _blob(_frame(camera, t_s), background)
        x, y, _ = walker.pose_at(t_s)
        assert np.hypot(*(to_plane(head_plane, centroid)[0] - (x, y))) < 20.0
        assert area == pytest.approx(head_area, rel=0.08)


def test_a_box_shows_as_its_top_and_the_side_facing_the_camera(plan: FloorPlan) -> None:
    """A 500 x 400 x 400 mm box 1 m along the image's +u: its near side runs from the
    floor at u = 220 to its top edge at u = 226.7; its top spans u 226.7 to 271.1."""
    box = ObstacleSpec(id="box", kind="cardboard_box", floor=1, x_mm=4000.0, y_mm=0.0)
    frame = _frame(SimCeilingCamera(_world(plan, obstacles=[box]), 1, CAMERA, NOISELESS))
    edges = np.array([[3750.0, 0.0], [4250.0, 0.0]])
    near_foot = project(nominal_homography(CAMERA), edges)[0, 0]
    near_top, far_top = project(nominal_homography(CAMERA, 400.0), edges)[:, 0]
    assert (near_foot, near_top, far_top) == pytest.approx((220.0, 226.7, 271.1), abs=0.05)
    grey = NOISELESS.obstacle_grey
    assert frame[118:122, 221:225].tolist() == [[grey] * 4] * 4  # the side
    assert frame[118:122, 228:270].tolist() == [[grey] * 42] * 4  # the top
    assert frame[118:122, 214:218].min() > grey + 10
    assert frame[118:122, 273:277].min() > grey + 10


def test_higher_things_are_drawn_over_lower_ones(plan: FloorPlan) -> None:
    """A person under the camera next to a robot: on the image the torso's top (1750 mm)
    covers the edge of the robot's top (900 mm), as it would from the ceiling."""
    person = ObstacleSpec(id="person", kind="person", floor=1, x_mm=3000.0, y_mm=0.0)
    world = _world(plan, Pose(3000.0, -450.0, 0.0), obstacles=[person])
    frame = _frame(SimCeilingCamera(world, 1, CAMERA, NOISELESS))
    # Robot's near edge (y = -195 mm) at 900 mm: row 140.2; the torso's rim: row 145.6.
    robot_edge = project(nominal_homography(CAMERA, ROBOT_TOP_MM), np.array([[3000.0, -195.0]]))[
        0, 1
    ]
    torso_rim = project(nominal_homography(CAMERA, PERSON_TOP_MM), np.array([[3000.0, -180.0]]))[
        0, 1
    ]
    assert robot_edge + 1.5 < 142.5 < torso_rim - 1.5
    assert frame[142, 155:165].tolist() == [NOISELESS.obstacle_grey] * 10
    assert frame[150, 155:165].tolist() == [NOISELESS.robot_grey] * 10


def test_a_lighting_change_scales_the_whole_frame(plan: FloorPlan) -> None:
    world = _world(plan, Pose(3500.0, 200.0, 0.0))
    dimmed = CameraSimSettings(noise_sigma=0.0, lighting_gain=0.6, lighting_change_at_s=1.0)
    camera = SimCeilingCamera(world, 1, CAMERA, dimmed)
    before, after = _frame(camera, 0.5).astype(float), _frame(camera, 1.5).astype(float)
    np.testing.assert_array_equal(before, _frame(SimCeilingCamera(world, 1, CAMERA, NOISELESS)))
    assert np.abs(after - 0.6 * before).max() <= 0.5 + 1e-9
    assert after.mean() == pytest.approx(0.6 * before.mean(), rel=0.01)


def test_a_dropout_delivers_nothing_between_its_times(plan: FloorPlan) -> None:
    world = _world(plan)
    faulty = CameraSimSettings(dropout_from_s=1.0, dropout_until_s=2.0)
    camera = SimCeilingCamera(world, 1, CAMERA, faulty)
    assert camera.frame(0.9) is not None
    assert camera.frame(1.0) is None
    assert camera.frame(1.95) is None
    assert camera.frame(2.0) is not None
    world.step(1.5)
    assert camera.frame() is None  # now, on the world's clock


def test_a_dropout_needs_both_ends_in_order() -> None:
    with pytest.raises(ValidationError):
        CameraSimSettings(dropout_from_s=1.0)
    with pytest.raises(ValidationError):
        CameraSimSettings(dropout_from_s=2.0, dropout_until_s=1.0)


def test_the_same_seed_gives_the_same_frames(plan: FloorPlan) -> None:
    world = _world(plan, Pose(3500.0, 200.0, 0.0))

    def run(seed: int) -> list[np.ndarray]:
        camera = SimCeilingCamera(world, 1, CAMERA, seed=seed)
        return [_frame(camera, t) for t in camera.frame_times(0.0, 0.3)]

    first, again, other = run(7), run(7), run(8)
    assert len(first) == 3
    for a, b in zip(first, again, strict=True):
        np.testing.assert_array_equal(a, b)
    assert not np.array_equal(first[0], other[0])


def test_frames_come_every_one_over_fps(plan: FloorPlan) -> None:
    camera = SimCeilingCamera(_world(plan), 1, CAMERA)
    np.testing.assert_allclose(camera.frame_times(0.0, 0.3), [0.0, 0.1, 0.2])
    np.testing.assert_allclose(camera.frame_times(0.05, 0.35), [0.1, 0.2, 0.3])
    assert len(camera.frame_times(1.0, 11.0)) == 100
