"""The SVG render of floors of several hallways: each hallway drawn in its own frame."""

from __future__ import annotations

import re
import xml.etree.ElementTree as ET

import pytest

from coffeebot.floorplan import FloorPlan, load_floorplan
from coffeebot.floorplan_svg import render_svg

from .conftest import ROOT

LINDEN_HALL = ROOT / "floorplans" / "linden-hall.toml"
NS = {"svg": "http://www.w3.org/2000/svg"}


@pytest.fixture(scope="module")
def linden() -> FloorPlan:
    return load_floorplan(LINDEN_HALL)


@pytest.fixture(scope="module")
def svg(linden: FloorPlan) -> ET.Element:
    return ET.fromstring(render_svg(linden))


def _panel(svg: ET.Element, level: int) -> tuple[ET.Element, tuple[float, float]]:
    """A floor's group and its frame's translation (plan x = px - tx, plan y = ty - py)."""
    group = svg.find(f".//svg:g[@id='floor-{level}']", NS)
    assert group is not None
    frame = group.find(f"svg:g[@id='frame-{level}']", NS)
    assert frame is not None
    found = re.match(
        r"translate\(([-\d.e]+) ([-\d.e]+)\) scale\(1 -1\)", frame.get("transform", "")
    )
    assert found is not None
    return group, (float(found.group(1)), float(found.group(2)))


def _plan_points(element: ET.Element, move: tuple[float, float]) -> list[tuple[float, float]]:
    """An element's ``points`` back in the floor frame."""
    tx, ty = move
    pairs = (p.split(",") for p in element.get("points", "").split())
    return [(float(x) - tx, ty - float(y)) for x, y in pairs]


def _rounded(points: list[tuple[float, float]]) -> set[tuple[int, int]]:
    return {(round(x), round(y)) for x, y in points}


def _by_hallway(group: ET.Element, tag: str, cls: str) -> dict[str, ET.Element]:
    return {
        str(e.get("data-hallway")): e
        for e in group.findall(f"svg:{tag}[@class='{cls}']", NS)
        if e.get("data-hallway") is not None
    }


def test_every_hallway_has_its_fill_start_and_arrow(linden: FloorPlan, svg: ET.Element) -> None:
    for floor in linden.floors:
        group, move = _panel(svg, floor.level)
        fills = _by_hallway(group, "polygon", "hallway")
        starts = _by_hallway(group, "circle", "start")
        labels = _by_hallway(group, "text", "start")
        arrows = _by_hallway(group, "polygon", "direction")
        ids = [h.id for h in floor.hallways]
        assert sorted(fills) == sorted(starts) == sorted(labels) == sorted(arrows) == sorted(ids)
        for hallway in floor.hallways:
            # The fill covers the run of the hallway's walls, in its own frame.
            lo, hi, _, _ = floor.extents[hallway.id]
            half = hallway.width_mm / 2
            corners = [hallway.from_local(s, d) for s in (lo, hi) for d in (-half, half)]
            assert _rounded(_plan_points(fills[hallway.id], move)) == _rounded(corners)
            start = starts[hallway.id]
            x0, y0 = hallway.from_local(0, 0)
            tx, ty = move
            assert (float(start.get("cx", "")), float(start.get("cy", ""))) == pytest.approx(
                (x0 + tx, ty - y0), abs=0.5
            )
            assert labels[hallway.id].text == f"{hallway.id}: s = 0"
            tip = _plan_points(arrows[hallway.id], move)[0]
            assert tip == pytest.approx(hallway.from_local(hallway.length_mm - 300, 0), abs=1.0)


def test_an_angle_zone_is_drawn_in_its_own_hallway(linden: FloorPlan, svg: ET.Element) -> None:
    floor = linden.floor(1)
    group, move = _panel(svg, 1)
    for zone_id, hallway_id in (("Z1c", "east"), ("Z1d", "south"), ("Z1a", "main")):
        zone = group.find(f"svg:polygon[@id='zone-{zone_id}']", NS)
        assert zone is not None
        hallway = next(h for h in floor.hallways if h.id == hallway_id)
        local = [hallway.to_local(*p) for p in _plan_points(zone, move)]
        spec = next(z for z in floor.angle_zones if z.id == zone_id)
        assert sorted({round(s) for s, _ in local}) == [spec.from_mm, spec.to_mm]
        assert sorted({round(d) for _, d in local}) == [-hallway.width_mm / 2, hallway.width_mm / 2]


