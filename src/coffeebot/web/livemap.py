"""What the live map draws over the floor plan, computed here so the browser only paints.

The page fetches the floor's SVG once and then receives a :class:`MapFrame` with every
inspector frame: a list of plain shapes in floor-plan millimetres. Shapes come from *layers*:
the robot poses (from a pose source the daemon provides) and one layer per board topic, keyed
by the topic's name in :data:`LAYERS`. A topic that is not declared on the board, or has not
published yet, simply draws nothing, so adding a layer is one function and one entry there.
A robot without ceiling cameras, say, has no ``cameras/layer`` and its map is unchanged.

Sensor cones (:mod:`coffeebot.sensor_view`) are drawn from each sensor's configured mount,
yaw and field of view, so a change of layout in the robot description shows as it is.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass
from typing import Annotated, Any, Literal

from pydantic import BaseModel, Field

from coffeebot.board import BoardError, BoardView, Envelope
from coffeebot.config import TofSensorConfig
from coffeebot.floorplan import FloorPlan
from coffeebot.messages import (
    CAMERA_LAYER,
    CURRENT_STATE,
    ELEVATOR_REQUEST,
    ELEVATOR_STATE,
    MOTION_STATUS,
    MOVE_INSTRUCTION,
    PARTICLES,
    RANGE_SCAN,
    ROUTE,
    CameraLayer,
    CameraObject,
    CameraView,
    CurrentState,
    MotionStatus,
    ParticleCloud,
    PlannedRoute,
    RangeScan,
)
from coffeebot.rectangles import corners
from coffeebot.sensor_view import ConeShape, sensor_cones

ELLIPSE_SCALE = math.sqrt(5.991)
"""The drawn ellipse holds the position with 95 % probability (chi-square, 2 degrees)."""

DETOUR_LEAD_MM = 600.0
"""How far ahead of the robot the drawn detour reaches its lane, and beyond the obstacle it
rejoins: a sketch of the go-around, not the dynamic window's arcs."""


class MapPose(BaseModel):
    """A robot pose on a floor: position in floor-plan mm, heading CCW from +x."""

    x_mm: float
    y_mm: float
    heading_deg: float
    floor: int
    silent_s: float | None = None
    """A fleet's robot not heard of for this long (drawn grey where it was last); None:
    reporting."""


PoseSource = Callable[[], Mapping[str, MapPose]]
"""Current poses by label, most trusted first (``estimated``, then the simulator's ``true``)."""


class RobotShape(BaseModel):
    kind: Literal["robot"] = "robot"
    label: str
    x_mm: float
    y_mm: float
    heading_deg: float
    floor: int
    """Robots are drawn on their own floor, whichever floor the map shows."""
    silent_s: float | None = None


class EllipseShape(BaseModel):
    """The estimate's 95 % position ellipse: centre, semi-axes and the first axis' angle."""

    kind: Literal["ellipse"] = "ellipse"
    x_mm: float
    y_mm: float
    rx_mm: float
    ry_mm: float
    angle_deg: float


class CloudShape(BaseModel):
    """Particles of the particle filter: x, y pairs in floor-plan mm."""

    kind: Literal["cloud"] = "cloud"
    points: list[tuple[float, float]]


class PathShape(BaseModel):
    """A line through floor-plan points: the planned route, or the detour round something."""

    kind: Literal["path"] = "path"
    role: Literal["route", "detour"]
    points: list[tuple[float, float]]


class GoalShape(BaseModel):
    kind: Literal["goal"] = "goal"
    label: str
    x_mm: float
    y_mm: float


class CameraFieldShape(BaseModel):
    """A ceiling camera's field of view on the floor: what the cameras can vouch for, and
    (drawn in the warning colour) where a camera that stopped working leaves a blind spot."""

    kind: Literal["camera_field"] = "camera_field"
    camera_id: str
    working: bool
    corners: list[tuple[float, float]]
    text: str
    """The camera's id and, when it is not working, why: the outline's hover text."""


class CameraObjectShape(BaseModel):
    """Something a ceiling camera sees standing still: its footprint's four corners, so the
    browser paints a polygon as it does a cone."""

    kind: Literal["camera_object"] = "camera_object"
    id: str
    camera_id: str
    corners: list[tuple[float, float]]
    text: str
    """Which camera sees it standing and for how long: the footprint's hover text."""


