"""The ceiling cameras' layer on the live map: the board's message to what the page draws."""

from __future__ import annotations

import json

import pytest

from coffeebot.board import Board
from coffeebot.messages import (
    ALL_TOPICS,
    CAMERA_LAYER,
    CameraLayer,
    CameraObject,
    CameraView,
)
from coffeebot.web.livemap import (
    CameraFieldShape,
    CameraObjectShape,
    MapFrame,
    MapPose,
    RobotShape,
    map_frame,
)

HERE = MapPose(x_mm=42_000, y_mm=0, heading_deg=180, floor=2)


class StoppedClock:
    """The board's time, set by the test."""

    def __init__(self, t: float) -> None:
        self.t = t

    def now(self) -> float:
        return self.t

    async def sleep(self, seconds: float) -> None:
        self.t += seconds


def view(camera_id: str, floor: int = 2, **fields: object) -> CameraView:
    corners = [(39_400.0, -1_950.0), (44_600.0, -1_950.0), (44_600.0, 1_950.0), (39_400.0, 1_950.0)]
    return CameraView.model_validate(
        {"camera_id": camera_id, "floor": floor, "corners_mm": corners, "working": True, **fields}
    )


def cart(floor: int = 2, axis_deg: float = 90.0) -> CameraObject:
    return CameraObject(
        id="t7",
        camera_id="lobby-2",
        floor=floor,
        x_mm=40_000,
        y_mm=300,
        length_mm=1_000,
        width_mm=400,
        axis_deg=axis_deg,
        standing_since_s=88.4,
        seen_s=99.5,
    )


def frame_with(layer: CameraLayer | None, now: float = 100.0) -> MapFrame:
    board = Board(ALL_TOPICS, clock=StoppedClock(now))
    if layer is not None:
        board.publish(CAMERA_LAYER, layer)
    return map_frame(board, lambda: {"estimated": HERE}, [])


def test_each_camera_on_the_robots_floor_is_an_outline_saying_whether_it_works() -> None:
    layer = CameraLayer(
        cameras=[
            view("lobby-2"),
            view("tea-room", working=False, problem="no frames for 3 s"),
            view("hall-3", floor=3),
            view("stairs", working=False),
        ],
        expiry_s=30,
    )
    fields = [s for s in frame_with(layer).shapes if isinstance(s, CameraFieldShape)]
    assert [(f.camera_id, f.working, f.text) for f in fields] == [
        ("lobby-2", True, "camera lobby-2"),
        ("tea-room", False, "camera tea-room: not working (no frames for 3 s)"),
        ("stairs", False, "camera stairs: not working"),
    ]
    assert fields[0].corners == layer.cameras[0].corners_mm


def test_an_object_standing_is_its_footprint_with_who_sees_it_and_for_how_long() -> None:
    # 1 m long along +y (axis 90 degrees), 0.4 m wide across, centred at (40 000, 300).
    layer = CameraLayer(objects=[cart(), cart(floor=3)], expiry_s=30)
    [thing] = [s for s in frame_with(layer).shapes if isinstance(s, CameraObjectShape)]
    assert (thing.id, thing.camera_id) == ("t7", "lobby-2")
    assert thing.corners == [
        pytest.approx((39_800, 800)),
        pytest.approx((39_800, -200)),
        pytest.approx((40_200, -200)),
        pytest.approx((40_200, 800)),
    ]
    assert thing.text == "seen standing by camera lobby-2 for 12 s"


def test_a_tilted_footprint_keeps_its_length_along_the_axis() -> None:
    layer = CameraLayer(objects=[cart(axis_deg=30.0)], expiry_s=30)
    [thing] = [s for s in frame_with(layer).shapes if isinstance(s, CameraObjectShape)]
    (ax, ay), (bx, by), (cx, cy), _ = thing.corners
    assert ((ax - bx) ** 2 + (ay - by) ** 2) ** 0.5 == pytest.approx(1_000)
    assert ((bx - cx) ** 2 + (by - cy) ** 2) ** 0.5 == pytest.approx(400)
    assert (ay - by) / (ax - bx) == pytest.approx(3**-0.5)  # tan 30 degrees
    assert ((ax + cx) / 2, (ay + cy) / 2) == pytest.approx((40_000, 300))


def test_the_fields_go_under_the_objects_and_everything_under_the_robot() -> None:
    layer = CameraLayer(objects=[cart()], cameras=[view("lobby-2")], expiry_s=30)
    kinds = [s.kind for s in frame_with(layer).shapes]
    assert kinds == ["camera_field", "camera_object", "robot"]


def test_the_page_gets_the_shapes_by_kind_in_floor_plan_millimetres() -> None:
    layer = CameraLayer(objects=[cart()], cameras=[view("lobby-2")], expiry_s=30)
    sent = json.loads(frame_with(layer).model_dump_json())
    field, thing, _ = sent["shapes"]
    assert field == {
        "kind": "camera_field",
        "camera_id": "lobby-2",
        "working": True,
        "corners": [[39400, -1950], [44600, -1950], [44600, 1950], [39400, 1950]],
        "text": "camera lobby-2",
    }
    assert thing["kind"] == "camera_object"
    assert MapFrame.model_validate(sent) == frame_with(layer)


def test_without_a_camera_layer_the_map_is_as_before() -> None:
    shapes = frame_with(None).shapes
    assert [type(s) for s in shapes] == [RobotShape]
