"""Offline hallway traces and the SVG rendering of floor plans."""

from __future__ import annotations

import argparse
import io
import re
import xml.etree.ElementTree as ET
from pathlib import Path

import numpy as np
import pytest

from coffeebot import cli
from coffeebot.floorplan import FloorPlan
from coffeebot.floorplan_svg import add_render_arguments, render_command, render_svg
from coffeebot.messages import ReadingStatus
from coffeebot.sim.world import RobotSpec, World
from coffeebot.sim.world.trace import hallway_pass, hallway_pose, write_trace_csv

from .conftest import CS_BUILDING


def _pass(plan: FloorPlan, robot: RobotSpec, *, steer: bool) -> tuple[World, list]:
    floor = plan.floor(2)
    world = World(plan, robot, floor=2, pose=hallway_pose(floor, 2000, -400), seed=4)
    return world, hallway_pass(world, speed_mm_s=300, to_s_mm=8000, steer=steer)


def test_pass_shows_the_door_recess_on_the_right_sensors(
    cs_building: FloorPlan, board_robot: RobotSpec
) -> None:
    """Room 202's door (s 5550..6450, recessed 100 mm) on the right, as in seed Figure 3."""
    world, rows = _pass(cs_building, board_robot, steer=True)
    assert world.robot.collisions == []
    assert rows[-1].s_mm >= 8000
    assert np.diff([r.t_s for r in rows]) == pytest.approx(0.1)
    front_right = [
        (r.s_mm + 138.5, r.readings[1]) for r in rows if r.readings[1].status is ReadingStatus.VALID
    ]
    wall = [r.distance_mm for s, r in front_right if 3500 < s < 5300]
    door = [r.distance_mm for s, r in front_right if 5800 < s < 6200]
    assert 90 <= np.median(door) - np.median(wall) <= 110
    assert abs(np.median(wall) - (850 - 400 - 255)) < 15


def test_open_loop_pass_drifts_into_the_wall(
    cs_building: FloorPlan, board_robot: RobotSpec
) -> None:
    world, rows = _pass(cs_building, board_robot, steer=False)
    assert world.robot.collisions and world.robot.collisions[0].element == "hallway right wall"
    assert rows[-1].pose.heading_deg < -3


def test_trace_csv(cs_building: FloorPlan, board_robot: RobotSpec) -> None:
    _, rows = _pass(cs_building, board_robot, steer=True)
    out = io.StringIO()
    write_trace_csv(rows[:3], out)
    lines = out.getvalue().splitlines()
    assert lines[0].startswith("t_s,x_mm,y_mm,heading_deg,s_mm,d_mm,status_0,distance_0_mm")
    assert len(lines) == 4
    assert lines[1].split(",")[6] in {s.value for s in ReadingStatus}


def test_svg_has_every_room_zone_and_anchor(cs_building: FloorPlan) -> None:
    svg = render_svg(cs_building)
    root = ET.fromstring(svg)
    texts = {t.text for t in root.iter("{http://www.w3.org/2000/svg}text")}
    assert set(cs_building.rooms) <= texts
    assert {"Tea room", "elevator", "Floor 2", "Floor 3"} <= texts
    zones = [
        p for p in root.iter("{http://www.w3.org/2000/svg}polygon") if p.get("class") == "zone"
    ]
    assert len(zones) == sum(len(f.angle_zones) for f in cs_building.floors)
    circles = list(root.iter("{http://www.w3.org/2000/svg}circle"))
    anchors = [c for c in circles if c.get("class") == "anchor"]
    assert len(anchors) == sum(len(f.anchors) for f in cs_building.floors)


def _args(*argv: str) -> argparse.Namespace:
    parser = argparse.ArgumentParser()
    add_render_arguments(parser)
    return parser.parse_args(list(argv))


