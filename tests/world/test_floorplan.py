"""Floor plan loading, the shipped CS building, geometry queries and validation errors."""

from __future__ import annotations

import math
from collections.abc import Callable
from pathlib import Path
from typing import Any

import numpy as np
import pytest

from coffeebot.cameras.geometry import nominal_homography, project
from coffeebot.cli import main
from coffeebot.floorplan import (
    Camera,
    FloorPlan,
    FloorPlanError,
    PlanWarning,
    load_floorplan,
    parse_floorplan,
    plan_warnings,
)

from .conftest import CS_BUILDING, EXAMPLE


def test_cs_building_has_the_seed_rooms(cs_building: FloorPlan) -> None:
    floor2, floor3 = cs_building.floor(2), cs_building.floor(3)
    assert [r for r in cs_building.rooms if r.startswith("2")] == [str(n) for n in range(201, 214)]
    assert [r for r in cs_building.rooms if r.startswith("3")] == [str(n) for n in range(302, 314)]
    assert floor2.hallway.width_mm == floor3.hallway.width_mm == 1700
    assert all(d.recess_mm == 100 for d in floor2.doors if d.kind == "office")
    assert cs_building.tea_room.floor.level == 2


def test_elevator_is_beside_213_and_313_on_both_floors(cs_building: FloorPlan) -> None:
    for level, neighbour in ((2, "213"), (3, "313")):
        floor = cs_building.floor(level)
        elevator = floor.elevator
        assert elevator is not None
        left = floor.features("left")
        assert left[left.index(elevator) - 1].id == neighbour
    e2, e3 = cs_building.floor(2).elevator, cs_building.floor(3).elevator
    assert e2 is not None and e3 is not None
    assert (e2.at_mm, e2.side) == (e3.at_mm, e3.side)


def test_no_wall_crosses_the_hallway(cs_building: FloorPlan) -> None:
    """Every generated segment stays on or behind a wall line, except the two end walls."""
    for floor in cs_building.floors:
        for seg in floor.segments:
            if seg.element.startswith("hallway") and seg.element.endswith(
                ("start wall", "end wall")
            ):
                continue
            for x, y in ((seg.x0, seg.y0), (seg.x1, seg.y1)):
                _, d = floor.to_hallway(x, y)
                assert abs(d) >= 850 - 1e-6, seg


def test_angle_zones_have_an_unbroken_wall_on_one_side(cs_building: FloorPlan) -> None:
    """The seed's red zones avoid doors: with the side sensors 277 mm apart and the cone
    spreading ~200 mm at 850 mm, one side must be plain wall 400 mm beyond the zone."""
    for floor in cs_building.floors:
        for zone in floor.angle_zones:
            lo, hi = zone.from_mm - 400, zone.to_mm + 400
            clear = [
                side
                for side in ("left", "right")
                if all(f.span[1] < lo or f.span[0] > hi for f in floor.features(side))
            ]
            assert clear, f"floor {floor.level} zone {zone.id}"


def test_hallway_frame_round_trip_on_a_diagonal_hallway(
    plan_dict: Callable[..., dict[str, Any]],
) -> None:
    floor = parse_floorplan(plan_dict(start=[1000, 1000], end=[8071.07, 8071.07])).floors[0]
    assert floor.hallway.heading_deg == pytest.approx(45.0)
    x, y = floor.from_hallway(2000, 300)
    assert floor.to_hallway(x, y) == pytest.approx((2000, 300))
    assert (x, y) == pytest.approx(
        (
            1000 + 2000 * math.sqrt(0.5) - 300 * math.sqrt(0.5),
            1000 + 2000 * math.sqrt(0.5) + 300 * math.sqrt(0.5),
        )
    )


def test_queries(tiny_plan: FloorPlan) -> None:
    floor = tiny_plan.floors[0]
    door = floor.feature_at(5300, "right")
    assert door is not None and door.id == "101"
    assert floor.feature_at(5300, "left") is None
    assert floor.feature_at(5500, "right", margin_mm=60) is door
    nearest = floor.nearest_door(6900)
    assert nearest is not None and nearest.room == "Tea"
    assert tiny_plan.find_room("101").door is door
    near = {s.element for s in floor.walls_near(4700, -750, 250)}
    assert near == {"hallway right wall", "door 101 jamb", "door 101"}


