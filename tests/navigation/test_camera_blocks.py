"""Which things the ceiling cameras see block the robot's way, and where it holds short."""

from __future__ import annotations

import numpy as np
import pytest
from helpers import CONFIG, PLAN, PLANNER

from coffeebot.messages import CameraLayer, CameraObject, MoveInstruction
from coffeebot.navigation.camera_blocks import (
    BlockRule,
    Extent,
    Leg,
    camera_marks,
    fresh_objects,
    leg_ends,
    outline,
)
from coffeebot.navigation.route import ElevatorRide, Lease, Move

RULE = BlockRule.from_config(CONFIG)
FLOOR2, FLOOR3 = PLAN.floor(2), PLAN.floor(3)
HALF_WIDTH = FLOOR2.hallway.width_mm / 2
FRONT = CONFIG.geometry.length_mm / 2
SHORT = CONFIG.navigation.camera_stop_short_mm
NEEDED = (
    CONFIG.geometry.width_mm + CONFIG.motion.side_clearance_mm + CONFIG.motion.obstacle_clearance_mm
)


def thing(
    s: float,
    d: float,
    *,
    across_mm: float,
    along_mm: float,
    floor: int = 2,
    ident: str = "t1",
) -> CameraObject:
    """Something standing at hallway (``s``, ``d``), ``across_mm`` across the hallway and
    ``along_mm`` along it (the long side across when it is the longer)."""
    x, y = PLAN.floor(floor).from_hallway(s, d)
    heading = PLAN.floor(floor).hallway.heading_deg
    across_is_long = across_mm >= along_mm
    return CameraObject(
        id=ident,
        camera_id="north-2",
        floor=floor,
        x_mm=x,
        y_mm=y,
        length_mm=max(across_mm, along_mm),
        width_mm=min(across_mm, along_mm),
        axis_deg=(heading + (90.0 if across_is_long else 0.0)) % 180.0,
        standing_since_s=0.0,
        seen_s=10.0,
    )


def box_across(s: float, floor: int = 2) -> CameraObject:
    """A 1200 x 600 mm cart across the middle of the hallway: 250 mm left each side."""
    return thing(s, 0.0, across_mm=1200.0, along_mm=600.0, floor=floor)


def leg(direction: float, target: float, end: float | None = None, floor: int = 2) -> Leg:
    return Leg(PLAN.floor(floor), direction, target, target if end is None else end)


def test_a_cart_across_the_hallway_ahead_blocks_and_is_waited_for_short_of_it() -> None:
    block = RULE.blocking(leg(1.0, 21000.0), 10000.0, 0.0, [box_across(15000.0)])
    assert block is not None
    assert block.object_id == "t1"
    assert block.free_mm == pytest.approx(HALF_WIDTH - 600.0)
    assert block.near_s_mm == pytest.approx(15000.0 - 300.0)
    # The body's front the configured distance before the near edge.
    assert block.stop_s_mm + FRONT == pytest.approx(block.near_s_mm - SHORT)
    assert block.waiting_detail == (
        "Something is blocking the hallway near room 205 (seen by a ceiling camera); "
        "the robot waits until it is cleared."
    )


def test_a_cart_along_the_wall_leaves_room_to_pass() -> None:
    against_wall = thing(15000.0, HALF_WIDTH - 300.0, across_mm=600.0, along_mm=900.0)
    free = Extent.of(FLOOR2, against_wall).free_width_mm(FLOOR2)
    assert free == pytest.approx(FLOOR2.hallway.width_mm - 600.0)
    assert RULE.blocking(leg(1.0, 21000.0), 10000.0, 0.0, [against_wall]) is None


def test_the_room_needed_is_the_body_and_the_clearances_motion_keeps() -> None:
    """A thing against the wall leaving just less than the robot needs blocks; just more
    does not."""
    for spare, blocks in ((-10.0, True), (10.0, False)):
        across = FLOOR2.hallway.width_mm - NEEDED - spare
        standing = thing(15000.0, HALF_WIDTH - across / 2, across_mm=across, along_mm=400.0)
        block = RULE.blocking(leg(1.0, 21000.0), 10000.0, 0.0, [standing])
        assert (block is not None) is blocks


