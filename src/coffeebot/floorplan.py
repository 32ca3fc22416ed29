"""Floor plans: the building as the robot knows it, loaded from TOML.

A floor plan is written the way one surveys a hallway with a tape measure: each floor has one
or more straight hallways, each given by its axis (start and end points in the floor frame)
and width, meeting where one's end lies on another's axis; doors and openings are placed by
their distance along their hallway's axis and the side they are on. Free-form walls cover
the rest (a tea room, an elevator lobby). The loader turns this into wall segments with
heights, which the simulator ray-casts against and the SVG renderer draws.

Frames: x, y in mm in the floor frame shared by all floors and the UWB anchors. Along a
hallway, ``s`` is the distance from its axis start and ``d`` the lateral offset, positive to
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
    PrivateAttr,
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
    """One straight hallway segment: an axis from ``start`` to ``end`` and a width. Its own
    frame: ``s`` along the axis from ``start``, ``d`` across it, left positive looking from
    start to end. Where hallways meet (an L, a T, a width change) is found from their axes
    (:attr:`Floor.meetings`)."""

    id: str = Field(min_length=1)
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

    @cached_property
    def _axis(self) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Origin, unit direction and unit left normal of the axis."""
        origin = np.array(self.start, dtype=float)
        direction = np.array(self.end, dtype=float) - origin
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

    def to_local(self, x_mm: float, y_mm: float) -> tuple[float, float]:
        """Floor-frame point to (s along the axis, d lateral, left positive)."""
        # In scalars, the same operations as the arrays' (a difference, then a two-term dot
        # product summed in order) and so the same result to the bit, at a fraction of the
        # cost: the door detector and the world ask this many times a scan.
        ox, oy, ux, uy, nx, ny = self._axis_floats
        rx, ry = x_mm - ox, y_mm - oy
        return float(rx * ux + ry * uy), float(rx * nx + ry * ny)

    def from_local(self, s_mm: float, d_mm: float) -> tuple[float, float]:
        """(s, d) in this hallway's frame to a floor-frame point."""
        origin, u, n = self._axis
        p = origin + s_mm * u + d_mm * n
        return float(p[0]), float(p[1])


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
    hallway: str | None = Field(None, description="the hallway's id (a floor of one: none)")

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
    hallway: str | None = Field(None, description="the hallway's id (a floor of one: none)")

    @property
    def span(self) -> tuple[float, float]:
        return (self.at_mm - self.width_mm / 2, self.at_mm + self.width_mm / 2)


class Junction(Opening):
    """Where another hallway meets this one from the side: the gap in this one's wall that
    the other's walls run from. Found from the hallways' axes, never written in a plan."""

    joins: str


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


class Frame(_Model):
    """A door frame across a hallway, or a fire door held open in one: two jambs standing
    in from the walls, ``clear_width_mm`` apart about the axis, ``depth_mm`` thick along
    the hallway. A fire door's two leaves stand folded back against the walls on the side
    of increasing ``s`` (``opens = "end"``) or the other (``"start"``)."""

    id: str
    hallway: str | None = Field(None, description="the hallway's id (a floor of one: none)")
    at_mm: Coordinate = Field(description="the frame's centre along the hallway")
    clear_width_mm: Size = Field(description="between the jambs")
    depth_mm: StrictFloat = Field(150.0, gt=0, le=2000)
    kind: Literal["frame", "fire_door"] = "frame"
    opens: Literal["start", "end"] = "end"
    leaf_mm: StrictFloat = Field(60.0, gt=0, le=300, description="a fire door leaf's thickness")

    @property
    def jambs(self) -> tuple[float, float]:
        """Along the hallway: where the jambs stand."""
        return self.at_mm - self.depth_mm / 2, self.at_mm + self.depth_mm / 2

    @property
    def span(self) -> tuple[float, float]:
        """Along the hallway: the jambs and, for a fire door, the leaves folded back."""
        lo, hi = self.jambs
        if self.kind == "fire_door":
            if self.opens == "end":
                hi += self.clear_width_mm / 2
            else:
                lo -= self.clear_width_mm / 2
        return lo, hi


class AngleZone(_Model):
    """A stretch of hallway where both walls are flat, so side sensors can measure heading."""

    id: str
    from_mm: Coordinate
    to_mm: Coordinate
    hallway: str | None = Field(None, description="the hallway's id (a floor of one: none)")

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


JUNCTION_TOLERANCE_MM = 10.0
"""How near a hallway's end must lie to another's axis for the two to meet there."""


