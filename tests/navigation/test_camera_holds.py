"""Navigation and motion acting on what the ceiling cameras see standing in the hallway."""

from __future__ import annotations

import asyncio
import contextlib
from collections.abc import AsyncIterator
from dataclasses import dataclass, field

import pytest
from helpers import CONFIG, PLAN, PLANNER, estimate_at

from coffeebot.board import Board
from coffeebot.daemon import Daemon
from coffeebot.messages import (
    ALL_TOPICS,
    CAMERA_LAYER,
    COLLISION,
    CURRENT_STATE,
    DELIVERY_STATUS,
    MOTION_STATUS,
    MOVE_INSTRUCTION,
    ODOMETRY,
    OPERATOR_EVENT,
    ORDER_DISPATCH,
    RANGE_SCAN,
    CameraLayer,
    CameraObject,
    CollisionStatus,
    CurrentState,
    DeliveryProblem,
    DeliveryUpdate,
    MotionState,
    MotionStatus,
    MoveInstruction,
    Odometry,
    OperatorEvent,
    OrderDispatch,
    OrderStatus,
    RangeReading,
    RangeScan,
    ReadingStatus,
    SafetyState,
)
from coffeebot.modules.motion import MotionModule
from coffeebot.modules.navigation import NavigationModule
from manual_clock import ManualClock

FLOOR = PLAN.floor(2)
HALF_WIDTH = FLOOR.hallway.width_mm / 2
FRONT = CONFIG.geometry.length_mm / 2


def standing(s: float, d: float, across_mm: float, along_mm: float, floor: int = 2) -> CameraObject:
    """Something the cameras see standing at hallway (``s``, ``d``) since time 0."""
    x, y = PLAN.floor(floor).from_hallway(s, d)
    long_across = across_mm >= along_mm
    return CameraObject(
        id=f"{floor}:{s:.0f}:{d:.0f}",
        camera_id="north-2",
        floor=floor,
        x_mm=x,
        y_mm=y,
        length_mm=max(across_mm, along_mm),
        width_mm=min(across_mm, along_mm),
        axis_deg=90.0 if long_across else 0.0,
        standing_since_s=0.0,
        seen_s=0.0,
    )


CART = standing(30000.0, 0.0, across_mm=1200.0, along_mm=600.0)
"""A cart across the middle of the hallway between the tea room (42 m) and 207 (21 m)."""


# --- navigation: holding short of a blocked stretch ----------------------------------------


class Driving:
    """Motion that drives lane moves along the hallway at a steady pace, finishing every
    other move at once, and reports as motion does; and a camera service publishing its
    layer every second while it runs."""

    SPEED_MM_S = 500.0
    TICK_S = 0.1

    def __init__(self, board: Board, clock: ManualClock) -> None:
        self.board = board
        self.clock = clock
        self.objects: list[CameraObject] = []
        self.cameras_on = True
        self.ident = -1
        self.direction = 1.0

    def s(self) -> float:
        pose = self.board.latest(CURRENT_STATE).msg.pose
        return FLOOR.to_hallway(pose.x_mm, pose.y_mm)[0]

    async def motion(self) -> None:
        while True:
            await self.clock.sleep(self.TICK_S)
            latest = self.board.latest(MOVE_INSTRUCTION)
            if latest is not None:
                self._step(latest.msg)

    def _step(self, ins: MoveInstruction) -> None:
        pose = self.board.latest(CURRENT_STATE).msg.pose
        state, remaining, speed = MotionState.DONE, 0.0, 0.0
        x, y = pose.x_mm, pose.y_mm
        if ins.action == "follow_lane":
            s = self.s()
            if ins.id != self.ident:
                self.direction = 1.0 if ins.target_s_mm >= s else -1.0
            remaining = (ins.target_s_mm - s) * self.direction
            step = self.SPEED_MM_S * self.TICK_S
            if remaining > step:
                s += self.direction * step
                state, speed = MotionState.MOVING, self.SPEED_MM_S
            else:
                s = ins.target_s_mm
            x, y = FLOOR.from_hallway(s, ins.lane_mm)
            remaining = (ins.target_s_mm - s) * self.direction
        elif ins.action == "drive_to":
            x, y = ins.x_mm, ins.y_mm
        elif ins.action in ("stop", "wait"):
            state = MotionState.IDLE
        self.ident = ins.id
        moved = estimate_at(2, x, y).model_copy(update={"speed_mm_s": speed})
        self.board.publish(CURRENT_STATE, CurrentState(pose=moved))
        self.board.publish(
            MOTION_STATUS,
            MotionStatus(
                instruction_id=ins.id, state=state, remaining_mm=remaining, detail=ins.detail
            ),
        )

    async def cameras(self) -> None:
        while True:
            if self.cameras_on:
                layer = CameraLayer(objects=self.objects, expiry_s=5.0)
                self.board.publish(CAMERA_LAYER, layer)
            await self.clock.sleep(1.0)


