"""Routes from the floor plan, the speed profile, and the delivery lifecycle."""

from __future__ import annotations

import math

from helpers import CONFIG, PLAN, ROOT

from coffeebot.floorplan import Floor, load_floorplan
from coffeebot.messages import DeliveryProblem, OrderStatus
from coffeebot.navigation.control import SpeedProfile, wheel_speeds
from coffeebot.navigation.lifecycle import DeliveryLifecycle
from coffeebot.navigation.passing import right_lane_mm
from coffeebot.navigation.path import route_legs
from coffeebot.navigation.route import ElevatorRide, Lease, Move, RoutePlanner

PLANNER = RoutePlanner.for_robot(PLAN, CONFIG)
FLEET_ROBOT = RoutePlanner.for_robot(PLAN, CONFIG, PLAN.floor(2).parking[1])
"""A robot of a fleet, parked at the tea room's second spot."""


def moves(route) -> list[Move]:
    return [s for s in route.steps if isinstance(s, Move)]


def test_keep_right_lane_is_at_the_wall_distance() -> None:
    floor = PLAN.floor(2)
    half = floor.hallway.width_mm / 2
    lane = PLANNER.lane_mm(floor, 1.0)  # travelling +s: the right wall is at d = -half
    gap = (lane + half) - CONFIG.geometry.width_mm / 2
    assert math.isclose(gap, CONFIG.motion.wall_distance_mm)
    assert PLANNER.lane_mm(floor, -1.0) == -lane


def test_route_on_the_base_floor_leaves_the_tea_room_and_stops_at_the_door() -> None:
    base = PLANNER.base
    route = PLANNER.route(base.floor, base.door.at_mm, PLANNER.door_place("205"), base.door)
    steps = moves(route)
    assert not any(isinstance(s, ElevatorRide) for s in route.steps)
    assert steps[0].instruction.action == "drive_to"
    last = steps[-1].instruction
    assert last.action == "follow_lane" and last.target_door == "205" and last.stop
    assert last.target_s_mm == PLAN.find_room("205").door.at_mm
    # 205 is on the left: the robot pulls over to that side for the last stretch.
    assert last.lane_mm > 0


def test_route_to_the_other_floor_rides_the_elevator() -> None:
    base = PLANNER.base
    route = PLANNER.route(base.floor, base.door.at_mm, PLANNER.door_place("305"), base.door)
    rides = [s for s in route.steps if isinstance(s, ElevatorRide)]
    assert [(r.from_floor, r.to_floor) for r in rides] == [(2, 3)]
    assert moves(route)[-1].instruction.floor == 3


def pivot(s: float, d: float, heading: float, to_heading: float) -> tuple[float, float]:
    """Where the centre ends after turning on the spot about the axle (hallway frame)."""
    a = CONFIG.motor.axle_x_mm
    axle_s = s + a * math.cos(math.radians(heading))
    axle_d = d + a * math.sin(math.radians(heading))
    return (
        axle_s - a * math.cos(math.radians(to_heading)),
        axle_d - a * math.sin(math.radians(to_heading)),
    )


def test_turning_to_a_door_leaves_the_centre_on_its_axis() -> None:
    """Coming back along the hallway from 207, the robot stops short of the tea room's door
    by the axle's offset: the quarter turn about the axle then puts the centre on the door's
    axis, and the drive in goes straight through the middle."""
    door = PLAN.find_room("207").door
    route = PLANNER.route(2, door.at_mm, PLANNER.base)
    steps = [m.instruction for m in moves(route)]
    i = next(k for k, ins in enumerate(steps) if ins.action == "turn")
    arrive, turn = steps[i - 1], steps[i]
    floor = PLAN.floor(2)
    travel = 0.0 if arrive.target_s_mm > door.at_mm else 180.0  # hallway frame
    facing = turn.heading_deg - floor.hallway.heading_deg
    s, _ = pivot(arrive.target_s_mm, arrive.lane_mm, travel, facing)
    assert abs(s - PLANNER.base.door.at_mm) < 1.0


