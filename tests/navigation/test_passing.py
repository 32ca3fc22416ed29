"""When another robot calls for the passing lane, and where that lane is."""

from __future__ import annotations

import math

from helpers import CONFIG, PLAN, PLANNER, estimate_at, reported

from coffeebot.messages import MoveInstruction, OtherRobot, Traffic
from coffeebot.modules.motion import MotionModule
from coffeebot.navigation.motion import MotionController
from coffeebot.navigation.passing import LOOKAHEAD_MM, MAX_AGE_S, oncoming, right_lane_mm
from coffeebot.navigation.route import RoutePlanner

FLOOR = PLAN.floor(2)
HEADING = FLOOR.hallway.heading_deg
LENGTH = CONFIG.geometry.length_mm
ME_S = 13000.0  # travelling +s


def other(
    s: float,
    d: float = 445.0,
    heading: float = HEADING + 180.0,
    *,
    floor: int = 2,
    moving: bool = True,
    age_s: float = 0.0,
) -> OtherRobot:
    x, y = FLOOR.from_hallway(s, d)
    return reported(x, y, heading, floor=floor, moving=moving, age_s=age_s)


def calls(robot: OtherRobot, traffic_age_s: float = 0.0) -> bool:
    found = oncoming([robot], FLOOR, ME_S, 1.0, passed_mm=LENGTH, age_s=traffic_age_s)
    return found is not None


def test_a_robot_coming_the_other_way_ahead_calls_for_the_passing_lane() -> None:
    assert oncoming([other(17000)], FLOOR, ME_S, 1.0, passed_mm=LENGTH) == "robot-2"
    assert calls(other(ME_S + LOOKAHEAD_MM - 100))
    assert calls(other(ME_S - LENGTH / 2))  # beside: not past yet


def test_one_standing_ahead_calls_for_it_whichever_way_it_faces() -> None:
    assert calls(other(16000, -445.0, HEADING, moving=False))


def test_one_past_behind_or_beyond_the_lookahead_does_not() -> None:
    assert not calls(other(ME_S - LENGTH - 100))
    assert not calls(other(9000))
    assert not calls(other(ME_S + LOOKAHEAD_MM + 100))


def test_one_on_another_floor_or_in_a_room_does_not() -> None:
    assert not calls(other(16000, floor=3))
    assert not calls(other(16000, d=FLOOR.hallway.width_mm / 2 + 300))


def test_stale_traffic_does_not() -> None:
    assert not calls(other(16000, age_s=MAX_AGE_S + 0.1))
    assert not calls(other(16000, age_s=1.5), traffic_age_s=1.0)


def test_one_driving_away_the_same_way_does_not() -> None:
    assert not calls(other(16000, -445.0, HEADING))
    assert not calls(other(16000, -445.0, HEADING + 30.0))


def test_travelling_the_other_way_the_sides_swap() -> None:
    coming = other(10000, -445.0, HEADING)
    assert oncoming([coming], FLOOR, ME_S, -1.0, passed_mm=LENGTH) == "robot-2"
    assert oncoming([coming], FLOOR, ME_S, 1.0, passed_mm=LENGTH) is None


def test_the_passing_lane_is_on_the_right_at_its_wall_distance() -> None:
    width = CONFIG.geometry.width_mm
    half = FLOOR.hallway.width_mm / 2
    for direction in (1.0, -1.0):
        lane = right_lane_mm(FLOOR, direction, 150.0, width)
        keep_right = RoutePlanner(
            PLAN, CONFIG.motion, CONFIG.navigation, width, body_length_mm=CONFIG.geometry.length_mm
        ).lane_mm(FLOOR, direction)
        assert math.isclose(half - abs(lane) - width / 2, 150.0)
        assert math.copysign(1.0, lane) == math.copysign(1.0, keep_right)
        assert abs(lane) > abs(keep_right)


def lane_keeping(
    lane_mm: float, to_s: float, traffic: OtherRobot | None = None
) -> MotionController:
    """The controller after one period in the lane at ``ME_S`` (another robot coming the other
    way 4 m ahead unless ``traffic`` says otherwise)."""
    module = MotionModule(CONFIG, PLAN)
    if traffic is not None:
        module.controller.note_traffic(Traffic(robots=[traffic]), 0.0)
    x, y = FLOOR.from_hallway(ME_S, lane_mm)
    instruction = MoveInstruction(
        id=1, action="follow_lane", floor=2, target_s_mm=to_s, lane_mm=lane_mm
    )
    module.controller.step(instruction, estimate_at(2, x, y, HEADING), 0.5, 0.05, 500.0)
    return module.controller


KEEP_RIGHT = PLANNER.lane_mm(FLOOR, 1.0)


def test_motion_keeps_the_passing_lane_in_place_of_a_keep_right_lane() -> None:
    coming = other(17000)
    assert lane_keeping(KEEP_RIGHT, 24000, coming).passing == "robot-2"
    assert lane_keeping(KEEP_RIGHT, 24000).passing is None
    stop_near = ME_S + CONFIG.motion.approach_mm - 100
    assert lane_keeping(KEEP_RIGHT, stop_near, coming).passing is None, "the last stretch"
    assert not lane_keeping(KEEP_RIGHT, 24000, coming).yielding


def test_crossing_to_a_door_on_the_left_it_waits_for_a_robot_driving_towards_it() -> None:
    """Pulling over to a door on the left would put it in the lane of a robot coming the
    other way: it keeps to its passing lane and stops ``approach_mm`` short of the door
    until that one is by."""
    door_at = ME_S + CONFIG.motion.approach_mm + 1.0
    controller = lane_keeping(-KEEP_RIGHT, door_at, other(17000))
    assert controller.passing == "robot-2" and controller.yielding
    assert controller.speed == 0.0
    further = lane_keeping(-KEEP_RIGHT, door_at + 3000, other(17000))
    assert further.yielding and further.speed > 0.0, "it drives on up to that point"
    standing = lane_keeping(-KEEP_RIGHT, door_at, other(17000, moving=False))
    assert standing.passing is None and not standing.yielding, "one standing is gone round"
    assert lane_keeping(-KEEP_RIGHT, door_at).passing is None
