"""Floors of several hallways: where they meet (an L, a T, a change of width), the walls that
follows from that, each hallway's own frame, and a surveyor's mistakes refused."""

from __future__ import annotations

import math
from typing import Any

import pytest

from coffeebot.floorplan import Floor, FloorPlanError, Junction, parse_floorplan


def _floor(hallways: list[dict[str, Any]], doors: list[dict[str, Any]] | None = None) -> Floor:
    tea = {"room": "Tea", "kind": "tea_room", "side": "left", "at_mm": 3000, "hallway": "A"}
    plan = parse_floorplan(
        {"floors": [{"level": 1, "hallways": hallways, "doors": [tea, *(doors or [])]}]}
    )
    return plan.floors[0]


def _error(hallways: list[dict[str, Any]], doors: list[dict[str, Any]] | None = None) -> str:
    with pytest.raises(FloorPlanError) as caught:
        _floor(hallways, doors)
    return str(caught.value)


A = {"id": "A", "start": [0, 0], "end": [20000, 0], "width_mm": 1700}
"""20 m along +x."""
L_NORTH = {"id": "B", "start": [20000, 0], "end": [20000, 15000], "width_mm": 1500}
"""From A's far end to the north: an L, turning left."""
T_SOUTH = {"id": "C", "start": [10000, 0], "end": [10000, -8000], "width_mm": 1500}
"""From the middle of A to the south: a T, on A's right."""


def _hit(floor: Floor, x: float, y: float, heading_deg: float) -> tuple[float, str]:
    """How far a ray from (x, y) runs before a wall, and which."""
    dx, dy = math.cos(math.radians(heading_deg)), math.sin(math.radians(heading_deg))
    best = (math.inf, "")
    for seg in floor.segments:
        ex, ey = seg.x1 - seg.x0, seg.y1 - seg.y0
        denom = dx * ey - dy * ex
        if abs(denom) < 1e-12:
            continue
        t = ((seg.x0 - x) * ey - (seg.y0 - y) * ex) / denom
        u = ((seg.x0 - x) * dy - (seg.y0 - y) * dx) / denom
        if t > 0 and -1e-9 <= u <= 1 + 1e-9 and t < best[0]:
            best = (t, seg.element)
    return best


def test_an_l_is_walled_round_its_corner() -> None:
    floor = _floor([A, L_NORTH])
    (meeting,) = floor.meetings
    assert (meeting.through.id, meeting.joining.id, meeting.side) == ("A", "B", "left")
    assert floor.extents["A"].hi_mm == 20750  # over the corner, to B's far wall
    assert floor.extents["B"].lo_mm == 850  # B's walls start at A's wall line
    # From the corner's middle: A's end wall east, A's right wall south, up B to the north.
    assert _hit(floor, 20000, 0, 0) == (pytest.approx(750), "hallway A end wall")
    assert _hit(floor, 20000, 0, -90) == (pytest.approx(850), "hallway A right wall")
    assert _hit(floor, 20000, 0, 90) == (pytest.approx(15000), "hallway B end wall")
    # In B, its walls either side; in A short of the corner, A's left wall.
    assert _hit(floor, 20000, 5000, 180) == (pytest.approx(750), "hallway B left wall")
    assert _hit(floor, 20000, 5000, 0) == (pytest.approx(750), "hallway B right wall")
    assert _hit(floor, 18000, 0, 90) == (pytest.approx(850), "hallway A left wall")
    # Nothing leaks: from anywhere inside, every direction meets a wall within 21 m.
    for x, y in ((20000, 0), (19300, 800), (20700, 14000), (500, 0)):
        for heading in range(0, 360, 15):
            assert _hit(floor, x, y, heading)[0] < 21000, (x, y, heading)


def test_a_t_opens_the_wall_it_joins() -> None:
    floor = _floor([A, T_SOUTH])
    (junction,) = floor.junctions
    assert isinstance(junction, Junction)
    assert (junction.hallway, junction.side, junction.at_mm, junction.width_mm) == (
        "A",
        "right",
        10000,
        1500,
    )
    assert floor.feature_at(10000, "right") == junction
    assert _hit(floor, 10000, 0, -90) == (pytest.approx(8000), "hallway C end wall")
    assert _hit(floor, 10000, 0, 90) == (pytest.approx(850), "hallway A left wall")
    assert _hit(floor, 10000, -3000, 0) == (pytest.approx(750), "hallway C left wall")


def test_a_hallway_going_on_narrower_steps_its_walls_in() -> None:
    narrower = {"id": "N", "start": [20000, 0], "end": [30000, 0], "width_mm": 1300}
    floor = _floor([A, narrower])
    (meeting,) = floor.meetings
    assert meeting.side is None and not floor.junctions
    assert floor.extents["A"].end_open and floor.extents["N"].start_open
    assert _hit(floor, 25000, 0, 90) == (pytest.approx(650), "hallway N left wall")
    assert _hit(floor, 19000, 800, 0) == (pytest.approx(1000), "hallway A step")
    assert _hit(floor, 15000, 0, 0) == (pytest.approx(15000), "hallway N end wall")


