"""One floor: its hallways and where they meet, the features along each, and the wall
segments the sensors see; a *view* of the floor answers along-hallway questions for one of
its hallways.
"""

from __future__ import annotations

import itertools
import math
from collections.abc import Iterator
from functools import cached_property
from typing import Any, Literal, NamedTuple

import numpy as np
from pydantic import Field, PrivateAttr, StrictInt, model_validator

from coffeebot.floorplan.features import (
    Anchor,
    AngleZone,
    Camera,
    Door,
    Frame,
    Hallway,
    Junction,
    Opening,
    ParkingSpot,
    Side,
    Size,
    StrictModel,
    Wall,
    WallSegment,
    segment_distances,
)

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


class Floor(StrictModel):
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

    def travel_deg(self, direction: float) -> float:
        """The heading of travel along :attr:`hallway`: towards increasing s for a positive
        ``direction``, the other way otherwise."""
        return self.hallway.heading_deg + (0.0 if direction > 0 else 180.0)

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
