"""Routes in a building of several hallways a floor (Linden Hall): the shortest way over the
hallways, the turn where two meet, and each lane move in its own hallway's frame."""

from __future__ import annotations

import pytest
from helpers import CONFIG, ROOT

from coffeebot.floorplan import load_floorplan
from coffeebot.messages import MoveInstruction
from coffeebot.navigation.hallway_graph import Hop, hops
from coffeebot.navigation.path import nearest
from coffeebot.navigation.route import ElevatorRide, Move, RoutePlanner

LINDEN = load_floorplan(ROOT / "floorplans" / "linden-hall.toml")
PLANNER = RoutePlanner.for_robot(LINDEN, CONFIG)
PIVOT = CONFIG.motor.axle_x_mm


def instructions(steps: list) -> list[MoveInstruction]:
    found = []
    for step in steps:
        if isinstance(step, ElevatorRide):
            found += [m.instruction for m in (step.face_doors, *step.enter, step.turn_round)]
            found += [m.instruction for m in step.exit if isinstance(m, Move)]
        elif isinstance(step, Move):
            found.append(step.instruction)
    return found


def test_the_way_between_two_wings_goes_through_the_main_hallway() -> None:
    floor = LINDEN.floor(1)
    assert hops(floor, "main", 4000, "main", 20000) == []
    assert hops(floor, "main", 4000, "east", 6500) == [Hop("main", 32000, "east", 0)]
    # From the east wing to the south wing: back down the main hallway, right at the T.
    assert hops(floor, "east", 6500, "south", 3500) == [
        Hop("east", 0, "main", 32000),
        Hop("main", 14000, "south", 0),
    ]


def test_round_a_bend_the_robot_turns_where_the_axes_meet() -> None:
    steps = PLANNER.route(1, 4500, PLANNER.door_place("112"), hallway="main").steps
    moves = instructions(steps)
    to_corner = next(i for i, m in enumerate(moves) if m.detail == "to hallway east")
    corner, turn, along = moves[to_corner], moves[to_corner + 1], moves[to_corner + 2 :]
    # On the main hallway's axis, the axle's offset short of the east wing's axis, so the
    # quarter turn about the axle leaves the centre on it.
    assert (corner.hallway, corner.target_s_mm, corner.lane_mm) == ("main", 32000 - PIVOT, 0.0)
    assert (turn.action, turn.heading_deg) == ("turn", pytest.approx(90.0))
    assert all(m.hallway == "east" for m in along if m.action == "follow_lane")
    assert along[-1].target_door == "112" and along[-1].target_s_mm == 6500
    # 112 is on the east wing's right: the last stretch in the right lane (d < 0).
    assert along[-1].lane_mm is not None and along[-1].lane_mm < 0


def test_into_a_side_hallway_on_the_right_the_robot_turns_right() -> None:
    steps = PLANNER.route(1, 4500, PLANNER.door_place("121"), hallway="main").steps
    moves = instructions(steps)
    turn = next(m for m in moves if m.detail == "into hallway south")
    assert turn.heading_deg == pytest.approx(-90.0)


def test_from_an_office_in_one_wing_to_another_by_the_main_hallway() -> None:
    where = PLANNER.where(1, 32000 + 800 + 600, 6500)  # inside 112, behind its door
    assert (where.hallway, where.leave is not None and where.leave.room) == ("east", "112")
    steps = PLANNER.route(
        1, where.s_mm, PLANNER.door_place("121"), where.leave, hallway=where.hallway
    ).steps
    turns = [m.detail for m in instructions(steps) if m.detail.startswith("into hallway")]
    assert turns == ["into hallway main", "into hallway south"]


def test_to_the_other_floor_along_the_hallway_that_goes_on_narrower() -> None:
    steps = PLANNER.route(1, 4500, PLANNER.door_place("205"), hallway="main").steps
    ride = next(s for s in steps if isinstance(s, ElevatorRide))
    assert (ride.from_floor, ride.to_floor) == (1, 2)
    after = instructions(steps[steps.index(ride) + 1 :])
    lanes = [(m.hallway, m.target_s_mm) for m in after if m.action == "follow_lane"]
    # Out of the car on floor 2 (s = 8000 along "main", surveyed westwards), on through
    # where it goes on as "west" (s = 16000) without stopping or turning, then along
    # "west" to 205's door at 9000.
    assert lanes[0][0] == "main" and lanes[-1] == ("west", 9000)
    through = next(m for m in after if m.detail == "to hallway west")
    assert (through.hallway, through.target_s_mm, through.stop) == ("main", 16000, False)
    # In the narrower hallway's lane before the step (west is 1500 mm wide, main 2000): keep
    # right (north, d < 0 along "main" surveyed westwards), 300 mm from the wall.
    assert through.lane_mm == pytest.approx(-(750 - 300 - CONFIG.geometry.width_mm / 2))
    assert not any(m.detail == "into hallway west" for m in after)


def test_a_single_robot_goes_back_to_the_nearer_pickup_point() -> None:
    """From 205 on floor 2, the kitchen on its floor, not the café a ride away; from 112 on
    floor 1, the café."""
    assert [p.door.room for p in PLANNER.pickup_points] == ["Café", "Kitchen"]
    for level, x, y, home in ((2, 7000, 0, "Kitchen"), (1, 32240, 6500, "Café")):
        where = PLANNER.where(level, x, y)
        routes = {
            place: PLANNER.route(level, where.s_mm, place, where.leave, hallway=where.hallway)
            for place in PLANNER.pickup_points
        }
        assert nearest(routes, LINDEN, level, (x, y)).door.room == home


def test_to_a_room_with_two_doors_the_robot_goes_to_the_nearer() -> None:
    """105 opens on the main hallway and, round the corner, on the east wing."""
    assert [p.door.id for p in PLANNER.door_places("105")] == ["105", "105-east"]
    for x, y, door in ((4500, -445, "105"), (32240, 10500, "105-east")):
        where = PLANNER.where(1, x, y)
        routes = {
            place: PLANNER.route(1, where.s_mm, place, where.leave, hallway=where.hallway)
            for place in PLANNER.door_places("105")
        }
        goal = nearest(routes, LINDEN, 1, (x, y))
        assert goal.door.id == door
        last = instructions(routes[goal].steps)[-1]
        assert last.target_door == door


def test_to_another_floor_the_robot_takes_the_nearer_car() -> None:
    """From the café the car half way along the main hallway (E1); from the east wing the
    one near its corner (E2)."""
    assert list(LINDEN.cars) == ["E1", "E2"]
    for x, y, room, car in ((4500, -445, "205", "E1"), (32240, 10500, "202", "E2")):
        where = PLANNER.where(1, x, y)
        place = PLANNER.door_place(room)
        routes = {
            car: PLANNER.route(1, where.s_mm, place, where.leave, hallway=where.hallway, car=car)
            for car in PLANNER.cars_to(1, place)
        }
        assert nearest(routes, LINDEN, 1, (x, y)) == car
        ride = next(s for s in routes[car].steps if isinstance(s, ElevatorRide))
        assert ride.car == car
