"""Routes computed from the floor plan: base -> hallways -> (elevator ->) door -> base.

A route is a list of steps. A :class:`Move` is one instruction for the motion module; an
:class:`ElevatorRide` is the elevator procedure (call, wait for doors, enter, ride, confirm
the floor, exit) with the moves it needs inside. Nothing is written per room: every point is
derived from the frame of the hallway it lies along (``s`` along the axis, ``d`` to its
left), the doors' positions and sides, and the robot's width. Between hallways the way is
the shortest over where they meet (:mod:`coffeebot.navigation.hallway_graph`); to another
floor, through the car the caller names (the first that stops on both, by default).

Lanes follow the seed's courtesy rule: keep right at ``wall_distance_mm`` between the body's
side and the wall, so the lane's centre line sits ``half_width - wall_distance - body/2`` from
the axis on the right of the direction of travel. For the last stretch to a door the robot
pulls over to the door's side, so the customer finds the cup at their door.

The robot turns on the spot about its driven axle, ``pivot_mm`` ahead of the body's centre,
so a quarter turn carries the centre that far along the hallway. Where a route turns to go
through a door (into a room, into the elevator car) it stops that much short of the door, so
the turn leaves the centre on the door's axis rather than aimed past a jamb.

A robot of a fleet (``parking`` given) parks at its own spot in the base room, not on the
loading spot, and passes the base room's door and the loading spot behind it as a shared
place: the route says where it must hold the place alone (:class:`Lease` steps), from
before it turns in at the door to when it stands at its spot, and from when it leaves its
spot to when it is out in the hallway. The elevator is the other shared place. A robot waits
for it where a robot coming out of the car is not in its way: on its own side, as near the
wall as a passing robot, ``max(pull_over_mm, hold_short_mm)`` short of the elevator, or in
the room it leaves when that room is nearer than that; and it holds the car until it is
out of the car on the other floor. The space in front of the car's door is held
apart from the car, by the *crossing* on the floor where the car faces the base room and the
*landing* on the others: a robot holds it driving up to the car and into it, and out of the
car until it is as far from it as the next robot waits, so the next robot on that floor sets
off only once the way is clear, while one on another floor has the car at once.
A robot riding to a base room near the car on the other floor takes the holding point
before the elevator, a place out of the car beside the doorways towards the hallway's nearer
end, and waits there for the loading spot: in front of the car's door it would stand where
the robot leaving the room with a cup has to pass, each holding what the other waits for.
It gives the point back once in the room. Where no holding point fits it takes the loading
spot itself before the elevator (which holds the spot through the wait for the car and the
ride).
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass, field
from typing import NamedTuple

from coffeebot.config import MotionConfig, NavigationConfig, RobotConfig
from coffeebot.floorplan import Door, Floor, FloorPlan, ParkingSpot
from coffeebot.messages import MoveInstruction, SharedPlace
from coffeebot.navigation.hallway_graph import hops
from coffeebot.navigation.passing import right_lane_mm

DOORWAY_CLEARANCE_MM = 100.0
"""Between a robot waiting at the holding point and the doorways it waits beside."""


@dataclass(frozen=True)
class Move:
    """One motion instruction (its ``id`` is assigned when it is sent)."""

    instruction: MoveInstruction


@dataclass(frozen=True)
class Lease:
    """Hold ``place`` alone from here (``want``), or give it back: only in a fleet."""

    place: SharedPlace
    want: bool


@dataclass(frozen=True)
class ElevatorRide:
    """Ride from ``from_floor`` to ``to_floor``: moves for before the call, in, and out of the
    car, which is released to the building after them (a fleet's robot gives the space in
    front of the car's door and the loading spot back once in the car, and takes the space
    on the other floor before it comes out). ``turn_round`` is made while the car closes its
    doors and travels: it is for no floor in particular (the floors share one frame)."""

    from_floor: int
    to_floor: int
    car: str
    """Which of the plan's cars (:attr:`~coffeebot.floorplan.FloorPlan.cars`)."""
    face_doors: Move
    enter: list[Move | Lease]
    turn_round: Move
    exit: list[Move | Lease]


Step = Move | ElevatorRide | Lease


@dataclass(frozen=True)
class Route:
    """Steps in order, ending at the goal."""

    steps: list[Step] = field(default_factory=list)


class Whereabouts(NamedTuple):
    """Where a robot is, as a route starts: along which hallway, how far, and behind which
    door (None: in the hallway)."""

    hallway: str
    s_mm: float
    leave: Door | None


@dataclass(frozen=True)
class Place:
    """Where a route starts or ends: parked inside a room, or in the hallway at its door."""

    floor: int
    door: Door
    inside: bool


