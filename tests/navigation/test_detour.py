"""The go-around's phases on a costmap holding one box in the lane ahead."""

from __future__ import annotations

import numpy as np
from helpers import CONFIG, PLAN

from coffeebot.messages import RangeReading, RangeScan, ReadingStatus
from coffeebot.modules.motion import MotionModule
from coffeebot.navigation.detour import REJOIN_MM, Detour, DetourPlanner, Phase

FLOOR = PLAN.floor(2)
HALF_WIDTH = FLOOR.hallway.width_mm / 2
LANE = -HALF_WIDTH + CONFIG.motion.wall_distance_mm + CONFIG.geometry.width_mm / 2
START_S = 20000.0
BOX_MM = 1200
"""What the front sensors read: the box this far ahead of the robot's centre."""


def planner_with_box(seen_for_s: float) -> DetourPlanner:
    """The detour of a robot at ``START_S`` in ``LANE`` whose front sensors have seen a box
    ahead for ``seen_for_s`` seconds."""
    module = MotionModule(CONFIG, PLAN)
    x, y = FLOOR.from_hallway(START_S, LANE)
    module.costmap.reset(FLOOR, x, y)
    seeing = {2, 3}  # the right-hand front sensors: the box stands in the right half
    readings = [
        RangeReading(sensor=s.id, status=ReadingStatus.VALID, distance_mm=BOX_MM)
        if s.id in seeing
        else RangeReading(sensor=s.id, status=ReadingStatus.OUT_OF_BOUNDS)
        for s in CONFIG.tof.sensors
    ]
    scan = RangeScan(cycle_start_s=0.0, cycle_time_s=0.05, readings=readings)
    for t in np.arange(0.0, seen_for_s, 0.05):
        module.costmap.update(scan, FLOOR, x, y, FLOOR.hallway.heading_deg, float(t))
    return module.controller.detour


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
