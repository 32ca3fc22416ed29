"""Floor plans drawn as SVG: walls, doors with their rooms, openings, angle zones, anchors.

The drawing is plain SVG with one ``<g>`` per floor and CSS classes on every element, so the
web map can restyle it and draw the robot on top. Floor-frame y points up; SVG y points down,
so points are flipped here and text stays readable. Each floor ends with an empty group,
``id="frame-<level>"``, whose transform maps the floor's frame (mm, y up) into the picture:
the live map draws the robot inside it in floor-plan coordinates.

Floors drawn together share one frame: each is a panel of the same size, stacked downwards,
a point of the building frame at the same place in every panel. Each panel shows the other
floors' hallways dashed beneath its own, and a line through every panel marks the elevator
shaft, so a surveyor sees at once whether the floors were surveyed in one frame and whether
the car's doors line up. Each hallway's start (s = 0) is marked and an arrow shows which way
it runs.
"""

from __future__ import annotations

import argparse
import sys
from collections.abc import Sequence
from pathlib import Path
from xml.sax.saxutils import escape

from coffeebot.floorplan import Door, Floor, FloorPlan, FloorPlanError, load_floorplan

_MARGIN_MM = 1500.0
_GAP_MM = 2000.0
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


def _hallway_outline(floor: Floor) -> list[tuple[float, float]]:
    half = floor.hallway.width_mm / 2
    corners = [(0, -half), (floor.hallway.length_mm, -half), (floor.hallway.length_mm, half)]
    return [floor.from_hallway(s, d) for s, d in [*corners, (0, half)]]


def _car_centre(floor: Floor) -> tuple[float, float] | None:
    """The middle of the elevator's door leaf on ``floor`` (None: no elevator there)."""
    door = floor.elevator
    return None if door is None else floor.behind_door(door, door.recess_mm)


def _floor_svg(floor: Floor, canvas: _Canvas, others: Sequence[Floor]) -> list[str]:
    half = floor.hallway.width_mm / 2
    length = floor.hallway.length_mm
    out = [f'<g class="floor" id="floor-{floor.level}">']
    out.append(f'<polygon class="hallway" points="{canvas.points(_hallway_outline(floor))}"/>')
    for other in others:
        name = escape(other.name or f"Floor {other.level}")
        out.append(
            f'<polygon class="other-floor" points="{canvas.points(_hallway_outline(other))}">'
            f"<title>{name}: its hallway, in the same frame</title></polygon>"
        )
    for zone in floor.angle_zones:
        box = [floor.from_hallway(s, d) for s in (zone.from_mm, zone.to_mm) for d in (-half, half)]
        box = [box[0], box[2], box[3], box[1]]
        out.append(
            f'<polygon class="zone" id="zone-{escape(zone.id)}" points="{canvas.points(box)}">'
            f"<title>angle zone {escape(zone.id)}</title></polygon>"
        )
    axis = [floor.from_hallway(0, 0), floor.from_hallway(length, 0)]
    out.append(f'<polyline class="axis" points="{canvas.points(axis)}"/>')
    sx, sy = canvas.point(*floor.from_hallway(0, 0))
    out.append(
        f'<circle class="start" cx="{sx:.0f}" cy="{sy:.0f}" r="180">'
        f"<title>hallway start (s = 0)</title></circle>"
        f'<text class="start" x="{sx:.0f}" y="{sy - 260:.0f}">s = 0</text>'
    )
    arrow = [floor.from_hallway(length - 300, 0)]
    arrow += [floor.from_hallway(length - 1100, d) for d in (350, -350)]
    out.append(
        f'<polygon class="direction" points="{canvas.points(arrow)}">'
        f"<title>the hallway runs this way: s = 0 to {length / 1000:.1f} m</title></polygon>"
    )
    car = _car_centre(floor)
    if car is not None:
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
    for feature in floor.features():
        sign = 1.0 if feature.side == "left" else -1.0
        label = feature.room if isinstance(feature, Door) else feature.name or feature.id
        lx, ly = canvas.point(*floor.from_hallway(feature.at_mm, sign * (half + 700)))
        out.append(f'<text x="{lx:.0f}" y="{ly + 130:.0f}">{escape(label)}</text>')
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
    cars = [car for car in map(_car_centre, floors) if car is not None]
    if len(floors) > 1 and cars:
        # Through every panel at the first floor's car: the others' should sit on it.
        x = cars[0][0] - frame.min_x
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