def test_angle_zone_lookup(cs_building: FloorPlan) -> None:
    floor = cs_building.floor(2)
    zone = floor.angle_zone_at(4500, -300)
    assert zone is not None and zone.id == "Z2a"
    assert floor.angle_zone_at(4500, -900) is None  # inside the wall, not the hallway
    assert floor.angle_zone_at(7000, 0) is None


def test_door_geometry_is_recessed(tiny_plan: FloorPlan) -> None:
    floor = tiny_plan.floors[0]
    leaf = next(s for s in floor.segments if s.element == "door 101")
    assert (leaf.y0, leaf.y1) == (-950, -950)
    assert sorted((leaf.x0, leaf.x1)) == [4550, 5450]
    assert leaf.z_top == 2100


def test_example_plan_loads() -> None:
    plan = load_floorplan(EXAMPLE)
    assert plan.rooms == ["101", "102"]
    assert plan.tea_room.door.room == "Kitchen"


# --- errors name the file, the element and the problem -------------------------------------


def _error(raw: dict[str, Any]) -> FloorPlanError:
    with pytest.raises(FloorPlanError) as info:
        parse_floorplan(raw, "plans/bad.toml")
    assert isinstance(info.value, ValueError)
    return info.value


def test_error_names_the_door_and_field(plan_dict: Callable[..., dict[str, Any]]) -> None:
    raw = plan_dict()
    raw["floors"][0]["doors"][0]["width_mm"] = -5
    error = _error(raw)
    assert error.element == "floor 1 / door 101"
    assert str(error).startswith("plans/bad.toml: floor 1 / door 101: width_mm:")


def test_error_for_unknown_field(plan_dict: Callable[..., dict[str, Any]]) -> None:
    raw = plan_dict()
    raw["floors"][0]["anchors"][1]["height"] = 3
    error = _error(raw)
    assert error.element == "floor 1 / anchor 0A02"
    assert "height" in error.problem


@pytest.mark.parametrize(
    ("change", "element", "problem"),
    [
        (lambda f: f["doors"][0].update(at_mm=9800), "floor 1 / door 101", "outside the hallway"),
        (
            lambda f: f["doors"].append({"room": "102", "side": "right", "at_mm": 5500}),
            "floor 1 / door 102",
            "overlaps 101",
        ),
        (
            lambda f: f["anchors"].append({"id": "0A01", "x_mm": 0, "y_mm": 0}),
            "floor 1 / anchor 0A01",
            "duplicate id",
        ),
        (
            lambda f: f["anchors"].append({"id": "A4", "x_mm": 0, "y_mm": 0}),
            "floor 1 / anchor A4",
            "should match pattern",
        ),
        (
            lambda f: f.setdefault("angle_zones", []).append(
                {"id": "Z", "from_mm": 9000, "to_mm": 12000}
            ),
            "floor 1 / angle zone Z",
            "outside the hallway",
        ),
        (lambda f: f["doors"].pop(), "floor plan", "tea_room"),
    ],
)
def test_consistency_errors(
    plan_dict: Callable[..., dict[str, Any]],
    change: Callable[[dict[str, Any]], None],
    element: str,
    problem: str,
) -> None:
    raw = plan_dict()
    change(raw["floors"][0])
    error = _error(raw)
    assert error.element == element
    assert problem in error.problem


def test_zone_must_be_ordered(plan_dict: Callable[..., dict[str, Any]]) -> None:
    raw = plan_dict()
    raw["floors"][0]["angle_zones"] = [{"id": "Z9", "from_mm": 3000, "to_mm": 2000}]
    error = _error(raw)
    assert error.element == "floor 1 / angle zone Z9"
    assert "greater than from_mm" in error.problem


def test_several_floors_need_an_elevator(plan_dict: Callable[..., dict[str, Any]]) -> None:
    raw = plan_dict()
    second = {"level": 2, "hallways": [{"id": "main", "start": [0, 0], "end": [5000, 0]}]}
    raw["floors"].append(second)
    assert _error(raw).element == "floor 1"


def test_file_errors_name_the_file(tmp_path: Path) -> None:
    bad = tmp_path / "broken.toml"
    bad.write_text("name = 'x'\n[[floors]\n")
    with pytest.raises(FloorPlanError, match=r"broken\.toml: file: not valid TOML"):
        load_floorplan(bad)
    with pytest.raises(FloorPlanError, match=r"missing\.toml: file"):
        load_floorplan(tmp_path / "missing.toml")


