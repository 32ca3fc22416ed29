"""Floor plans: the building as the robot knows it, loaded from TOML.

A floor plan is written the way one surveys a hallway with a tape measure: each floor has one
main hallway given by its axis (start and end points in the floor frame) and width; doors and
openings (side hallways) are placed by their distance along that axis and the side they are
on. Free-form walls cover the rest (a tea room, an elevator lobby). The loader turns this into
wall segments with heights, which the simulator ray-casts against and the SVG renderer draws.

Frames: x, y in mm in the floor frame shared by all floors and the UWB anchors. Along the
hallway, ``s`` is the distance from the axis start and ``d`` the lateral offset, positive to
the left when looking from start to end.
"""

from __future__ import annotations

import itertools
import math
from collections.abc import Iterator, Sequence
from functools import cached_property
from pathlib import Path
from typing import Annotated, Any, Literal, NamedTuple

import numpy as np
from pydantic import (
    BaseModel,
    ConfigDict,
    Field,
    Strict,
    StrictFloat,
    StrictInt,
    ValidationError,
    model_validator,
)

from coffeebot.config import read_toml
from coffeebot.errors import ConfigError

Side = Literal["left", "right"]

PLAN_MM = 1_000_000.0
"""Every coordinate lies within a kilometre of the origin: a survey typo, not a building."""
# Numbers are strict (an integer still passes for a float): pydantic would read a quoted
# "42000" as 42000, and a survey with quoted figures is one nobody has checked.
Coordinate = Annotated[float, Strict(), Field(ge=-PLAN_MM, le=PLAN_MM)]
Size = Annotated[float, Strict(), Field(gt=0, le=100_000)]
"""A width, depth or height: positive and under 100 m."""


class FloorPlanError(ConfigError):
    """A floor plan file that cannot be used, naming the file, the element and the problem.

    A :class:`~coffeebot.config.ConfigError` (so a ``ValueError``): the CLI reports both alike.
    """

    def __init__(self, path: str | Path, element: str, problem: str) -> None:
        self.path = str(path)
        self.element = element
        self.problem = problem
        super().__init__(f"{self.path}: {element}: {problem}")


class _Model(BaseModel):
    """Unknown keys, ``nan`` and ``inf`` are refused: a NaN position makes every comparison
    false, so the robot would never reach (or stop at) it."""

    model_config = ConfigDict(frozen=True, extra="forbid", allow_inf_nan=False)


class Hallway(_Model):
    """The main hallway of a floor: a straight axis and a width."""

    start: tuple[Coordinate, Coordinate]
    end: tuple[Coordinate, Coordinate]
    width_mm: Size = 1700.0
    start_closed: bool = True
    end_closed: bool = True

    @property
    def length_mm(self) -> float:
        return math.dist(self.start, self.end)

    @property
    def heading_deg(self) -> float:
        """Direction of travel from start to end, degrees CCW from +x."""
        return math.degrees(math.atan2(self.end[1] - self.start[1], self.end[0] - self.start[0]))


class Door(_Model):
    """A door in a hallway wall, recessed ``recess_mm`` behind the wall line."""

    id: str
    room: str
    side: Side
    at_mm: Coordinate = Field(description="distance of the door centre along the hallway axis")
    width_mm: Size = 900.0
    recess_mm: StrictFloat = Field(100.0, ge=0, le=10_000)
    height_mm: Size = 2100.0
    kind: Literal["office", "elevator", "tea_room", "other"] = "office"
    open: bool = False

    @model_validator(mode="before")
    @classmethod
    def _id_defaults_to_room(cls, data: Any) -> Any:
        if isinstance(data, dict) and "id" not in data and "room" in data:
            return {**data, "id": str(data["room"])}
        return data

    @property
    def span(self) -> tuple[float, float]:
        return (self.at_mm - self.width_mm / 2, self.at_mm + self.width_mm / 2)