class Meeting(NamedTuple):
    """Where ``joining`` ends on ``through``'s axis, ``s_mm`` along it: from the side
    (``side``, an L or a T: a gap in ``through``'s wall), or straight on (``side`` None: the
    hallway goes on at another width). At an L, the hallway listed first runs through."""

    through: Hallway
    joining: Hallway
    joining_end: Literal["start", "end"]
    s_mm: float
    side: Side | None


class Extent(NamedTuple):
    """How far a hallway's walls run in its own frame, and which of its ends are open."""

    lo_mm: float
    hi_mm: float
    start_open: bool
    end_open: bool


class Floor(_Model):
    """One floor: its hallways, the doors, openings and angle zones along them, free-form
    walls, anchors, parking spots and cameras.

    The along-hallway questions (``to_hallway``, ``features``, ``nearest_door``...) are asked
    of one hallway, :attr:`hallway`: the first listed, or the one :meth:`view` names. A view
    shares the floor's walls; a floor of one hallway is its own only view."""

    level: StrictInt = Field(ge=-100, le=1000)
    name: str = ""
    wall_height_mm: Size = 2700.0
    hallways: list[Hallway] = Field(min_length=1)
    doors: list[Door] = []
    openings: list[Opening] = []
    walls: list[Wall] = []
    angle_zones: list[AngleZone] = []
    anchors: list[Anchor] = []
    parking: list[ParkingSpot] = []
    """A fleet's robots' places to wait, one each (in the tea room's floor)."""
    cameras: list[Camera] = []
    frames: list[Frame] = []
    """Door frames and fire doors across a hallway."""
    _focus: int = PrivateAttr(0)

    @model_validator(mode="before")
    @classmethod
    def _hallway_is_now_a_list(cls, data: Any) -> Any:
        if isinstance(data, dict) and "hallway" in data:
            raise ValueError(
                "[floors.hallway] is now [[floors.hallways]] with an id (a floor may have "
                'several): write [[floors.hallways]] and id = "main" above its start'
            )
        return data

    # --- which hallway ---------------------------------------------------------------------

    @property
    def hallway(self) -> Hallway:
        """The hallway this floor (or view of it) answers along-hallway questions for."""
        # Read from pydantic's store of private attributes: ``self._focus`` goes through
        # ``BaseModel.__getattr__`` (2.5 us against 0.1), and this is asked at every scan.
        private = self.__pydantic_private__
        assert private is not None
        return self.hallways[private["_focus"]]

    def view(self, hallway_id: str | None) -> Floor:
        """This floor with ``hallway_id`` as its :attr:`hallway` (None: the first)."""
        if hallway_id is None:
            return self._views[self.hallways[0].id]
        try:
            return self._views[hallway_id]
        except KeyError:
            raise KeyError(f"floor {self.level} has no hallway {hallway_id!r}") from None

    @cached_property
    def _views(self) -> dict[str, Floor]:
        # Computed once, before the copies, so every view shares them.
        self.segment_array, self.segment_bounds, self.junctions, self.extents  # noqa: B018
        views = {}
        for index, hallway in enumerate(self.hallways):
            if index == self._focus:
                views[hallway.id] = self
                continue
            view = self.model_copy()
            view._focus = index
            views[hallway.id] = view
        return views

    def view_near(self, x_mm: float, y_mm: float) -> Floor:
        """The view of the hallway a floor-frame point stands in, or is nearest to (from a
        room, the hallway its door opens on); where hallways meet, the nearer axis."""

        def outside(hallway: Hallway) -> tuple[float, float]:
            lo, hi, _, _ = self.extents[hallway.id]
            s, d = hallway.to_local(x_mm, y_mm)
            beyond = max(0.0, lo - s, s - hi) + max(0.0, abs(d) - hallway.width_mm / 2)
            return beyond, abs(d)

        if len(self.hallways) == 1:
            return self
        return self.view(min(self.hallways, key=outside).id)

    def view_of(self, feature: Door | Opening | AngleZone | Frame) -> Floor:
        """The view of the hallway a door, opening, angle zone or frame lies along."""
        return self.view(self._hallway_id(feature))

    def hallway_of(self, feature: Door | Opening | AngleZone | Frame) -> Hallway:
        """The hallway a door, opening, angle zone or frame lies along."""
        return next(h for h in self.hallways if h.id == self._hallway_id(feature))

    def _hallway_id(self, feature: Door | Opening | AngleZone | Frame) -> str:
        """The feature's hallway (on a floor of one, it need not say)."""
        return feature.hallway or self.hallways[0].id

    def _lies_along(self, feature: Door | Opening | AngleZone | Frame, hallway: Hallway) -> bool:
        return self._hallway_id(feature) == hallway.id

    def _name(self, hallway: Hallway) -> str:
        """How walls and warnings name a hallway: by its id where there are several."""
        return "hallway" if len(self.hallways) == 1 else f"hallway {hallway.id}"

    # --- hallway frame ---------------------------------------------------------------------

    def to_hallway(self, x_mm: float, y_mm: float) -> tuple[float, float]:
        """Floor-frame point to (s along :attr:`hallway`'s axis, d lateral, left positive)."""
        return self.hallway.to_local(x_mm, y_mm)

    def from_hallway(self, s_mm: float, d_mm: float) -> tuple[float, float]:
        """(s, d) in :attr:`hallway`'s frame to a floor-frame point."""
        return self.hallway.from_local(s_mm, d_mm)

    def behind_door(self, door: Door, depth_mm: float) -> tuple[float, float]:
        """The floor-frame point ``depth_mm`` behind its hallway's wall line, through the
        middle of ``door`` (the recess's leaf at ``door.recess_mm``; inside the room beyond)."""
        hallway = self.hallway_of(door)
        sign = 1.0 if door.side == "left" else -1.0
        return hallway.from_local(door.at_mm, sign * (hallway.width_mm / 2 + depth_mm))

    # --- where hallways meet ---------------------------------------------------------------

    @cached_property
    def meetings(self) -> tuple[Meeting, ...]:
        """Every place where one hallway's end lies on another's axis."""
        found = []
        for j_index, joining in enumerate(self.hallways):
            for end, point, other in (
                ("start", joining.start, joining.end),
                ("end", joining.end, joining.start),
            ):
                for h_index, through in enumerate(self.hallways):
                    if through is joining:
                        continue
                    s, d = through.to_local(*point)
                    tol = JUNCTION_TOLERANCE_MM
                    if abs(d) > tol or not -tol <= s <= through.length_mm + tol:
                        continue
                    at_an_end = s <= tol or s >= through.length_mm - tol
                    ends_meet = at_an_end and self._ends_meet(joining, through)
                    if ends_meet and h_index > j_index:
                        continue  # an L or a width change: the one listed first runs through
                    if ends_meet and self._on_an_axis(point, (joining, through)):
                        continue  # a crossroads: both meet the hallway they cross, not each other
                    d_other = through.to_local(*other)[1]
                    side: Side | None = None
                    if abs(d_other) > tol:
                        side = "left" if d_other > 0 else "right"
                    found.append(Meeting(through, joining, end, s, side))  # type: ignore[arg-type]
        return tuple(found)

    def _on_an_axis(self, point: tuple[float, float], besides: tuple[Hallway, ...]) -> bool:
        """Whether ``point`` lies on another hallway's axis between its ends."""
        tol = JUNCTION_TOLERANCE_MM
        for hallway in self.hallways:
            if hallway in besides:
                continue
            s, d = hallway.to_local(*point)
            if abs(d) <= tol and tol < s < hallway.length_mm - tol:
                return True
        return False

    @staticmethod
    def _ends_meet(a: Hallway, b: Hallway) -> bool:
        """Whether an end of ``a`` and an end of ``b`` are one point."""
        return any(
            math.dist(p, q) <= JUNCTION_TOLERANCE_MM
            for p in (a.start, a.end)
            for q in (b.start, b.end)
        )

    @cached_property
    def extents(self) -> dict[str, Extent]:
        """Each hallway's walls' run in its own frame: shortened where it ends on another's
        wall line, lengthened over the corner where another ends on its end."""
        found = {}
        for hallway in self.hallways:
            lo, hi = 0.0, hallway.length_mm
            start_open, end_open = not hallway.start_closed, not hallway.end_closed
            for meeting in self.meetings:
                if meeting.joining is hallway:
                    step = 0.0 if meeting.side is None else meeting.through.width_mm / 2
                    if meeting.joining_end == "start":
                        lo, start_open = step, True
                    else:
                        hi, end_open = hallway.length_mm - step, True
                elif meeting.through is hallway:
                    at_start = meeting.s_mm <= JUNCTION_TOLERANCE_MM
                    at_end = meeting.s_mm >= hallway.length_mm - JUNCTION_TOLERANCE_MM
                    if meeting.side is None:
                        start_open, end_open = start_open or at_start, end_open or at_end
                    elif at_start:
                        lo = -meeting.joining.width_mm / 2
                    elif at_end:
                        hi = hallway.length_mm + meeting.joining.width_mm / 2
            found[hallway.id] = Extent(lo, hi, start_open, end_open)
        return found

    @cached_property
    def junctions(self) -> tuple[Junction, ...]:
        """The gaps other hallways leave in a hallway's walls, as openings of it."""
        return tuple(
            Junction(
                id=m.joining.id,
                side=m.side,
                at_mm=m.s_mm,
                width_mm=m.joining.width_mm,
                depth_mm=m.joining.length_mm,
                name=f"hallway {m.joining.id}",
                hallway=m.through.id,
                joins=m.joining.id,
            )
            for m in self.meetings
            if m.side is not None
        )

    # --- queries ---------------------------------------------------------------------------

    def features(self, side: Side | None = None) -> list[Door | Opening]:
        """Doors, openings and junctions along :attr:`hallway`, optionally on one side,
        ordered along it."""
        return self._features_along(self.hallway, side)

    def _features_along(self, hallway: Hallway, side: Side | None) -> list[Door | Opening]:
        items: list[Door | Opening] = [*self.doors, *self.openings, *self.junctions]
        return sorted(
            (f for f in items if side in (None, f.side) and self._lies_along(f, hallway)),
            key=lambda f: f.at_mm,
        )

    def frames_along(self) -> list[Frame]:
        """The door frames and fire doors across :attr:`hallway`, ordered along it."""
        return sorted(
            (f for f in self.frames if self._lies_along(f, self.hallway)), key=lambda f: f.at_mm
        )

    def feature_at(self, s_mm: float, side: Side, margin_mm: float = 0.0) -> Door | Opening | None:
        """The door or opening whose span (widened by ``margin_mm``) covers ``s`` on a side."""
        for feature in self.features(side):
            lo, hi = feature.span
            if lo - margin_mm <= s_mm <= hi + margin_mm:
                return feature
        return None

    def nearest_door(self, s_mm: float, side: Side | None = None) -> Door | None:
        """The door along :attr:`hallway` whose centre is closest to ``s``."""
        doors = [
            d for d in self.doors if side in (None, d.side) and self._lies_along(d, self.hallway)
        ]
        return min(doors, key=lambda d: abs(d.at_mm - s_mm), default=None)

    def angle_zone_at(self, x_mm: float, y_mm: float) -> AngleZone | None:
        """The angle zone containing a floor-frame point, if any."""
        for zone in self.angle_zones:
            hallway = self.hallway_of(zone)
            s, d = hallway.to_local(x_mm, y_mm)
            if abs(d) <= hallway.width_mm / 2 and zone.from_mm <= s <= zone.to_mm:
                return zone
        return None

    def door(self, door_id: str) -> Door:
        for door in self.doors:
            if door.id == door_id:
                return door
        raise KeyError(f"floor {self.level} has no door {door_id!r}")

    @property
    def elevators(self) -> list[Door]:
        """Every elevator door of the floor, one a car."""
        return [d for d in self.doors if d.kind == "elevator"]

    @property
    def elevator(self) -> Door | None:
        """The first elevator door listed: the car of a building with one, a fleet's car."""
        return next(iter(self.elevators), None)

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
        for hallway in self.hallways:
            yield from self._hallway_segments(hallway)
        for meeting in self.meetings:
            if meeting.side is None:
                yield from self._width_steps(meeting)
        h = self.wall_height_mm
        for wall in self.walls:
            points = [*wall.points, wall.points[0]] if wall.closed else wall.points
            top = wall.height_mm or h
            for a, b in itertools.pairwise(points):
                yield WallSegment(f"wall {wall.id}", a[0], a[1], b[0], b[1], 0.0, top)

    def _hallway_segments(self, hallway: Hallway) -> Iterator[WallSegment]:
        """One hallway's walls, with its doors, openings and the gaps of those joining it."""
        h = self.wall_height_mm
        name = self._name(hallway)
        half = hallway.width_mm / 2
        lo_mm, hi_mm, start_open, end_open = self.extents[hallway.id]

        def seg(
            element: str, a: tuple[float, float], b: tuple[float, float], top: float = h
        ) -> WallSegment:
            return WallSegment(element, *hallway.from_local(*a), *hallway.from_local(*b), 0.0, top)

        for side, sign in (("left", 1.0), ("right", -1.0)):
            wall_d = sign * half
            cursor = lo_mm
            for feature in self._features_along(hallway, side):  # type: ignore[arg-type]
                lo, hi = feature.span
                if lo > cursor:
                    yield seg(f"{name} {side} wall", (cursor, wall_d), (lo, wall_d))
                cursor = max(cursor, hi)
                if isinstance(feature, Junction):
                    continue  # the joining hallway's own walls run from the gap
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
            if cursor < hi_mm:
                yield seg(f"{name} {side} wall", (cursor, wall_d), (hi_mm, wall_d))
        for frame in self.frames:
            if self._lies_along(frame, hallway):
                yield from self._frame_segments(hallway, frame)
        if not start_open:
            yield seg(f"{name} start wall", (lo_mm, -half), (lo_mm, half))
        if not end_open:
            yield seg(f"{name} end wall", (hi_mm, -half), (hi_mm, half))

    def _frame_segments(self, hallway: Hallway, frame: Frame) -> Iterator[WallSegment]:
        """A frame's two jambs, from the wall lines in to its opening; a fire door's leaves
        folded back flat against the walls beside it."""
        half, inner = hallway.width_mm / 2, frame.clear_width_mm / 2
        lo, hi = frame.jambs
        h = self.wall_height_mm

        def box(
            element: str, s0: float, s1: float, d_wall: float, d_in: float
        ) -> Iterator[WallSegment]:
            corners = [(s0, d_wall), (s0, d_in), (s1, d_in), (s1, d_wall)]
            for a, b in itertools.pairwise(corners):
                yield WallSegment(element, *hallway.from_local(*a), *hallway.from_local(*b), 0.0, h)

        for sign in (1.0, -1.0):
            yield from box(f"frame {frame.id} jamb", lo, hi, sign * half, sign * inner)
            if frame.kind == "fire_door":
                s0, s1 = (hi, hi + inner) if frame.opens == "end" else (lo - inner, lo)
                d_in = sign * (half - frame.leaf_mm)
                yield from box(f"fire door {frame.id} leaf", s0, s1, sign * half, d_in)

    def _width_steps(self, meeting: Meeting) -> Iterator[WallSegment]:
        """Where a hallway goes straight on at another width: the step in each wall."""
        through, joining = meeting.through, meeting.joining
        if abs(through.width_mm - joining.width_mm) < 1.0:
            return
        for sign in (1.0, -1.0):
            a = through.from_local(meeting.s_mm, sign * through.width_mm / 2)
            b = through.from_local(meeting.s_mm, sign * joining.width_mm / 2)
            yield WallSegment(f"hallway {through.id} step", *a, *b, 0.0, self.wall_height_mm)


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
        """The floor and (first listed) door of a room, by its name ("205", "Tea room")."""
        return self.room_doors(room)[0]

    def room_doors(self, room: str) -> list[RoomLocation]:
        """Every door of a room (a room may have several, on one floor)."""
        found = [
            RoomLocation(floor, door)
            for floor in self.floors
            for door in floor.doors
            if door.room == room
        ]
        if not found:
            raise KeyError(f"no room {room!r} in floor plan {self.name!r}")
        return found

    @cached_property
    def cars(self) -> dict[str, list[RoomLocation]]:
        """The elevator cars, each named by its first door's id, with its door on each floor
        it serves: elevator doors at one place in the building frame (the leaf's centre
        within ``ELEVATOR_TOLERANCE_MM``), opening the same way, are one car."""
        cars: dict[str, list[RoomLocation]] = {}
        for floor in self.floors:
            for door in floor.elevators:
                front = _elevator_front(floor, door)
                car = next(
                    (
                        name
                        for name, stops in cars.items()
                        if _same_car(front, _elevator_front(*stops[0]))
                        and all(stop.floor.level != floor.level for stop in stops)
                    ),
                    None,
                )
                if car is None:  # a new car, named by its door (and floor, if that is taken)
                    car = door.id if door.id not in cars else f"{door.id} (floor {floor.level})"
                cars.setdefault(car, []).append(RoomLocation(floor, door))
        return cars

    def car_door(self, car: str, level: int) -> Door:
        """Car ``car``'s door on floor ``level``."""
        for stop in self.cars[car]:
            if stop.floor.level == level:
                return stop.door
        raise KeyError(f"elevator {car} does not stop on floor {level}")

    def cars_between(self, a: int, b: int) -> list[str]:
        """The cars that stop on both floors."""
        return [
            car
            for car, stops in self.cars.items()
            if {a, b} <= {stop.floor.level for stop in stops}
        ]

    @property
    def tea_rooms(self) -> list[RoomLocation]:
        """Every pickup point (a door of kind ``tea_room``), in floor then plan order."""
        return [
            RoomLocation(floor, door)
            for floor in self.floors
            for door in floor.doors
            if door.kind == "tea_room"
        ]

    @property
    def tea_room(self) -> RoomLocation:
        """The first pickup point: a fleet's base, where its robots park and are loaded."""
        first = next(iter(self.tea_rooms), None)
        if first is None:
            raise KeyError("floor plan has no tea room")
        return first

    @property
    def rooms(self) -> list[str]:
        """Rooms a delivery can go to: every office door, in floor then hallway order."""
        doors = [
            d.room
            for f in self.floors
            for h in f.hallways
            for d in f.view(h.id).features()
            if isinstance(d, Door) and d.kind == "office"
        ]
        return list(dict.fromkeys(doors))  # a room of two doors once


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
        if error["type"] == "value_error":
            message = str(error["ctx"]["error"])  # without pydantic's "Value error, "
        if error["type"] in ("float_type", "int_type") and isinstance(error["input"], str):
            message = f"a number was expected, not the string {error['input']!r}"
        problem = f"{field}: {message}" if field else message
        raise FloorPlanError(path, element, problem) from None
    _check_consistency(plan, path)
    return plan