def test_shipped_file_path_is_in_errors(tmp_path: Path) -> None:
    text = CS_BUILDING.read_text().replace('room = "205"', 'room = "203"', 1)
    copy = tmp_path / "cs.toml"
    copy.write_text(text)
    with pytest.raises(FloorPlanError, match=r"cs\.toml: floor 2 / door 203: duplicate id"):
        load_floorplan(copy)


def test_a_number_written_as_a_string_is_refused(
    plan_dict: Callable[..., dict[str, Any]],
) -> None:
    """Lax pydantic would read "5000" as 5000; integers still pass for millimetres."""
    raw = plan_dict()
    raw["floors"][0]["doors"][0]["at_mm"] = "5000"
    error = _error(raw)
    assert error.element == "floor 1 / door 101"
    assert error.problem == "at_mm: a number was expected, not the string '5000'"


def test_an_angle_zone_over_doors_on_both_sides_is_refused(
    plan_dict: Callable[..., dict[str, Any]],
) -> None:
    """Door 101 (right, 4550..5450) and the tea room (left, 7550..8450) both lie in it."""
    raw = plan_dict()
    raw["floors"][0]["angle_zones"] = [{"id": "Z1", "from_mm": 5000, "to_mm": 7800}]
    error = _error(raw)
    assert error.element == "floor 1 / angle zone Z1"
    assert error.problem.startswith("from_mm, to_mm: lies over Tea on the left and 101 on the")


def test_an_anchor_far_outside_the_building_is_refused(
    plan_dict: Callable[..., dict[str, Any]],
) -> None:
    """A digit too many: 50 m along a 10 m hallway."""
    raw = plan_dict()
    raw["floors"][0]["anchors"][2]["x_mm"] = 50000
    error = _error(raw)
    assert error.element == "floor 1 / anchor 0A03"
    assert error.problem.startswith("x_mm: 50000 lies 40000 mm outside the floor's hallway")


def _two_floors(plan_dict: Callable[..., dict[str, Any]]) -> dict[str, Any]:
    """The tiny plan with an elevator on the left at s = 2000 mm, and a second floor above."""
    raw = plan_dict()
    first = raw["floors"][0]
    elevator = {"id": "E", "room": "elevator", "kind": "elevator", "side": "left", "at_mm": 2000}
    first["doors"].append(elevator)
    second = {"level": 2, "hallways": [dict(first["hallways"][0])], "doors": [dict(elevator)]}
    raw["floors"].append(second)
    return raw


def test_two_floors_with_one_elevator_load(plan_dict: Callable[..., dict[str, Any]]) -> None:
    plan = parse_floorplan(_two_floors(plan_dict))
    assert [f.elevator.id for f in plan.floors if f.elevator is not None] == ["E", "E"]


@pytest.mark.parametrize(
    ("change", "problem"),
    [
        ({"at_mm": 2300}, "at_mm: the elevator door is 300 mm from E on floor 1"),
        ({"side": "right"}, "side: the elevator opens on the right side"),
    ],
)
def test_an_elevator_car_misplaced_between_floors_is_refused(
    plan_dict: Callable[..., dict[str, Any]], change: dict[str, Any], problem: str
) -> None:
    raw = _two_floors(plan_dict)
    raw["floors"][1]["doors"][0].update(change)
    error = _error(raw)
    assert error.element == "floor 2 / door E"
    assert error.problem.startswith(problem)


def test_an_elevator_on_a_hallway_surveyed_the_other_way_is_the_same_car(
    plan_dict: Callable[..., dict[str, Any]],
) -> None:
    """Floor 2's hallway runs from x 10000 to 0: the same door is on its right, 8000 mm in."""
    raw = _two_floors(plan_dict)
    raw["floors"][1]["hallways"][0].update(start=[10000, 0], end=[0, 0])
    raw["floors"][1]["doors"][0].update(side="right", at_mm=8000)
    assert parse_floorplan(raw).floor(2).elevator is not None


# --- ceiling cameras ------------------------------------------------------------------------


