"""A ceiling camera's image pipeline (seed 003, IV.A and VI.B) on frames drawn here: a
textured floor with walls and sensor noise, a robot (a dark 610 x 510 mm rectangle) and a
person (a light disc 450 mm across), drawn at 4x resolution and averaged down as a sensor
would, so their edges fall between pixels."""

from __future__ import annotations

import math
from collections.abc import Iterator, Sequence

import cv2
import numpy as np
import pytest

from coffeebot.cameras.geometry import nominal_homography, project, raise_plane
from coffeebot.cameras.pipeline import CameraPipeline, Detection, PipelineSettings
from coffeebot.cameras.tracks import Tracker, TrackerSettings
from coffeebot.floorplan import Camera

CAMERA = Camera(id="lab", x_mm=2000.0, y_mm=1500.0, height_mm=4000.0)
"""The seed's camera: 320 x 240 px from 4 m, 12.5 mm a pixel over a 4 m x 3 m patch."""
PX_MM = 12.5
PERIOD_S = 0.1
SETTINGS = PipelineSettings()

ROBOT_LENGTH_MM, ROBOT_WIDTH_MM, ROBOT_GREY = 610.0, 510.0, 45.0
PERSON_DIAMETER_MM, PERSON_GREY = 450.0, 205.0
SEAM_MM, SEAM_GREY = 40.0, 130.0
SUPERSAMPLE = 4

Thing = tuple[np.ndarray, float]
"""A polygon on the drawn plane (corners in mm) and its grey level."""


def rectangle(
    x_mm: float, y_mm: float, length_mm: float, width_mm: float, axis_deg: float, grey: float
) -> Thing:
    along = np.array([math.cos(math.radians(axis_deg)), math.sin(math.radians(axis_deg))])
    across = np.array([-along[1], along[0]])
    half_l, half_w = length_mm / 2 * along, width_mm / 2 * across
    centre = np.array([x_mm, y_mm])
    corners = [centre + half_l + half_w, centre - half_l + half_w]
    corners += [centre - half_l - half_w, centre + half_l - half_w]
    return np.array(corners), grey


def robot(x_mm: float, y_mm: float, axis_deg: float) -> Thing:
    return rectangle(x_mm, y_mm, ROBOT_LENGTH_MM, ROBOT_WIDTH_MM, axis_deg, ROBOT_GREY)


def seam(x_mm: float, y_mm: float, axis_deg: float) -> Thing:
    """A 40 mm floor-grey gap right across a robot's top, between two panels: only the
    mask's closing keeps the robot one blob."""
    return rectangle(x_mm, y_mm, SEAM_MM, ROBOT_WIDTH_MM, axis_deg, SEAM_GREY)


def person(x_mm: float, y_mm: float) -> Thing:
    angles = np.linspace(0.0, 2 * math.pi, 72, endpoint=False)
    rim = np.column_stack([np.cos(angles), np.sin(angles)]) * PERSON_DIAMETER_MM / 2
    return rim + np.array([x_mm, y_mm]), PERSON_GREY


