"""The go-around's phases on a costmap holding one box in the lane ahead."""

from __future__ import annotations

import numpy as np
import pytest
from helpers import CONFIG, PLAN, estimate_at

from coffeebot.messages import MotionState, MoveInstruction, RangeReading, RangeScan, ReadingStatus
from coffeebot.modules.motion import MotionModule
from coffeebot.navigation.costmap import LocalCostmap
from coffeebot.navigation.detour import REJOIN_MM, Detour, DetourPlanner, Phase
from coffeebot.navigation.dwa import rollout
from coffeebot.navigation.motion import Command, MotionController
from coffeebot.navigation.passing import right_lane_mm

FLOOR = PLAN.floor(2)
HALF_WIDTH = FLOOR.hallway.width_mm / 2
LANE = -HALF_WIDTH + CONFIG.motion.wall_distance_mm + CONFIG.geometry.width_mm / 2
START_S = 20000.0
BOX_MM = 1200
"""What the front sensors read: the box this far ahead of the robot's centre."""


def planner_with_box(seen_for_s: float) -> DetourPlanner:
    """The detour of a robot at ``START_S`` in ``LANE`` whose front sensors have seen a box
    ahead for ``seen_for_s`` seconds."""
    return module_with_box(seen_for_s).controller.detour


def module_with_box(
    seen_for_s: float,
    box_mm: float = BOX_MM,
    seeing: frozenset[int] = frozenset({2, 3}),
    lane_mm: float = LANE,
) -> MotionModule:
    """The motion module of a robot at ``START_S`` in ``lane_mm`` whose front sensors
    ``seeing`` (by default the right-hand ones: the box stands in the right half) have seen
    a box ``box_mm`` ahead for ``seen_for_s`` seconds."""
    module = MotionModule(CONFIG, PLAN)
    x, y = FLOOR.from_hallway(START_S, lane_mm)
    module.costmap.reset(FLOOR, x, y)
    readings = [
        RangeReading(sensor=s.id, status=ReadingStatus.VALID, distance_mm=box_mm)
        if s.id in seeing
        else RangeReading(sensor=s.id, status=ReadingStatus.OUT_OF_BOUNDS)
        for s in CONFIG.tof.sensors
    ]
    scan = RangeScan(cycle_start_s=0.0, cycle_time_s=0.05, readings=readings)
    for t in np.arange(0.0, seen_for_s, 0.05):
        module.costmap.update(scan, FLOOR, x, y, FLOOR.hallway.heading_deg, float(t))
    return module


def stop_in_lane(
    controller: MotionController,
    target_s: float,
    room: str | None = None,
    at_mm: float = LANE,
    lane_mm: float = LANE,
) -> list[Command]:
    """Five control periods of a robot at ``START_S`` in ``at_mm``, at rest, told to drive
    in ``lane_mm`` to a stop at ``target_s`` (at ``room``'s door, if given), going round
    what it must."""
    x, y = FLOOR.from_hallway(START_S, at_mm)
    pose = estimate_at(2, x, y, FLOOR.hallway.heading_deg)
    instruction = MoveInstruction(
        id=1,
        action="follow_lane",
        floor=2,
        target_s_mm=target_s,
        lane_mm=lane_mm,
        stop=True,
        avoid=True,
        target_door=room,
    )
    return [controller.step(instruction, pose, 3.0 + 0.05 * k, 0.05, 500.0) for k in range(5)]


def test_an_obstacle_just_seen_is_confirmed_before_it_is_gone_round() -> None:
    planner = planner_with_box(seen_for_s=0.5)
    sighting = planner.update(FLOOR, START_S, LANE, LANE, 1.0, avoid=True, now=0.5)
    assert sighting is not None and not sighting.static
    assert planner.phase is Phase.CONFIRMING
    assert planner.lane_mm is None
    assert sighting.s_mm > START_S