@dataclass
class Rig:
    clock: ManualClock
    board: Board
    world: Driving
    updates: list[DeliveryUpdate] = field(default_factory=list)

    def take_updates(self) -> list[DeliveryUpdate]:
        taken, self.updates = self.updates, []
        return taken


@pytest.fixture
async def rig() -> AsyncIterator[Rig]:
    clock = ManualClock(0.0)
    board = Board(ALL_TOPICS, clock=clock)
    x, y = FLOOR.behind_door(PLANNER.base.door, 800)
    board.publish(CURRENT_STATE, CurrentState(pose=estimate_at(2, x, y, 90.0)))
    daemon = Daemon(board, [NavigationModule(CONFIG, PLAN)])
    world = Driving(board, clock)
    rig = Rig(clock, board, world)

    async def collect() -> None:
        with board.subscribe(DELIVERY_STATUS) as statuses:
            async for envelope in statuses:
                rig.updates.append(envelope.msg)

    tasks = [
        asyncio.create_task(world.motion()),
        asyncio.create_task(world.cameras()),
        asyncio.create_task(collect()),
    ]
    await daemon.start()
    yield rig
    for task in tasks:
        task.cancel()
        with contextlib.suppress(asyncio.CancelledError):
            await task
    await daemon.shutdown()


async def leave_for_207(rig: Rig) -> None:
    """The order placed and the cup loaded: the robot drives out of the tea room towards
    207, down the hallway (towards the start of its axis)."""
    rig.board.publish(ORDER_DISPATCH, OrderDispatch(order_id="o1", room="207", drink="tea"))
    await rig.clock.advance(1.0)
    rig.board.publish(OPERATOR_EVENT, OperatorEvent(kind="cup_loaded", order_id="o1"))
    await rig.clock.advance(2.0)
    assert rig.world.s() < PLANNER.base.door.at_mm  # on its way down the hallway
    assert [u.status for u in rig.take_updates()] == [
        OrderStatus.PREPARING,
        OrderStatus.ON_THE_WAY,
    ]


async def test_a_blocked_stretch_holds_the_robot_short_until_it_is_cleared(rig: Rig) -> None:
    await leave_for_207(rig)
    rig.world.objects = [CART]
    await rig.clock.advance(60.0)  # without the cart it would have arrived after 42 s
    near_edge = 30000.0 + 300.0
    held_at = rig.world.s()
    assert held_at - FRONT == pytest.approx(near_edge + CONFIG.navigation.camera_stop_short_mm)
    blocked = [u for u in rig.take_updates() if u.problem is DeliveryProblem.BLOCKED]
    assert [(u.status, u.detail) for u in blocked] == [
        (
            OrderStatus.ON_THE_WAY,
            "Something is blocking the hallway near room 210 (seen by a ceiling camera); "
            "the robot waits until it is cleared.",
        )
    ]
    # Still there a minute later, the layer still showing it: it keeps waiting.
    await rig.clock.advance(60.0)
    assert rig.world.s() == pytest.approx(held_at)
    assert rig.take_updates() == []
    # Cleared: the leg goes on to the door.
    rig.world.objects = []
    await rig.clock.advance(40.0)
    updates = rig.take_updates()
    assert [(u.status, u.detail, u.problem) for u in updates] == [
        (OrderStatus.ON_THE_WAY, "on the way again: to 207", None),
        (OrderStatus.ARRIVED, "at the door of 207 (+0 mm)", None),
    ]
    assert rig.world.s() == pytest.approx(21000.0)


