"""A ceiling camera's calibration from floor marks, and the calibrations it refuses."""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path

import cv2
import numpy as np
import pytest

from coffeebot.cameras.calibration import calibrate
from coffeebot.cameras.geometry import nominal_homography, project, raise_plane, to_plane
from coffeebot.floorplan import Camera, FloorMark, FloorPlanError, load_floorplan

CS_BUILDING = Path(__file__).resolve().parents[2] / "floorplans" / "cs-building.toml"

LAB = Camera(id="lab", x_mm=2000.0, y_mm=1500.0, height_mm=4000.0)
"""The seed's camera: 320 x 240 px from 4 m over a 4 m x 3 m patch of floor, 12.5 mm a px."""

SPREAD = [(300, 250), (3700, 250), (3700, 2750), (300, 2750), (2000, 1500), (2000, 400)]
"""Six floor marks as a surveyor spreads them: near the image's corners, and two inside."""

CORNERS = np.array([[0.0, 0.0], [320.0, 0.0], [320.0, 240.0], [0.0, 240.0]])


def marked(
    camera: Camera, floor_points: Sequence[tuple[float, float]], pixels: np.ndarray | None = None
) -> Camera:
    """The camera with marks at ``floor_points``, showing at ``pixels`` (default: where the
    camera's nominal model puts them)."""
    points = np.array(floor_points, dtype=float)
    if pixels is None:
        pixels = project(nominal_homography(camera), points)
    marks = [
        FloorMark(x_mm=float(x), y_mm=float(y), u_px=float(u), v_px=float(v))
        for (x, y), (u, v) in zip(points, pixels, strict=True)
    ]
    return camera.model_copy(update={"marks": marks})


def refusal(camera: Camera) -> FloorPlanError:
    """The error calibrating ``camera`` on floor 2 of plans/lab.toml raises."""
    with pytest.raises(FloorPlanError) as info:
        calibrate(camera, floor=2, path="plans/lab.toml")
    message = str(info.value)
    assert "\n" not in message
    assert message.startswith(f"plans/lab.toml: {info.value.element}: ")
    assert info.value.element.startswith("floor 2 / camera lab")
    return info.value


# --- what a calibration gives ------------------------------------------------------------------


def test_exact_marks_reproduce_the_nominal_homography() -> None:
    calibration = calibrate(marked(LAB, SPREAD))
    assert calibration.source == "marks"
    assert calibration.rms_px is not None and calibration.rms_px < 1e-4
    assert len(calibration.errors_px) == len(SPREAD)
    grid = np.array([(x, y) for x in range(0, 4001, 500) for y in range(0, 3001, 500)], float)
    np.testing.assert_allclose(
        project(calibration.homography, grid), project(nominal_homography(LAB), grid), atol=1e-4
    )
    assert calibration.image_centre_on_floor() == pytest.approx((2000.0, 1500.0), abs=1e-3)


def test_a_camera_without_marks_keeps_its_nominal_homography() -> None:
    calibration = calibrate(LAB)
    assert (calibration.source, calibration.rms_px, calibration.errors_px) == ("nominal", None, ())
    np.testing.assert_array_equal(calibration.homography, nominal_homography(LAB))


def test_marks_read_to_a_third_of_a_pixel_place_the_corners_within_two_pixels() -> None:
    """0.3 px of reading noise (3.75 mm on the floor) over 50 surveys: the RMS stays under
    0.6 px; the image centre, inside the marks, is within 8 mm (0.6 px); the corners,
    extrapolated, within 20 mm (1.6 px) and 10 mm in the median."""
    rng = np.random.default_rng(3)
    truth = nominal_homography(LAB)
    exact = project(truth, np.array(SPREAD, dtype=float))
    centre_errors, corner_errors = [], []
    for _ in range(50):
        noisy = exact + rng.normal(0.0, 0.3, exact.shape)
        calibration = calibrate(marked(LAB, SPREAD, noisy))
        assert calibration.rms_px is not None and calibration.rms_px < 0.6
        centre = np.array(calibration.image_centre_on_floor())
        centre_errors.append(np.linalg.norm(centre - (LAB.x_mm, LAB.y_mm)))
        off = to_plane(calibration.homography, CORNERS) - to_plane(truth, CORNERS)
        corner_errors.append(np.linalg.norm(off, axis=1).max())
    assert max(centre_errors) < 8.0
    assert max(corner_errors) < 20.0
    assert float(np.median(corner_errors)) < 10.0


