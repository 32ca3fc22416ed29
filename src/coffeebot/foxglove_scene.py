"""The robot in Foxglove's 3D panel: its pose, body, walls and what each ToF sensor sees, as
Foxglove's own message types (``foxglove-sdk``), so the panel draws them with no setup.

Frames: ``map`` is the floor plan's frame in metres (x along the hallway, y to its left);
``base_link`` is the robot's body centre, x forward, y left, z up from the floor.
"""

from __future__ import annotations

import math
import struct
from collections.abc import Sequence

from foxglove.messages import (
    Color,
    CubePrimitive,
    FrameTransform,
    LinePrimitive,
    LinePrimitiveLineType,
    PackedElementField,
    PackedElementFieldNumericType,
    Point3,
    PointCloud,
    Pose,
    Quaternion,
    SceneEntity,
    SceneUpdate,
    Timestamp,
    Vector3,
)

from coffeebot.config import GeometryConfig, TofSensorConfig
from coffeebot.floorplan import Floor
from coffeebot.messages import PoseEstimate, RangeReading
from coffeebot.sensor_view import Reach, sensor_cones

MAP_FRAME = "map"
BODY_FRAME = "base_link"
BODY_HEIGHT_M = 0.3
"""How tall the drawn body is: a box to see the robot by, not its real shape."""
CONE_ARC_STEPS = 6
"""Straight pieces of a drawn cone's far edge."""

REACH_COLOURS: dict[Reach, tuple[float, float, float, float]] = {
    "hit": (0.1, 0.61, 0.23, 0.8),
    "clear": (0.18, 0.61, 0.8, 0.5),
    "fault": (0.83, 0.2, 0.2, 0.9),
}
"""The live map's colours: green sees something, blue sees nothing in range, red no reading."""

POINT_FIELDS = ("x", "y", "z", "distance")
"""Each point of ``/tof/points``: where the reading hit in ``base_link`` and its range, m."""


def _m(mm: float) -> float:
    return mm / 1000.0


def _colour(reach: Reach) -> Color:
    r, g, b, a = REACH_COLOURS[reach]
    return Color(r=r, g=g, b=b, a=a)


def _yaw(heading_deg: float) -> Quaternion:
    half = math.radians(heading_deg) / 2
    return Quaternion(x=0.0, y=0.0, z=math.sin(half), w=math.cos(half))


def pose_transform(pose: PoseEstimate, stamp: float) -> FrameTransform:
    """The estimated pose as the transform from ``map`` to ``base_link``."""
    return FrameTransform(
        timestamp=Timestamp.from_epoch_secs(stamp),
        parent_frame_id=MAP_FRAME,
        child_frame_id=BODY_FRAME,
        translation=Vector3(x=_m(pose.x_mm), y=_m(pose.y_mm), z=0.0),
        rotation=_yaw(pose.heading_deg),
    )


def floor_walls(floor: Floor, stamp: float) -> SceneUpdate:
    """Every wall of ``floor`` as lines on the floor of ``map``."""
    points = [
        Point3(x=_m(x), y=_m(y), z=0.0)
        for x0, y0, x1, y1, *_ in floor.segment_array.tolist()
        for x, y in ((x0, y0), (x1, y1))
    ]
    walls = LinePrimitive(
        type=LinePrimitiveLineType.LineList,
        thickness=0.04,
        points=points,
        color=Color(r=0.15, g=0.2, b=0.22, a=1.0),
    )
    return SceneUpdate(
        entities=[
            SceneEntity(
                timestamp=Timestamp.from_epoch_secs(stamp),
                frame_id=MAP_FRAME,
                id="walls",
                lines=[walls],
            )
        ]
    )


def body_and_cones(
    readings: Sequence[RangeReading],
    sensors: Sequence[TofSensorConfig],
    geometry: GeometryConfig,
    max_range_mm: float,
    stamp: float,
) -> SceneUpdate:
    """The robot's body and each sensor's field of view, as far as its reading reaches."""
    heights = {s.id: _m(s.height_mm) for s in sensors}
    lines = []
    for cone in sensor_cones(readings, sensors, 0.0, 0.0, 0.0, max_range_mm):
        x, y, z = _m(cone.x_mm), _m(cone.y_mm), heights[cone.sensor]
        reach = _m(cone.range_mm)
        outline = [Point3(x=x, y=y, z=z)]
        for i in range(CONE_ARC_STEPS + 1):
            a = math.radians(
                cone.heading_deg - cone.half_fov_deg + 2 * cone.half_fov_deg * i / CONE_ARC_STEPS
            )
            outline.append(Point3(x=x + reach * math.cos(a), y=y + reach * math.sin(a), z=z))
        outline.append(outline[0])
        lines.append(
            LinePrimitive(
                type=LinePrimitiveLineType.LineStrip,
                thickness=0.015,
                points=outline,
                color=_colour(cone.reach),
            )
        )
    body = CubePrimitive(
        pose=Pose(position=Vector3(x=0.0, y=0.0, z=BODY_HEIGHT_M / 2), orientation=_yaw(0.0)),
        size=Vector3(x=_m(geometry.length_mm), y=_m(geometry.width_mm), z=BODY_HEIGHT_M),
        color=Color(r=0.92, g=0.55, b=0.2, a=0.9),
    )
    return SceneUpdate(
        entities=[
            SceneEntity(
                timestamp=Timestamp.from_epoch_secs(stamp),
                frame_id=BODY_FRAME,
                id="robot",
                cubes=[body],
                lines=lines,
            )
        ]
    )


def scan_points(
    readings: Sequence[RangeReading],
    sensors: Sequence[TofSensorConfig],
    max_range_mm: float,
    stamp: float,
) -> PointCloud:
    """Where each reading that ranged something hit, on its sensor's axis, in ``base_link``."""
    heights = {s.id: _m(s.height_mm) for s in sensors}
    data = bytearray()
    for cone in sensor_cones(readings, sensors, 0.0, 0.0, 0.0, max_range_mm):
        if cone.reach != "hit":
            continue
        a = math.radians(cone.heading_deg)
        reach = _m(cone.range_mm)
        x = _m(cone.x_mm) + reach * math.cos(a)
        y = _m(cone.y_mm) + reach * math.sin(a)
        data += struct.pack("<ffff", x, y, heights[cone.sensor], reach)
    f32 = PackedElementFieldNumericType.Float32
    return PointCloud(
        timestamp=Timestamp.from_epoch_secs(stamp),
        frame_id=BODY_FRAME,
        pose=Pose(position=Vector3(x=0.0, y=0.0, z=0.0), orientation=_yaw(0.0)),
        point_stride=4 * len(POINT_FIELDS),
        fields=[
            PackedElementField(name=name, offset=4 * i, type=f32)
            for i, name in enumerate(POINT_FIELDS)
        ],
        data=bytes(data),
    )