def test_what_is_behind_the_robot_changes_nothing() -> None:
    assert RULE.blocking(leg(1.0, 21000.0), 16000.0, 0.0, [box_across(15000.0)]) is None


def test_what_stands_beyond_the_goal_changes_nothing() -> None:
    assert RULE.blocking(leg(1.0, 12000.0), 10000.0, 0.0, [box_across(15000.0)]) is None


def test_what_stands_on_the_other_floor_changes_nothing() -> None:
    on_three = box_across(15000.0, floor=3)
    assert RULE.blocking(leg(1.0, 21000.0), 10000.0, 0.0, [on_three]) is None
    # The same cart blocks a robot driving on floor 3.
    block = RULE.blocking(leg(1.0, 21000.0, floor=3), 10000.0, 0.0, [on_three])
    assert block is not None and block.place == "room 305"


def test_what_stands_in_a_room_changes_nothing() -> None:
    in_room = thing(15000.0, HALF_WIDTH + 1500.0, across_mm=1200.0, along_mm=600.0)
    assert Extent.of(FLOOR2, in_room).free_width_mm(FLOOR2) is None
    assert RULE.blocking(leg(1.0, 21000.0), 10000.0, 0.0, [in_room]) is None


def test_driving_the_other_way_the_near_edge_is_the_other_one() -> None:
    block = RULE.blocking(leg(-1.0, 9000.0), 20000.0, 0.0, [box_across(15000.0)])
    assert block is not None
    assert block.near_s_mm == pytest.approx(15000.0 + 300.0)
    assert block.stop_s_mm - FRONT == pytest.approx(block.near_s_mm + SHORT)
    # The same cart lies the other way from a robot driving from 10000 towards 3000.
    assert RULE.blocking(leg(-1.0, 3000.0), 10000.0, 0.0, [box_across(15000.0)]) is None


def test_the_nearest_of_two_is_the_one_waited_for() -> None:
    far, near = box_across(18000.0), box_across(14000.0)
    block = RULE.blocking(leg(1.0, 21000.0), 10000.0, 0.0, [far, near])
    assert block is not None and block.near_s_mm == pytest.approx(14000.0 - 300.0)


def test_the_hold_is_never_behind_where_the_robot_can_stand_still() -> None:
    """Seen late, 1 m ahead: the robot holds where it is (standing) or where it can stop
    (driving), never further back: motion would turn round to drive back to it."""
    cart = box_across(15000.0)
    standing = RULE.blocking(leg(1.0, 21000.0), 14000.0, 0.0, [cart])
    assert standing is not None and standing.stop_s_mm == pytest.approx(14000.0)
    speed = 300.0
    driving = RULE.blocking(leg(1.0, 21000.0), 14000.0, speed, [cart])
    braking = speed**2 / (2 * CONFIG.motion.accel_mm_s2)
    assert driving is not None and driving.stop_s_mm == pytest.approx(14000.0 + braking)
    back = RULE.blocking(leg(-1.0, 3000.0), 16000.0, speed, [cart])
    assert back is not None and back.stop_s_mm == pytest.approx(16000.0 - braking)


def test_the_hold_is_at_the_end_of_the_current_move_when_that_comes_first() -> None:
    """A lane change at 12000 before a cart blocking the leg beyond it: the robot holds at
    the lane change, further short, not at speed past it."""
    block = RULE.blocking(leg(1.0, 12000.0, end=21000.0), 10000.0, 0.0, [box_across(15000.0)])
    assert block is not None and block.stop_s_mm == pytest.approx(12000.0)


def test_a_cart_right_beyond_the_door_blocks_the_body_standing_at_it() -> None:
    """The centre stops at the door; the front reaches half a length beyond it."""
    beyond = box_across(21000.0 + 300.0 + FRONT / 2)
    assert RULE.blocking(leg(1.0, 21000.0), 10000.0, 0.0, [beyond]) is not None