def test_an_honest_survey_of_the_pose_is_accepted() -> None:
    """The marks tell the truth; the camera's pose as surveyed is 100 mm and 4 degrees off,
    and its height 50 mm: within what the pose check allows."""
    surveyed = LAB.model_copy(update={"x_mm": 2100.0, "yaw_deg": 4.0, "height_mm": 4050.0})
    truth = project(nominal_homography(LAB), np.array(SPREAD, dtype=float))
    calibration = calibrate(marked(surveyed, SPREAD, truth))
    assert calibration.image_centre_on_floor() == pytest.approx((2000.0, 1500.0), abs=0.01)


def test_the_calibration_sees_a_robots_top_like_the_nominal_model() -> None:
    """raise_plane works on a calibrated homography as on the nominal one."""
    calibration = calibrate(marked(LAB, SPREAD))
    top = raise_plane(calibration.homography, LAB, 800.0)
    np.testing.assert_allclose(
        project(top, np.array([[3000.0, 1500.0]])),
        project(nominal_homography(LAB, 800.0), np.array([[3000.0, 1500.0]])),
        atol=1e-6,
    )


# --- calibrations that cannot be trusted -----------------------------------------------------


def test_fewer_than_four_marks_are_refused() -> None:
    error = refusal(marked(LAB, SPREAD[:3]))
    assert error.element == "floor 2 / camera lab"
    assert error.problem.startswith("marks: 3 given, a calibration needs at least 4")


@pytest.mark.parametrize(
    "points",
    [
        [(300, 250), (1150, 875), (2850, 2125), (3700, 2750), (2000, 1600)],
        [(300, 250), (3700, 250), (2000, 250), (2000, 2750)],
    ],
    ids=["along the diagonal, one 8 px off it", "three of four on one edge"],
)
def test_marks_in_a_line_are_refused(points: list[tuple[float, float]]) -> None:
    error = refusal(marked(LAB, points))
    assert error.element == "floor 2 / camera lab"
    assert error.problem.startswith("marks: lie (nearly) in a line")


def test_marks_bunched_in_a_corner_are_refused() -> None:
    bunched = [(300, 250), (1200, 250), (1200, 900), (300, 900), (700, 600)]
    error = refusal(marked(LAB, bunched))
    assert error.problem.startswith("marks: span 72 x 52 px of the 320 x 240 image")


def test_a_mark_outside_the_image_is_refused() -> None:
    camera = marked(LAB, SPREAD)
    marks = list(camera.marks)
    marks[1] = marks[1].model_copy(update={"u_px": 330.0})
    error = refusal(camera.model_copy(update={"marks": marks}))
    assert error.element == "floor 2 / camera lab / mark #2"
    assert error.problem == "u_px, v_px: (330.0, 220.0) lies outside the camera's 320 x 240 image"


def test_a_mark_mistyped_by_a_metre_is_refused_and_named() -> None:
    """The pixels are read right; the third mark's y is written 1 m off (3750 for 2750).
    The fit spreads its error, mark #5's residual is the largest, yet without #3 the other
    five agree."""
    pixels = project(nominal_homography(LAB), np.array(SPREAD, dtype=float))
    typo = [*SPREAD]
    typo[2] = (3700, 3750)
    fit, _ = cv2.findHomography(np.array(typo, dtype=float), pixels)
    residuals = np.linalg.norm(project(fit, np.array(typo, dtype=float)) - pixels, axis=1)
    assert int(np.argmax(residuals)) == 4
    error = refusal(marked(LAB, typo, pixels))
    assert error.element == "floor 2 / camera lab"
    assert error.problem.startswith("marks: reprojection error ")
    assert error.problem.endswith(
        "px RMS (at most 1.5): mark #3 mismeasured or mistyped, the others agree without it"
    )


def test_a_mistyped_mark_among_five_is_refused_without_a_name() -> None:
    """Any four of five marks fit exactly: none can be told from the others."""
    five = SPREAD[:5]
    pixels = project(nominal_homography(LAB), np.array(five, dtype=float))
    typo = [*five]
    typo[2] = (4700, 2750)
    error = refusal(marked(LAB, typo, pixels))
    assert error.problem.endswith(
        "(at most 1.5): a mark mismeasured or mistyped, and none stands out (that takes six "
        "or more)"
    )


