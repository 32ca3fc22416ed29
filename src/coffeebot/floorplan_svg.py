"""Floor plans drawn as SVG: walls, doors with their rooms, openings, angle zones, anchors.

The drawing is plain SVG with one ``<g>`` per floor and CSS classes on every element, so the
web map can restyle it and draw the robot on top. Floor-frame y points up; SVG y points down,
so points are flipped here and text stays readable. Each floor ends with an empty group,
``id="frame-<level>"``, whose transform maps the floor's frame (mm, y up) into the picture:
the live map draws the robot inside it in floor-plan coordinates.

Every hallway of a floor is drawn in its own frame (its ``s`` and its left and right): its
floor over the run of its walls (``Floor.extents``), its angle zones, a mark at its start
(s = 0, with the hallway's id on a floor of several) and an arrow showing which way it runs;
each door's and opening's label stands beside its own hallway's wall. What belongs to one
hallway carries its id in a ``data-hallway`` attribute.

Floors drawn together share one frame: each is a panel of the same size, stacked downwards,
a point of the building frame at the same place in every panel. Each panel shows the other
floors' hallways dashed beneath its own (the outline of all of a floor's hallways taken
together), and a line through every panel marks each elevator shaft, so a surveyor sees at
once whether the floors were surveyed in one frame and whether the car's doors line up.
"""

from __future__ import annotations

import argparse
import itertools
import math
import sys
from collections.abc import Sequence
from pathlib import Path
from xml.sax.saxutils import escape

from coffeebot.floorplan import (
    Door,
    Extent,
    Floor,
    FloorPlan,
    FloorPlanError,
    Hallway,
    load_floorplan,
)

_MARGIN_MM = 1500.0
_GAP_MM = 2000.0
_EDGE_PROBE_MM = 1.0
"""How far to either side of an outline's edge to look for floor."""
_STYLE = """
.hallway { fill: #f4f1ea; }
.other-floor { fill: none; stroke: #b0bec5; stroke-width: 40; stroke-dasharray: 250 200; }
.zone { fill: #e53935; fill-opacity: 0.25; }
.axis { stroke: #9e9e9e; stroke-dasharray: 400 300; stroke-width: 30; }
.start { fill: #43a047; }
.direction { fill: #43a047; }
.shaft { stroke: #8e24aa; stroke-width: 40; stroke-dasharray: 120 120; }
.car { fill: #8e24aa; fill-opacity: 0.5; }
.wall { stroke: #263238; stroke-width: 60; stroke-linecap: round; }
.door { stroke: #8d6e63; stroke-width: 80; }
.anchor { fill: #1e88e5; }
text { font-family: sans-serif; font-size: 380px; fill: #37474f; text-anchor: middle; }
text.title { font-size: 700px; text-anchor: start; font-weight: bold; }
text.small { font-size: 260px; fill: #1e88e5; }
text.start { font-size: 260px; fill: #43a047; }
"""


class _Frame:
    """The building-frame box every floor drawn together fits in, with a margin."""

    def __init__(self, floors: Sequence[Floor]) -> None:
        xs: list[float] = []
        ys: list[float] = []
        for floor in floors:
            a = floor.segment_array
            xs += [*a[:, 0], *a[:, 2], *(an.x_mm for an in floor.anchors)]
            ys += [*a[:, 1], *a[:, 3], *(an.y_mm for an in floor.anchors)]
        self.min_x, self.max_y = min(xs) - _MARGIN_MM, max(ys) + _MARGIN_MM
        self.width = max(xs) + _MARGIN_MM - self.min_x
        self.height = self.max_y - (min(ys) - _MARGIN_MM)


class _Canvas:
    """Maps the building frame into one floor's panel: y flipped, panels stacked downwards."""

    def __init__(self, frame: _Frame, top: float) -> None:
        self.min_x, self.max_y = frame.min_x, frame.max_y
        self.width, self.height = frame.width, frame.height
        self.top = top

    @property
    def transform(self) -> str:
        """The SVG transform from floor-frame mm to the picture: the same mapping as
        :meth:`point`, for a group whose contents are given in the floor's frame."""
        return f"translate({-self.min_x:g} {self.top + self.max_y:g}) scale(1 -1)"

    def point(self, x: float, y: float) -> tuple[float, float]:
        return x - self.min_x, self.top + self.max_y - y

    def points(self, pts: Sequence[tuple[float, float]]) -> str:
        return " ".join("{:.0f},{:.0f}".format(*self.point(x, y)) for x, y in pts)