def test_a_static_obstacle_is_gone_round_in_a_free_lane_past_its_extent() -> None:
    planner = planner_with_box(seen_for_s=3.0)
    sighting = planner.update(FLOOR, START_S, LANE, LANE, 1.0, avoid=True, now=3.0)
    assert sighting is not None and sighting.static
    assert planner.phase is Phase.GOING_ROUND
    assert planner.detour is not None
    assert planner.lane_mm is not None and planner.lane_mm > LANE + REJOIN_MM  # to the left
    extent = planner.detour.extent_s_mm
    assert extent is not None and extent > sighting.s_mm


def test_a_robot_beyond_where_this_one_stops_is_neither_waited_for_nor_gone_round() -> None:
    """A robot waiting for the tea room short of its door swerved round the robot coming out
    of the door beyond its stop, and stood off its lane when its turn came. Something the
    body and the zone kept free ahead of it would not reach at the stop does not change where
    it stops: it drives on in its lane, also when that is nearer than the robot would wait
    from it to go round (a robot 113 mm short of its turn into the tea room waited for good
    there for one standing 1.3 m ahead, which waited for it). Stopping nearer, it waits to
    go round, as before."""
    ahead_mm, wide = 1400.0, frozenset({2, 3, 4, 5})  # across the lane: all four see it
    module = module_with_box(seen_for_s=3.0, box_mm=ahead_mm, seeing=wide)
    sighting = module.controller.detour.obstacle_ahead(FLOOR, START_S, LANE, 1.0, 3.0)
    assert sighting is not None and sighting.static
    reaches_at = sighting.near_edge(1.0) - module.controller.detour.keep_distance_mm()

    def step_to(target_s: float) -> list[Command]:
        controller = module_with_box(seen_for_s=3.0, box_mm=ahead_mm, seeing=wide).controller
        return stop_in_lane(controller, target_s)

    assert reaches_at - 200.0 > START_S + 200.0
    short = step_to(reaches_at - 200.0)
    assert all(c.status.state is MotionState.MOVING for c in short)
    assert all("obstacle" not in c.status.detail for c in short)
    assert short[-1].speed_mm_s > 0.0 and abs(short[-1].yaw_rate_dps) < 1.0
    waits_at = sighting.near_edge(1.0) - module.controller.detour.wait_distance_mm()
    beyond_waiting = step_to(waits_at + 200.0)
    assert reaches_at > waits_at + 200.0
    assert all("obstacle" not in c.status.detail for c in beyond_waiting)
    assert beyond_waiting[-1].speed_mm_s > 0.0
    near = step_to(reaches_at + 200.0)
    # Closing in to wait in front of it: no lane past a robot across the hallway.
    assert near[-1].status.detail == "no way past the obstacle ahead, waiting"


def test_a_box_just_before_a_stop_in_the_lane_is_waited_for_not_gone_round() -> None:
    """A robot that went round another just before the elevator ended its move 334 mm off
    the lane it had to turn from, and its turn into the car had no room (a fleet jam; before
    turns were checked, a contact). A move that ends in its lane (no door's: a turn or a
    wait follows) begins no go-round it would not be back from by its end; a move to an
    office door, where the customer takes the cup wherever the robot stands, still does."""
    module = module_with_box(seen_for_s=3.0)
    sighting = module.controller.detour.obstacle_ahead(FLOOR, START_S, LANE, 1.0, 3.0)
    assert sighting is not None and sighting.static
    stop_at = sighting.far_edge(1.0) + 1000.0  # past the box, not back in the lane by then

    def go(room: str | None, target_s: float) -> tuple[Command, Phase | None]:
        controller = module_with_box(seen_for_s=3.0).controller
        return stop_in_lane(controller, target_s, room)[-1], controller.detour.phase

    waits, phase = go(None, stop_at)
    assert phase is Phase.CONFIRMING and waits.speed_mm_s == 0.0
    assert waits.status.detail == "obstacle ahead, too near the stop to go round, waiting"
    _, phase = go("209", stop_at)
    assert phase is Phase.GOING_ROUND
    _, phase = go(None, stop_at + 3000.0)  # room to be back in the lane first
    assert phase is Phase.GOING_ROUND


