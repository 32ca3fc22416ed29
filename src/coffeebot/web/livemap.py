"""What the live map draws over the floor plan, computed here so the browser only paints.

The page fetches the floor's SVG once and then receives a :class:`MapFrame` with every
inspector frame: a list of plain shapes in floor-plan millimetres. Shapes come from *layers*:
the robot poses (from a pose source the daemon provides) and one layer per board topic, keyed
by the topic's name in :data:`LAYERS`. A topic that is not declared on the board, or has not
published yet, simply draws nothing, so adding the route or detected doors later is one
function and one entry in that table.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Mapping, Sequence
from typing import Annotated, Any, Literal

from pydantic import BaseModel, Field

from coffeebot.board import BoardError, BoardView, Envelope
from coffeebot.config import TofSensorConfig
from coffeebot.messages import (
    CURRENT_STATE,
    PARTICLES,
    RANGE_SCAN,
    CurrentState,
    ParticleCloud,
    RangeScan,
    ReadingStatus,
)

NO_TARGET_RAY_MM = 300.0
"""Readings without a distance are drawn as a short stub so the sensor's state still shows."""

ELLIPSE_SCALE = math.sqrt(5.991)
"""The drawn ellipse holds the position with 95 % probability (chi-square, 2 degrees)."""


class MapPose(BaseModel):
    """A robot pose on a floor: position in floor-plan mm, heading CCW from +x."""

    x_mm: float
    y_mm: float
    heading_deg: float
    floor: int


PoseSource = Callable[[], Mapping[str, MapPose]]
"""Current poses by label, most trusted first (``estimated``, then the simulator's ``true``)."""


class RobotShape(BaseModel):
    kind: Literal["robot"] = "robot"
    label: str
    x_mm: float
    y_mm: float
    heading_deg: float


class RayShape(BaseModel):
    kind: Literal["ray"] = "ray"
    sensor: int
    status: str
    x1_mm: float
    y1_mm: float
    x2_mm: float
    y2_mm: float


class CloudShape(BaseModel):
    """Particles of the particle filter: x, y pairs in floor-plan mm."""

    kind: Literal["cloud"] = "cloud"
    points: list[tuple[float, float]]


class EllipseShape(BaseModel):
    """The estimate's 95 % position ellipse: centre, semi-axes and the first axis' angle."""

    kind: Literal["ellipse"] = "ellipse"
    x_mm: float
    y_mm: float
    rx_mm: float
    ry_mm: float
    angle_deg: float


Shape = Annotated[
    RobotShape | RayShape | CloudShape | EllipseShape, Field(discriminator="kind")
]


class MapFrame(BaseModel):
    floor: int | None
    shapes: list[Shape]


def to_floor(pose: MapPose, x_mm: float, y_mm: float) -> tuple[float, float]:
    """A robot-frame point (x forward, y left) in floor-plan coordinates."""
    h = math.radians(pose.heading_deg)
    return (
        pose.x_mm + x_mm * math.cos(h) - y_mm * math.sin(h),
        pose.y_mm + x_mm * math.sin(h) + y_mm * math.cos(h),
    )


def scan_rays(
    envelope: Envelope[Any], pose: MapPose, sensors: Sequence[TofSensorConfig]
) -> list[RayShape]:
    """One ray per reading from its sensor's mount, as long as the reading, coloured by status."""
    scan: RangeScan = envelope.msg
    mounts = {s.id: s for s in sensors}
    rays = []
    for reading in scan.readings:
        mount = mounts.get(reading.sensor)
        if mount is None:
            continue
        x1, y1 = to_floor(pose, mount.x_mm, mount.y_mm)
        length = reading.distance_mm if reading.distance_mm is not None else NO_TARGET_RAY_MM
        yaw = math.radians(pose.heading_deg + mount.yaw_deg)
        status = reading.status.value if reading.healthy else ReadingStatus.HARDWARE_FAIL.value
        rays.append(
            RayShape(
                sensor=reading.sensor,
                status=status,
                x1_mm=x1,
                y1_mm=y1,
                x2_mm=x1 + length * math.cos(yaw),
                y2_mm=y1 + length * math.sin(yaw),
            )
        )
    return rays


def particle_cloud(
    envelope: Envelope[Any], pose: MapPose, sensors: Sequence[TofSensorConfig]
) -> list[CloudShape]:
    cloud: ParticleCloud = envelope.msg
    if cloud.floor != pose.floor:
        return []
    return [CloudShape(points=list(zip(cloud.x_mm, cloud.y_mm, strict=True)))]


def uncertainty_ellipse(
    envelope: Envelope[Any], pose: MapPose, sensors: Sequence[TofSensorConfig]
) -> list[EllipseShape]:
    """The 95 % ellipse of the estimate's x-y covariance (both fusion methods report it)."""
    state: CurrentState = envelope.msg
    p = state.pose
    if not p.initialised or p.floor != pose.floor:
        return []
    a, b, c = p.sigma_x_mm**2, p.sigma_y_mm**2, p.cov_xy_mm2
    mean, half = (a + b) / 2, math.hypot((a - b) / 2, c)
    return [
        EllipseShape(
            x_mm=p.x_mm,
            y_mm=p.y_mm,
            rx_mm=ELLIPSE_SCALE * math.sqrt(max(mean + half, 0.0)),
            ry_mm=ELLIPSE_SCALE * math.sqrt(max(mean - half, 0.0)),
            angle_deg=math.degrees(0.5 * math.atan2(2 * c, a - b)),
        )
    ]


Layer = Callable[[Envelope[Any], MapPose, Sequence[TofSensorConfig]], Sequence[Shape]]

LAYERS: dict[str, Layer] = {
    RANGE_SCAN.name: scan_rays,
    PARTICLES.name: particle_cloud,
    CURRENT_STATE.name: uncertainty_ellipse,
}


def map_frame(
    board: BoardView, poses: PoseSource | None, sensors: Sequence[TofSensorConfig]
) -> MapFrame:
    """Everything to draw now; topic layers are placed relative to the first (trusted) pose."""
    current = dict(poses()) if poses is not None else {}
    if not current:
        return MapFrame(floor=None, shapes=[])
    anchor = next(iter(current.values()))
    shapes: list[Shape] = []
    for topic, layer in LAYERS.items():
        try:
            envelope: Envelope[Any] | None = board.latest(topic)
        except BoardError:  # the topic is not declared on this board
            continue
        if envelope is not None:
            shapes.extend(layer(envelope, anchor, sensors))
    shapes.extend(
        RobotShape(label=label, x_mm=p.x_mm, y_mm=p.y_mm, heading_deg=p.heading_deg)
        for label, p in current.items()
        if p.floor == anchor.floor
    )
    return MapFrame(floor=anchor.floor, shapes=shapes)
