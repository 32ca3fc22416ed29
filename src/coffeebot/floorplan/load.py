"""Loading a floor plan from TOML, and every check a surveyed plan must pass, each failure one
line naming the file, the floor, the element and the field.
"""

from __future__ import annotations

import itertools
import math
from collections.abc import Sequence
from pathlib import Path
from typing import Any

import numpy as np
from pydantic import ValidationError

from coffeebot.config import read_toml
from coffeebot.floorplan.features import (
    Anchor,
    AngleZone,
    Door,
    FloorPlanError,
    Frame,
    Hallway,
    Junction,
    Opening,
    Wall,
)
from coffeebot.floorplan.floor import JUNCTION_TOLERANCE_MM, Floor
from coffeebot.floorplan.plan import ELEVATOR_TOLERANCE_MM, FloorPlan, elevator_front, facing_alike

ANGLE_ZONE_CLEARANCE_MM = 400.0
"""Plain wall an angle zone needs beyond each end, on one side at least: the side sensors are
277 mm apart and their cones spread ~200 mm at 850 mm."""

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
    # Imported here: the camera modules build on the plan's features, and importing one of
    # those loads this package first.
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
        centre, inward = elevator_front(floor, door)
        others = [
            (float(np.linalg.norm(elevator_front(f, d)[0] - centre)), f, d)
            for f in plan.floors
            if f.level != floor.level
            for d in f.elevators
        ]
        _, other_floor, other = min(others, key=lambda o: o[0])
        other_centre, other_inward = elevator_front(other_floor, other)
        where = f"floor {floor.level} / door {door.id}"
        if not facing_alike(inward, other_inward):
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