def test_out_of_a_door_and_turned_along_the_hallway_the_centre_is_in_the_lane() -> None:
    """Out of the tea room (right side) for a room either way, and out of the car on floor 3
    (left side): the drive out stops short of the lane (or past it) by the axle's offset, so
    the quarter turn about the axle along the hallway leaves the centre in the lane, not
    150 mm beyond it (in front of the car's door) or short of it (towards the robot waiting
    beside the lane)."""
    floor2, floor3 = PLAN.floor(2), PLAN.floor(3)
    base = PLANNER.base
    cases = [
        (floor2, PLANNER.route(2, base.door.at_mm, PLANNER.door_place(room), base.door))
        for room in ("205", "212")  # west and east of the tea room
    ]
    cases.append((floor3, PLANNER.route(2, base.door.at_mm, PLANNER.door_place("305"), base.door)))
    for floor, route in cases:
        steps = [m.instruction for m in moves(route)]
        rides = [s for s in route.steps if isinstance(s, ElevatorRide)]
        if floor is floor3:
            steps = [m.instruction for m in rides[0].exit] + steps[-1:]
        out = next(ins for ins in steps if ins.action == "drive_to" and ins.floor == floor.level)
        along = next(ins for ins in steps[steps.index(out) + 1 :] if ins.action == "follow_lane")
        s, d = floor.to_hallway(out.x_mm, out.y_mm)
        # Heading out of the door, hallway frame: the car is on the left, the tea room right.
        facing_out = -90.0 if floor is floor3 else 90.0
        travel = 0.0 if along.target_s_mm > s else 180.0
        _, centre_d = pivot(s, d, facing_out, travel)
        assert abs(centre_d - along.lane_mm) < 1.0, (floor.level, along.detail)


def test_route_back_to_base_parks_inside() -> None:
    door = PLAN.find_room("308").door
    route = PLANNER.route(3, door.at_mm, PLANNER.base)
    rides = [s for s in route.steps if isinstance(s, ElevatorRide)]
    assert [(r.from_floor, r.to_floor) for r in rides] == [(3, 2)]
    last = moves(route)[-2].instruction
    assert last.action == "drive_to" and last.floor == 2
    x, y = last.x_mm, last.y_mm
    _, d = PLAN.floor(2).to_hallway(x, y)
    assert d < -PLAN.floor(2).hallway.width_mm / 2  # behind the tea room's door line


def test_out_of_the_car_across_from_the_tea_room_the_robot_drives_straight_in() -> None:
    """The tea room's door is across the hallway from the car: coming out, the robot faces
    it on its axis. It used to turn into the lane, stop short of the door by the axle's
    offset (behind it), turn round to get there and turn in carrying the centre 150 mm
    off the axis, and stood held by the door's jamb."""
    floor = PLAN.floor(2)
    steps = PLANNER.route(3, PLAN.find_room("308").door.at_mm, PLANNER.base).steps
    at = next(i for i, s in enumerate(steps) if isinstance(s, ElevatorRide))
    ride = steps[at]
    assert isinstance(ride, ElevatorRide)
    (out,) = [m.instruction for m in ride.exit]
    face, into = [s.instruction for s in steps[at + 1 :] if isinstance(s, Move)][:2]
    assert (face.action, face.detail) == ("turn", "facing Tea room")
    assert into.action == "drive_to"
    for ins in (out, into):
        s, _ = floor.to_hallway(ins.x_mm, ins.y_mm)
        assert abs(s - PLANNER.base.door.at_mm) < 1.0, "off the door's axis"