def test_not_allowed_to_leave_the_lane_it_stays_confirming() -> None:
    planner = planner_with_box(seen_for_s=3.0)
    planner.update(FLOOR, START_S, LANE, LANE, 1.0, avoid=False, now=3.0)
    assert planner.phase is Phase.CONFIRMING


def test_past_the_obstacle_it_rejoins_then_hands_back_to_lane_keeping() -> None:
    planner = planner_with_box(seen_for_s=3.0)
    planner.update(FLOOR, START_S, LANE, LANE, 1.0, avoid=True, now=3.0)
    assert planner.detour is not None and planner.detour.extent_s_mm is not None
    detour_lane = planner.lane_mm
    assert detour_lane is not None
    # Beside the box, the rear not yet past it: still going round.
    beside = planner.detour.extent_s_mm
    planner.update(FLOOR, beside, detour_lane, LANE, 1.0, avoid=True, now=3.1)
    assert planner.phase is Phase.GOING_ROUND
    # The rear is past: steer back to the instruction's lane.
    past = beside + CONFIG.geometry.length_mm / 2 + CONFIG.motion.obstacle_clearance_mm + 50
    planner.update(FLOOR, past, detour_lane, LANE, 1.0, avoid=True, now=3.2)
    assert planner.phase is Phase.REJOINING
    assert planner.lane_mm == LANE
    # Within REJOIN_MM of the lane, the detour ends.
    planner.update(FLOOR, past + 500, LANE + REJOIN_MM / 2, LANE, 1.0, avoid=True, now=3.3)
    assert planner.phase is None and planner.detour is None


def test_a_new_obstacle_while_rejoining_is_judged_afresh() -> None:
    planner = planner_with_box(seen_for_s=3.0)
    planner.update(FLOOR, START_S, LANE, LANE, 1.0, avoid=True, now=3.0)
    planner.detour = Detour(phase=Phase.REJOINING, lane_mm=LANE)
    sighting = planner.update(FLOOR, START_S, LANE + 300, LANE, 1.0, avoid=False, now=3.0)
    assert sighting is not None
    assert planner.phase is Phase.CONFIRMING


# --- narrow returns: a pole carries what the cones do not see --------------------------------

MARGIN = CONFIG.collision.narrow_margin_mm


def planner_seeing(readings_mm: dict[int, float], seen_for_s: float, narrow: bool) -> DetourPlanner:
    """The detour of a robot at ``START_S`` in ``LANE`` whose front sensors have read
    ``readings_mm`` (sensor id: distance; the others nothing) for ``seen_for_s`` seconds, on
    a costmap that flags narrow returns or (``narrow`` False) one that does not."""
    module = MotionModule(CONFIG, PLAN)
    costmap = module.costmap
    if not narrow:
        costmap = LocalCostmap(
            CONFIG.motion, CONFIG.tof.sensors, module.footprint, CONFIG.tof.cone_half_deg
        )
    x, y = FLOOR.from_hallway(START_S, LANE)
    costmap.reset(FLOOR, x, y)
    readings = [
        RangeReading(sensor=s.id, status=ReadingStatus.VALID, distance_mm=readings_mm[s.id])
        if s.id in readings_mm
        else RangeReading(sensor=s.id, status=ReadingStatus.OUT_OF_BOUNDS)
        for s in CONFIG.tof.sensors
    ]
    scan = RangeScan(cycle_start_s=0.0, cycle_time_s=0.05, readings=readings)
    for t in np.arange(0.0, seen_for_s, 0.05):
        costmap.update(scan, FLOOR, x, y, FLOOR.hallway.heading_deg, float(t))
    return DetourPlanner(CONFIG.motion, costmap, module.footprint)