class RoutePlanner:
    """Plans routes on one floor plan for a robot of a given width."""

    def __init__(
        self,
        plan: FloorPlan,
        motion: MotionConfig,
        nav: NavigationConfig,
        body_width_mm: float,
        pivot_mm: float = 0.0,
        parking: ParkingSpot | None = None,
        *,
        body_length_mm: float,
    ) -> None:
        """``parking``: this robot's spot in the base room, if it is one of a fleet."""
        self.plan = plan
        self.motion = motion
        self.nav = nav
        self.body_width_mm = body_width_mm
        self.body_length_mm = body_length_mm
        self.pivot_mm = pivot_mm
        self.parking = parking

    @classmethod
    def for_robot(
        cls, plan: FloorPlan, config: RobotConfig, parking: ParkingSpot | None = None
    ) -> RoutePlanner:
        """The planner for the robot ``config`` describes (its body, its axle, its lanes)."""
        return cls(
            plan,
            config.motion,
            config.navigation,
            config.geometry.width_mm,
            body_length_mm=config.geometry.length_mm,
            pivot_mm=config.motor.axle_x_mm,
            parking=parking,
        )

    # --- places ----------------------------------------------------------------------------

    @property
    def base(self) -> Place:
        """The first pickup point: a fleet's base."""
        loc = self.plan.tea_room
        return Place(loc.floor.level, loc.door, inside=True)

    @property
    def pickup_points(self) -> list[Place]:
        """Every tea room, where a single robot may wait for its next cup."""
        return [Place(loc.floor.level, loc.door, inside=True) for loc in self.plan.tea_rooms]

    def door_place(self, room: str) -> Place:
        """In the hallway at ``room``'s (first) door."""
        loc = self.plan.find_room(room)
        return Place(loc.floor.level, loc.door, inside=False)

    def door_places(self, room: str) -> list[Place]:
        """In the hallway at each of ``room``'s doors."""
        return [
            Place(loc.floor.level, loc.door, inside=False) for loc in self.plan.room_doors(room)
        ]

    # --- geometry --------------------------------------------------------------------------

    def lane_mm(self, floor: Floor, direction: float) -> float:
        """Keep-right lane centre (``d``) when travelling towards ``direction`` (+1/-1 in s)."""
        return right_lane_mm(floor, direction, self.motion.wall_distance_mm, self.body_width_mm)

    def waiting_lane_mm(self, floor: Floor, direction: float) -> float:
        """Where a fleet's robot waits for a shared place: on its own side, as close to the
        wall as a robot passing another, so one coming the other way passes it."""
        return right_lane_mm(
            floor, direction, self.motion.passing_wall_distance_mm, self.body_width_mm
        )

    def side_lane_mm(self, floor: Floor, door: Door) -> float:
        """Lane centre at the wall distance on the door's side of the hallway."""
        return self.lane_mm(floor, -1.0 if door.side == "left" else 1.0)

    @staticmethod
    def facing_deg(floor: Floor, door: Door) -> float:
        """Heading that looks from the hallway through ``door``."""
        return floor.hallway.heading_deg + (90.0 if door.side == "left" else -90.0)

    def turn_point_mm(self, door: Door, direction: float) -> float:
        """Where to stop, arriving towards ``direction``, so that a quarter turn towards
        ``door`` leaves the body's centre on the door's axis."""
        return door.at_mm - direction * self.pivot_mm

    def out_to_mm(self, door: Door, lane: float) -> float:
        """Where (``d``) to stop driving out of ``door`` so that the quarter turn along the
        hallway that follows leaves the body's centre in ``lane``. The turn is about the
        axle, ``pivot_mm`` ahead of the centre, which ends where the axle stood: stopped in
        the lane, a robot out of the tea room for the far lane ended 150 mm beyond it, in
        front of the car's door, and one out of the car 150 mm short of it, in the way of
        the robot waiting beside its lane."""
        out_of_door = -1.0 if door.side == "left" else 1.0
        return lane - out_of_door * self.pivot_mm

    # --- moves -----------------------------------------------------------------------------

    def _lane(
        self,
        floor: Floor,
        to_s: float,
        lane: float,
        *,
        speed: float | None = None,
        stop: bool = True,
        door: Door | None = None,
        detail: str,
    ) -> Move:
        """Along ``floor``'s hallway to ``to_s`` in ``lane``; towards ``door``, the stop
        refined by that door's detection."""
        return Move(
            MoveInstruction(
                action="follow_lane",
                floor=floor.level,
                hallway=floor.hallway.id,
                target_s_mm=to_s,
                lane_mm=lane,
                speed_mm_s=speed or self.motion.cruise_speed_mm_s,
                stop=stop,
                target_door=None if door is None else door.id,
                detail=detail,
            )
        )

    def _drive_to(self, floor: Floor, point: tuple[float, float], detail: str) -> Move:
        return Move(
            MoveInstruction(
                action="drive_to",
                floor=floor.level,
                x_mm=point[0],
                y_mm=point[1],
                speed_mm_s=self.motion.room_speed_mm_s,
                avoid=False,
                detail=detail,
            )
        )

    @staticmethod
    def _turn(floor: Floor, heading: float, detail: str) -> Move:
        return Move(
            MoveInstruction(action="turn", floor=floor.level, heading_deg=heading, detail=detail)
        )

    # --- routes ----------------------------------------------------------------------------

    def route(
        self,
        floor_level: int,
        s_start: float,
        goal: Place,
        leave: Door | None = None,
        park: bool = True,
        hallway: str | None = None,
        car: str | None = None,
    ) -> Route:
        """From ``s_start`` along ``hallway`` (None: the first) of ``floor_level`` (or parked
        behind ``leave``) to ``goal``, riding ``car`` to another floor (None: the first that
        stops on both; :meth:`cars_to` lists them); a fleet's robot coming home ends on the
        loading spot, holding it, unless it goes on to ``park`` (:meth:`back_to_spot`, or
        :meth:`face_out` for its next cup)."""
        steps: list[Step] = []
        floor = self.plan.floor(floor_level).view(hallway)
        s = s_start
        rides = goal.floor != floor_level
        if rides:
            car = car if car is not None else self.cars_to(floor_level, goal)[0]
            lift: Door | None = self.plan.car_door(car, floor_level)
        else:
            lift = None
        # Leaving a room near the elevator, a fleet's robot waits for it in the room.
        asked = rides and leave is not None and self._near_elevator(floor, leave.at_mm)
        if asked:
            steps.extend(self._elevator_leases(goal))
            steps.extend(self._in_front_of_car(floor, True))
        # A fleet's robot leaves the base room from the loading spot (:meth:`loading`),
        # holding it until it is out in the hallway; one leaving it for the car nearby (across
        # the hallway in the CS building) until it is in the car: waiting in front of the
        # door for the car's doors, it is still in the way of a robot turning in for the spot.
        spot_given_back = Lease("loading_spot", False)
        from_base = (
            self.parking is not None
            and leave is not None
            and leave.room == self.plan.tea_room.door.room
        )
        to_car_near = asked and from_base
        # Out of the base room across from the car, it holds the crossing until it is clear
        # of both doorways (one leaving for that car took it with the car).
        crossing_out = from_base and not to_car_near and self._crossing(floor)
        if leave is not None:
            s = leave.at_mm
            direction = self._direction(floor, s, goal, lift)
            lane = self.lane_mm(floor, direction)
            # Out and turned along the hallway, unless the car it rides in is straight across.
            across = lift is not None and abs(lift.at_mm - s) <= self.motion.stop_tolerance_mm
            out_to = lane if across else self.out_to_mm(leave, lane)
            if crossing_out:
                steps.append(Lease("crossing", True))
            steps.append(
                self._drive_to(floor, floor.from_hallway(s, out_to), f"out of {leave.room}")
            )
            if self.parking is not None and not across:
                # A fleet's robot turns along the hallway before it sets off: lane keeping
                # from facing across sets off 45 degrees askew, and with the passing lane
                # 150 mm from the wall (a robot coming) it swung to 43 mm of the wall, where
                # the side sensor held it for good.
                steps.append(self._turn(floor, floor.travel_deg(direction), "along the hallway"))
            if from_base and not to_car_near:
                steps.append(spot_given_back)
            if crossing_out:
                clear, s = self._out_of_crossing(floor, s, goal, lane, direction)
                steps += clear
        if car is not None and lift is not None:
            between, floor, s = self._between_hallways(floor, s, lift)
            steps += between
            steps.extend(self._to_elevator(floor, s, goal, asked, lift))
            in_the_car = _front_of_car_given_back(steps)
            if to_car_near:
                in_the_car.append(spot_given_back)
            steps.append(self._ride(floor_level, goal.floor, goal, car, in_the_car))
            there = self.plan.car_door(car, goal.floor)
            floor, s = self._view_of(goal.floor, there), there.at_mm
            steps += self._out_of_car(floor, goal, there)
            if self.parking is not None:
                clear, s = self._clear_of_elevator(floor, s, goal)
                steps += clear
        # Waiting at the holding point, the robot is out of every other's way until it
        # turns in: the next may ride down to it once it is in the room.
        held = Lease("holding_point", True) in steps
        between, floor, s = self._between_hallways(floor, s, goal.door)
        steps += between
        steps.extend(self._along(floor, s, goal, park, held=held))
        # Its goal lies within the space in front of the car.
        steps += _front_of_car_given_back(steps)
        return Route(steps)

    def where(self, floor_level: int, x_mm: float, y_mm: float) -> Whereabouts:
        """The hallway the robot is in (or whose door it stands behind, in a room), its
        ``s`` along it, and that door."""
        floor = self.plan.floor(floor_level).view_near(x_mm, y_mm)
        s, d = floor.to_hallway(x_mm, y_mm)
        if abs(d) <= floor.hallway.width_mm / 2:
            return Whereabouts(floor.hallway.id, s, None)
        return Whereabouts(floor.hallway.id, s, floor.nearest_door(s, "left" if d > 0 else "right"))

    def _direction(self, floor: Floor, s: float, goal: Place, lift: Door | None) -> float:
        """Which way along ``floor``'s hallway the route leaves ``s`` in (to ``lift``, the
        car's door, for a goal on another floor)."""
        target = self._aim_mm(floor, s, goal.door if lift is None else lift)
        return 1.0 if target >= s else -1.0

    def cars_to(self, level: int, goal: Place) -> list[str]:
        """The cars that take a robot from floor ``level`` to ``goal``'s floor."""
        return self.plan.cars_between(level, goal.floor)

    # --- between hallways -------------------------------------------------------------------

    def _view_of(self, level: int, door: Door) -> Floor:
        """Floor ``level`` as seen along the hallway ``door`` opens on."""
        return self.plan.floor(level).view_of(door)

    def _aim_mm(self, floor: Floor, s: float, door: Door) -> float:
        """Where along ``floor``'s hallway the way to ``door`` goes: the door, if it opens on
        this hallway, else where this hallway meets the next one on the way."""
        whole = self.plan.floor(floor.level)
        on = whole.hallway_of(door).id
        if on == floor.hallway.id:
            return door.at_mm
        return hops(whole, floor.hallway.id, s, on, door.at_mm)[0].s_mm

    def _between_hallways(
        self, floor: Floor, s: float, door: Door
    ) -> tuple[list[Step], Floor, float]:
        """From ``s`` along ``floor``'s hallway to the hallway ``door`` opens on; and the
        view and ``s`` it ends at. Where the next hallway goes on straight (at another
        width), through the meeting at speed, in the narrower hallway's keep-right lane from
        ``pull_over_mm`` short of it. Where it leaves to a side: kept right until
        ``pull_over_mm`` short, then on the axis to ``pivot_mm`` short of the next
        hallway's axis, where a quarter turn about the axle leaves the centre on that axis
        (in a lane beside the wall the rear corners' sweep has little room), and turned
        along the next hallway."""
        whole = self.plan.floor(floor.level)
        to_s = door.at_mm
        steps: list[Step] = []
        route = hops(whole, floor.hallway.id, s, whole.hallway_of(door).id, to_s)
        for index, hop in enumerate(route):
            direction = 1.0 if hop.s_mm >= s else -1.0
            here = floor.travel_deg(direction)
            following = whole.view(hop.next_hallway)
            aim = route[index + 1].s_mm if index + 1 < len(route) else to_s
            along = following.travel_deg(1.0 if aim >= hop.next_s_mm else -1.0)
            detail = f"to hallway {hop.next_hallway}"
            straight_on = abs(math.remainder(along - here, 360.0)) < 1.0
            keep_right = hop.s_mm - direction * self.nav.pull_over_mm
            lane = self.lane_mm(floor, direction)
            if (keep_right - s) * direction > 0:
                steps.append(
                    self._lane(floor, keep_right, lane, stop=False, detail="along the hallway")
                )
            if straight_on:
                # Into the narrower hallway's lane before the step: changing lanes past it,
                # the rear swung about the axle into the step's corner.
                x, y = following.from_hallway(
                    hop.next_s_mm, self.lane_mm(following, 1.0 if aim >= hop.next_s_mm else -1.0)
                )
                there = floor.to_hallway(x, y)[1]
                narrower = there if abs(there) < abs(lane) else lane
                steps.append(self._lane(floor, hop.s_mm, narrower, stop=False, detail=detail))
            else:
                stop_at = hop.s_mm - direction * self.pivot_mm
                steps.append(self._lane(floor, stop_at, 0.0, detail=detail))
                steps.append(self._turn(following, along, f"into hallway {hop.next_hallway}"))
            floor, s = following, hop.next_s_mm
        return steps, floor, s

    # --- the elevator in a fleet ------------------------------------------------------------

    @property
    def _elevator_hold_mm(self) -> float:
        return max(self.nav.pull_over_mm, self.nav.hold_short_mm)

    def _near_elevator(self, floor: Floor, s: float) -> bool:
        return (
            self.parking is not None
            and floor.elevator is not None
            and abs(floor.elevator.at_mm - s) <= self._elevator_hold_mm
        )

    def _crossing(self, floor: Floor) -> bool:
        """Whether a fleet's robot holds the crossing on ``floor``: the base room's door is
        as near the car's as a robot waits for the car (across from it in the CS building).
        There the ways into and out of both doors cross, and two robots turning or driving
        out in them at once stood in each other's sweep for good; each such move holds the
        crossing, taken after every other lease and given back before any other is asked
        for, so it cannot close a circle of robots waiting for each other."""
        base = self.plan.tea_room
        return (
            self.parking is not None
            and base.floor.level == floor.level
            and floor.elevator is not None
            and abs(base.door.at_mm - floor.elevator.at_mm) <= self._elevator_hold_mm
        )

    def _in_front_of_car(self, floor: Floor, want: bool) -> list[Lease]:
        """A fleet's robot's lease on the space in front of the car's door on ``floor``: the
        crossing where the base room faces the car, the landing on the other floors (one
        lease for them all). Without it, a robot driving out of the car would meet one
        driving up to it: the car is given back once the robot is out of it, so holding the
        car no longer keeps the way in front of its door clear."""
        if self.parking is None or floor.elevator is None:
            return []
        return [Lease("crossing" if self._crossing(floor) else "landing", want)]

    def _crossing_clear_mm(self, floor: Floor) -> float:
        """How far along the hallway from the car's door a robot's body is clear of the
        crossing: past both doorways by ``DOORWAY_CLEARANCE_MM``."""
        elevator = floor.elevator
        assert elevator is not None
        base = self.plan.tea_room.door
        reach = abs(base.at_mm - elevator.at_mm) + max(elevator.width_mm, base.width_mm) / 2
        return reach + DOORWAY_CLEARANCE_MM + self.body_length_mm / 2

    def _elevator_leases(self, goal: Place) -> list[Step]:
        """What a fleet's robot holds before it rides: the elevator, and first the loading
        spot when the base room it rides to is near the elevator on the other floor."""
        if self.parking is None:
            return []
        there = self.plan.floor(goal.floor).elevator
        assert there is not None
        leases: list[Step] = []
        if goal.inside and abs(goal.door.at_mm - there.at_mm) <= self._elevator_hold_mm:
            first: SharedPlace = (
                "holding_point" if self._holding_point(goal) is not None else "loading_spot"
            )
            leases.append(Lease(first, True))
        return [*leases, Lease("elevator", True)]

    def _holding_point(self, goal: Place) -> float | None:
        """Where (``s``) a fleet's robot out of the car waits for the loading spot of a base
        room across from or near the car: towards the nearer end of the hallway (the CS
        building's dead end, away from every office), the whole body ``DOORWAY_CLEARANCE_MM``
        clear of the car's and the room's doorways, so the robot leaving the room for the
        car passes it. None when the room is farther from the car than a robot waits for
        it, or when there is not a body's length left beyond it to turn round
        in (a turn on the spot is held while the front is within its stop distance of a
        wall)."""
        floor = self._view_of(goal.floor, goal.door)
        elevator = floor.elevator
        if not goal.inside or elevator is None:
            return None
        if abs(goal.door.at_mm - elevator.at_mm) > self._elevator_hold_mm:
            return None
        length = floor.hallway.length_mm
        direction = 1.0 if length - elevator.at_mm < elevator.at_mm else -1.0
        edge = max(
            direction * (d.at_mm + direction * d.width_mm / 2) for d in (elevator, goal.door)
        )
        point = direction * (edge + DOORWAY_CLEARANCE_MM + self.body_length_mm / 2)
        room = 1.5 * self.body_length_mm
        if not room <= point <= length - room:
            return None
        return point

    def _out_of_crossing(
        self, floor: Floor, s: float, goal: Place, lane: float, direction: float
    ) -> tuple[list[Step], float]:
        """On along the lane until clear of the crossing, giving it back there (or at the
        goal, if that is nearer); and where it is then."""
        assert floor.elevator is not None
        clear_at = floor.elevator.at_mm + direction * self._crossing_clear_mm(floor)
        if goal.floor == floor.level and (goal.door.at_mm - clear_at) * direction <= 0:
            return [], s
        away = self._lane(floor, clear_at, lane, stop=False, detail="clear of the crossing")
        return [away, Lease("crossing", False)], clear_at

    def _clear_of_elevator(self, floor: Floor, s: float, goal: Place) -> tuple[list[Step], float]:
        """Out of the car, a fleet's robot gives the space in front of its door back once
        its body is a body's length clear past where the next robot waits
        (:meth:`_to_elevator`), so the lane that one crosses to for the car is clear beside
        it (given back right beside it, the robot waiting beside the wall set off across
        into the one driving past, went round it along the wall and stopped at the car with
        no room to turn: the fleet stood for good); at its goal's door if that is nearer;
        at the holding point if it goes on to the loading spot nearby, where it then waits
        for it; and where it is then."""
        given_back: list[Step] = [*self._in_front_of_car(floor, False)]
        holding = self._holding_point(goal)
        if holding is not None:
            # On the hallway's axis, where the half turn back has room on both sides (in a
            # lane, 150 mm off it after the quarter turn out of the car, the body's corners
            # swung into the wall and the turn never ended); turned back at once, so a
            # granted spot is driven to straight away. The turn about the axle carries the
            # centre twice ``pivot_mm`` on.
            direction = 1.0 if holding >= s else -1.0
            wait = self._drive_to(floor, floor.from_hallway(holding, 0.0), "to the holding point")
            back = self._turn(floor, floor.travel_deg(-direction), "facing back")
            return [wait, *given_back, back], holding + direction * 2 * self.pivot_mm
        direction = 1.0 if goal.door.at_mm >= s else -1.0
        clear_at = s + direction * (self._elevator_hold_mm + 2 * self.body_length_mm)
        if (goal.door.at_mm - clear_at) * direction <= 0:
            # Held to the door (given back at the route's end), unless the robot turns in
            # there: then no other place may be asked for while holding it.
            return (given_back if goal.inside else []), s
        lane = self.lane_mm(floor, direction)
        away = self._lane(floor, clear_at, lane, stop=False, detail="away from the elevator")
        return [away, *given_back], clear_at

    def _to_elevator(
        self, floor: Floor, s: float, goal: Place, asked: bool, elevator: Door
    ) -> list[Step]:
        """To ``elevator``, the car's door; a fleet's robot holds short of it for its leases
        unless it ``asked`` for them already."""
        leases = (
            [] if asked else [*self._elevator_leases(goal), *self._in_front_of_car(floor, True)]
        )
        if abs(elevator.at_mm - s) <= self.motion.stop_tolerance_mm:
            return leases  # across the hallway from it already (out of the tea room)
        direction = 1.0 if elevator.at_mm >= s else -1.0
        lane = self.side_lane_mm(floor, elevator)
        if self.parking is None:
            steps = self._keep_right_first(floor, s, elevator, direction, lane)
        else:
            # On its own side, as close to the wall as a robot passing another: a robot
            # coming out of the car and going the other way passes it.
            hold_at = elevator.at_mm - direction * self._elevator_hold_mm
            holds = self._wait_beside_wall(
                floor,
                s,
                hold_at,
                self.turn_point_mm(elevator, direction),
                direction,
                self.waiting_lane_mm(floor, direction),
                "short of the elevator",
            )
            steps = [*holds, *leases]
        stop_at = self.turn_point_mm(elevator, direction)
        steps.append(self._lane(floor, stop_at, lane, detail=f"to the elevator on {floor.name}"))
        return steps

    def _wait_beside_wall(
        self,
        floor: Floor,
        s: float,
        hold_at: float,
        turn_at: float,
        direction: float,
        waiting_lane: float,
        detail: str,
    ) -> list[Step]:
        """To where a fleet's robot waits for a shared place, in ``waiting_lane`` (beside the
        wall): ``hold_at`` with way enough to change lanes on the way, as when pulling over
        to a door. Nearer (out of an office beside it: 313 4 mm short of the elevator's hold
        point, a lane of 4 mm left it in the way of the robot coming out of the car; 213, 3 m
        from the tea room across the hallway, a lane change over 1.6 m left it 220 mm off the
        lane and 17 degrees askew, its corner in the way of the robot coming out of the room
        for good): square to the hallway, then into that lane along the way there is, up to
        ``hold_short_mm`` short of the turn at ``turn_at``, room for the robot coming out to
        turn into its lane, and square again there (lane keeping over so short a way stops
        ~100 mm short of the lane, askew). Driven diagonally at the lane, the front sensors
        read the wall near enough to stop it mid-hallway."""
        if (hold_at - s) * direction >= self.nav.pull_over_mm:
            return [self._lane(floor, hold_at, waiting_lane, detail=detail)]
        wait_at = turn_at - direction * self.nav.hold_short_mm
        if (wait_at - s) * direction <= 0:
            return []  # there already: it waits where it stands
        along = floor.travel_deg(direction)
        return [
            self._turn(floor, along, "along the hallway"),
            self._lane(floor, wait_at, waiting_lane, detail=detail),
            self._turn(floor, along, "square to the lane"),
        ]

    def _keep_right_first(
        self, floor: Floor, s: float, door: Door, direction: float, lane: float
    ) -> list[Step]:
        """Keep right along the hallway until ``pull_over_mm`` before ``door``, where the
        robot crosses to ``lane``, the door's side: on the oncoming side for the whole way it
        would meet everyone coming the other way head-on."""
        keep_right = self.lane_mm(floor, direction)
        pull_over_at = door.at_mm - direction * self.nav.pull_over_mm
        if lane == keep_right or (pull_over_at - s) * direction <= 0:
            return []
        return [self._lane(floor, pull_over_at, keep_right, stop=False, detail="along the hallway")]

    def _ride(
        self,
        from_level: int,
        to_level: int,
        goal: Place,
        car: str,
        given_back: Sequence[Lease] = (),
    ) -> ElevatorRide:
        """The ride in ``car`` to ``goal``'s floor; ``given_back``: the places it no longer
        needs once in the car (it is in nobody's way there)."""
        door_here = self.plan.car_door(car, from_level)
        door_there = self.plan.car_door(car, to_level)
        here = self._view_of(from_level, door_here)
        there = self._view_of(to_level, door_there)
        depth = self.nav.elevator.car_depth_mm
        facing = self.facing_deg(here, door_here)
        target_s = self._aim_mm(there, door_there.at_mm, goal.door)
        direction = 1.0 if target_s >= door_there.at_mm else -1.0
        out_lane = self.lane_mm(there, direction)
        straight_across = goal.inside and self._across_from(there, goal.door, door_there.at_mm)
        out_to = out_lane if straight_across else self.out_to_mm(door_there, out_lane)
        if straight_across and self.parking is not None and self._holding_point(goal) is not None:
            # Bound for the holding point, on the hallway's axis: its turn towards the point
            # has room there. In the lane in front of the room's door, 250 mm from its jamb,
            # the turn was stopped by the jamb and a robot standing in the doorway for good.
            out_to = 0.0
        out: list[Move | Lease] = [
            *self._in_front_of_car(there, True),
            self._drive_to(
                there,
                there.from_hallway(door_there.at_mm, out_to),
                f"out of the elevator on floor {to_level}",
            ),
        ]
        return ElevatorRide(
            from_floor=from_level,
            to_floor=to_level,
            car=car,
            face_doors=self._turn(here, facing, "facing the elevator doors"),
            # Parked ``car_depth_mm`` past the door line, the body's sweep about the axle
            # stays in the car: what it holds for the way in is given back before it turns,
            # and the doors may close while it turns (sent before the turn, the car rides
            # some 8 s shorter: the turn took that long before the doors began to close).
            enter=[
                self._drive_to(here, here.behind_door(door_here, depth), "into the car"),
                *given_back,
            ],
            turn_round=Move(
                MoveInstruction(
                    action="turn",
                    floor=None,
                    heading_deg=facing + 180.0,
                    detail="turning round in the car",
                )
            ),
            exit=out,
        )

    def _out_of_car(self, there: Floor, goal: Place, door_there: Door) -> list[Step]:
        """Out of the car at ``door_there`` (and the car released): a fleet's robot gives
        the elevator back, so a robot on another floor has it at once; then the robot turns
        into its lane unless its goal's door is straight across."""
        steps: list[Step] = [Lease("elevator", False)] if self.parking is not None else []
        if not (goal.inside and self._across_from(there, goal.door, door_there.at_mm)):
            aim = self._aim_mm(there, door_there.at_mm, goal.door)
            direction = 1.0 if aim >= door_there.at_mm else -1.0
            steps.append(self._turn(there, there.travel_deg(direction), "into the lane"))
        return steps

    def _across_from(self, floor: Floor, door: Door, s: float) -> bool:
        """Whether a robot at ``s`` along ``floor``'s hallway stands across it from ``door``
        (on that hallway), nearer to its
        axis than a turn onto it carries the centre: there is no stopping short of it to
        turn in (the point lies behind the robot, and the turn made arriving from the other
        way carries the centre off the axis, towards a jamb), so it turns where it stands."""
        return abs(door.at_mm - s) < self.pivot_mm

    def _along(
        self, floor: Floor, s: float, goal: Place, park: bool = True, held: bool = False
    ) -> list[Step]:
        """Along the hallway from ``s`` to the goal's door, then into it if it is parked in
        (giving the holding point back once in, if it ``held`` it)."""
        door = goal.door
        direction = 1.0 if door.at_mm >= s else -1.0
        steps: list[Step] = []
        side_lane = self.side_lane_mm(floor, door)
        keep_right = self.lane_mm(floor, direction)
        if self.nav.door_side_lane:
            steps.extend(self._keep_right_first(floor, s, door, direction, side_lane))
        lane = side_lane if self.nav.door_side_lane or goal.inside else keep_right
        spot = self.parking if goal.inside else None
        turn_at = self.turn_point_mm(door, direction)
        if spot is not None:
            # A robot may be driving out of the door: wait for the room clear of its way, as
            # close to the wall as a robot passing another, so the one coming out can pass.
            # In the lane (64 mm short of it after a short lane change) the gap was too
            # narrow for the collision monitor: the one out of the room stood in front of
            # it, holding the crossing it waited for.
            hold_at = turn_at - direction * self.nav.hold_short_mm
            waiting_lane = self.waiting_lane_mm(floor, direction)
            if lane * waiting_lane <= 0:
                waiting_lane = lane  # the door is on the other side: wait in its lane
            steps += self._wait_beside_wall(
                floor, s, hold_at, turn_at, direction, waiting_lane, f"short of {door.room}'s door"
            )
            steps.append(Lease("loading_spot", True))
            if self._crossing(floor):
                steps.append(Lease("crossing", True))
        if not (goal.inside and self._across_from(floor, door, s)):
            steps.append(
                self._lane(
                    floor,
                    turn_at if goal.inside else door.at_mm,
                    lane,
                    door=None if goal.inside else door,
                    detail=f"to {door.room}",
                )
            )
        if goal.inside:
            steps.append(self._turn(floor, self.facing_deg(floor, door), f"facing {door.room}"))
            steps.append(self.to_loading_spot(floor, door, f"into {door.room}"))
            if spot is not None and self._crossing(floor):
                steps.append(Lease("crossing", False))
            if held:
                steps.append(Lease("holding_point", False))
            if spot is None:
                steps.append(self._turn(floor, self.facing_deg(floor, door) + 180.0, "parked"))
            elif park:
                steps += self.back_to_spot()
        return steps

    # --- a fleet's base room ----------------------------------------------------------------
    # Inside the base room a robot goes between the loading spot and its parking spot along
    # the door's axis to the spot's depth, then straight across: between the parked robots,
    # never diagonally past them. A turn on the spot swings the centre about the axle, so the
    # point before a turn onto the axis is set off by ``pivot_mm`` to end on it.

    def _axis_at(self, floor: Floor, door: Door, spot: ParkingSpot) -> tuple[float, float]:
        """The door's axis at the parking spot's depth."""
        _, depth = floor.to_hallway(spot.x_mm, spot.y_mm)
        return floor.from_hallway(door.at_mm, depth)

    def _loading_to_spot(self, floor: Floor, door: Door, spot: ParkingSpot) -> list[Move]:
        return [
            self._drive_to(floor, self._axis_at(floor, door, spot), "into the room"),
            self._drive_to(floor, (spot.x_mm, spot.y_mm), "to its parking spot"),
            self._turn(floor, spot.heading_deg, "parked"),
        ]

    def _spot_to_loading(self, floor: Floor, door: Door) -> list[Move]:
        """From the parking spot onto the loading spot, facing out of the room."""
        spot = self.parking
        assert spot is not None
        ax, ay = self._axis_at(floor, door, spot)
        out = self.facing_deg(floor, door) + 180.0
        across = math.atan2(ay - spot.y_mm, ax - spot.x_mm)
        # Arriving on the axis heading ``across``, the quarter turn to ``out`` about the axle
        # leaves the centre ``pivot_mm`` further along ``across``: stop that much short.
        stop = (ax - self.pivot_mm * math.cos(across), ay - self.pivot_mm * math.sin(across))
        return [
            self._drive_to(floor, stop, "to the door's axis"),
            self._turn(floor, out, "facing the door"),
            self.to_loading_spot(floor, door),
        ]

    def to_loading_spot(
        self, floor: Floor, door: Door, detail: str = "to the loading spot"
    ) -> Move:
        """Where the cup is loaded: ``base_depth_mm`` behind the base room's door line."""
        point = floor.behind_door(door, door.recess_mm + self.nav.base_depth_mm)
        return self._drive_to(floor, point, detail)

    def loading(self) -> list[Step]:
        """From a fleet robot's parking spot onto the loading spot, facing out, holding it:
        where it waits for the cup, and where a route out of the base room starts."""
        base = self.base
        floor = self._view_of(base.floor, base.door)
        return [Lease("loading_spot", True), *self._spot_to_loading(floor, base.door)]

    def face_out(self) -> list[Step]:
        """On the loading spot, come home with its next order taken: turned round to face
        out, ready for the cup, as :meth:`loading` leaves it (no parking and coming back out,
        which held the spot twice as long). The half turn about the axle carries the centre
        into the room; the drive back puts it on the spot."""
        base = self.base
        floor = self._view_of(base.floor, base.door)
        facing_out = self._turn(floor, self.facing_deg(floor, base.door) + 180.0, "facing out")
        return [facing_out, self.to_loading_spot(floor, base.door)]

    def back_to_spot(self) -> list[Step]:
        """From the loading spot back to its parking spot (home, or no cup came), giving it
        back."""
        base = self.base
        floor = self._view_of(base.floor, base.door)
        assert self.parking is not None
        moves = self._loading_to_spot(floor, base.door, self.parking)
        return [*moves, Lease("loading_spot", False)]


def _holds(steps: list[Step], place: SharedPlace) -> bool:
    """Whether a robot that went through ``steps`` holds ``place`` at their end."""
    flat: list[Step] = []
    for step in steps:
        flat += [*step.enter, *step.exit] if isinstance(step, ElevatorRide) else [step]
    for step in reversed(flat):
        if isinstance(step, Lease) and step.place == place:
            return step.want
    return False


def _front_of_car_given_back(steps: list[Step]) -> list[Lease]:
    """Giving back whichever space in front of the car's door (the crossing, the landing) a
    robot that went through ``steps`` holds at their end."""
    return [Lease(p, False) for p in ("crossing", "landing") if _holds(steps, p)]