def test_a_fleet_robot_out_of_the_car_waits_for_the_loading_spot_at_the_holding_point() -> None:
    """Out of the car across from the tea room, a fleet's robot without the loading spot
    must wait somewhere: in front of the car's door it stands in the way of the robot
    leaving the room for the car, each holding what the other waits for. So it takes the
    holding point before the car (not the loading spot: that held the spot for the whole
    wait for the car and the ride, a minute or more a cup), waits there for the spot, and
    gives the point back once in the room, so the next robot rides down only then."""
    floor = PLAN.floor(2)
    elevator = floor.elevator
    assert elevator is not None
    door = FLEET_ROBOT.base.door
    for start in ("305", "313"):
        loc = PLAN.find_room(start)
        steps = FLEET_ROBOT.route(3, loc.door.at_mm, FLEET_ROBOT.base, loc.door).steps
        leases = [s for s in steps if isinstance(s, Lease)]
        assert leases[:2] == [Lease("holding_point", True), Lease("elevator", True)]
        assert Lease("loading_spot", True) not in steps[: steps.index(Lease("elevator", True))]
        at = next(i for i, s in enumerate(steps) if isinstance(s, ElevatorRide))
        # Out of the car onto the hallway's axis, where the turn towards the point has room
        # (in the lane in front of the tea room's door, 250 mm from its jamb, it did not).
        ride = steps[at]
        assert isinstance(ride, ElevatorRide)
        (out,) = [m.instruction for m in ride.exit if isinstance(m, Move)]
        assert out.x_mm is not None and out.y_mm is not None
        assert floor.to_hallway(out.x_mm, out.y_mm) == (elevator.at_mm, 0.0)
        # The car given back once out of it; the crossing in front of it at the point.
        assert ride.exit[0] == Lease("crossing", True)
        back, hold, crossing_back, turn, ask = steps[at + 1 : at + 6]
        assert isinstance(hold, Move) and hold.instruction.action == "drive_to"
        assert (back, ask) == (Lease("elevator", False), Lease("loading_spot", True))
        assert crossing_back == Lease("crossing", False)
        assert isinstance(turn, Move) and turn.instruction.heading_deg == 180.0
        # Towards the dead end on the hallway's axis, the whole body clear of both doorways,
        # and a body's length before the end wall to turn round in (at 1.2 m from the car,
        # 400 mm from the wall, the turn back was held by the wall ahead for good; in a
        # lane, the body's corners swung into the side wall).
        assert hold.instruction.x_mm is not None and hold.instruction.y_mm is not None
        s, d = floor.to_hallway(hold.instruction.x_mm, hold.instruction.y_mm)
        assert s > elevator.at_mm and abs(d) < 1.0
        half = CONFIG.geometry.length_mm / 2
        for doorway in (door, elevator):
            assert s - half >= doorway.at_mm + doorway.width_mm / 2 + 100.0
        assert s + half + CONFIG.geometry.length_mm <= floor.hallway.length_mm
        into = next(
            i
            for i, s in enumerate(steps)
            if isinstance(s, Move) and s.instruction.detail == ("into Tea room")
        )
        assert Lease("holding_point", False) in steps[into + 1 : into + 3]


def test_without_room_for_a_holding_point_the_spot_is_taken_before_the_car() -> None:
    """No holding point fits between the car and the hallway's end: the robot takes the
    loading spot before the car, so it never waits for it in front of the car's door."""
    planner = RoutePlanner(
        PLAN,
        CONFIG.motion,
        CONFIG.navigation,
        CONFIG.geometry.width_mm,
        body_length_mm=1000.0,  # beside the doorways, 350 mm from the end wall
        pivot_mm=CONFIG.motor.axle_x_mm,
        parking=PLAN.floor(2).parking[1],
    )
    steps = planner.route(3, PLAN.find_room("305").door.at_mm, planner.base).steps
    ask = steps.index(Lease("elevator", True))
    assert steps[ask - 1] == Lease("loading_spot", True)
    assert not any(isinstance(s, Lease) and s.place == "holding_point" for s in steps)


def test_a_fleet_robot_coming_back_waits_for_the_loading_spot_short_of_the_door() -> None:
    """Not in the doorway: a robot driving out of the tea room must get past it."""
    start = PLAN.find_room("209").door.at_mm
    steps = FLEET_ROBOT.route(2, start, FLEET_ROBOT.base).steps
    ask = next(i for i, s in enumerate(steps) if s == Lease("loading_spot", True))
    before = steps[ask - 1]
    assert isinstance(before, Move) and before.instruction.stop
    door = FLEET_ROBOT.base.door
    short_by = door.at_mm - before.instruction.target_s_mm
    assert short_by >= CONFIG.navigation.hold_short_mm
    assert short_by - CONFIG.navigation.hold_short_mm < CONFIG.motor.axle_x_mm + 1
    assert steps[-1] == Lease("loading_spot", False), "the spot is given back once parked"