def _with_camera(plan_dict: Callable[..., dict[str, Any]]) -> dict[str, Any]:
    """The tiny plan with camera "c1" over its hallway at s = 5000 mm, 2600 mm up with a
    90-degree lens (5.2 x 3.9 m of floor), and six marks in the hallway (no three in a line)
    at the pixels its nominal model gives them."""
    raw = plan_dict()
    camera = Camera(id="c1", x_mm=5000.0, y_mm=0.0, height_mm=2600.0, fov_deg=90.0)
    points = [(2700.0, 700.0), (2700.0, -700.0), (4300.0, -250.0), (5700.0, 350.0)]
    points += [(7300.0, 700.0), (7300.0, -700.0)]
    pixels = project(nominal_homography(camera), np.array(points))
    marks = [
        {"x_mm": x, "y_mm": y, "u_px": round(float(u), 1), "v_px": round(float(v), 1)}
        for (x, y), (u, v) in zip(points, pixels, strict=True)
    ]
    raw["floors"][0]["cameras"] = [
        {"id": "c1", "x_mm": 5000, "y_mm": 0, "height_mm": 2600, "fov_deg": 90, "marks": marks}
    ]
    return raw


def test_a_calibrated_camera_loads(plan_dict: Callable[..., dict[str, Any]]) -> None:
    camera = parse_floorplan(_with_camera(plan_dict)).floors[0].cameras[0]
    assert (camera.id, camera.width_px, camera.height_px, len(camera.marks)) == ("c1", 320, 240, 6)


def _set_mark(index: int, **fields: Any) -> Callable[[dict[str, Any]], None]:
    return lambda camera: camera["marks"][index].update(fields)


@pytest.mark.parametrize(
    ("change", "element", "problem"),
    [
        (
            lambda camera: camera.update(x_mm=50000),
            "floor 1 / camera c1",
            "x_mm: 50000 lies outside the floor's hallway and rooms (0..10000 mm)",
        ),
        (
            lambda camera: camera.update(height_mm="2600"),
            "floor 1 / camera c1",
            "height_mm: a number was expected, not the string '2600'",
        ),
        (
            _set_mark(1, u_px=-3),
            "floor 1 / camera c1 / mark #2",
            "u_px: Input should be greater than or equal to 0",
        ),
        (
            _set_mark(1, v_px=250.0),
            "floor 1 / camera c1 / mark #2",
            "u_px, v_px: (18.5, 250.0) lies outside the camera's 320 x 240 image",
        ),
        (
            lambda camera: camera.update(marks=camera["marks"][:3]),
            "floor 1 / camera c1",
            "marks: 3 given, a calibration needs at least 4",
        ),
        (
            _set_mark(2, x_mm=5300),
            "floor 1 / camera c1",
            "mark #3 mismeasured or mistyped, the others agree without it",
        ),
        (
            lambda camera: camera.update(yaw_deg=90),
            "floor 1 / camera c1",
            "marks: put the image's top-left corner",
        ),
    ],
    ids=[
        "off the floor",
        "string",
        "negative pixel",
        "outside the image",
        "three marks",
        "mistyped mark",
        "mistyped yaw",
    ],
)
def test_camera_errors(
    plan_dict: Callable[..., dict[str, Any]],
    change: Callable[[dict[str, Any]], None],
    element: str,
    problem: str,
) -> None:
    raw = _with_camera(plan_dict)
    change(raw["floors"][0]["cameras"][0])
    error = _error(raw)
    assert error.element == element
    assert problem in error.problem
    assert "\n" not in str(error)


def test_camera_ids_are_unique_in_the_building(plan_dict: Callable[..., dict[str, Any]]) -> None:
    """Two floors, one car: the same camera over the same place on floor 2 keeps its id."""
    raw = _two_floors(plan_dict)
    raw["floors"][0]["cameras"] = _with_camera(plan_dict)["floors"][0]["cameras"]
    raw["floors"][1]["cameras"] = _with_camera(plan_dict)["floors"][0]["cameras"]
    error = _error(raw)
    assert error.element == "floor 2 / camera c1"
    assert error.problem == (
        "duplicate id: floor 1 has a camera 'c1' too (camera ids are unique in the building)"
    )
    raw["floors"][1]["cameras"][0]["id"] = "c2"
    assert [c.id for f in parse_floorplan(raw).floors for c in f.cameras] == ["c1", "c2"]