def _hallway_outline(floor: Floor, hallway: Hallway) -> list[tuple[float, float]]:
    """The floor-frame corners of ``hallway``'s floor, over the run of its walls."""
    lo, hi, _, _ = floor.extents[hallway.id]
    half = hallway.width_mm / 2
    return [hallway.from_local(s, d) for s, d in [(lo, -half), (hi, -half), (hi, half), (lo, half)]]


def _floor_outlines(floor: Floor) -> list[list[tuple[float, float]]]:
    """The outline of a floor's hallways taken together: the edges of the hallways' outlines
    that have floor on one side only, joined into closed loops (one for hallways that meet).
    """
    outlines = [_hallway_outline(floor, h) for h in floor.hallways]
    if len(outlines) == 1:
        return outlines
    inside = [_Box(h, floor.extents[h.id]) for h in floor.hallways]
    pieces: list[tuple[tuple[float, float], tuple[float, float]]] = []
    for index, outline in enumerate(outlines):
        corners = [c for k, o in enumerate(outlines) if k != index for c in o]
        for a, b in zip(outline, [*outline[1:], outline[0]], strict=True):
            pieces += _boundary_pieces(a, b, corners, inside)
    return _loops(pieces)


class _Box:
    """A hallway's floor as a test of whether a floor-frame point lies on it."""

    def __init__(self, hallway: Hallway, extent: Extent) -> None:
        self.hallway, self.lo, self.hi = hallway, extent.lo_mm, extent.hi_mm

    def __contains__(self, point: tuple[float, float]) -> bool:
        s, d = self.hallway.to_local(*point)
        return self.lo < s < self.hi and abs(d) < self.hallway.width_mm / 2


def _boundary_pieces(
    a: tuple[float, float],
    b: tuple[float, float],
    corners: Sequence[tuple[float, float]],
    boxes: Sequence[_Box],
) -> list[tuple[tuple[float, float], tuple[float, float]]]:
    """The stretches of the edge ``a``-``b`` (floor on its left) that bound the hallways
    taken together: cut where another's corner lies across it (hallways meet at right angles
    or straight on, so there their edges cross or join), kept where floor lies on the left
    and none on the right."""
    length = math.dist(a, b)
    if length < 1.0:
        return []
    ux, uy = (b[0] - a[0]) / length, (b[1] - a[1]) / length
    cuts = {0.0, length}
    for cx, cy in corners:
        t = (cx - a[0]) * ux + (cy - a[1]) * uy
        if 1.0 < t < length - 1.0:
            cuts.add(round(t, 1))
    stops = sorted(cuts)
    kept = []
    for t0, t1 in itertools.pairwise(stops):
        mid = (a[0] + ux * (t0 + t1) / 2, a[1] + uy * (t0 + t1) / 2)
        left = (mid[0] - uy * _EDGE_PROBE_MM, mid[1] + ux * _EDGE_PROBE_MM)
        right = (mid[0] + uy * _EDGE_PROBE_MM, mid[1] - ux * _EDGE_PROBE_MM)
        if any(left in box for box in boxes) and not any(right in box for box in boxes):
            kept.append(((a[0] + ux * t0, a[1] + uy * t0), (a[0] + ux * t1, a[1] + uy * t1)))
    return kept


def _loops(
    pieces: list[tuple[tuple[float, float], tuple[float, float]]],
) -> list[list[tuple[float, float]]]:
    """Directed edges joined end to start into closed loops, corners where they turn."""
    left = list(pieces)
    loops = []
    while left:
        a, b = left.pop(0)
        loop = [a]
        while left:
            # The piece starting where this one ends (to the millimetre: the ends were
            # computed along different edges).
            k = min(range(len(left)), key=lambda i: math.dist(left[i][0], b))
            if math.dist(left[k][0], b) > 1.0:
                break
            a, b = left.pop(k)
            loop.append(a)
        loops.append(_corners(loop))
    return loops