class Scene:
    """One camera's view: a fixed floor texture, things drawn on it, fresh noise per frame."""

    def __init__(self, camera: Camera = CAMERA, seed: int = 3) -> None:
        self.camera = camera
        self.floor_homography = nominal_homography(camera)
        self.rng = np.random.default_rng(seed)
        h, w = camera.height_px, camera.width_px
        blotches = cv2.resize(
            self.rng.normal(0.0, 1.0, (h // 8, w // 8)).astype(np.float32),
            (w, h),
            interpolation=cv2.INTER_CUBIC,
        )
        self.floor = 130.0 + 15.0 * blotches + 6.0 * self.rng.normal(0.0, 1.0, (h, w))
        self.floor[:16] = 200.0  # a wall's top along the image's upper edge
        self.floor[-14:] = 70.0  # and a darker one along its lower edge

    def frame(
        self,
        things: Sequence[Thing] = (),
        *,
        homography: np.ndarray | None = None,
        gain: float = 1.0,
        noise_grey: float = 3.0,
    ) -> np.ndarray:
        return self.sensor(self.light(things, homography=homography, gain=gain), noise_grey)

    def light(
        self,
        things: Sequence[Thing] = (),
        *,
        homography: np.ndarray | None = None,
        gain: float = 1.0,
    ) -> np.ndarray:
        """The light reaching the sensor (float grey levels), before its noise."""
        drawn_on = self.floor_homography if homography is None else homography
        image = self.floor.copy()
        for corners, grey in things:
            cover = self._coverage(project(drawn_on, corners))
            image = image * (1.0 - cover) + grey * cover
        return image * gain

    def sensor(self, light: np.ndarray, noise_grey: float = 3.0) -> np.ndarray:
        noisy = light + self.rng.normal(0.0, noise_grey, light.shape)
        return np.clip(np.round(noisy), 0, 255).astype(np.uint8)

    def _coverage(self, pixels: np.ndarray) -> np.ndarray:
        """Fraction of each pixel inside the polygon (pixel i spans [i, i + 1])."""
        h, w = self.camera.height_px, self.camera.width_px
        fine = np.zeros((h * SUPERSAMPLE, w * SUPERSAMPLE), np.uint8)
        # fillPoly fills the fine pixels whose centres (their indices) lie inside.
        points = np.round((pixels * SUPERSAMPLE - 0.5) * 16).astype(np.int32)
        cv2.fillPoly(fine, [points], 255, lineType=cv2.LINE_8, shift=4)
        return cv2.resize(fine, (w, h), interpolation=cv2.INTER_AREA) / 255.0


def times(start_s: float, period_s: float = PERIOD_S) -> Iterator[float]:
    t = start_s
    while True:
        yield t
        t += period_s


def learned_pipeline(
    scene: Scene, homography: np.ndarray | None = None
) -> tuple[CameraPipeline, Iterator[float]]:
    """A pipeline that has learned the empty scene, and the clock of its next frames."""
    pipeline = CameraPipeline(
        scene.camera, scene.floor_homography if homography is None else homography, SETTINGS
    )
    clock = times(0.0)
    for _ in range(SETTINGS.learn_frames):
        assert not pipeline.learned
        assert pipeline.step(scene.frame(), next(clock)) == []
    assert pipeline.learned
    return pipeline, clock


def nearest(detections: Sequence[Detection], x_mm: float, y_mm: float) -> Detection:
    return min(detections, key=lambda d: math.hypot(d.x_mm - x_mm, d.y_mm - y_mm))


def axis_error_deg(measured: float, true: float) -> float:
    """Difference of two line directions, modulo 180."""
    return abs((measured - true + 90.0) % 180.0 - 90.0)


def test_the_scenes_noise_is_3_grey_levels() -> None:
    scene = Scene()
    noise = scene.frame().astype(float) - scene.frame(noise_grey=0.0)
    assert np.std(noise) == pytest.approx(3.0, abs=0.1)


def test_an_empty_noisy_scene_gives_no_detections_once_learned() -> None:
    scene = Scene()
    pipeline, clock = learned_pipeline(scene)
    for _ in range(300):
        assert pipeline.step(scene.frame(noise_grey=3.0), next(clock)) == []
    assert pipeline.foreground_average().max() == 0.0


@pytest.mark.parametrize("camera_yaw_deg", [0.0, 73.0])
def test_a_moving_robot_is_found_where_it_is_and_how_it_is_turned(camera_yaw_deg: float) -> None:
    scene = Scene(CAMERA.model_copy(update={"yaw_deg": camera_yaw_deg}))
    pipeline, clock = learned_pipeline(scene)
    for k in range(40):
        x, y, axis = 1300.0 + 35.0 * k, 1200.0 + 15.0 * k, 20.0 + 4.0 * k
        frame = scene.frame([robot(x, y, axis), seam(x, y, axis)])
        (seen,) = pipeline.step(frame, next(clock))
        assert math.hypot(seen.x_mm - x, seen.y_mm - y) < PX_MM / 2
        assert axis_error_deg(seen.axis_deg, axis) < 3.0
        assert 0.0 <= seen.axis_deg < 180.0
        # The blurred outline, cut well below half the contrast, is 1-2 px wider each way.
        assert seen.length_mm == pytest.approx(ROBOT_LENGTH_MM, abs=3 * PX_MM)
        assert seen.width_mm == pytest.approx(ROBOT_WIDTH_MM, abs=3 * PX_MM)
        assert seen.area_mm2 == pytest.approx(ROBOT_LENGTH_MM * ROBOT_WIDTH_MM, rel=0.06)
        assert seen.camera_id == "lab"
        assert seen.t_s == pytest.approx(SETTINGS.learn_frames * PERIOD_S + k * PERIOD_S)


def test_a_person_a_metre_from_the_robot_is_a_detection_of_its_own() -> None:
    scene = Scene()
    pipeline, clock = learned_pipeline(scene)
    for k in range(20):
        robot_at = (1200.0 + 40.0 * k, 1500.0)
        person_at = (robot_at[0] + 600.0, robot_at[1] + 800.0)  # 1 m away, centre to centre
        things = [robot(*robot_at, axis_deg=10.0), person(*person_at)]
        detections = pipeline.step(scene.frame(things), next(clock))
        assert len(detections) == 2
        the_robot, the_person = nearest(detections, *robot_at), nearest(detections, *person_at)
        assert math.dist((the_robot.x_mm, the_robot.y_mm), robot_at) < PX_MM / 2
        assert math.dist((the_person.x_mm, the_person.y_mm), person_at) < PX_MM / 2
        assert the_person.length_mm == pytest.approx(PERSON_DIAMETER_MM, abs=3 * PX_MM)
        assert the_person.width_mm == pytest.approx(PERSON_DIAMETER_MM, abs=3 * PX_MM)
        assert the_person.area_mm2 == pytest.approx(math.pi * 225.0**2, rel=0.08)


def test_positions_are_on_the_plane_the_homography_maps_from() -> None:
    """A robot's top 800 mm up, off the nadir: its own plane places it; the floor's places
    it 25 % further from the nadir."""
    scene = Scene()
    top = raise_plane(scene.floor_homography, CAMERA, 800.0)
    on_top, _ = learned_pipeline(scene, top)
    on_floor, _ = learned_pipeline(scene)
    for k in range(10):
        x, y = 3000.0 + 20.0 * k, 1500.0 - 10.0 * k
        frame = scene.frame([robot(x, y, axis_deg=90.0)], homography=top)
        t_s = 10.0 + k * PERIOD_S
        (seen_on_top,) = on_top.step(frame, t_s)
        (seen_on_floor,) = on_floor.step(frame, t_s)
        assert math.hypot(seen_on_top.x_mm - x, seen_on_top.y_mm - y) < PX_MM / 2
        nadir_x, nadir_y = CAMERA.x_mm, CAMERA.y_mm
        assert seen_on_floor.x_mm - nadir_x == pytest.approx(1.25 * (x - nadir_x), abs=PX_MM)
        assert seen_on_floor.y_mm - nadir_y == pytest.approx(1.25 * (y - nadir_y), abs=PX_MM)


@pytest.mark.parametrize("gain", [1.2, 0.8])
def test_a_global_brightness_jump_shows_nothing_new_even_in_its_own_frame(gain: float) -> None:
    """Gain normalisation against the background: no frame, not even the jump's, has a
    false detection."""
    scene = Scene()
    pipeline, clock = learned_pipeline(scene)
    before = scene.frame(noise_grey=0.0).astype(float)
    after = scene.frame(gain=gain, noise_grey=0.0).astype(float)
    assert np.median(np.abs(after - before)) > SETTINGS.threshold_grey  # subtraction alone fails
    for k in range(40):
        x, y = 1200.0 + 40.0 * k, 1400.0
        frame = scene.frame([robot(x, y, axis_deg=60.0)], gain=1.0 if k < 20 else gain)
        (seen,) = pipeline.step(frame, next(clock))
        assert math.hypot(seen.x_mm - x, seen.y_mm - y) < PX_MM / 2
    for _ in range(20):
        assert pipeline.step(scene.frame(gain=gain), next(clock)) == []


def test_a_robot_waiting_half_a_minute_stays_but_a_cart_left_for_minutes_becomes_floor() -> None:
    scene = Scene()
    pipeline, clock = learned_pipeline(scene)
    x, y = 2300.0, 1700.0
    waiting = scene.light([robot(x, y, axis_deg=45.0)])
    arrived_s = SETTINGS.learn_frames * PERIOD_S
    for _ in range(300):  # 30 s at 10 fps
        detections = pipeline.step(scene.sensor(waiting), next(clock))
    (seen,) = detections
    assert math.hypot(seen.x_mm - x, seen.y_mm - y) < PX_MM / 2
    assert seen.area_mm2 == pytest.approx(ROBOT_LENGTH_MM * ROBOT_WIDTH_MM, rel=0.06)
    slow_clock = times(next(clock), period_s=1.0)
    last_seen_s = None
    for _ in range(660):  # 11 min more at one frame a second
        t_s = next(slow_clock)
        if pipeline.step(scene.sensor(waiting), t_s):
            last_seen_s = t_s
    assert last_seen_s is not None
    assert 120.0 < last_seen_s - arrived_s < 600.0  # absorbed after minutes, in the end


def test_the_foreground_average_marks_what_stands_still_not_what_passes() -> None:
    scene = Scene()
    pipeline, clock = learned_pipeline(scene)
    standing, passing_y = (1200.0, 1000.0), 2200.0
    for k in range(300):  # 30 s: a person crosses the view every 5 s at 1 m/s
        things = [robot(*standing, axis_deg=0.0), person(500.0 + 100.0 * (k % 50), passing_y)]
        pipeline.step(scene.frame(things), next(clock))
    average = pipeline.foreground_average()
    h = scene.floor_homography
    (robot_px,), (path_px,), (bare_px,) = (
        np.floor(project(h, np.array([p]))).astype(int)
        for p in (standing, (2000.0, passing_y), (3000.0, 800.0))
    )
    assert average[robot_px[1], robot_px[0]] > 0.9
    assert 0.0 < average[path_px[1], path_px[0]] < 0.2
    assert average[bare_px[1], bare_px[0]] == 0.0
    pipeline.foreground_average()[:] = 1.0  # a copy: the caller cannot disturb the average
    assert pipeline.foreground_average()[bare_px[1], bare_px[0]] == 0.0


def test_a_robot_and_a_person_passing_800_mm_apart_keep_their_tracks() -> None:
    scene = Scene()
    pipeline, clock = learned_pipeline(scene)
    tracker = Tracker(TrackerSettings())
    ids_seen: dict[str, set[str]] = {"robot": set(), "person": set()}
    for k in range(30):
        robot_at = (800.0 + 80.0 * k, 1100.0)
        person_at = (3200.0 - 80.0 * k, 1900.0)
        things = [robot(*robot_at, axis_deg=0.0), person(*person_at)]
        t_s = next(clock)
        tracks = tracker.update(pipeline.step(scene.frame(things), t_s), t_s)
        assert len(tracks) == 2
        for name, (x, y) in (("robot", robot_at), ("person", person_at)):
            track = min(tracks, key=lambda tr: math.hypot(tr.latest.x_mm - x, tr.latest.y_mm - y))
            ids_seen[name].add(track.id)
    assert [len(ids) for ids in ids_seen.values()] == [1, 1]
    assert ids_seen["robot"] != ids_seen["person"]


def test_a_frame_of_the_wrong_size_or_time_is_refused() -> None:
    scene = Scene()
    pipeline, clock = learned_pipeline(scene)
    with pytest.raises(ValueError, match="uint8 frames of"):
        pipeline.step(np.zeros((240, 320), np.float32), next(clock))
    with pytest.raises(ValueError, match="uint8 frames of"):
        pipeline.step(np.zeros((480, 640), np.uint8), next(clock))
    t_s = next(clock)
    pipeline.step(scene.frame(), t_s)
    with pytest.raises(ValueError, match="not after"):
        pipeline.step(scene.frame(), t_s)


def test_a_robot_driving_out_of_view_is_marked_cut_once_it_touches_the_border() -> None:
    """The camera sees x 0..4000 mm: the body (610 mm long, along x) reaches the border when
    its centre passes 3695 mm, and from there its blob is only the part still in view."""
    scene = Scene()
    pipeline, clock = learned_pipeline(scene)
    cuts: dict[float, bool] = {}
    for k in range(22):
        x = 3000.0 + 50.0 * k
        detections = pipeline.step(scene.frame([robot(x, 1500.0, 0.0)]), next(clock))
        if detections:
            cuts[x] = nearest(detections, x, 1500.0).cut
    assert not any(cut for x, cut in cuts.items() if x < 3600.0)
    assert all(cut for x, cut in cuts.items() if x > 3750.0)
    assert any(x > 3750.0 for x in cuts), "still seen, in part, past the border"


def test_a_robot_in_the_first_frames_leaves_no_ghost_when_it_drives_off() -> None:
    scene = Scene()
    pipeline = CameraPipeline(scene.camera, scene.floor_homography, SETTINGS)
    clock = times(0.0)
    docked = [robot(2300.0, 1700.0, axis_deg=0.0)]
    for _ in range(SETTINGS.learn_frames):  # the robot stood at its dock while learning
        pipeline.step(scene.frame(docked), next(clock))
    # It drives off; a second later a cart is put down elsewhere, which must be seen.
    assert pipeline.step(scene.frame(), next(clock)) == []
    for _ in range(50):
        assert pipeline.step(scene.frame(), next(clock)) == []
    cart = [rectangle(1200.0, 1000.0, 900.0, 600.0, 0.0, 60.0)]
    for _ in range(10):
        detections = pipeline.step(scene.frame(cart), next(clock))
    assert len(detections) == 1
    assert math.hypot(detections[0].x_mm - 1200.0, detections[0].y_mm - 1000.0) < PX_MM


def test_a_cart_absorbed_into_the_background_leaves_no_ghost_when_pushed_away() -> None:
    scene = Scene()
    pipeline, clock = learned_pipeline(scene)
    cart = [rectangle(2300.0, 1700.0, 900.0, 600.0, 30.0, 60.0)]
    slow_clock = times(next(clock), period_s=1.0)
    for _ in range(900):  # a quarter of an hour: the cart is background now
        pipeline.step(scene.frame(cart), next(slow_clock))
    assert pipeline.step(scene.frame(cart), next(slow_clock)) == []
    assert pipeline.step(scene.frame(), next(slow_clock)) == []
    assert pipeline.step(scene.frame(), next(slow_clock)) == []


def test_a_dark_cart_wheeled_away_after_a_minute_and_a_half_leaves_no_ghost() -> None:
    scene = Scene()
    pipeline, clock = learned_pipeline(scene)
    cart = [rectangle(2300.0, 1700.0, 900.0, 500.0, 90.0, 20.0)]
    for _ in range(900):  # 90 s at 10 fps: about a quarter of it learned into the background
        detections = pipeline.step(scene.frame(cart), next(clock))
    assert len(detections) == 1
    for _ in range(30):
        assert pipeline.step(scene.frame(), next(clock)) == []