class Opening(_Model):
    """A gap in a hallway wall: a side hallway, a stairwell, a lobby."""

    id: str
    side: Side
    at_mm: Coordinate
    width_mm: Size = 1700.0
    depth_mm: Size = Field(3000.0, description="how far its side walls run")
    end: Literal["open", "wall"] = "open"
    name: str = ""

    @property
    def span(self) -> tuple[float, float]:
        return (self.at_mm - self.width_mm / 2, self.at_mm + self.width_mm / 2)


class Wall(_Model):
    """A free-form wall as a polyline of floor-frame points."""

    id: str
    points: list[tuple[Coordinate, Coordinate]] = Field(min_length=2)
    height_mm: Size | None = None
    closed: bool = False


class ParkingSpot(_Model):
    """Where one robot of a fleet waits for orders: inside the room with the loading spot,
    out of the way of the door (a single robot parks on the loading spot itself)."""

    x_mm: Coordinate
    y_mm: Coordinate
    heading_deg: StrictFloat = Field(0.0, ge=-360, le=360)


class FloorMark(_Model):
    """A mark on the floor seen by a ceiling camera: where it lies in the floor frame,
    surveyed, and the pixel it shows at in the camera's image (the calibration's input)."""

    x_mm: Coordinate
    y_mm: Coordinate
    u_px: StrictFloat = Field(ge=0, le=10_000)
    v_px: StrictFloat = Field(ge=0, le=10_000)


class Camera(_Model):
    """A fixed camera on the ceiling looking straight down (seed 003: 320 x 240 px at 10 fps
    from 4 m, 1.25 cm a pixel). ``yaw_deg`` is the floor-frame heading of the image's +u
    axis; its +v axis points 90 degrees clockwise of that (image rows grow downwards)."""

    id: str = Field(min_length=1)
    x_mm: Coordinate
    y_mm: Coordinate
    height_mm: Size = 4000.0
    yaw_deg: StrictFloat = Field(0.0, ge=-360, le=360)
    width_px: StrictInt = Field(320, ge=16, le=8192)
    height_px: StrictInt = Field(240, ge=16, le=8192)
    fov_deg: StrictFloat = Field(
        53.13, gt=1, lt=170, description="horizontal field of view (53.13: 4 m wide from 4 m)"
    )
    fps: StrictFloat = Field(10.0, gt=0, le=120)
    marks: list[FloorMark] = Field(
        [],
        description="floor marks and their pixels, four or more: the calibration's "
        "homography from them (none: the nominal one from the pose and lens above)",
    )


class AngleZone(_Model):
    """A stretch of hallway where both walls are flat, so side sensors can measure heading."""

    id: str
    from_mm: Coordinate
    to_mm: Coordinate

    @model_validator(mode="after")
    def _ordered(self) -> AngleZone:
        if self.to_mm <= self.from_mm:
            raise ValueError(f"to_mm ({self.to_mm}) must be greater than from_mm ({self.from_mm})")
        return self


class Anchor(_Model):
    """A UWB anchor at a surveyed position."""

    id: str = Field(
        pattern=r"^[0-9A-F]{4}$",
        description="the anchor's UWB short address, 4 upper-case hex digits, as the tag "
        "reports it (this is how a fix's anchors are matched to a floor)",
    )
    x_mm: Coordinate
    y_mm: Coordinate
    z_mm: StrictFloat = Field(2400.0, ge=-10_000, le=100_000)


class WallSegment(NamedTuple):
    """One straight piece of surface: what sensors see and what the robot can hit."""

    element: str
    x0: float
    y0: float
    x1: float
    y1: float
    z_bottom: float
    z_top: float


def segment_distances(
    segments: np.ndarray, x: float | np.ndarray, y: float | np.ndarray
) -> np.ndarray:
    """Distance from (x, y) to each segment of an (N, >=4) array of x0, y0, x1, y1 rows.

    ``x`` and ``y`` may be column arrays (P, 1): the result is then (P, N), one row per point.
    """
    px, py = segments[:, 0], segments[:, 1]
    ex, ey = segments[:, 2] - px, segments[:, 3] - py
    length2 = np.maximum(ex * ex + ey * ey, 1e-9)
    t = np.clip(((x - px) * ex + (y - py) * ey) / length2, 0.0, 1.0)
    return np.hypot(px + t * ex - x, py + t * ey - y)