_ELEMENT_NAMES = {
    "floors": "floor",
    "hallways": "hallway",
    "doors": "door",
    "openings": "opening",
    "walls": "wall",
    "angle_zones": "angle zone",
    "anchors": "anchor",
    "cameras": "camera",
    "marks": "mark",
    "frames": "frame",
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
        _check_hallways(floor, path)
        groups: list[tuple[str, Sequence[Door | Opening | Wall | AngleZone | Anchor | Frame]]] = [
            ("door", floor.doors),
            ("opening", floor.openings),
            ("wall", floor.walls),
            ("angle zone", floor.angle_zones),
            ("anchor", floor.anchors),
            ("frame", floor.frames),
        ]
        for kind, items in groups:
            seen: set[str] = set()
            for item in items:
                if item.id in seen:
                    raise FloorPlanError(path, f"{where} / {kind} {item.id}", "duplicate id")
                seen.add(item.id)
        for hallway in floor.hallways:
            _check_along(floor.view(hallway.id), path)
        _check_anchors_near(floor, path)
        _check_cameras(floor, path)
        if len(plan.floors) > 1 and not floor.elevators:
            raise FloorPlanError(path, where, "no elevator door in a building of several floors")
    _check_elevator_aligned(plan, path)
    _check_camera_ids_unique(plan, path)
    if not plan.tea_rooms:
        raise FloorPlanError(
            path, "floor plan", "needs a door of kind 'tea_room' (where cups are picked up)"
        )
    first_doors: dict[str, tuple[int, Door]] = {}
    for floor in plan.floors:
        for door in floor.doors:
            if door.kind == "elevator":
                continue
            if door.room not in first_doors:
                first_doors[door.room] = (floor.level, door)
                continue
            level, first = first_doors[door.room]
            if level != floor.level:
                raise FloorPlanError(
                    path,
                    f"floor {floor.level} / door {door.id}",
                    f"room: {door.room!r} has a door on floor {level} too: a room's doors "
                    "are on one floor (name the rooms apart)",
                )
            if door.kind != first.kind:
                raise FloorPlanError(
                    path,
                    f"floor {floor.level} / door {door.id}",
                    f"kind: {door.kind!r}, but {door.room!r}'s door {first.id} is "
                    f"{first.kind!r}: a room's doors are of one kind",
                )


def _check_hallways(floor: Floor, path: str | Path) -> None:
    """Hallways with ids of their own, a length, meeting only end to axis at right angles
    (or straight on), and every door, opening and zone on one of them."""
    where = f"floor {floor.level}"
    ids = [h.id for h in floor.hallways]
    for hallway in floor.hallways:
        element = f"{where} / hallway {hallway.id}"
        if ids.count(hallway.id) > 1:
            raise FloorPlanError(path, element, "duplicate id")
        if hallway.length_mm <= 0:
            raise FloorPlanError(path, element, "start and end are the same point")
    for kind, items in (
        ("door", floor.doors),
        ("opening", floor.openings),
        ("angle zone", floor.angle_zones),
        ("frame", floor.frames),
    ):
        for item in items:
            element = f"{where} / {kind} {item.id}"
            if item.hallway is None and len(ids) > 1:
                raise FloorPlanError(
                    path, element, f"hallway: the floor has several ({', '.join(ids)}): say which"
                )
            if item.hallway is not None and item.hallway not in ids:
                raise FloorPlanError(
                    path, element, f"hallway: no hallway {item.hallway!r} ({', '.join(ids)})"
                )
    for meeting in floor.meetings:
        turn = abs(math.remainder(meeting.joining.heading_deg - meeting.through.heading_deg, 180))
        if min(turn, abs(turn - 90)) > 1.0:
            raise FloorPlanError(
                path,
                f"{where} / hallway {meeting.joining.id}",
                f"meets hallway {meeting.through.id} at {turn:.0f} degrees: hallways meet at "
                "right angles or go straight on",
            )
    for a, b in itertools.combinations(floor.hallways, 2):
        crossing = _axes_cross(a, b)
        if crossing is not None:
            raise FloorPlanError(
                path,
                f"{where} / hallway {b.id}",
                f"crosses hallway {a.id} {crossing:.0f} mm along it: where hallways cross, "
                "end one at the other's axis and start another there",
            )
    for joining in floor.hallways:
        for point in (joining.start, joining.end):
            for through in floor.hallways:
                s, d = through.to_local(*point)
                # At the wall line, too: a side hallway stopped there is walled off.
                inside = (
                    JUNCTION_TOLERANCE_MM < abs(d) <= through.width_mm / 2 + JUNCTION_TOLERANCE_MM
                )
                if through is not joining and inside and 0 < s < through.length_mm:
                    raise FloorPlanError(
                        path,
                        f"{where} / hallway {joining.id}",
                        f"ends inside hallway {through.id}, {abs(d):.0f} mm off its axis: "
                        "a hallway ends on the other's axis where they meet",
                    )


def _axes_cross(a: Hallway, b: Hallway) -> float | None:
    """Where along ``a`` the axis of ``b`` passes through it (neither ending there), if it
    does."""
    tol = JUNCTION_TOLERANCE_MM
    (s0, d0), (s1, d1) = a.to_local(*b.start), a.to_local(*b.end)
    if not ((d0 < -tol and d1 > tol) or (d0 > tol and d1 < tol)):
        return None
    s = s0 + (s1 - s0) * d0 / (d0 - d1)
    return s if tol < s < a.length_mm - tol else None


def _check_along(view: Floor, path: str | Path) -> None:
    """One hallway's doors, openings, junctions and angle zones: inside its walls' run, not
    overlapping on a side."""
    where = f"floor {view.level}"
    lo_mm, hi_mm, _, _ = view.extents[view.hallway.id]
    name = "the hallway" if len(view.hallways) == 1 else f"hallway {view.hallway.id}"
    for side in ("left", "right"):
        previous: Door | Opening | None = None
        for feature in view.features(side):
            kind = (
                "door"
                if isinstance(feature, Door)
                else "hallway"
                if isinstance(feature, Junction)
                else "opening"
            )
            lo, hi = feature.span
            if lo < lo_mm - JUNCTION_TOLERANCE_MM or hi > hi_mm + JUNCTION_TOLERANCE_MM:
                raise FloorPlanError(
                    path,
                    f"{where} / {kind} {feature.id}",
                    f"spans {lo:.0f}..{hi:.0f} mm, outside {name} ({lo_mm:.0f}..{hi_mm:.0f} mm)",
                )
            if previous is not None and lo < previous.span[1]:
                raise FloorPlanError(
                    path,
                    f"{where} / {kind} {feature.id}",
                    f"overlaps {previous.id} on the {side} side of {name}",
                )
            previous = feature
    for frame in view.frames_along():
        element = f"{where} / frame {frame.id}"
        lo, hi = frame.span
        if lo < lo_mm or hi > hi_mm:
            raise FloorPlanError(
                path,
                element,
                f"spans {lo:.0f}..{hi:.0f} mm, outside {name} ({lo_mm:.0f}..{hi_mm:.0f} mm)",
            )
        if frame.clear_width_mm >= view.hallway.width_mm:
            raise FloorPlanError(
                path,
                element,
                f"clear_width_mm: {frame.clear_width_mm:.0f} is not narrower than {name} "
                f"({view.hallway.width_mm:.0f} mm)",
            )
        across = next((f for f in view.features() if f.span[1] > lo and f.span[0] < hi), None)
        if across is not None:
            raise FloorPlanError(
                path,
                element,
                f"at_mm: stands across {across.id}'s doorway or mouth ({lo:.0f}..{hi:.0f} mm)",
            )
    for zone in view.angle_zones:
        if view.hallway_of(zone) is not view.hallway:
            continue
        if zone.from_mm < lo_mm or zone.to_mm > hi_mm:
            raise FloorPlanError(
                path, f"{where} / angle zone {zone.id}", "lies outside the hallway"
            )
        _check_angle_zone_clear(view, zone, path)


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
    frame = next((f for f in floor.frames_along() if f.span[1] >= lo and f.span[0] <= hi), None)
    if frame is not None:
        raise FloorPlanError(
            path,
            f"floor {floor.level} / angle zone {zone.id}",
            f"from_mm, to_mm: lies over frame {frame.id}, whose jambs stand in from both walls "
            f"(keep {ANGLE_ZONE_CLEARANCE_MM:.0f} mm of plain wall beyond each end)",
        )
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


def _facing_alike(inward_a: np.ndarray, inward_b: np.ndarray) -> bool:
    """Whether two elevator doors open the same way (within 45 degrees)."""
    return float(inward_a @ inward_b) >= math.cos(math.radians(45))


def _same_car(a: tuple[np.ndarray, np.ndarray], b: tuple[np.ndarray, np.ndarray]) -> bool:
    """Whether two elevator doors (:func:`_elevator_front`) open one car."""
    (centre_a, inward_a), (centre_b, inward_b) = a, b
    near = float(np.linalg.norm(centre_a - centre_b)) <= ELEVATOR_TOLERANCE_MM
    return near and _facing_alike(inward_a, inward_b)


def _check_elevator_aligned(plan: FloorPlan, path: str | Path) -> None:
    """In a building of several floors every car serves two floors at least: an elevator
    door that lines up with none on another floor (the same place, facing the same way) is a
    survey mistake, named against the nearest elevator door of another floor."""
    if len(plan.floors) < 2:
        return
    for stops in reversed(plan.cars.values()):  # the later floor's door is the one named
        if len(stops) > 1:
            continue
        floor, door = stops[0]
        centre, inward = _elevator_front(floor, door)
        others = [
            (float(np.linalg.norm(_elevator_front(f, d)[0] - centre)), f, d)
            for f in plan.floors
            if f.level != floor.level
            for d in f.elevators
        ]
        _, other_floor, other = min(others, key=lambda o: o[0])
        other_centre, other_inward = _elevator_front(other_floor, other)
        where = f"floor {floor.level} / door {door.id}"
        if not _facing_alike(inward, other_inward):
            raise FloorPlanError(
                path,
                where,
                f"side: the elevator opens on the {door.side} side, facing another way than "
                f"{other.id} on floor {other_floor.level} ({other.side} side): not one car",
            )
        offset = float(np.linalg.norm(centre - other_centre))
        raise FloorPlanError(
            path,
            where,
            f"at_mm: the elevator door is {offset:.0f} mm from {other.id} on floor "
            f"{other_floor.level} in the building frame (at most "
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
    """Stretches of each hallway's centre line with fewer than three anchors in range: no
    UWB fix there. The tag is taken at floor height, so an anchor's whole height counts."""
    anchors = np.array([(a.x_mm, a.y_mm, a.z_mm) for a in floor.anchors], dtype=float)
    anchors = anchors.reshape(-1, 3)
    warnings = []
    for hallway in floor.hallways:
        length = hallway.length_mm
        along = np.linspace(0.0, length, math.ceil(length / COVERAGE_STEP_MM) + 1)
        points = np.array([hallway.from_local(float(s), 0.0) for s in along])
        distances = np.hypot(
            np.hypot(points[:, :1] - anchors[:, 0], points[:, 1:] - anchors[:, 1]), anchors[:, 2]
        )
        in_range = (distances <= uwb_range_mm).sum(axis=1)
        short = in_range < MIN_ANCHORS
        name = floor._name(hallway)
        for is_short, run in itertools.groupby(range(len(along)), key=lambda i: bool(short[i])):
            if not is_short:
                continue
            indices = list(run)
            fewest = int(in_range[indices].min())
            warnings.append(
                PlanWarning(
                    f"floor {floor.level} / {name}",
                    f"{along[indices[0]]:.0f}..{along[indices[-1]]:.0f} mm along it has "
                    f"{fewest} UWB anchor{'' if fewest == 1 else 's'} within "
                    f"{uwb_range_mm:.0f} mm, a fix needs {MIN_ANCHORS}: the robot relies on "
                    "odometry, walls and doors there",
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