def test_profile_brakes_to_zero_within_the_band_and_rate_limits() -> None:
    profile = SpeedProfile.from_config(CONFIG.motion)
    assert profile.target(profile.stop_band_mm, 500) == 0
    assert profile.target(5000, 500) == 500
    assert profile.target(100, 500) < profile.target(400, 500) < 500
    approach = profile.target(1000, 500, approach_mm=1200, approach_mm_s=150)
    assert approach == 150
    assert profile.step(0.0, 500.0, 0.1) == CONFIG.motion.accel_mm_s2 * 0.1
    left, right = wheel_speeds(100, 10, 450)
    assert left < 100 < right and math.isclose((left + right) / 2, 100)


def test_lifecycle_reports_each_status_once_and_in_order() -> None:
    life = DeliveryLifecycle("o1", "205")
    assert life.pickup_confirmed() is None  # not there yet
    assert life.cup_loaded().status is OrderStatus.ON_THE_WAY
    assert life.cup_loaded() is None
    assert life.waiting_for_elevator("lift").status is OrderStatus.WAITING_FOR_ELEVATOR
    assert life.progress("floor 3").status is OrderStatus.ON_THE_WAY
    assert life.arrived("door").status is OrderStatus.ARRIVED
    assert life.pickup_confirmed().status is OrderStatus.DELIVERED
    assert life.cancel() is None and life.fail("late", DeliveryProblem.BLOCKED) is None
    assert life.returning


def test_lifecycle_cancel_before_leaving_needs_no_return() -> None:
    life = DeliveryLifecycle("o2", "205")
    assert life.cancel().status is OrderStatus.CANCELLED
    assert not life.returning


def test_a_route_is_drawn_as_one_leg_per_floor_from_where_the_robot_stands() -> None:
    base = PLANNER.base
    start = PLAN.floor(2).behind_door(base.door, 500.0)
    route = PLANNER.route(base.floor, base.door.at_mm, PLANNER.door_place("307"), base.door)
    first, second = route_legs(route, PLAN, 2, start)
    assert (first.floor, second.floor) == (2, 3)
    assert first.points[0] == start
    # The car rides straight: floor 3's leg starts where floor 2's ended, inside the car.
    assert second.points[0] == first.points[-1]
    assert abs(first.points[-1][1]) > PLAN.floor(2).hallway.width_mm / 2
    # It ends in the lane at 307's door.
    door = PLAN.find_room("307").door
    s, d = PLAN.floor(3).to_hallway(*second.points[-1])
    assert math.isclose(s, door.at_mm) and abs(d) < PLAN.floor(3).hallway.width_mm / 2


def test_the_base_is_the_plans_tea_room_whatever_it_is_called() -> None:
    """The example building calls its tea room "Kitchen": the way home is found by the
    door's kind, not by a name (a name lookup crashed navigation on the way back)."""
    plan = load_floorplan(ROOT / "floorplans" / "example.toml")
    planner = RoutePlanner(
        plan,
        CONFIG.motion,
        CONFIG.navigation,
        CONFIG.geometry.width_mm,
        body_length_mm=CONFIG.geometry.length_mm,
    )
    assert planner.base.door.room == "Kitchen"
    route = planner.route(1, plan.find_room("101").door.at_mm, planner.base)
    [*_, last] = [m.instruction for m in moves(route) if m.instruction.action == "drive_to"]
    assert last.x_mm is not None and last.y_mm is not None
    _, d = plan.floor(1).to_hallway(last.x_mm, last.y_mm)
    assert abs(d) > plan.floor(1).hallway.width_mm / 2, "parked inside the Kitchen"


def test_the_way_to_the_elevator_keeps_right_and_pulls_over_near_it() -> None:
    """The elevator (on the left going towards it) is reached as an office door is: in the
    keep-right lane, crossing to the elevator's side only for the last ``pull_over_mm``, not
    on the oncoming side for the whole hallway."""
    floor = PLAN.floor(2)
    elevator = floor.elevator
    assert elevator is not None
    route = PLANNER.route(2, 10000.0, PLANNER.door_place("305"))
    before_ride = route.steps[
        : next(i for i, s in enumerate(route.steps) if isinstance(s, ElevatorRide))
    ]
    lanes = [m.instruction for m in before_ride if isinstance(m, Move)]
    assert [i.lane_mm for i in lanes] == [
        PLANNER.lane_mm(floor, 1.0),
        PLANNER.side_lane_mm(floor, elevator),
    ]
    assert lanes[0].target_s_mm == elevator.at_mm - CONFIG.navigation.pull_over_mm


