"""What Foxglove's 3D panel is given, decoded as Foxglove decodes it: the pose as a transform,
the walls, the body with each sensor's cone, and the readings as points where they hit."""

from __future__ import annotations

import base64
import math
import struct
from pathlib import Path

import pytest

from coffeebot.config import GeometryConfig, TofSensorConfig
from coffeebot.floorplan import load_floorplan
from coffeebot.foxglove_scene import (
    REACH_COLOURS,
    body_and_cones,
    floor_walls,
    pose_transform,
    scan_points,
)
from coffeebot.messages import PoseEstimate, RangeReading, ReadingStatus
from foxglove_decode import decode_message

REPO = Path(__file__).resolve().parents[1]


SENSORS = [
    TofSensorConfig(id=0, channel=0, face="right", x_mm=-138.5, y_mm=-255, yaw_deg=-90),
    TofSensorConfig(id=3, channel=3, face="front", x_mm=305, y_mm=-57.5, yaw_deg=0),
    TofSensorConfig(id=6, channel=6, face="left", x_mm=138.5, y_mm=255, yaw_deg=90),
]
"""Three of the seed's mounts, straight out (27 degree field of view, 250 mm up)."""
MAX_RANGE_MM = 4000


def readings() -> list[RangeReading]:
    """Sensor 3 (front, 57.5 mm right of the centre line) sees 800 mm; 6 (left) nothing; 0
    (right) has no reading."""
    return [
        RangeReading(sensor=3, status=ReadingStatus.VALID, distance_mm=800),
        RangeReading(sensor=6, status=ReadingStatus.NO_TARGET),
        RangeReading(sensor=0, status=ReadingStatus.VALID, distance_mm=300, healthy=False),
    ]


def test_the_pose_is_the_transform_from_map_to_the_body_in_metres() -> None:
    pose = PoseEstimate(
        x_mm=12_000, y_mm=-1_500, heading_deg=90, floor=2,
        sigma_x_mm=50, sigma_y_mm=50, sigma_heading_deg=2,
    )  # fmt: skip
    tf = decode_message(pose_transform(pose, stamp=3.25))
    assert (tf["parentFrameId"], tf["childFrameId"]) == ("map", "base_link")
    assert tf["translation"] == {"x": 12.0, "y": -1.5, "z": 0.0}
    r = tf["rotation"]
    assert (r["x"], r["y"]) == (0.0, 0.0)
    assert r["z"] == pytest.approx(math.sqrt(0.5)) and r["w"] == pytest.approx(math.sqrt(0.5))
    assert tf["timestamp"] == "1970-01-01T00:00:03.250Z"


def test_a_reading_that_hit_is_a_point_on_its_sensors_axis_others_are_not() -> None:
    cloud = decode_message(scan_points(readings(), SENSORS, MAX_RANGE_MM, stamp=1.0))
    assert cloud["frameId"] == "base_link"
    assert [f["name"] for f in cloud["fields"]] == ["x", "y", "z", "distance"]
    data = base64.b64decode(cloud["data"])
    assert len(data) == cloud["pointStride"] == 16  # one point: sensor 3's
    x, y, z, distance = struct.unpack("<ffff", data)
    # Mounted at (305, -57.5) mm facing forward, 250 mm up: 800 mm ahead of its lens.
    assert (x, y, z, distance) == pytest.approx((1.105, -0.0575, 0.25, 0.8))


def test_each_sensor_is_a_cone_from_its_mount_coloured_by_what_it_saw() -> None:
    geometry = GeometryConfig(width_mm=510, length_mm=610)
    scene = decode_message(body_and_cones(readings(), SENSORS, geometry, MAX_RANGE_MM, stamp=1.0))
    (robot,) = scene["entities"]
    assert robot["frameId"] == "base_link"
    (body,) = robot["cubes"]
    assert (body["size"]["x"], body["size"]["y"]) == pytest.approx((0.61, 0.51))
    hit, clear, fault = robot["lines"]
    for line, reach in ((hit, "hit"), (clear, "clear"), (fault, "fault")):
        colour = line["color"]
        assert (colour["r"], colour["g"], colour["b"], colour["a"]) == pytest.approx(
            REACH_COLOURS[reach]
        )
        assert line["points"][0] == line["points"][-1]  # a closed outline
    apex, *arc, _ = hit["points"]
    assert (apex["x"], apex["y"], apex["z"]) == pytest.approx((0.305, -0.0575, 0.25))
    # The far edge is 800 mm from the lens, across the 27 degree field of view.
    ranges = [math.hypot(p["x"] - 0.305, p["y"] + 0.0575) for p in arc]
    assert ranges == pytest.approx([0.8] * len(arc))
    bearings = [math.degrees(math.atan2(p["y"] + 0.0575, p["x"] - 0.305)) for p in arc]
    assert (bearings[0], bearings[-1]) == pytest.approx((-13.5, 13.5))
    # Nothing in range: out to the sensor's range, to the left; no reading: no length.
    assert max(p["y"] for p in clear["points"]) == pytest.approx(0.255 + 4.0)
    assert {(p["x"], p["y"]) for p in fault["points"]} == {(-0.1385, -0.255)}


def test_the_walls_are_every_wall_segment_of_the_floor_in_metres() -> None:
    floor = load_floorplan(REPO / "floorplans" / "cs-building.toml").floor(2)
    (walls,) = decode_message(floor_walls(floor, stamp=0.0))["entities"]
    assert walls["frameId"] == "map"
    (lines,) = walls["lines"]
    points = [v for p in lines["points"] for v in (p["x"], p["y"])]
    expected = [
        v / 1000 for x0, y0, x1, y1, *_ in floor.segment_array.tolist() for v in (x0, y0, x1, y1)
    ]
    assert len(points) == 4 * len(floor.segments) > 0
    assert points == pytest.approx(expected)