def test_each_hallway_answers_in_its_own_frame() -> None:
    office = {"room": "B1", "side": "right", "at_mm": 5000, "hallway": "B"}
    floor = _floor([A, L_NORTH], [office])
    b = floor.view("B")
    assert b.hallway.id == "B" and floor.hallway.id == "A"
    assert b.to_hallway(20000, 5000) == pytest.approx((5000, 0))
    assert [f.id for f in b.features()] == ["B1"]
    assert [f.id for f in floor.features()] == ["Tea", "B"]  # the tea room, B's mouth
    assert b.nearest_door(4000).id == "B1"  # type: ignore[union-attr]
    assert floor.nearest_door(4000).id == "Tea"  # type: ignore[union-attr]
    # A door is behind its own hallway's wall, whichever view is asked.
    assert floor.behind_door(office_door := b.door("B1"), 100) == pytest.approx((20850, 5000))
    assert b.behind_door(office_door, 100) == pytest.approx((20850, 5000))
    assert floor.view_near(20000, 5000).hallway.id == "B"
    assert floor.view_near(20000, 0).hallway.id == "A"  # the corner: A's axis is nearer
    assert floor.view_near(21200, 5000).hallway.id == "B"  # in B1, behind its door
    assert b.segment_array is floor.segment_array  # the views share the walls


def test_a_plan_of_the_old_single_hallway_names_the_change() -> None:
    with pytest.raises(FloorPlanError) as caught:
        parse_floorplan({"floors": [{"level": 1, "hallway": {"start": [0, 0], "end": [1, 0]}}]})
    assert str(caught.value) == (
        "<floor plan>: floor 1: [floors.hallway] is now [[floors.hallways]] with an id (a "
        'floor may have several): write [[floors.hallways]] and id = "main" above its start'
    )


@pytest.mark.parametrize(
    ("hallways", "doors", "problem"),
    [
        (
            [A, L_NORTH],
            [{"room": "B1", "side": "right", "at_mm": 5000}],
            "floor 1 / door B1: hallway: the floor has several (A, B): say which",
        ),
        (
            [A, L_NORTH],
            [{"room": "B1", "side": "right", "at_mm": 5000, "hallway": "Z"}],
            "floor 1 / door B1: hallway: no hallway 'Z' (A, B)",
        ),
        (
            [A, {**L_NORTH, "end": [30000, 10000]}],
            [],
            "floor 1 / hallway B: meets hallway A at 45 degrees: hallways meet at right angles "
            "or go straight on",
        ),
        (
            [A, {**T_SOUTH, "start": [10000, -500]}],
            [],
            "floor 1 / hallway C: ends inside hallway A, 500 mm off its axis",
        ),
        (
            [A, T_SOUTH],
            [{"room": "A9", "side": "right", "at_mm": 10500, "hallway": "A"}],
            "floor 1 / door A9: overlaps C on the right side of hallway A",
        ),
        (
            [A, {**A, "id": "A"}],
            [],
            "floor 1 / hallway A: duplicate id",
        ),
    ],
)
def test_a_surveyors_mistakes_with_hallways_are_refused(
    hallways: list[dict[str, Any]], doors: list[dict[str, Any]], problem: str
) -> None:
    assert problem in _error(hallways, doors)


def test_a_crossroads_is_two_side_hallways_of_the_one_they_cross() -> None:
    """North and south leave A at one point: each meets A, not each other."""
    north = {"id": "N", "start": [10000, 0], "end": [10000, 6000], "width_mm": 1500}
    floor = _floor([A, north, T_SOUTH])
    assert sorted((m.through.id, m.joining.id, m.side) for m in floor.meetings) == [
        ("A", "C", "right"),
        ("A", "N", "left"),
    ]
    assert _hit(floor, 10000, 0, 90) == (pytest.approx(6000), "hallway N end wall")
    assert _hit(floor, 10000, 0, -90) == (pytest.approx(8000), "hallway C end wall")


def test_a_hallway_through_the_middle_of_another_is_refused() -> None:
    through = {"id": "X", "start": [10000, -5000], "end": [10000, 5000], "width_mm": 1500}
    assert "floor 1 / hallway X: crosses hallway A 10000 mm along it" in _error([A, through])


def test_a_side_hallway_stopped_at_the_wall_line_is_refused() -> None:
    """Its axis ends 850 mm off A's: walled off from A, it would meet nothing."""
    at_the_wall = {**T_SOUTH, "start": [10000, -850]}
    assert "floor 1 / hallway C: ends inside hallway A, 850 mm off its axis" in _error(
        [A, at_the_wall]
    )