async def test_a_stretch_blocked_for_good_fails_the_delivery_in_the_end(rig: Rig) -> None:
    """Nothing waits forever: after ``blocked_give_up_s`` the delivery fails with the reason,
    and the robot drives back to the tea room (away from the cart)."""
    await leave_for_207(rig)
    rig.world.objects = [CART]
    await rig.clock.advance(CONFIG.navigation.blocked_give_up_s + 30.0)
    failed = [u for u in rig.take_updates() if u.status.final]
    assert [(u.status, u.problem) for u in failed] == [
        (OrderStatus.FAILED, DeliveryProblem.BLOCKED)
    ]
    assert failed[0].detail == (
        f"blocked for {CONFIG.navigation.blocked_give_up_s:.0f} s: something blocking the "
        "hallway near room 210 (seen by a ceiling camera)"
    )
    await rig.clock.advance(30.0)
    assert rig.world.s() == pytest.approx(PLANNER.base.door.at_mm)


async def test_a_layer_gone_stale_is_no_reason_to_keep_waiting(rig: Rig) -> None:
    """The camera service stops (no layer for longer than ``camera_stale_s``): what it last
    showed is no longer waited for; the robot's own sensors answer for what is there."""
    await leave_for_207(rig)
    rig.world.objects = [CART]
    await rig.clock.advance(1.5)  # the next layer shows it
    assert [u.problem for u in rig.take_updates()] == [DeliveryProblem.BLOCKED]
    rig.world.cameras_on = False
    await rig.clock.advance(60.0)
    updates = rig.take_updates()
    assert [u.detail for u in updates] == ["on the way again: to 207", "at the door of 207 (+0 mm)"]
    assert rig.world.s() == pytest.approx(21000.0)


async def test_what_leaves_room_or_is_not_on_the_way_changes_nothing(rig: Rig) -> None:
    """A cart along the wall, a cart across the hallway on floor 3, one behind the robot and
    one in a room: the robot drives on to the door without a word about any of them."""
    await leave_for_207(rig)
    rig.world.objects = [
        standing(30000.0, HALF_WIDTH - 300.0, across_mm=600.0, along_mm=900.0),
        standing(30000.0, 0.0, across_mm=1200.0, along_mm=600.0, floor=3),
        standing(rig.world.s() + 1500.0, 0.0, across_mm=1200.0, along_mm=600.0),
        standing(25000.0, -HALF_WIDTH - 1500.0, across_mm=1200.0, along_mm=600.0),
    ]
    await rig.clock.advance(60.0)
    updates = rig.take_updates()
    assert [u.problem for u in updates] == [None]
    assert updates[0].status is OrderStatus.ARRIVED


# --- motion: the detour's side chosen from afar --------------------------------------------