def test_a_narrow_return_gets_the_narrow_margin_and_a_wide_one_does_not() -> None:
    """What one front sensor sees while its neighbours see nothing is narrow (a pole, a leg):
    its cells count ``narrow_margin_mm`` nearer in every gap the planners ask for. The
    same distance read across all four front sensors is a wall of something: no margin."""
    pole = planner_seeing({3: 900}, seen_for_s=0.5, narrow=True).costmap
    plain = planner_seeing({3: 900}, seen_for_s=0.5, narrow=False).costmap
    wide = planner_seeing(dict.fromkeys((2, 3, 4, 5), 900), seen_for_s=0.5, narrow=True).costmap
    # Seen by the left half of the row only: the edge of something wide (a box in the
    # left half of the lane) as well as a pole, so no margin either.
    half = planner_seeing({4: 700, 5: 700}, seen_for_s=0.5, narrow=True).costmap
    assert set(pole.obstacles(0.5).margins) == {MARGIN}
    assert set(plain.obstacles(0.5).margins) == {0.0}
    assert set(wide.obstacles(0.5).margins) == {0.0}
    assert half.obstacles(0.5).margins.size > 0 and set(half.obstacles(0.5).margins) == {0.0}
    x, y = FLOOR.from_hallway(START_S, LANE)
    pose = (np.array([x]), np.array([y]), np.array([np.radians(FLOOR.hallway.heading_deg)]))
    gap_pole = pole.obstacle_gaps(*pose, now=0.5)[0]
    gap_plain = plain.obstacle_gaps(*pose, now=0.5)[0]
    assert gap_pole == pytest.approx(gap_plain - MARGIN)


def test_a_narrow_return_is_placed_at_the_near_end_of_its_spread() -> None:
    """A pole in front of a far wall reads beyond it with a large sigma: its cells go where
    the collision monitor judges it, 1.5 sigmas nearer, so the margin is kept from the pole."""
    module = MotionModule(CONFIG, PLAN)
    x, y = FLOOR.from_hallway(START_S, LANE)
    module.costmap.reset(FLOOR, x, y)
    readings = [
        RangeReading(sensor=3, status=ReadingStatus.VALID, distance_mm=1100, sigma_mm=100.0)
    ] + [
        RangeReading(sensor=s.id, status=ReadingStatus.OUT_OF_BOUNDS)
        for s in CONFIG.tof.sensors
        if s.id != 3
    ]
    module.costmap.update(
        RangeScan(cycle_start_s=0.0, cycle_time_s=0.05, readings=readings),
        FLOOR,
        x,
        y,
        FLOOR.hallway.heading_deg,
        0.0,
    )
    xs, ys, _, _ = module.costmap.obstacles(0.0)
    along = np.array([FLOOR.to_hallway(cx, cy)[0] for cx, cy in zip(xs, ys, strict=True)])
    sensor = next(s for s in CONFIG.tof.sensors if s.id == 3)
    nearest = along.min() - START_S - sensor.x_mm
    assert 900 < nearest < 1000  # 1100 less 1.5 x 100, not 1100


def test_a_detour_round_a_narrow_thing_keeps_the_overhang_margin() -> None:
    """A swivel chair's pole in the lane: the lane past it is chosen clear of the pole by the
    body, the clearance and the narrow margin (the seat overhangs the pole by ~240 mm), so
    it lies at least the margin further out than past a thing of the pole's size alone; and
    the body's rear must be past the pole by the margin before the robot rejoins."""
    reading = {3: 1000}
    narrow = planner_seeing(reading, seen_for_s=3.0, narrow=True)
    plain = planner_seeing(reading, seen_for_s=3.0, narrow=False)
    for planner in (narrow, plain):
        planner.update(FLOOR, START_S, LANE, LANE, 1.0, avoid=True, now=3.0)
    assert narrow.lane_mm is not None and plain.lane_mm is not None
    assert narrow.lane_mm >= plain.lane_mm + MARGIN - CONFIG.motion.costmap_resolution_mm
    xs, ys, _, _ = narrow.costmap.obstacles(3.0)
    cells_d = np.array([FLOOR.to_hallway(cx, cy)[1] for cx, cy in zip(xs, ys, strict=True)])
    body = CONFIG.geometry.width_mm / 2 + CONFIG.motion.obstacle_clearance_mm
    assert np.all(np.abs(cells_d - narrow.lane_mm) >= body + MARGIN)
    assert narrow.detour is not None and plain.detour is not None
    assert narrow.detour.extent_s_mm is not None and plain.detour.extent_s_mm is not None
    assert narrow.detour.extent_s_mm == pytest.approx(plain.detour.extent_s_mm + MARGIN)