def _corners(loop: list[tuple[float, float]]) -> list[tuple[float, float]]:
    """A closed loop's points without those where it runs straight on."""
    kept = []
    for prev, here, nxt in zip([loop[-1], *loop[:-1]], loop, [*loop[1:], loop[0]], strict=True):
        cross = (here[0] - prev[0]) * (nxt[1] - here[1]) - (here[1] - prev[1]) * (nxt[0] - here[0])
        if abs(cross) > math.dist(prev, here) * math.dist(here, nxt) * 1e-6:
            kept.append(here)
    return kept or loop


def _car_centres(floor: Floor) -> list[tuple[float, float]]:
    """The middle of each elevator door's leaf on ``floor``."""
    return [floor.behind_door(door, door.recess_mm) for door in floor.elevators]


def _hallway_marks(floor: Floor, hallway: Hallway, canvas: _Canvas) -> list[str]:
    """A hallway's axis, its start (s = 0, with its id on a floor of several) and the arrow
    at its far end showing which way it runs."""
    length = hallway.length_mm
    several = len(floor.hallways) > 1
    name = f"hallway {escape(hallway.id)}" if several else "the hallway"
    data = f'data-hallway="{escape(hallway.id)}"'
    axis = [hallway.from_local(0, 0), hallway.from_local(length, 0)]
    out = [f'<polyline class="axis" {data} points="{canvas.points(axis)}"/>']
    sx, sy = canvas.point(*hallway.from_local(0, 0))
    label = f"{escape(hallway.id)}: s = 0" if several else "s = 0"
    start = f"{name}: its start" if several else "hallway start"
    out.append(
        f'<circle class="start" {data} cx="{sx:.0f}" cy="{sy:.0f}" r="180">'
        f"<title>{start} (s = 0)</title></circle>"
        f'<text class="start" {data} x="{sx:.0f}" y="{sy - 260:.0f}">{label}</text>'
    )
    arrow = [hallway.from_local(length - 300, 0)]
    arrow += [hallway.from_local(length - 1100, d) for d in (350, -350)]
    out.append(
        f'<polygon class="direction" {data} points="{canvas.points(arrow)}">'
        f"<title>{name} runs this way: s = 0 to {length / 1000:.1f} m</title></polygon>"
    )
    return out


def _floor_svg(floor: Floor, canvas: _Canvas, others: Sequence[Floor]) -> list[str]:
    out = [f'<g class="floor" id="floor-{floor.level}">']
    for hallway in floor.hallways:
        fill = canvas.points(_hallway_outline(floor, hallway))
        out.append(
            f'<polygon class="hallway" data-hallway="{escape(hallway.id)}" points="{fill}"/>'
        )
    for other in others:
        name = escape(other.name or f"Floor {other.level}")
        what = "its hallway" if len(other.hallways) == 1 else "its hallways"
        for outline in _floor_outlines(other):
            out.append(
                f'<polygon class="other-floor" points="{canvas.points(outline)}">'
                f"<title>{name}: {what}, in the same frame</title></polygon>"
            )
    for zone in floor.angle_zones:
        hallway = floor.hallway_of(zone)
        half = hallway.width_mm / 2
        box = [hallway.from_local(s, d) for s, d in [(zone.from_mm, -half), (zone.to_mm, -half)]]
        box += [hallway.from_local(s, d) for s, d in [(zone.to_mm, half), (zone.from_mm, half)]]
        out.append(
            f'<polygon class="zone" id="zone-{escape(zone.id)}" '
            f'data-hallway="{escape(hallway.id)}" points="{canvas.points(box)}">'
            f"<title>angle zone {escape(zone.id)}</title></polygon>"
        )
    for hallway in floor.hallways:
        out += _hallway_marks(floor, hallway, canvas)
    for car in _car_centres(floor):
        cx, cy = canvas.point(*car)
        out.append(
            f'<rect class="car" x="{cx - 250:.0f}" y="{cy - 250:.0f}" width="500" height="500">'
            f"<title>elevator door, floor {floor.level}</title></rect>"
        )
    doors = {f"door {d.id}" for d in floor.doors}
    for seg in floor.segments:
        cls = "door" if seg.element in doors else "wall"
        (x0, y0), (x1, y1) = canvas.point(seg.x0, seg.y0), canvas.point(seg.x1, seg.y1)
        out.append(
            f'<line class="{cls}" x1="{x0:.0f}" y1="{y0:.0f}" x2="{x1:.0f}" y2="{y1:.0f}">'
            f"<title>{escape(seg.element)}</title></line>"
        )
    for hallway in floor.hallways:
        # Beside the hallway's own wall, in its own frame.
        half = hallway.width_mm / 2
        for feature in floor.view(hallway.id).features():
            sign = 1.0 if feature.side == "left" else -1.0
            label = feature.room if isinstance(feature, Door) else feature.name or feature.id
            lx, ly = canvas.point(*hallway.from_local(feature.at_mm, sign * (half + 700)))
            out.append(
                f'<text data-hallway="{escape(hallway.id)}" x="{lx:.0f}" y="{ly + 130:.0f}">'
                f"{escape(label)}</text>"
            )
    for anchor in floor.anchors:
        ax, ay = canvas.point(anchor.x_mm, anchor.y_mm)
        out.append(
            f'<circle class="anchor" cx="{ax:.0f}" cy="{ay:.0f}" r="120">'
            f"<title>UWB anchor {escape(anchor.id)}</title></circle>"
            f'<text class="small" x="{ax:.0f}" y="{ay - 200:.0f}">{escape(anchor.id)}</text>'
        )
    title = escape(floor.name or f"Floor {floor.level}")
    out.append(f'<text class="title" x="200" y="{canvas.top + 800:.0f}">{title}</text>')
    # Empty, in the floor's own frame: what is drawn inside it lands where the plan says.
    out.append(f'<g class="frame" id="frame-{floor.level}" transform="{canvas.transform}"/>')
    out.append("</g>")
    return out