HOLD_MM = max(CONFIG.navigation.pull_over_mm, CONFIG.navigation.hold_short_mm)


def waiting_lane(floor: Floor) -> float:
    """Towards the elevator (+s), on the right as close to the wall as a passing robot."""
    half = floor.hallway.width_mm / 2
    return -(half - CONFIG.motion.passing_wall_distance_mm - CONFIG.geometry.width_mm / 2)


def test_a_fleet_robot_waits_for_the_elevator_in_the_tea_room_across_from_it() -> None:
    """In front of the car's door it would stand in the way of a robot coming out of it:
    it leaves the room holding the car and the crossing in front of it (the robot out of
    the car before it gave the car back at its door, and holds the crossing until clear)."""
    base = FLEET_ROBOT.base
    steps = FLEET_ROBOT.route(2, base.door.at_mm, FLEET_ROBOT.door_place("305"), base.door).steps
    assert steps[:2] == [Lease("elevator", True), Lease("crossing", True)]
    assert isinstance(steps[2], Move) and steps[2].instruction.detail == "out of Tea room"
    assert steps.count(Lease("elevator", True)) == 1


def test_a_fleet_robot_from_the_tea_room_holds_the_spot_until_it_is_in_the_car() -> None:
    """Waiting in front of the tea room's door for the car's doors, it is in the way of a
    robot turning in for the loading spot: the spot is given back once it is in the car
    (given back at the door, a robot coming home turned in there, face to face with it
    driving into the car, and both stood for good), not after the ride (held through the
    ride and out on the other floor, the spot was the fleet's bottleneck)."""
    base = FLEET_ROBOT.base
    steps = FLEET_ROBOT.route(2, base.door.at_mm, FLEET_ROBOT.door_place("305"), base.door).steps
    (ride,) = [s for s in steps if isinstance(s, ElevatorRide)]
    assert Lease("loading_spot", False) not in steps
    in_car = next(
        i
        for i, s in enumerate(ride.enter)
        if isinstance(s, Move) and s.instruction.detail == "into the car"
    )
    assert Lease("loading_spot", False) in ride.enter[in_car + 1 :]
    steps = FLEET_ROBOT.route(2, base.door.at_mm, FLEET_ROBOT.door_place("205"), base.door).steps
    out = next(
        i
        for i, s in enumerate(steps)
        if isinstance(s, Move) and s.instruction.detail == "out of Tea room"
    )
    turn, given_back = steps[out + 1 : out + 3]
    assert isinstance(turn, Move) and turn.instruction.detail == "along the hallway"
    assert given_back == Lease("loading_spot", False), "along the floor: given back once out"


def test_in_the_car_the_body_and_its_half_turn_stay_past_the_door_line() -> None:
    """A fleet's robot gives back what it held for the way in (the loading spot, the space
    in front of the car's door) once it is in the car, before it turns round: the body
    parked ``car_depth_mm`` past the door line, and every corner's sweep about the axle
    (``axle_x_mm`` ahead of the centre), stay behind the line, out of everyone's way."""
    depth = CONFIG.navigation.elevator.car_depth_mm
    half_length = CONFIG.geometry.length_mm / 2
    half_width = CONFIG.geometry.width_mm / 2
    axle = CONFIG.motor.axle_x_mm
    assert depth - half_length > 0, "the body parked in the car crosses the door line"
    sweep = math.hypot(half_length + axle, half_width)  # the rear corners, farthest out
    assert depth + axle - sweep > 0, "the half turn in the car sweeps past the door line"
    base = FLEET_ROBOT.base
    steps = FLEET_ROBOT.route(2, base.door.at_mm, FLEET_ROBOT.door_place("305"), base.door).steps
    (ride,) = [s for s in steps if isinstance(s, ElevatorRide)]
    details = [s.instruction.detail if isinstance(s, Move) else s for s in ride.enter]
    assert details == ["into the car", Lease("crossing", False), Lease("loading_spot", False)]
    turn = ride.turn_round.instruction
    assert (turn.action, turn.detail) == ("turn", "turning round in the car")
    assert turn.floor is None, "the car may arrive on the other floor before the turn ends"