Shape = Annotated[
    RobotShape
    | ConeShape
    | EllipseShape
    | CloudShape
    | PathShape
    | GoalShape
    | CameraFieldShape
    | CameraObjectShape,
    Field(discriminator="kind"),
]


class MapFrame(BaseModel):
    floor: int | None
    shapes: list[Shape]
    caption: str = ""
    """What the map cannot show by itself (riding the elevator to another floor)."""


@dataclass(frozen=True)
class MapContext:
    """What layers draw with besides the topic: the anchor pose, the robot's sensors and
    range, and the floor plan (for hallway coordinates)."""

    pose: MapPose
    sensors: Sequence[TofSensorConfig]
    max_range_mm: float
    plan: FloorPlan | None
    board: BoardView


def scan_cones(envelope: Envelope[Any], ctx: MapContext) -> list[ConeShape]:
    """One cone per reading from its sensor's mount and field of view."""
    scan: RangeScan = envelope.msg
    p = ctx.pose
    return sensor_cones(scan.readings, ctx.sensors, p.x_mm, p.y_mm, p.heading_deg, ctx.max_range_mm)


def uncertainty_ellipse(envelope: Envelope[Any], ctx: MapContext) -> list[EllipseShape]:
    """The 95 % ellipse of the estimate's x-y covariance (both fusion methods report it)."""
    state: CurrentState = envelope.msg
    p = state.pose
    if not p.initialised or p.floor != ctx.pose.floor:
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


def particle_cloud(envelope: Envelope[Any], ctx: MapContext) -> list[CloudShape]:
    """A sample of the particle filter's particles on the shown floor."""
    cloud: ParticleCloud = envelope.msg
    if cloud.floor != ctx.pose.floor:
        return []
    return [CloudShape(points=list(zip(cloud.x_mm, cloud.y_mm, strict=True)))]


def planned_route(envelope: Envelope[Any], ctx: MapContext) -> list[PathShape | GoalShape]:
    """The route's leg on the shown floor, from the robot on, and where it ends."""
    route: PlannedRoute = envelope.msg
    shapes: list[PathShape | GoalShape] = []
    for i, leg in enumerate(route.legs):
        if leg.floor != ctx.pose.floor or len(leg.points) < 2:
            continue
        ahead = leg.points[_nearest_segment(leg.points, ctx.pose) + 1 :]
        shapes.append(PathShape(role="route", points=[(ctx.pose.x_mm, ctx.pose.y_mm), *ahead]))
        if i == len(route.legs) - 1:
            x, y = leg.points[-1]
            shapes.append(GoalShape(label=route.to, x_mm=x, y_mm=y))
    return shapes


def _nearest_segment(points: Sequence[tuple[float, float]], pose: MapPose) -> int:
    """Index of the segment of ``points`` nearest the robot (where it is along the line)."""

    def distance(i: int) -> float:
        (ax, ay), (bx, by) = points[i], points[i + 1]
        dx, dy = bx - ax, by - ay
        length2 = dx * dx + dy * dy
        t = 0.0 if length2 == 0 else ((pose.x_mm - ax) * dx + (pose.y_mm - ay) * dy) / length2
        t = min(1.0, max(0.0, t))
        return math.hypot(pose.x_mm - (ax + t * dx), pose.y_mm - (ay + t * dy))

    return min(range(len(points) - 1), key=distance)


def detour_path(envelope: Envelope[Any], ctx: MapContext) -> list[PathShape]:
    """The go-around motion holds: out to the detour lane, past the obstacle, back."""
    status: MotionStatus = envelope.msg
    instruction = ctx.board.latest(MOVE_INSTRUCTION)
    if status.detour_lane_mm is None or ctx.plan is None or instruction is None:
        return []
    ins = instruction.msg
    if ins.action != "follow_lane" or ins.floor != ctx.pose.floor or ins.target_s_mm is None:
        return []
    floor = ctx.plan.floor(ins.floor).view(ins.hallway)
    s, _ = floor.to_hallway(ctx.pose.x_mm, ctx.pose.y_mm)
    direction = 1.0 if ins.target_s_mm >= s else -1.0
    until = status.detour_until_s_mm if status.detour_until_s_mm is not None else s
    until = s + direction * max(0.0, (until - s) * direction)
    lane = status.detour_lane_mm
    points = [
        (ctx.pose.x_mm, ctx.pose.y_mm),
        floor.from_hallway(s + direction * DETOUR_LEAD_MM, lane),
        floor.from_hallway(until + direction * DETOUR_LEAD_MM, lane),
    ]
    if ins.lane_mm is not None:
        points.append(floor.from_hallway(until + direction * 3 * DETOUR_LEAD_MM, ins.lane_mm))
    return [PathShape(role="detour", points=points)]