def test_a_mistyped_mark_in_the_shipped_file_names_the_file_floor_and_camera(
    tmp_path: Path,
) -> None:
    text = CS_BUILDING.read_text()
    mark = "{ x_mm = 39700, y_mm = 700,"
    assert mark in text
    copy = tmp_path / "cs.toml"
    copy.write_text(text.replace(mark, "{ x_mm = 38700, y_mm = 700,", 1))
    with pytest.raises(
        FloorPlanError,
        match=r"^\S*cs\.toml: floor 2 / camera lobby-2: marks: reprojection error \d+\.\d px RMS "
        r"\(at most 1\.5\): mark #1 mismeasured or mistyped, the others agree without it$",
    ):
        load_floorplan(copy)


# --- warnings: what a valid plan leaves the robot to do poorly ------------------------------


def test_a_stretch_with_fewer_than_three_anchors_in_range_is_a_warning(
    plan_dict: Callable[..., dict[str, Any]],
) -> None:
    """Anchors at s 0, 5000 and 10000, 2.4 m up: with a 6 m range only s 4559..5441 mm has
    all three in range (sampled every 100 mm)."""
    plan = parse_floorplan(plan_dict())
    assert plan_warnings(plan, uwb_range_mm=25_000, min_recess_mm=100) == []
    warnings = plan_warnings(plan, uwb_range_mm=6_000, min_recess_mm=100)
    assert [w.element for w in warnings] == ["floor 1 / hallway"] * 2
    assert warnings[0].problem.startswith("0..4500 mm along it has 2 UWB anchors within 6000 mm")
    assert warnings[1].problem.startswith("5500..10000 mm along it has 2 UWB anchors")


def test_a_door_too_shallow_for_the_detector_is_a_warning(
    plan_dict: Callable[..., dict[str, Any]],
) -> None:
    raw = plan_dict()
    raw["floors"][0]["doors"][0]["recess_mm"] = 60
    warnings = plan_warnings(parse_floorplan(raw), uwb_range_mm=25_000, min_recess_mm=100)
    assert warnings == [
        PlanWarning(
            "floor 1 / door 101",
            "recess_mm: 60 mm is shallower than the door detector sees (100 mm): the robot "
            "will not see this door and relies on UWB and odometry there",
        )
    ]


def test_the_plan_check_prints_the_warnings_without_a_recording(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """The board's door detector (jump_mm 80) needs about 100 mm; the example's 102 has 80."""
    assert main(["floorplan", "check", "--floorplan", str(EXAMPLE)]) == 0
    err = capsys.readouterr().err.strip().splitlines()
    assert err == [
        f"warning: {EXAMPLE}: floor 1 / door 102: recess_mm: 80 mm is shallower than the door "
        "detector sees (100 mm): the robot will not see this door and relies on UWB and "
        "odometry there"
    ]
    assert main(["floorplan", "check", "--floorplan", str(CS_BUILDING)]) == 0
    assert capsys.readouterr().err == ""


def test_a_camera_whose_calibration_nothing_checks_is_a_warning(
    plan_dict: Callable[..., dict[str, Any]],
) -> None:
    """Without marks its pose alone places what it sees; four marks fit any homography."""
    raw = _with_camera(plan_dict)
    camera = raw["floors"][0]["cameras"][0]
    second = {**camera, "id": "c2", "marks": []}
    camera["marks"] = [camera["marks"][i] for i in (0, 1, 4, 5)]
    raw["floors"][0]["cameras"].append(second)
    warnings = plan_warnings(parse_floorplan(raw), uwb_range_mm=25_000, min_recess_mm=100)
    assert [(w.element, w.problem.split(",")[0]) for w in warnings] == [
        ("floor 1 / camera c1", "marks: 4"),
        ("floor 1 / camera c2", "marks: none"),
    ]


def test_a_rooms_doors_on_two_floors_are_refused(
    plan_dict: Callable[..., dict[str, Any]],
) -> None:
    raw = _two_floors(plan_dict)
    raw["floors"][1]["doors"].append({"room": "101", "side": "right", "at_mm": 5000})
    error = _error(raw)
    assert error.element == "floor 2 / door 101"
    assert error.problem.startswith("room: '101' has a door on floor 1 too")