class Floor(_Model):
    level: StrictInt = Field(ge=-100, le=1000)
    name: str = ""
    wall_height_mm: Size = 2700.0
    hallway: Hallway
    doors: list[Door] = []
    openings: list[Opening] = []
    walls: list[Wall] = []
    angle_zones: list[AngleZone] = []
    anchors: list[Anchor] = []
    parking: list[ParkingSpot] = []
    """A fleet's robots' places to wait, one each (in the tea room's floor)."""
    cameras: list[Camera] = []

    # --- hallway frame ---------------------------------------------------------------------

    @cached_property
    def _axis(self) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Origin, unit direction and unit left normal of the hallway axis."""
        origin = np.array(self.hallway.start, dtype=float)
        direction = np.array(self.hallway.end, dtype=float) - origin
        direction /= np.linalg.norm(direction)
        return origin, direction, np.array([-direction[1], direction[0]])

    @cached_property
    def _axis_floats(self) -> tuple[float, float, float, float, float, float]:
        """:attr:`_axis` as plain floats: origin x, y, direction x, y, normal x, y."""
        origin, u, n = self._axis
        return (
            float(origin[0]),
            float(origin[1]),
            float(u[0]),
            float(u[1]),
            float(n[0]),
            float(n[1]),
        )

    def to_hallway(self, x_mm: float, y_mm: float) -> tuple[float, float]:
        """Floor-frame point to (s along the axis, d lateral, left positive)."""
        # In scalars, the same operations as the arrays' (a difference, then a two-term dot
        # product summed in order) and so the same result to the bit, at a fraction of the
        # cost: the door detector and the world ask this many times a scan.
        ox, oy, ux, uy, nx, ny = self._axis_floats
        rx, ry = x_mm - ox, y_mm - oy
        return float(rx * ux + ry * uy), float(rx * nx + ry * ny)

    def from_hallway(self, s_mm: float, d_mm: float) -> tuple[float, float]:
        """(s, d) in the hallway frame to a floor-frame point."""
        origin, u, n = self._axis
        p = origin + s_mm * u + d_mm * n
        return float(p[0]), float(p[1])

    def behind_door(self, door: Door, depth_mm: float) -> tuple[float, float]:
        """The floor-frame point ``depth_mm`` behind the hallway's wall line, through the
        middle of ``door`` (the recess's leaf at ``door.recess_mm``; inside the room beyond)."""
        sign = 1.0 if door.side == "left" else -1.0
        return self.from_hallway(door.at_mm, sign * (self.hallway.width_mm / 2 + depth_mm))

    # --- queries ---------------------------------------------------------------------------

    def features(self, side: Side | None = None) -> list[Door | Opening]:
        """Doors and openings, optionally on one side, ordered along the hallway."""
        items: list[Door | Opening] = [*self.doors, *self.openings]
        return sorted((f for f in items if side in (None, f.side)), key=lambda f: f.at_mm)

    def feature_at(self, s_mm: float, side: Side, margin_mm: float = 0.0) -> Door | Opening | None:
        """The door or opening whose span (widened by ``margin_mm``) covers ``s`` on a side."""
        for feature in self.features(side):
            lo, hi = feature.span
            if lo - margin_mm <= s_mm <= hi + margin_mm:
                return feature
        return None

    def nearest_door(self, s_mm: float, side: Side | None = None) -> Door | None:
        """The door whose centre is closest to ``s`` along the hallway."""
        doors = [d for d in self.doors if side in (None, d.side)]
        return min(doors, key=lambda d: abs(d.at_mm - s_mm), default=None)

    def angle_zone_at(self, x_mm: float, y_mm: float) -> AngleZone | None:
        """The angle zone containing a floor-frame point, if any."""
        s, d = self.to_hallway(x_mm, y_mm)
        if abs(d) > self.hallway.width_mm / 2:
            return None
        return next((z for z in self.angle_zones if z.from_mm <= s <= z.to_mm), None)

    def door(self, door_id: str) -> Door:
        for door in self.doors:
            if door.id == door_id:
                return door
        raise KeyError(f"floor {self.level} has no door {door_id!r}")

    @property
    def elevator(self) -> Door | None:
        return next((d for d in self.doors if d.kind == "elevator"), None)

    def walls_near(self, x_mm: float, y_mm: float, radius_mm: float) -> list[WallSegment]:
        """Wall segments passing within ``radius_mm`` of a point."""
        dist = segment_distances(self.segment_array, x_mm, y_mm)
        return [self.segments[i] for i in np.flatnonzero(dist <= radius_mm)]

    # --- geometry --------------------------------------------------------------------------

    @cached_property
    def segments(self) -> tuple[WallSegment, ...]:
        """Every wall surface of the floor, generated from the survey description."""
        return tuple(self._generate_segments())

    @cached_property
    def segment_array(self) -> np.ndarray:
        """Segments as an (N, 6) float array: x0, y0, x1, y1, z_bottom, z_top."""
        return np.array([s[1:] for s in self.segments], dtype=float).reshape(-1, 6)

    @cached_property
    def segment_bounds(self) -> np.ndarray:
        """Each segment's bounding box as an (N, 4) array: x_min, y_min, x_max, y_max (a
        cheap first test of which walls a ray of limited reach can meet)."""
        ends = self.segment_array[:, :4]
        return np.concatenate(
            [np.minimum(ends[:, :2], ends[:, 2:]), np.maximum(ends[:, :2], ends[:, 2:])], axis=1
        )

    def _generate_segments(self) -> Iterator[WallSegment]:
        h = self.wall_height_mm
        half = self.hallway.width_mm / 2
        length = self.hallway.length_mm

        def seg(
            element: str, a: tuple[float, float], b: tuple[float, float], top: float = h
        ) -> WallSegment:
            return WallSegment(element, *self.from_hallway(*a), *self.from_hallway(*b), 0.0, top)

        for side, sign in (("left", 1.0), ("right", -1.0)):
            wall_d = sign * half
            cursor = 0.0
            for feature in self.features(side):  # type: ignore[arg-type]
                lo, hi = feature.span
                if lo > cursor:
                    yield seg(f"hallway {side} wall", (cursor, wall_d), (lo, wall_d))
                cursor = max(cursor, hi)
                if isinstance(feature, Door):
                    back = wall_d + sign * feature.recess_mm
                    element = f"door {feature.id}"
                    if feature.recess_mm > 0:
                        yield seg(f"{element} jamb", (lo, wall_d), (lo, back))
                        yield seg(f"{element} jamb", (hi, wall_d), (hi, back))
                    if not feature.open:
                        yield seg(element, (lo, back), (hi, back), feature.height_mm)
                else:
                    far = wall_d + sign * feature.depth_mm
                    element = f"opening {feature.id}"
                    yield seg(element, (lo, wall_d), (lo, far))
                    yield seg(element, (hi, wall_d), (hi, far))
                    if feature.end == "wall":
                        yield seg(element, (lo, far), (hi, far))
            if cursor < length:
                yield seg(f"hallway {side} wall", (cursor, wall_d), (length, wall_d))
        if self.hallway.start_closed:
            yield seg("hallway start wall", (0.0, -half), (0.0, half))
        if self.hallway.end_closed:
            yield seg("hallway end wall", (length, -half), (length, half))
        for wall in self.walls:
            points = [*wall.points, wall.points[0]] if wall.closed else wall.points
            top = wall.height_mm or h
            for a, b in itertools.pairwise(points):
                yield WallSegment(f"wall {wall.id}", a[0], a[1], b[0], b[1], 0.0, top)


class RoomLocation(NamedTuple):
    floor: Floor
    door: Door


class FloorPlan(_Model):
    name: str = ""
    note: str = ""
    floors: list[Floor] = Field(min_length=1)

    def floor(self, level: int) -> Floor:
        for floor in self.floors:
            if floor.level == level:
                return floor
        raise KeyError(f"no floor {level}; floors are {[f.level for f in self.floors]}")

    def find_room(self, room: str) -> RoomLocation:
        """The floor and door of a room, by its name ("205", "Tea room")."""
        for floor in self.floors:
            for door in floor.doors:
                if door.room == room:
                    return RoomLocation(floor, door)
        raise KeyError(f"no room {room!r} in floor plan {self.name!r}")

    @property
    def tea_room(self) -> RoomLocation:
        for floor in self.floors:
            for door in floor.doors:
                if door.kind == "tea_room":
                    return RoomLocation(floor, door)
        raise KeyError("floor plan has no tea room")

    @property
    def rooms(self) -> list[str]:
        """Rooms a delivery can go to: every office door, in floor then hallway order."""
        return [
            d.room
            for f in self.floors
            for d in sorted(f.doors, key=lambda d: d.at_mm)
            if d.kind == "office"
        ]


# --- loading and validation -----------------------------------------------------------------

ANGLE_ZONE_CLEARANCE_MM = 400.0
"""Plain wall an angle zone needs beyond each end, on one side at least: the side sensors are
277 mm apart and their cones spread ~200 mm at 850 mm."""

ELEVATOR_TOLERANCE_MM = 200.0
"""How far apart the elevator doors of two floors may be in the building frame: one car."""

ANCHOR_MARGIN_MM = 10_000.0
"""How far outside its floor's hallway and rooms an anchor may be: beyond, a survey typo."""


def load_floorplan(path: str | Path) -> FloorPlan:
    """Read and validate a floor plan TOML file; every problem raises :class:`FloorPlanError`."""
    path = Path(path)
    raw = read_toml(path, lambda problem: FloorPlanError(path, "file", problem))
    return parse_floorplan(raw, path)


def parse_floorplan(raw: dict[str, Any], path: str | Path = "<floor plan>") -> FloorPlan:
    """Validate an already-parsed floor plan document."""
    try:
        plan = FloorPlan.model_validate(raw)
    except ValidationError as exc:
        error = exc.errors()[0]
        element, field = _describe_location(raw, error["loc"])
        message = error["msg"]
        if error["type"] in ("float_type", "int_type") and isinstance(error["input"], str):
            message = f"a number was expected, not the string {error['input']!r}"
        problem = f"{field}: {message}" if field else message
        raise FloorPlanError(path, element, problem) from None
    _check_consistency(plan, path)
    return plan


_ELEMENT_NAMES = {
    "floors": "floor",
    "doors": "door",
    "openings": "opening",
    "walls": "wall",
    "angle_zones": "angle zone",
    "anchors": "anchor",
    "cameras": "camera",
    "marks": "mark",
}


def _describe_location(raw: Any, loc: Sequence[int | str]) -> tuple[str, str]:
    """Turn a pydantic error location into ("floor 2 / door 205", "width_mm")."""
    names: list[str] = []
    node = raw
    fields: list[str] = []
    i = 0
    while i < len(loc):
        key = loc[i]
        if key in _ELEMENT_NAMES and i + 1 < len(loc) and isinstance(loc[i + 1], int):
            index = int(loc[i + 1])
            item = node.get(key, [])[index] if isinstance(node, dict) else None
            ident = None
            if isinstance(item, dict):
                ident = item.get("level") if key == "floors" else item.get("id", item.get("room"))
            label = ident if ident is not None else f"#{index + 1}"
            names.append(f"{_ELEMENT_NAMES[str(key)]} {label}")
            node = item
            fields = []
            i += 2
            continue
        fields.append(str(key))
        node = node.get(key) if isinstance(node, dict) else None
        i += 1
    return (" / ".join(names) or "floor plan"), ".".join(fields)


def _check_consistency(plan: FloorPlan, path: str | Path) -> None:
    """Checks that span elements: unique ids, features inside the hallway and not overlapping."""
    levels = [f.level for f in plan.floors]
    for level in levels:
        if levels.count(level) > 1:
            raise FloorPlanError(path, f"floor {level}", "level appears more than once")
    for floor in plan.floors:
        where = f"floor {floor.level}"
        if floor.hallway.length_mm <= 0:
            raise FloorPlanError(path, f"{where} / hallway", "start and end are the same point")
        groups: list[tuple[str, Sequence[Door | Opening | Wall | AngleZone | Anchor]]] = [
            ("door", floor.doors),
            ("opening", floor.openings),
            ("wall", floor.walls),
            ("angle zone", floor.angle_zones),
            ("anchor", floor.anchors),
        ]
        for kind, items in groups:
            seen: set[str] = set()
            for item in items:
                if item.id in seen:
                    raise FloorPlanError(path, f"{where} / {kind} {item.id}", "duplicate id")
                seen.add(item.id)
        length = floor.hallway.length_mm
        for side in ("left", "right"):
            previous: Door | Opening | None = None
            for feature in floor.features(side):
                kind = "door" if isinstance(feature, Door) else "opening"
                lo, hi = feature.span
                if lo < 0 or hi > length:
                    raise FloorPlanError(
                        path,
                        f"{where} / {kind} {feature.id}",
                        f"spans {lo:.0f}..{hi:.0f} mm, outside the hallway (0..{length:.0f} mm)",
                    )
                if previous is not None and lo < previous.span[1]:
                    raise FloorPlanError(
                        path,
                        f"{where} / {kind} {feature.id}",
                        f"overlaps {previous.id} on the {side} side",
                    )
                previous = feature
        for zone in floor.angle_zones:
            if zone.from_mm < 0 or zone.to_mm > length:
                raise FloorPlanError(
                    path, f"{where} / angle zone {zone.id}", "lies outside the hallway"
                )
            _check_angle_zone_clear(floor, zone, path)
        _check_anchors_near(floor, path)
        _check_cameras(floor, path)
        elevators = [d for d in floor.doors if d.kind == "elevator"]
        if len(elevators) > 1:
            raise FloorPlanError(path, f"{where} / door {elevators[1].id}", "second elevator door")
        if len(plan.floors) > 1 and not elevators:
            raise FloorPlanError(path, where, "no elevator door in a building of several floors")
    _check_elevator_aligned(plan, path)
    _check_camera_ids_unique(plan, path)
    tea_rooms = [(f, d) for f in plan.floors for d in f.doors if d.kind == "tea_room"]
    if len(tea_rooms) != 1:
        raise FloorPlanError(
            path, "floor plan", f"needs exactly one door of kind 'tea_room', found {len(tea_rooms)}"
        )
    rooms = [d.room for f in plan.floors for d in f.doors if d.kind != "elevator"]
    for room in rooms:
        if rooms.count(room) > 1:
            raise FloorPlanError(path, f"room {room}", "has more than one door")


def _check_angle_zone_clear(floor: Floor, zone: AngleZone, path: str | Path) -> None:
    """An angle zone needs flat wall on one side at least: with doors or openings on both,
    the side sensors have no wall to measure the heading against."""
    lo = zone.from_mm - ANGLE_ZONE_CLEARANCE_MM
    hi = zone.to_mm + ANGLE_ZONE_CLEARANCE_MM
    in_the_way = [
        next((f for f in floor.features(side) if f.span[1] >= lo and f.span[0] <= hi), None)
        for side in ("left", "right")
    ]
    left, right = in_the_way
    if left is not None and right is not None:
        raise FloorPlanError(
            path,
            f"floor {floor.level} / angle zone {zone.id}",
            f"from_mm, to_mm: lies over {left.id} on the left and {right.id} on the right "
            f"(one side needs plain wall {ANGLE_ZONE_CLEARANCE_MM:.0f} mm beyond each end)",
        )


def _check_anchors_near(floor: Floor, path: str | Path) -> None:
    """An anchor far outside the floor is a mistyped figure: the robot would trust fixes
    computed from a position the anchor does not have."""
    ends = floor.segment_array[:, :4]
    xs, ys = ends[:, 0::2], ends[:, 1::2]
    for anchor in floor.anchors:
        for field, value, coords in (("x_mm", anchor.x_mm, xs), ("y_mm", anchor.y_mm, ys)):
            lo, hi = float(coords.min()), float(coords.max())
            outside = max(lo - value, value - hi)
            if outside > ANCHOR_MARGIN_MM:
                raise FloorPlanError(
                    path,
                    f"floor {floor.level} / anchor {anchor.id}",
                    f"{field}: {value:.0f} lies {outside:.0f} mm outside the floor's hallway "
                    f"and rooms ({lo:.0f}..{hi:.0f} mm; at most {ANCHOR_MARGIN_MM:.0f} allowed)",
                )


def _check_cameras(floor: Floor, path: str | Path) -> None:
    """A camera must hang over the floor it watches and its calibration must be one to
    trust: robots it sees are placed by it."""
    # Imported here: the camera modules build on this module's models.
    from coffeebot.cameras.calibration import calibrate

    ends = floor.segment_array[:, :4]
    xs, ys = ends[:, 0::2], ends[:, 1::2]
    for camera in floor.cameras:
        for field, value, coords in (("x_mm", camera.x_mm, xs), ("y_mm", camera.y_mm, ys)):
            lo, hi = float(coords.min()), float(coords.max())
            if not lo <= value <= hi:
                raise FloorPlanError(
                    path,
                    f"floor {floor.level} / camera {camera.id}",
                    f"{field}: {value:.0f} lies outside the floor's hallway and rooms "
                    f"({lo:.0f}..{hi:.0f} mm)",
                )
        calibrate(camera, floor=floor.level, path=path)


def _check_camera_ids_unique(plan: FloorPlan, path: str | Path) -> None:
    """A camera's id names its images and fixes across the building, whatever the floor."""
    levels: dict[str, int] = {}
    for floor in plan.floors:
        for camera in floor.cameras:
            if camera.id in levels:
                raise FloorPlanError(
                    path,
                    f"floor {floor.level} / camera {camera.id}",
                    f"duplicate id: floor {levels[camera.id]} has a camera {camera.id!r} too "
                    "(camera ids are unique in the building)",
                )
            levels[camera.id] = floor.level


def _elevator_front(floor: Floor, door: Door) -> tuple[np.ndarray, np.ndarray]:
    """Where the car's door stands (the leaf's centre) in the building frame, and the unit
    direction from there into the car."""
    centre = np.array(floor.behind_door(door, door.recess_mm))
    inward = np.array(floor.behind_door(door, door.recess_mm + 1.0)) - centre
    return centre, inward / np.linalg.norm(inward)


def _check_elevator_aligned(plan: FloorPlan, path: str | Path) -> None:
    """One car serves every floor: its door must stand at the same place, facing the same
    way, on each (the robot drives into the car on one floor and out of it on another)."""
    stops = [(f, f.elevator) for f in plan.floors if f.elevator is not None]
    if len(stops) < 2:
        return
    first_floor, first = stops[0]
    first_centre, first_inward = _elevator_front(first_floor, first)
    for floor, door in stops[1:]:
        centre, inward = _elevator_front(floor, door)
        where = f"floor {floor.level} / door {door.id}"
        if float(inward @ first_inward) < math.cos(math.radians(45)):
            raise FloorPlanError(
                path,
                where,
                f"side: the elevator opens on the {door.side} side, facing another way than "
                f"{first.id} on floor {first_floor.level} ({first.side} side): not one car",
            )
        offset = float(np.linalg.norm(centre - first_centre))
        if offset > ELEVATOR_TOLERANCE_MM:
            raise FloorPlanError(
                path,
                where,
                f"at_mm: the elevator door is {offset:.0f} mm from {first.id} on floor "
                f"{first_floor.level} in the building frame (at most "
                f"{ELEVATOR_TOLERANCE_MM:.0f}): not one car",
            )


# --- warnings: what a valid plan leaves the robot to do poorly ---------------------------------

MIN_ANCHORS = 3
"""Anchors in range a UWB fix needs: the tag reports no position with fewer."""

COVERAGE_STEP_MM = 100.0
"""Spacing of the points along a hallway where anchor coverage is counted."""


class PlanWarning(NamedTuple):
    """Something a plan may contain but the robot will handle poorly, as a check reports it."""

    element: str
    problem: str

    def describe(self, path: str | Path) -> str:
        return f"{path}: {self.element}: {self.problem}"


def plan_warnings(
    plan: FloorPlan, *, uwb_range_mm: float, min_recess_mm: float
) -> list[PlanWarning]:
    """The plan's weak spots for a robot whose UWB reaches ``uwb_range_mm`` and whose door
    detector sees recesses from ``min_recess_mm``: the loader knows neither, so the plan's
    check asks for these."""
    warnings: list[PlanWarning] = []
    for floor in plan.floors:
        warnings += _uwb_coverage_gaps(floor, uwb_range_mm)
        warnings += _unseen_doors(floor, min_recess_mm)
        warnings += _unchecked_cameras(floor)
    return warnings


def _uwb_coverage_gaps(floor: Floor, uwb_range_mm: float) -> list[PlanWarning]:
    """Stretches of the hallway's centre line with fewer than three anchors in range: no UWB
    fix there. The tag is taken at floor height, so an anchor's whole height counts."""
    length = floor.hallway.length_mm
    along = np.linspace(0.0, length, math.ceil(length / COVERAGE_STEP_MM) + 1)
    points = np.array([floor.from_hallway(float(s), 0.0) for s in along])
    anchors = np.array([(a.x_mm, a.y_mm, a.z_mm) for a in floor.anchors], dtype=float)
    anchors = anchors.reshape(-1, 3)
    distances = np.hypot(
        np.hypot(points[:, :1] - anchors[:, 0], points[:, 1:] - anchors[:, 1]), anchors[:, 2]
    )
    in_range = (distances <= uwb_range_mm).sum(axis=1)
    warnings = []
    short = in_range < MIN_ANCHORS
    for is_short, run in itertools.groupby(range(len(along)), key=lambda i: bool(short[i])):
        if not is_short:
            continue
        indices = list(run)
        fewest = int(in_range[indices].min())
        warnings.append(
            PlanWarning(
                f"floor {floor.level} / hallway",
                f"{along[indices[0]]:.0f}..{along[indices[-1]]:.0f} mm along it has "
                f"{fewest} UWB anchor{'' if fewest == 1 else 's'} within {uwb_range_mm:.0f} mm, "
                f"a fix needs {MIN_ANCHORS}: the robot relies on odometry, walls and doors there",
            )
        )
    return warnings


def _unseen_doors(floor: Floor, min_recess_mm: float) -> list[PlanWarning]:
    """Closed doors too shallow for the door detector (an open one shows the room behind)."""
    return [
        PlanWarning(
            f"floor {floor.level} / door {door.id}",
            f"recess_mm: {door.recess_mm:.0f} mm is shallower than the door detector sees "
            f"({min_recess_mm:.0f} mm): the robot will not see this door and relies on UWB "
            "and odometry there",
        )
        for door in sorted(floor.doors, key=lambda d: d.at_mm)
        if not door.open and door.recess_mm < min_recess_mm
    ]


def _unchecked_cameras(floor: Floor) -> list[PlanWarning]:
    """Cameras whose calibration nothing checks: without marks the pose and lens alone place
    what the camera sees; through exactly four the homography fits them all exactly."""
    warnings = []
    for camera in floor.cameras:
        element = f"floor {floor.level} / camera {camera.id}"
        if not camera.marks:
            warnings.append(
                PlanWarning(
                    element,
                    "marks: none, so its pose and lens alone place what it sees (a bracket "
                    "one degree askew: 45 mm at 2.6 m): tape four to six marks to calibrate it",
                )
            )
        elif len(camera.marks) == 4:
            warnings.append(
                PlanWarning(
                    element,
                    "marks: 4, which the homography fits exactly: a misread one shows only "
                    "if it disagrees with the camera's pose, a fifth would check them",
                )
            )
    return warnings