def test_a_mistyped_mark_among_exactly_four_is_refused_by_the_pose() -> None:
    """Four marks fit a homography exactly (no reprojection error to see), and this typo
    moves the image centre less than 300 mm: the image's corners, over a metre from where
    the camera's pose puts them, give it away."""
    four = SPREAD[:4]
    pixels = project(nominal_homography(LAB), np.array(four, dtype=float))
    typo = [four[0], four[1], (4700, 2750), four[3]]
    error = refusal(marked(LAB, typo, pixels))
    assert error.element == "floor 2 / camera lab"
    assert error.problem.startswith("marks: put the image's ")
    assert "corner" in error.problem and "(at most 600 mm): a typo in a mark" in error.problem


@pytest.mark.parametrize(
    ("update", "problem"),
    [
        ({"x_mm": 3000.0}, "marks: put the image centre 1000 mm from where the camera's pose"),
        ({"yaw_deg": 180.0}, "marks: put the image's top-left corner 5000 mm from where"),
        ({"height_mm": 2800.0}, "marks: put the image's top-left corner 750 mm from where"),
    ],
    ids=["x off by a metre", "turned round", "height mistyped"],
)
def test_a_camera_whose_pose_disagrees_with_its_marks_is_refused(
    update: dict[str, float], problem: str
) -> None:
    truth = project(nominal_homography(LAB), np.array(SPREAD, dtype=float))
    error = refusal(marked(LAB.model_copy(update=update), SPREAD, truth))
    assert error.element == "floor 2 / camera lab"
    assert error.problem.startswith(problem)


# --- the CS building ------------------------------------------------------------------------


def test_the_cs_building_loads_with_its_calibrated_cameras() -> None:
    plan = load_floorplan(CS_BUILDING)
    cameras = {(floor.level, c.id): c for floor in plan.floors for c in floor.cameras}
    assert sorted(cameras) == [
        (2, "lobby-2"),
        (2, "north-hall-2"),
        (2, "tea-room"),
        (3, "lobby-3"),
        (3, "north-hall-3"),
    ]
    for camera in cameras.values():
        calibration = calibrate(camera)
        assert calibration.source == "marks"
        assert calibration.rms_px is not None and calibration.rms_px < 0.1
        assert len(camera.marks) >= 5
        centre = calibration.image_centre_on_floor()
        assert centre == pytest.approx((camera.x_mm, camera.y_mm), abs=1.0)


def test_the_cs_cameras_see_what_they_are_there_for() -> None:
    """The tea room camera sees a robot's top (900 mm) on every parking spot and the
    loading spot; each lobby camera the car's door; each crossing camera 2 m up the side
    hallway."""
    plan = load_floorplan(CS_BUILDING)

    def in_view(camera: Camera, point: tuple[float, float], plane_mm: float = 0.0) -> bool:
        calibration = calibrate(camera)
        h = raise_plane(calibration.homography, camera, plane_mm)
        u, v = project(h, np.array([point]))[0]
        return bool(0 <= u <= camera.width_px and 0 <= v <= camera.height_px)

    floor2 = plan.floor(2)
    tea = next(c for c in floor2.cameras if c.id == "tea-room")
    loading = floor2.behind_door(plan.tea_room.door, plan.tea_room.door.recess_mm + 700)
    spots = [(p.x_mm, p.y_mm) for p in floor2.parking]
    assert all(in_view(tea, spot, 900.0) for spot in [*spots, loading])
    for floor in plan.floors:
        cameras = {c.id.rsplit("-", 1)[0]: c for c in floor.cameras}
        car = floor.elevator
        assert car is not None
        assert in_view(cameras["lobby"], floor.behind_door(car, car.recess_mm))
        side_hallway = next(o for o in floor.openings if o.id == "north hall")
        wall_line = floor.hallway.width_mm / 2
        up_it = [floor.from_hallway(side_hallway.at_mm, wall_line + d) for d in (2000, 3000)]
        assert in_view(cameras["north-hall"], up_it[0])
        assert not in_view(cameras["north-hall"], up_it[1])