def test_a_fleet_robot_holds_short_of_the_elevator_on_its_side_near_the_wall() -> None:
    """Coming along the hallway, it waits on its own side ``HOLD_MM`` short, close to the
    wall: a robot coming out of the car towards it passes it on the other side."""
    floor = PLAN.floor(3)
    elevator = floor.elevator
    assert elevator is not None
    start = PLAN.find_room("305").door.at_mm
    steps = FLEET_ROBOT.route(3, start, FLEET_ROBOT.base).steps
    ask = steps.index(Lease("elevator", True))
    hold = steps[ask - 2]
    assert isinstance(hold, Move) and hold.instruction.stop
    assert hold.instruction.target_s_mm == elevator.at_mm - HOLD_MM
    assert hold.instruction.lane_mm == waiting_lane(floor)
    # The tea room is across from the car on floor 2: the holding point out of the car is
    # taken before it, so the robot never waits for the spot in front of the car's door.
    assert steps[ask - 1] == Lease("holding_point", True)
    ride = next(i for i, s in enumerate(steps) if isinstance(s, ElevatorRide))
    assert ask < ride and steps[ride + 1] == Lease("elevator", False)


def test_a_fleet_robot_gives_the_car_back_once_out_and_its_landing_once_clear() -> None:
    """The car is given back as soon as the robot is out of it (a robot on the other floor
    has it at once), the landing in front of its door once the robot's body is a body's
    length clear past where the next robot on that floor waits (that one sets off across
    the hallway only once the way beside it is clear)."""
    base = FLEET_ROBOT.base
    steps = FLEET_ROBOT.route(2, base.door.at_mm, FLEET_ROBOT.door_place("305"), base.door).steps
    ride_at = next(i for i, s in enumerate(steps) if isinstance(s, ElevatorRide))
    ride = steps[ride_at]
    assert isinstance(ride, ElevatorRide)
    assert ride.exit[0] == Lease("landing", True), "taken in the car, before it drives out"
    back, turn, away, landing_back = steps[ride_at + 1 : ride_at + 5]
    elevator = PLAN.floor(3).elevator
    assert elevator is not None
    assert back == Lease("elevator", False)
    assert isinstance(turn, Move) and turn.instruction.detail == "into the lane"
    length = CONFIG.geometry.length_mm
    assert isinstance(away, Move)
    assert away.instruction.target_s_mm == elevator.at_mm - HOLD_MM - 2 * length
    assert landing_back == Lease("landing", False)


def test_a_fleet_robot_out_of_the_car_holds_the_landing_to_a_door_nearer_than_that() -> None:
    """313's door lies between the car and where the next robot is clear of the one coming
    out: the landing is held until the robot stands at that door, not given back at once
    (the next robot would set off across the hallway as this one drives past it)."""
    base = FLEET_ROBOT.base
    steps = FLEET_ROBOT.route(2, base.door.at_mm, FLEET_ROBOT.door_place("313"), base.door).steps
    ride_at = next(i for i, s in enumerate(steps) if isinstance(s, ElevatorRide))
    after = steps[ride_at + 1 :]
    moves = [s for s in after if isinstance(s, Move)]
    assert moves[-1].instruction.detail == "to 313"
    assert after[-1] == Lease("landing", False)
    assert Lease("landing", False) not in after[:-1]


def test_a_single_robot_holds_no_places() -> None:
    base = PLANNER.base
    for start, goal, leave in (
        (base.door.at_mm, PLANNER.door_place("305"), base.door),
        (PLAN.find_room("305").door.at_mm, base, None),
    ):
        floor = 2 if leave is not None else 3
        steps = PLANNER.route(floor, start, goal, leave).steps
        assert not any(isinstance(s, Lease) for s in steps)