def render_svg(plan: FloorPlan, levels: Sequence[int] | None = None) -> str:
    """The floors (all, or those in ``levels``) stacked top to bottom in one frame, mm units."""
    floors = [plan.floor(level) for level in levels] if levels else plan.floors
    frame = _Frame(floors)
    body: list[str] = []
    for index, floor in enumerate(floors):
        canvas = _Canvas(frame, index * (frame.height + _GAP_MM))
        body += _floor_svg(floor, canvas, [f for f in floors if f is not floor])
    height = len(floors) * (frame.height + _GAP_MM) - _GAP_MM
    if len(floors) > 1:
        # Through every panel at each of the first floor's cars: the others' should sit on it.
        for car in _car_centres(floors[0]):
            x = car[0] - frame.min_x
            body.append(
                f'<line class="shaft" x1="{x:.0f}" y1="0" x2="{x:.0f}" y2="{height:.0f}">'
                f"<title>elevator shaft</title></line>"
            )
    return "\n".join(
        [
            f'<svg xmlns="http://www.w3.org/2000/svg" viewBox="0 0 {frame.width:.0f} '
            f'{height:.0f}" width="{frame.width / 20:.0f}" height="{height / 20:.0f}">',
            f"<title>{escape(plan.name or 'floor plan')}</title>",
            f"<style>{_STYLE}</style>",
            *body,
            "</svg>",
        ]
    )


def add_render_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("file", type=Path, help="floor plan TOML")
    parser.add_argument("-o", "--output", type=Path, required=True, help="SVG file to write")
    parser.add_argument("--floor", type=int, action="append", help="only this floor (repeatable)")


def render_command(args: argparse.Namespace) -> int:
    """``coffeebot floorplan render FILE -o OUT.svg``: exit status 2 on a bad floor plan."""
    try:
        plan = load_floorplan(args.file)
        svg = render_svg(plan, args.floor)
    except FloorPlanError as exc:
        print(f"coffeebot: {exc}", file=sys.stderr)
        return 2
    except KeyError as exc:
        print(f"coffeebot: {args.file}: {exc.args[0]}", file=sys.stderr)
        return 2
    try:
        args.output.write_text(svg, encoding="utf-8")
    except OSError as exc:
        print(f"coffeebot: cannot write {args.output}: {exc.strerror or exc}", file=sys.stderr)
        return 1
    drawn = args.floor or [f.level for f in plan.floors]
    print(f"{args.output}: {plan.name or 'floor plan'}, floor {', '.join(map(str, drawn))}")
    return 0