def test_a_room_may_have_two_doors_on_one_floor() -> None:
    doors = [
        {"room": "B1", "side": "right", "at_mm": 5000, "hallway": "B"},
        {"id": "B1-side", "room": "B1", "side": "right", "at_mm": 18000, "hallway": "A"},
    ]
    floor = _floor([A, L_NORTH], doors)
    plan = parse_floorplan({"floors": [floor.model_dump(exclude_defaults=True) | {"level": 1}]})
    assert [loc.door.id for loc in plan.room_doors("B1")] == ["B1", "B1-side"]
    assert plan.rooms == ["B1"] and plan.find_room("B1").door.id == "B1"


@pytest.mark.parametrize(
    ("second", "problem"),
    [
        ({"kind": "other"}, "kind: 'other', but 'B1''s door B1 is 'office'"),
    ],
)
def test_a_rooms_doors_are_of_one_kind(second: dict[str, Any], problem: str) -> None:
    doors = [
        {"room": "B1", "side": "right", "at_mm": 5000, "hallway": "B"},
        {"id": "B1-side", "room": "B1", "side": "right", "at_mm": 18000, "hallway": "A", **second},
    ]
    assert problem in _error([A, L_NORTH], doors)


def _with_frames(frames: list[dict[str, Any]], doors: list[dict[str, Any]] | None = None) -> Any:
    tea = {"room": "Tea", "kind": "tea_room", "side": "left", "at_mm": 3000}
    return {
        "floors": [
            {
                "level": 1,
                "hallways": [A],
                "doors": [tea, *(doors or [])],
                "frames": frames,
                "angle_zones": [{"id": "Z", "from_mm": 15000, "to_mm": 16000}],
            }
        ]
    }


def test_a_fire_door_across_a_hallway_narrows_it_at_its_frame() -> None:
    fire_door = {"id": "F", "kind": "fire_door", "at_mm": 9000, "clear_width_mm": 1300}
    floor = parse_floorplan(_with_frames([fire_door])).floors[0]
    assert [f.id for f in floor.frames_along()] == ["F"]
    # Across the frame the jambs stand 650 mm from the axis; beside the folded leaves the
    # walls are 60 mm nearer; beyond them, the hallway's own walls.
    assert _hit(floor, 9000, 0, 90) == (pytest.approx(650), "frame F jamb")
    assert _hit(floor, 9300, 0, -90) == (pytest.approx(790), "fire door F leaf")
    assert _hit(floor, 9800, 0, 90) == (pytest.approx(850), "hallway left wall")


@pytest.mark.parametrize(
    ("frame", "doors", "problem"),
    [
        (
            {"clear_width_mm": 1800},
            [],
            "floor 1 / frame F: clear_width_mm: 1800 is not narrower than the hallway",
        ),
        (
            {},
            [{"room": "101", "side": "right", "at_mm": 9200}],
            "floor 1 / frame F: at_mm: stands across 101's doorway",
        ),
        ({"at_mm": 15500}, [], "floor 1 / angle zone Z: from_mm, to_mm: lies over frame F"),
        ({"at_mm": 19990}, [], "floor 1 / frame F: spans 19915..20065 mm, outside the hallway"),
    ],
)
def test_a_frame_a_surveyor_got_wrong_is_refused(
    frame: dict[str, Any], doors: list[dict[str, Any]], problem: str
) -> None:
    plain = {"id": "F", "at_mm": 9000, "clear_width_mm": 1300, **frame}
    with pytest.raises(FloorPlanError) as caught:
        parse_floorplan(_with_frames([plain], doors))
    assert problem in str(caught.value)


def test_elevator_doors_at_one_place_on_two_floors_are_one_car() -> None:
    """Two cars: one at A's 5000 mm, one at its 15000 mm, on both floors (the second floor's
    hallway surveyed the other way, so the doors are on its other side)."""
    back = {"id": "A", "start": [20000, 0], "end": [0, 0], "width_mm": 1700}

    def car(ident: str, side: str, at: float) -> dict[str, Any]:
        return {"id": ident, "room": f"lift {ident}", "kind": "elevator", "side": side, "at_mm": at}

    tea = {"room": "Tea", "kind": "tea_room", "side": "left", "at_mm": 3000}
    raw = {
        "floors": [
            {
                "level": 1,
                "hallways": [A],
                "doors": [tea, car("L1", "left", 5000), car("L2", "left", 15000)],
            },
            {
                "level": 2,
                "hallways": [back],
                "doors": [car("M2", "right", 5000), car("M1", "right", 15000)],
            },
        ]
    }
    plan = parse_floorplan(raw)
    assert {name: [s.door.id for s in stops] for name, stops in plan.cars.items()} == {
        "L1": ["L1", "M1"],
        "L2": ["L2", "M2"],
    }
    assert plan.cars_between(1, 2) == ["L1", "L2"] and plan.car_door("L2", 2).id == "M2"
    raw["floors"][1]["doors"][1]["at_mm"] = 14500  # a car stopping on floor 1 only
    with pytest.raises(FloorPlanError) as caught:
        parse_floorplan(raw)
    assert "floor 2 / door M1: at_mm: the elevator door is 500 mm from L1 on floor 1" in str(
        caught.value
    )