def test_a_fleet_robot_beside_the_elevator_waits_for_it_in_its_own_lane() -> None:
    """313 is on the elevator's side, 3 m from it: a robot leaving it must not wait in the
    lane of a robot coming out of the car towards 303, nor askew, reaching into it."""
    floor = PLAN.floor(3)
    elevator = floor.elevator
    assert elevator is not None
    door = PLAN.find_room("313").door
    steps = FLEET_ROBOT.route(3, door.at_mm, FLEET_ROBOT.base).steps
    ask = steps.index(Lease("holding_point", True))
    along, hold, square = steps[ask - 3 : ask]
    travel = floor.travel_deg(1.0)
    assert isinstance(along, Move) and along.instruction.action == "turn"
    assert along.instruction.heading_deg == travel
    assert isinstance(hold, Move) and hold.instruction.action == "follow_lane"
    assert hold.instruction.stop and hold.instruction.lane_mm == waiting_lane(floor)
    assert hold.instruction.target_s_mm is not None
    assert door.at_mm < hold.instruction.target_s_mm < elevator.at_mm
    # Over so short a way lane keeping ends askew: squared up where it stops.
    assert isinstance(square, Move) and square.instruction.action == "turn"
    assert square.instruction.heading_deg == travel


def test_a_fleet_robot_changes_lanes_for_the_elevator_only_with_way_enough() -> None:
    """Less than ``pull_over_mm`` short of the hold point (313 is 4 mm short of it), lane
    keeping would stop before it changed lanes, leaving the robot in the way of a robot
    coming out of the car: it takes the way from nearer the elevator instead."""
    floor = PLAN.floor(3)
    elevator = floor.elevator
    assert elevator is not None
    for start, squares in ((elevator.at_mm - HOLD_MM - 4.0, True), (5000.0, False)):
        steps = FLEET_ROBOT.route(3, start, FLEET_ROBOT.base).steps
        ask = steps.index(Lease("holding_point", True))
        last = steps[ask - 1]
        assert isinstance(last, Move)
        assert (last.instruction.action == "turn") is squares


INNERMOST = {"crossing", "landing"}


def _crossing_holds(route_steps: list, held: set[str]) -> list[tuple[Move, set[str]]]:
    """Each move of a route begun holding ``held``, with the places held while it is made
    (rides' moves included), checking the rule of the spaces in front of the car's door
    (the crossing, the landing) on the way: each is asked for last (never another place
    while one is held) and given back by the route's end."""
    made: list[tuple[Move, set[str]]] = []
    flat: list = []
    for step in route_steps:
        flat += [*step.enter, *step.exit] if isinstance(step, ElevatorRide) else [step]
    for step in flat:
        if isinstance(step, Lease):
            if step.want and step.place not in INNERMOST:
                inner = held & INNERMOST
                assert not inner, f"asks for the {step.place} holding the {inner}"
            (held.add if step.want else held.discard)(step.place)
        else:
            made.append((step, set(held)))
    assert not held & INNERMOST, f"the {held & INNERMOST} still held at the route's end"
    return made


def test_a_fleet_robot_turns_along_the_hallway_before_it_sets_off_from_a_door() -> None:
    """Out of a door, a fleet's robot turns along the hallway on the spot before it follows
    its lane: set off facing across, lane keeping leaves 45 degrees askew, and with the
    passing lane 150 mm from the wall (a robot coming) one swung to 43 mm of the wall, where
    its side sensor held it for good. Its centre is then in its keep-right lane."""
    for start in ("Tea room", "205", "212", "305"):
        loc = PLAN.find_room(start)
        for goal in ("201", "213", "303"):
            route = FLEET_ROBOT.route(
                loc.floor.level, loc.door.at_mm, FLEET_ROBOT.door_place(goal), loc.door
            )
            made = [s.instruction for s in route.steps if isinstance(s, Move)]
            first = [s for s in route.steps if isinstance(s, (Move, ElevatorRide))][:2]
            if isinstance(first[1], ElevatorRide):
                continue  # straight across into the car
            out, turn = made[:2]
            lane = next(m for m in made if m.action == "follow_lane")
            assert out.detail == f"out of {start}" and turn.detail == "along the hallway"
            travel = 0.0 if lane.target_s_mm > loc.door.at_mm else 180.0
            assert turn.heading_deg == loc.floor.hallway.heading_deg + travel
            s, d = loc.floor.to_hallway(out.x_mm, out.y_mm)
            _, inside = loc.floor.to_hallway(*loc.floor.behind_door(loc.door, 100.0))
            facing_out = -90.0 if inside > 0 else 90.0
            _, centre_d = pivot(s, d, facing_out, travel)
            keep_right = FLEET_ROBOT.lane_mm(loc.floor, 1.0 if travel == 0.0 else -1.0)
            assert abs(centre_d - keep_right) < 1.0