MOTION_S, LANE = 10000.0, -295.0
"""The robot on floor 2, keeping right, driving up the hallway."""
GO = CollisionStatus(state=SafetyState.GO, scan_seq=1, speed_limit_mm_s=1000.0)
TELEMETRY = Odometry(
    controller_time_ms=0, left_ticks=0, right_ticks=0, gyro_z_dps=0.0, left_mm_s=0.0, right_mm_s=0.0
)
NOTHING_IN_RANGE = RangeScan(
    cycle_start_s=0.0,
    cycle_time_s=0.05,
    readings=[
        RangeReading(sensor=s.id, status=ReadingStatus.OUT_OF_BOUNDS) for s in CONFIG.tof.sensors
    ],
)
"""Every sensor ranging and seeing nothing: the box is beyond their reach."""
BOX = standing(MOTION_S + 2200.0, -HALF_WIDTH + 300.0, across_mm=600.0, along_mm=800.0)
"""A box against the right-hand wall 1.8 m ahead of the robot's centre: room on the left."""
MotionRig = tuple[ManualClock, Board, MotionModule]


@pytest.fixture
async def motion() -> AsyncIterator[MotionRig]:
    clock = ManualClock(100.0)
    board = Board(ALL_TOPICS, clock=clock)
    module = MotionModule(CONFIG, PLAN)
    daemon = Daemon(board, [module])
    await daemon.start()
    board.publish(
        MOVE_INSTRUCTION,
        MoveInstruction(id=1, action="follow_lane", floor=2, target_s_mm=30000, lane_mm=LANE),
    )
    yield clock, board, module
    await daemon.shutdown()


async def run_motion(clock: ManualClock, board: Board, seconds: float) -> MotionStatus:
    """Periods with a fresh pose (standing at ``MOTION_S``), telemetry, a clear verdict and
    a scan that sees nothing; motion's last status."""
    x, y = FLOOR.from_hallway(MOTION_S, LANE)
    for _ in range(round(seconds / CONFIG.motion.period_s)):
        board.publish(CURRENT_STATE, CurrentState(pose=estimate_at(2, x, y)))
        board.publish(ODOMETRY, TELEMETRY)
        board.publish(RANGE_SCAN, NOTHING_IN_RANGE)
        board.publish(COLLISION, GO)
        await clock.advance(CONFIG.motion.period_s)
    return board.latest(MOTION_STATUS).msg


async def test_a_box_the_cameras_see_is_gone_round_before_the_sensors_see_it(
    motion: MotionRig,
) -> None:
    clock, board, module = motion
    status = await run_motion(clock, board, 0.5)
    assert status.detour_phase is None  # nothing seen: lane keeping
    board.publish(CAMERA_LAYER, CameraLayer(objects=[BOX], expiry_s=5.0))
    status = await run_motion(clock, board, 0.5)
    assert status.detour_phase == "going_round"
    assert status.detour_lane_mm is not None and status.detour_lane_mm > LANE + 300.0  # left
    xs, _, _, _ = module.costmap.obstacles(clock.now())
    assert xs.size > 0  # from the camera alone: every sensor saw nothing


async def test_camera_marks_leave_with_the_object_or_the_layer(motion: MotionRig) -> None:
    clock, board, module = motion
    await run_motion(clock, board, 0.2)
    board.publish(CAMERA_LAYER, CameraLayer(objects=[BOX], expiry_s=5.0))
    await run_motion(clock, board, 0.2)
    assert module.costmap.obstacles(clock.now())[0].size > 0
    board.publish(CAMERA_LAYER, CameraLayer(objects=[], expiry_s=5.0))
    await run_motion(clock, board, 0.2)
    assert module.costmap.obstacles(clock.now())[0].size == 0  # the box left the layer
    board.publish(CAMERA_LAYER, CameraLayer(objects=[BOX], expiry_s=5.0))
    await run_motion(clock, board, CONFIG.navigation.camera_stale_s + 0.5)
    assert module.costmap.obstacles(clock.now())[0].size == 0  # no layer since: stale
    on_three = BOX.model_copy(update={"floor": 3})
    board.publish(CAMERA_LAYER, CameraLayer(objects=[on_three], expiry_s=5.0))
    await run_motion(clock, board, 0.2)
    assert module.costmap.obstacles(clock.now())[0].size == 0  # another floor's