def camera_layer(
    envelope: Envelope[Any], ctx: MapContext
) -> list[CameraFieldShape | CameraObjectShape]:
    """The ceiling cameras' fields on the shown floor, then what they see standing there
    (over the fields, so a footprint is never hidden by an outline)."""
    layer: CameraLayer = envelope.msg
    floor, now = ctx.pose.floor, ctx.board.clock.now()
    shapes: list[CameraFieldShape | CameraObjectShape] = [
        CameraFieldShape(
            camera_id=camera.camera_id,
            working=camera.working,
            corners=camera.corners_mm,
            text=_camera_text(camera),
        )
        for camera in layer.cameras
        if camera.floor == floor
    ]
    shapes.extend(
        CameraObjectShape(
            id=thing.id,
            camera_id=thing.camera_id,
            corners=footprint(thing),
            text=f"seen standing by camera {thing.camera_id} "
            f"for {max(0.0, now - thing.standing_since_s):.0f} s",
        )
        for thing in layer.objects
        if thing.floor == floor
    )
    return shapes


def _camera_text(camera: CameraView) -> str:
    """The camera's id, and for one not working, that it is not and why."""
    if camera.working:
        return f"camera {camera.camera_id}"
    why = f" ({camera.problem})" if camera.problem else ""
    return f"camera {camera.camera_id}: not working{why}"


def footprint(thing: CameraObject) -> list[tuple[float, float]]:
    """The rectangle a camera measured, corner after corner."""
    points = corners(thing.x_mm, thing.y_mm, thing.length_mm, thing.width_mm, thing.axis_deg)
    return [(float(x), float(y)) for x, y in points]


Layer = Callable[[Envelope[Any], MapContext], Sequence[Shape]]

LAYERS: dict[str, Layer] = {
    CAMERA_LAYER.name: camera_layer,
    ROUTE.name: planned_route,
    MOTION_STATUS.name: detour_path,
    PARTICLES.name: particle_cloud,
    CURRENT_STATE.name: uncertainty_ellipse,
    RANGE_SCAN.name: scan_cones,
}
"""Drawn in this order, each over the one before; the robots go on top."""


def _latest(board: BoardView, name: str) -> Envelope[Any] | None:
    try:
        return board.latest(name)
    except BoardError:  # the topic is not declared on this board
        return None


def elevator_caption(board: BoardView) -> str:
    """While the car moves the map cannot show the ride: say it."""
    state, request = _latest(board, ELEVATOR_STATE.name), _latest(board, ELEVATOR_REQUEST.name)
    if state is None or not state.msg.moving:
        return ""
    if request is not None and request.msg.action == "send":
        return f"riding the elevator to floor {request.msg.floor}"
    return "the elevator car is moving"


def map_frame(
    board: BoardView,
    poses: PoseSource | None,
    sensors: Sequence[TofSensorConfig],
    max_range_mm: float = 4000.0,
    plan: FloorPlan | None = None,
) -> MapFrame:
    """Everything to draw now; topic layers are placed relative to the first (trusted) pose."""
    current = dict(poses()) if poses is not None else {}
    if not current:
        return MapFrame(floor=None, shapes=[])
    anchor = next(iter(current.values()))
    ctx = MapContext(anchor, sensors, max_range_mm, plan, board)
    shapes: list[Shape] = []
    for topic, layer in LAYERS.items():
        envelope = _latest(board, topic)
        if envelope is not None:
            shapes.extend(layer(envelope, ctx))
    shapes.extend(
        RobotShape(
            label=label,
            x_mm=p.x_mm,
            y_mm=p.y_mm,
            heading_deg=p.heading_deg,
            floor=p.floor,
            silent_s=p.silent_s,
        )
        for label, p in current.items()
    )
    return MapFrame(floor=anchor.floor, shapes=shapes, caption=elevator_caption(board))