def test_a_pole_beside_the_lane_whose_seat_reaches_into_it_is_in_the_way() -> None:
    """A pole just outside the lane's width (body plus clearance) is no obstacle to the body
    going straight, but the seat it carries is: seen narrow, it is an obstacle ahead."""
    sensor = next(s for s in CONFIG.tof.sensors if s.id == 3)  # the inner right one
    reading = {3: 450}
    narrow = planner_seeing(reading, seen_for_s=0.5, narrow=True)
    plain = planner_seeing(reading, seen_for_s=0.5, narrow=False)
    # Move the lane left until the plain return is just out of it.
    xs, ys, _, _ = plain.costmap.obstacles(0.5)
    cells_d = np.array([FLOOR.to_hallway(cx, cy)[1] for cx, cy in zip(xs, ys, strict=True)])
    half = CONFIG.geometry.width_mm / 2 + CONFIG.motion.obstacle_clearance_mm
    lane = float(cells_d.max()) + half + 10.0
    assert sensor.yaw_deg < 0
    assert plain.obstacle_ahead(FLOOR, START_S, lane, 1.0, 0.5) is None
    sighting = narrow.obstacle_ahead(FLOOR, START_S, lane, 1.0, 0.5)
    assert sighting is not None and sighting.margin_mm == MARGIN
    assert sighting.near_edge(1.0) == pytest.approx(sighting.s_mm - MARGIN)


def test_turning_out_keeps_the_front_corner_the_margin_from_a_pole() -> None:
    """The corner sweep: turning on the spot swings a front corner forward. Past a pole
    seen as narrow, a turn that keeps clear of the pole itself but not of what it carries is
    refused; past the same return seen as part of something wide it is allowed."""
    reading = {4: 420}
    narrow = planner_seeing(reading, seen_for_s=0.5, narrow=True).costmap
    plain = planner_seeing(reading, seen_for_s=0.5, narrow=False).costmap
    x, y = FLOOR.from_hallway(START_S, LANE)
    heading = np.radians(FLOOR.hallway.heading_deg)
    times = np.linspace(0.0, np.radians(40.0), 7)
    xs, ys, headings = rollout((x, y, heading), np.zeros(1), np.array([-1.0]), times, 150.0)
    start = (x, y, heading)
    assert plain.admissible(xs, ys, headings, start, 0.5, plain.body)[0][0]
    assert not narrow.admissible(xs, ys, headings, start, 0.5, narrow.body)[0][0]


def test_waiting_beside_the_wall_it_does_not_turn_towards_a_lane_across() -> None:
    """Told to cross the hallway (to the car, to a door on the left) and waiting beside the
    wall for what stands ahead, it does not begin a turn towards the lane across that
    would swing its rear about the axle into the wall's margin (in the fleet benchmark a
    robot waiting there turned 14 degrees, and its side sensor, reading the wall at 49 mm,
    held it 71 s while it held the car). In its keep-right lane the same turn has room."""
    beside_wall = right_lane_mm(
        FLOOR, 1.0, CONFIG.motion.passing_wall_distance_mm, CONFIG.geometry.width_mm
    )

    def waiting(lane_mm: float, turning_dps: float = 0.0) -> list[float]:
        module = module_with_box(3.0, 800, frozenset({2, 3, 4, 5}), lane_mm)
        module.controller.yaw_rate = turning_dps
        commands = stop_in_lane(module.controller, START_S + 3000.0, None, lane_mm, -LANE)
        assert module.controller.detour.phase is Phase.CONFIRMING
        assert all(c.speed_mm_s == 0.0 for c in commands)
        return [c.yaw_rate_dps for c in commands]

    assert all(rate == 0.0 for rate in waiting(beside_wall))
    assert any(rate > 0.0 for rate in waiting(LANE)), "room to turn: it turns"
    # A turn begun while it still rolled is not carried on once it stands.
    rates = waiting(beside_wall, turning_dps=10.0)
    assert rates == sorted(rates, reverse=True) and rates[-1] == 0.0, rates