def test_a_turned_cart_is_measured_by_its_corners() -> None:
    """A 1000 x 1000 mm crate turned 45 degrees reaches 707 mm either way of its centre."""
    crate = thing(15000.0, 0.0, across_mm=1000.0, along_mm=1000.0)
    crate = crate.model_copy(update={"axis_deg": 45.0})
    extent = Extent.of(FLOOR2, crate)
    half_diagonal = 1000.0 / np.sqrt(2.0)
    assert (extent.d_lo, extent.d_hi) == pytest.approx((-half_diagonal, half_diagonal))
    assert (extent.s_lo, extent.s_hi) == pytest.approx(
        (15000.0 - half_diagonal, 15000.0 + half_diagonal)
    )


def test_the_place_is_named_as_people_name_it() -> None:
    block = RULE.blocking(leg(1.0, 42000.0), 30000.0, 0.0, [box_across(41000.0)])
    assert block is not None and block.place == "the elevator"


def test_a_stale_or_missing_layer_is_no_information() -> None:
    layer = CameraLayer(objects=[box_across(15000.0)], expiry_s=5.0)
    stale_s = CONFIG.navigation.camera_stale_s
    assert fresh_objects(layer, 0.5, stale_s) == layer.objects
    assert fresh_objects(layer, stale_s + 0.1, stale_s) == []
    assert fresh_objects(None, None, stale_s) == []


def test_marks_lie_on_each_outline_by_floor() -> None:
    cart = thing(15000.0, -500.0, across_mm=600.0, along_mm=900.0)
    other = box_across(15000.0, floor=3).model_copy(update={"standing_since_s": 4.0})
    marks = camera_marks([cart, other], spacing_mm=25.0)
    assert set(marks) == {2, 3}
    xs, ys, since = marks[2]
    sd = np.array([FLOOR2.to_hallway(x, y) for x, y in zip(xs, ys, strict=True)])
    along, across = np.abs(sd[:, 0] - 15000.0), np.abs(sd[:, 1] + 500.0)
    on_side = np.isclose(along, 450.0) | np.isclose(across, 300.0)
    assert on_side.all() and (along <= 450.0 + 1e-6).all() and (across <= 300.0 + 1e-6).all()
    gaps = np.hypot(np.diff(xs), np.diff(ys))
    assert gaps[gaps > 0].max() <= 25.0 + 1e-6  # dense enough to mark every cell it crosses
    assert (since == 0.0).all() and (marks[3][2] == 4.0).all()
    assert outline(cart).shape == (4, 4)


def test_a_leg_runs_over_lane_moves_without_a_turn_between() -> None:
    """To 305 from the tea room: the lane move out of the car is its own leg on floor 3;
    every other step has none."""
    base = PLANNER.base
    route = PLANNER.route(2, base.door.at_mm, PLANNER.door_place("305"), base.door)
    ends = leg_ends(route.steps)
    for step, end in zip(route.steps, ends, strict=True):
        lane = isinstance(step, Move) and step.instruction.action == "follow_lane"
        assert (end is not None) is lane
        if lane:
            assert isinstance(step, Move) and end == 15000.0
    assert any(isinstance(step, ElevatorRide) for step in route.steps)


def lane_move(target: float, floor: int = 2, stop: bool = True) -> Move:
    return Move(MoveInstruction(action="follow_lane", floor=floor, target_s_mm=target, stop=stop))


def test_a_lane_change_on_the_way_is_one_leg_with_the_move_after_it() -> None:
    """Leases between lane moves move nothing; a turn ends the leg, and so does the floor."""
    along = lane_move(18000.0, stop=False)
    turn = Move(MoveInstruction(action="turn", floor=2, heading_deg=90.0))
    steps = [
        along,
        Lease("elevator", True),
        lane_move(21000.0),
        turn,
        lane_move(30000.0),
        lane_move(9000.0, floor=3),
    ]
    assert leg_ends(steps) == [21000.0, None, 21000.0, None, 30000.0, 9000.0]