def test_each_label_stands_beside_its_own_hallways_wall(linden: FloorPlan, svg: ET.Element) -> None:
    for floor in linden.floors:
        group, (tx, ty) = _panel(svg, floor.level)
        texts = group.findall("svg:text", NS)
        for door in floor.doors:
            hallway = floor.hallway_of(door)
            sign = 1.0 if door.side == "left" else -1.0
            x, y = hallway.from_local(door.at_mm, sign * (hallway.width_mm / 2 + 700))
            # The text's baseline sits 130 below the point, so the label is centred on it
            # (a room of two doors is labelled at each).
            at = {
                (round(float(t.get("x", "")) - tx), round(ty - float(t.get("y", "")) + 130)): t
                for t in texts
                if t.text == door.room
            }
            label = at.get((round(x), round(y)))
            assert label is not None, (door.id, sorted(at))
            assert label.get("data-hallway") == hallway.id
    # Room 111 is on the east wing's left, so west of it, 700 mm beyond its wall line.
    group, (tx, ty) = _panel(svg, 1)
    label = next(t for t in group.findall("svg:text", NS) if t.text == "111")
    assert float(label.get("x", "")) - tx == pytest.approx(32000 - 800 - 700, abs=1.0)
    assert ty - float(label.get("y", "")) + 130 == pytest.approx(4000, abs=1.0)


def _corners(group: ET.Element, move: tuple[float, float]) -> list[set[tuple[int, int]]]:
    return [
        _rounded(_plan_points(p, move))
        for p in group.findall("svg:polygon[@class='other-floor']", NS)
    ]


def test_the_other_floors_hallways_are_dashed_beneath_as_one_outline(svg: ET.Element) -> None:
    # Floor 1 (an L and a T) under floor 2: one outline round all three hallways, nothing
    # across the mouths where the east and south wings join the main hallway.
    group, move = _panel(svg, 2)
    assert _corners(group, move) == [
        {
            (0, -1000),
            (13200, -1000),
            (13200, -10000),
            (14800, -10000),
            (14800, -1000),
            (32800, -1000),
            (32800, 16000),
            (31200, 16000),
            (31200, 1000),
            (0, 1000),
        }
    ]
    # Floor 2 under floor 1: the step where the hallway goes on narrower, nothing across it.
    group, move = _panel(svg, 1)
    assert _corners(group, move) == [
        {
            (32000, 1000),
            (16000, 1000),
            (16000, 750),
            (0, 750),
            (0, -750),
            (16000, -750),
            (16000, -1000),
            (32000, -1000),
        }
    ]


def test_a_floor_of_one_hallway_marks_its_start_without_an_id(cs_building: FloorPlan) -> None:
    svg = ET.fromstring(render_svg(cs_building))
    for floor in cs_building.floors:
        group, _ = _panel(svg, floor.level)
        (label,) = group.findall("svg:text[@class='start']", NS)
        assert label.text == "s = 0"
        assert len(group.findall("svg:polygon[@class='hallway']", NS)) == 1
        assert len(group.findall("svg:polygon[@class='other-floor']", NS)) == 1


@pytest.mark.parametrize("name", ["l-corner", "t-junction", "width-change"])
def test_the_documentations_example_plans_draw_both_hallways(name: str) -> None:
    """docs/floorplans.md shows these three plans' renders (docs/floorplan-NAME.svg)."""
    plan = load_floorplan(ROOT / "docs" / "floorplans" / f"{name}.toml")
    (floor,) = plan.floors
    assert len(floor.hallways) == 2 and len(floor.meetings) == 1
    group, _ = _panel(ET.fromstring(render_svg(plan)), floor.level)
    assert len(_by_hallway(group, "polygon", "hallway")) == 2
    assert (ROOT / "docs" / f"floorplan-{name}.svg").is_file()