def test_a_fleet_robot_holds_the_crossing_for_every_way_through_the_doors() -> None:
    """Where the car faces the tea room (floor 2), every way into or out of either door is
    made holding the crossing (holding the car is not enough: it is given back once the
    robot is out of it, with the robot still in front of its door). Two robots in it at
    once stood in each other's sweep for good in the fleet benchmark: one out of the car
    turning towards the holding point, one coming out of the tea room. The crossing is asked
    for after every other place and given back before any other is asked for, so no two
    robots can each hold what the other waits for."""
    base = FLEET_ROBOT.base
    ways = {"out of Tea room", "into Tea room", "out of the elevator on floor 2"}
    ways |= {"to the elevator on Floor 2", "into the car"}
    rooms = ["201", "205", "212", "213", "303", "305", "313"]
    # From the loading spot (held since ``RoutePlanner.loading``), and from each office.
    routes = [
        (
            FLEET_ROBOT.route(2, base.door.at_mm, FLEET_ROBOT.door_place(r), base.door),
            {"loading_spot"},
        )
        for r in rooms
    ]
    for room in rooms:
        loc = PLAN.find_room(room)
        start = (loc.floor.level, loc.door.at_mm)
        routes.append((FLEET_ROBOT.route(*start, base, loc.door), set()))
        for other in rooms:
            if other != room:
                place = FLEET_ROBOT.door_place(other)
                routes.append((FLEET_ROBOT.route(*start, place, loc.door), set()))
    # On floor 3 the landing in front of the car's door: the car is given back once a robot
    # is out of it, so only the landing keeps one driving up to it from one coming out.
    landing_ways = {"out of the elevator on floor 3", "to the elevator on Floor 3", "into the car"}
    seen: set[str] = set()
    landing_seen: set[str] = set()
    for route, start_held in routes:
        for move, held in _crossing_holds(route.steps, start_held):
            ins = move.instruction
            if ins.floor == 2 and ins.detail in ways:
                seen.add(ins.detail)
                assert "crossing" in held, ins.detail
            if ins.floor == 3 and ins.detail in landing_ways:
                landing_seen.add(ins.detail)
                assert "landing" in held, ins.detail
    assert seen == ways
    assert landing_seen == landing_ways
    # A single robot has the places alone: no leases at all.
    assert not any(isinstance(s, Lease) for s in PLANNER.route(3, 15000.0, PLANNER.base).steps)


def test_a_fleet_robot_waits_for_the_tea_room_beside_the_lane_of_the_one_coming_out() -> None:
    """Coming home along the hallway, a fleet's robot waits for the loading spot 1.2 m short
    of its turn into the tea room as close to the wall as a robot passing another: in its
    lane, a robot coming out of the room for an office had too narrow a gap to pass it and
    stood in front of it for good, holding the crossing the waiting one needed."""
    floor = PLAN.floor(2)
    base = FLEET_ROBOT.base
    for start in ("201", "213", "212"):
        loc = PLAN.find_room(start)
        steps = FLEET_ROBOT.route(2, loc.door.at_mm, base, loc.door).steps
        ask = steps.index(Lease("loading_spot", True))
        (wait,) = [
            s
            for s in steps[:ask]
            if isinstance(s, Move) and s.instruction.detail == "short of Tea room's door"
        ]
        # From 213, 3 m away across the hallway, it squares up there: a lane change over
        # 1.6 m ended 220 mm off the lane and 17 degrees askew, a corner in the way of the
        # robot coming out of the room (it stood there for good, found in the benchmark).
        squared = [m.instruction for m in steps[steps.index(wait) + 1 : ask]]
        if start == "213":
            (square,) = squared
            assert square.detail == "square to the lane"
            assert square.heading_deg == floor.travel_deg(1.0)
        else:
            assert squared == []
        passing = right_lane_mm(
            floor, 1.0, CONFIG.motion.passing_wall_distance_mm, CONFIG.geometry.width_mm
        )
        assert wait.instruction.lane_mm == passing
        coming_out = FLEET_ROBOT.lane_mm(floor, -1.0)  # towards the offices
        gap = abs(coming_out - passing) - CONFIG.geometry.width_mm
        assert gap >= 200.0
