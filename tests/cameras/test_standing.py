"""The map's camera layer: what stands still and is no robot becomes an object; it leaves
when it moves or its working camera no longer sees it, and only expires while the camera
is out."""

from __future__ import annotations

from collections.abc import Iterable, Sequence

import pytest

from coffeebot.cameras.pipeline import Detection
from coffeebot.cameras.standing import StandingObjects, StandingRules
from coffeebot.cameras.tracks import Track
from coffeebot.cameras.watch import CameraWatch
from coffeebot.floorplan import Camera

CAMERA = Camera(id="hall", x_mm=24000.0, y_mm=0.0, height_mm=2600.0, fov_deg=90.0)
RULES = StandingRules(standing_after_s=10.0, gone_after_s=2.0, expiry_s=60.0)
ROBOT_TOP_MM = 900.0


def watch() -> CameraWatch:
    return CameraWatch(CAMERA, 2, ROBOT_TOP_MM, keep_s=8.0)


def seen(track_id: str, t_s: float, x_mm: float, y_mm: float, *, still: bool = True) -> Track:
    detection = Detection(
        t_s=t_s,
        x_mm=x_mm,
        y_mm=y_mm,
        length_mm=900.0,
        width_mm=600.0,
        axis_deg=0.0,
        area_mm2=540_000.0,
        camera_id=CAMERA.id,
    )
    track = Track(track_id, detection, max_history=600)
    track.still = still
    return track


def feed(
    layer: StandingObjects,
    cameras: CameraWatch,
    tracks: list[Track],
    t_s: float,
    robots: Sequence[tuple[int, float, float]] = (),
    robot_tracks: Iterable[str] = (),
) -> bool:
    cameras.tracks = tracks
    return layer.update(cameras, t_s, robots, robot_tracks)


def test_a_track_standing_long_enough_becomes_an_object_covering_it_at_any_height() -> None:
    layer, cameras = StandingObjects(RULES), watch()
    for k in range(100):  # 9.9 s: not yet
        assert not feed(layer, cameras, [seen("hall-1", k / 10, 25000.0, 400.0)], k / 10)
    assert layer.objects == []
    assert feed(layer, cameras, [seen("hall-1", 10.0, 25000.0, 400.0)], 10.0)
    (cart,) = layer.objects
    assert (cart.id, cart.camera_id, cart.floor, cart.standing_since_s) == (
        "hall-1",
        "hall",
        2,
        0.0,
    )
    # What a flat thing and a thing as tall as a robot would cover, together: the blob read
    # on the robot's top (900 x 600 mm about (25 000, 400)) and on the floor, where that is
    # scaled by 2600 / 1700 about the camera's nadir (24 000, 0).
    ratio = 2600.0 / (2600.0 - 900.0)
    floor_x, floor_y = 24000.0 + 1000.0 * ratio, 400.0 * ratio
    x0, x1 = 25000.0 - 450.0, floor_x + 450.0 * ratio
    y0, y1 = 400.0 - 300.0, floor_y + 300.0 * ratio
    assert cart.x_mm == pytest.approx((x0 + x1) / 2, abs=2.0)
    assert cart.y_mm == pytest.approx((y0 + y1) / 2, abs=2.0)
    assert cart.length_mm == pytest.approx(x1 - x0, abs=2.0)
    assert cart.width_mm == pytest.approx(y1 - y0, abs=2.0)
    assert cart.axis_deg == pytest.approx(0.0, abs=0.1) or cart.axis_deg == pytest.approx(
        180.0, abs=0.1
    )


def test_it_leaves_the_map_as_soon_as_it_moves() -> None:
    layer, cameras = StandingObjects(RULES), watch()
    for k in range(120):
        feed(layer, cameras, [seen("hall-1", k / 10, 25000.0, 400.0)], k / 10)
    assert layer.objects
    assert feed(
        layer, cameras, [seen("hall-1", 12.0, 25100.0, 400.0, still=False)], 12.0, robots=[]
    )
    assert layer.objects == []


def test_an_object_its_working_camera_no_longer_sees_is_gone_after_two_seconds() -> None:
    layer, cameras = StandingObjects(RULES), watch()
    for k in range(120):
        feed(layer, cameras, [seen("hall-1", k / 10, 25000.0, 400.0)], k / 10)
    assert not feed(layer, cameras, [], 13.0)
    assert layer.objects
    assert feed(layer, cameras, [], 14.2)
    assert layer.objects == []


def test_while_its_camera_is_out_an_object_stays_until_it_expires() -> None:
    layer, cameras = StandingObjects(RULES), watch()
    for k in range(120):
        feed(layer, cameras, [seen("hall-1", k / 10, 25000.0, 400.0)], k / 10)
    assert not layer.camera_out("hall", 60.0)
    assert layer.objects
    assert not layer.camera_out("other-camera", 100.0)
    assert layer.objects
    assert layer.camera_out("hall", 71.95)
    assert layer.objects == []


def test_a_robot_standing_is_no_object_by_its_pose_or_by_its_track() -> None:
    layer, cameras = StandingObjects(RULES), watch()
    for k in range(150):
        t = k / 10
        tracks = [seen("hall-1", t, 25000.0, 400.0), seen("hall-2", t, 23000.0, -400.0)]
        feed(
            layer,
            cameras,
            tracks,
            t,
            robots=[(2, 25300.0, 500.0)],  # 316 mm from hall-1's blob
            robot_tracks={"hall-2"},
        )
    assert layer.objects == []
    # The same robot on the other floor is no excuse.
    layer = StandingObjects(RULES)
    for k in range(150):
        t = k / 10
        feed(layer, cameras, [seen("hall-1", t, 25000.0, 400.0)], t, robots=[(3, 25300.0, 500.0)])
    assert [o.id for o in layer.objects] == ["hall-1"]