def test_render_command_writes_one_floor(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    out = tmp_path / "floor3.svg"
    assert render_command(_args(str(CS_BUILDING), "-o", str(out), "--floor", "3")) == 0
    assert capsys.readouterr().out == f"{out}: CS Building, floor 3\n"
    text = out.read_text()
    assert 'id="floor-3"' in text and 'id="floor-2"' not in text


def test_render_command_reports_a_bad_plan(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    bad = tmp_path / "bad.toml"
    bad.write_text("[[floors]]\nlevel = 1\n")
    assert render_command(_args(str(bad), "-o", str(tmp_path / "x.svg"))) == 2
    err = capsys.readouterr().err
    assert "bad.toml: floor 1: hallways: Field required" in err


def test_cli_renders_a_floor_plan(tmp_path: Path) -> None:
    out = tmp_path / "plan.svg"
    assert cli.main(["floorplan", "render", str(CS_BUILDING), "-o", str(out)]) == 0
    assert ET.fromstring(out.read_text()).tag == "{http://www.w3.org/2000/svg}svg"


def test_each_floor_has_a_frame_that_maps_plan_mm_into_the_picture(cs_building: FloorPlan) -> None:
    svg = ET.fromstring(render_svg(cs_building))
    ns = {"svg": "http://www.w3.org/2000/svg"}
    for floor in cs_building.floors:
        group = svg.find(f".//svg:g[@id='floor-{floor.level}']", ns)
        assert group is not None
        frame = group.find(f"svg:g[@id='frame-{floor.level}']", ns)
        assert frame is not None
        # The frame's transform puts a plan point where the drawing put the hallway's corner.
        hallway = group.find("svg:polygon[@class='hallway']", ns)
        assert hallway is not None
        corner = [float(v) for v in hallway.get("points", "").split()[0].split(",")]
        tx, ty = (
            float(v)
            for v in re.match(
                r"translate\(([-\d.e]+) ([-\d.e]+)\)", frame.get("transform", "")
            ).groups()  # type: ignore[union-attr]
        )
        assert "scale(1 -1)" in frame.get("transform", "")
        x, y = floor.from_hallway(0, -floor.hallway.width_mm / 2)
        assert (x + tx, ty - y) == pytest.approx(corner, abs=0.5)


def _translate(group: ET.Element) -> tuple[float, float]:
    found = re.match(r"translate\(([-\d.e]+) ([-\d.e]+)\)", group.get("transform", ""))
    assert found is not None
    return float(found.group(1)), float(found.group(2))


def test_floors_share_one_frame_with_the_shaft_and_each_hallways_way_marked(
    cs_building: FloorPlan,
) -> None:
    svg = ET.fromstring(render_svg(cs_building))
    ns = {"svg": "http://www.w3.org/2000/svg"}
    frames = {
        f.level: _translate(svg.find(f".//svg:g[@id='frame-{f.level}']", ns))  # type: ignore[arg-type]
        for f in cs_building.floors
    }
    # One frame: the same x offset on every floor, and each floor's hallway drawn dashed in
    # the other's panel exactly where it is in its own, but for the panels' offset.
    assert len({tx for tx, _ in frames.values()}) == 1

    def points(polygon: ET.Element | None) -> list[float]:
        assert polygon is not None
        return [float(v) for p in polygon.get("points", "").split() for v in p.split(",")]

    (low, _), (high, _) = sorted(frames.items(), key=lambda kv: kv[0])[:2]
    own = points(svg.find(f".//svg:g[@id='floor-{high}']/svg:polygon[@class='hallway']", ns))
    seen = points(svg.find(f".//svg:g[@id='floor-{low}']/svg:polygon[@class='other-floor']", ns))
    offset = frames[high][1] - frames[low][1]
    shifted = [v + offset if k % 2 else v for k, v in enumerate(seen)]
    assert shifted == pytest.approx(own, abs=1.0)
    shaft = svg.find("svg:line[@class='shaft']", ns)
    assert shaft is not None
    for floor in cs_building.floors:
        group = svg.find(f".//svg:g[@id='floor-{floor.level}']", ns)
        assert group is not None
        # The other floors' hallways drawn beneath this one's.
        assert len(group.findall("svg:polygon[@class='other-floor']", ns)) == 1
        # The car's door on the shaft line (the loader holds the floors' cars together).
        car = group.find("svg:rect[@class='car']", ns)
        assert car is not None
        centre = float(car.get("x", "")) + float(car.get("width", "")) / 2
        assert centre == pytest.approx(float(shaft.get("x1", "")), abs=100)
        # Where the hallway starts, and which way it runs: the arrow's tip at its far end.
        tx, ty = frames[floor.level]
        start = group.find("svg:circle[@class='start']", ns)
        assert start is not None
        x0, y0 = floor.from_hallway(0, 0)
        assert (float(start.get("cx", "")), float(start.get("cy", ""))) == pytest.approx(
            (x0 + tx, ty - y0), abs=0.5
        )
        arrow = group.find("svg:polygon[@class='direction']", ns)
        assert arrow is not None
        tip = [float(v) for v in arrow.get("points", "").split()[0].split(",")]
        x1, y1 = floor.from_hallway(floor.hallway.length_mm - 300, 0)
        assert tip == pytest.approx([x1 + tx, ty - y1], abs=0.5)
