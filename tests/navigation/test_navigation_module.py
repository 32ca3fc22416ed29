"""The navigation module's delivery flow against a stand-in motion module and elevator."""

from __future__ import annotations

import asyncio
import contextlib

import pytest
from helpers import CONFIG, PLAN, PLANNER, estimate_at

from coffeebot.board import Board
from coffeebot.daemon import Daemon
from coffeebot.messages import (
    ALL_TOPICS,
    CURRENT_STATE,
    DELIVERY_STATUS,
    ELEVATOR_REQUEST,
    ELEVATOR_STATE,
    LEASE_NEED,
    LEASE_STATE,
    MOTION_STATUS,
    MOVE_INSTRUCTION,
    OPERATOR_EVENT,
    ORDER_DISPATCH,
    CurrentState,
    DeliveryProblem,
    ElevatorState,
    LeaseState,
    MotionState,
    MotionStatus,
    OperatorEvent,
    OrderDispatch,
    OrderStatus,
    StopCause,
)
from coffeebot.modules.navigation import NavigationModule
from coffeebot.sim.crash import CrashSwitch
from manual_clock import ManualClock


def pose_at(floor: int, x: float, y: float, heading: float = 0.0) -> CurrentState:
    return CurrentState(pose=estimate_at(floor, x, y, heading))


class Stand:
    """Motion that finishes every instruction at once; an elevator that answers, or not."""

    def __init__(self, board: Board, elevator: bool) -> None:
        self.board = board
        self.elevator = elevator
        self.floor = 2
        self.car = 2
        self.done: list[str] = []
        """The details of the instructions it finished, in order."""
        self.asked_of_lift: list[str | None] = []
        """For each of those, the last thing asked of the elevator when it came."""

    async def motion(self) -> None:
        with self.board.subscribe(MOVE_INSTRUCTION) as instructions:
            async for envelope in instructions:
                ins = envelope.msg
                floor = PLAN.floor(ins.floor or self.floor)
                latest = self.board.latest(CURRENT_STATE)
                x, y = latest.msg.pose.x_mm, latest.msg.pose.y_mm
                if ins.action == "follow_lane":
                    x, y = floor.from_hallway(ins.target_s_mm, ins.lane_mm)
                elif ins.action == "drive_to":
                    x, y = ins.x_mm, ins.y_mm
                self.board.publish(CURRENT_STATE, pose_at(self.floor, x, y))
                self.done.append(ins.detail)
                request = self.board.latest(ELEVATOR_REQUEST)
                self.asked_of_lift.append(None if request is None else request.msg.action)
                self.board.publish(
                    MOTION_STATUS,
                    MotionStatus(instruction_id=ins.id, state=MotionState.DONE, remaining_mm=0.0),
                )

    async def lift(self) -> None:
        with self.board.subscribe(ELEVATOR_REQUEST) as requests:
            async for envelope in requests:
                if not self.elevator:
                    continue
                if envelope.msg.action in ("call", "send"):
                    self.car = envelope.msg.floor
                    if envelope.msg.action == "send":
                        self.floor = self.car
                        latest = self.board.latest(CURRENT_STATE).msg.pose
                        self.board.publish(
                            CURRENT_STATE, pose_at(self.floor, latest.x_mm, latest.y_mm)
                        )
                    self.board.publish(
                        ELEVATOR_STATE, ElevatorState(car_floor=self.car, doors="open")
                    )


@pytest.fixture
async def rig():
    clock = ManualClock(0.0)
    board = Board(ALL_TOPICS, clock=clock)
    base = PLANNER.base
    x, y = PLAN.floor(2).behind_door(base.door, 800)
    board.publish(CURRENT_STATE, pose_at(2, x, y, 90.0))
    daemon = Daemon(board, [NavigationModule(CONFIG, PLAN)])
    statuses = board.subscribe(DELIVERY_STATUS)
    yield clock, board, daemon, statuses
    await daemon.shutdown()


async def run_stand(
    board: Board, elevator: bool, stand: Stand | None = None
) -> list[asyncio.Task[None]]:
    stand = stand or Stand(board, elevator)
    return [asyncio.create_task(stand.motion()), asyncio.create_task(stand.lift())]


def drain(statuses) -> list[OrderStatus]:
    out = []
    while (envelope := statuses.get_nowait()) is not None:
        out.append(envelope.msg.status)
    return out


async def dispatch_and_load(clock: ManualClock, board: Board, room: str) -> None:
    """Order o1 for ``room`` dispatched, its cup loaded a second later."""
    board.publish(ORDER_DISPATCH, OrderDispatch(order_id="o1", room=room, drink="tea"))
    await clock.advance(1.0)
    board.publish(OPERATOR_EVENT, OperatorEvent(kind="cup_loaded", order_id="o1"))
    await clock.advance(5.0)


async def stop(tasks: list[asyncio.Task[None]]) -> None:
    for task in tasks:
        task.cancel()
        with contextlib.suppress(asyncio.CancelledError):
            await task


async def test_delivery_to_the_other_floor_and_home(rig) -> None:
    clock, board, daemon, statuses = rig
    tasks = await run_stand(board, elevator=True)
    await daemon.start()
    await dispatch_and_load(clock, board, "305")
    assert drain(statuses) == [
        OrderStatus.PREPARING,  # ready in the tea room
        OrderStatus.ON_THE_WAY,
        OrderStatus.WAITING_FOR_ELEVATOR,
        OrderStatus.ON_THE_WAY,
        OrderStatus.ARRIVED,
    ]
    board.publish(OPERATOR_EVENT, OperatorEvent(kind="pickup_confirmed", order_id="o1"))
    await clock.advance(5.0)
    assert drain(statuses) == [OrderStatus.DELIVERED]
    assert board.latest(MOVE_INSTRUCTION).msg.action == "stop"  # home and parked
    assert board.latest(CURRENT_STATE).msg.pose.floor == 2
    await stop(tasks)


async def test_the_car_is_sent_before_the_robot_turns_round_in_it(rig, monkeypatch) -> None:
    """The doors close and the car travels while the robot turns: sent only once it had
    turned, every ride took the turn's time longer (some 8 s). Then it stands."""
    clock, board, daemon, _ = rig
    stand = Stand(board, elevator=True)
    instructed: list[str] = []
    publish = board.publish

    def spy(topic, msg):
        if topic is MOVE_INSTRUCTION:
            instructed.append(msg.detail)
        return publish(topic, msg)

    monkeypatch.setattr(board, "publish", spy)
    tasks = await run_stand(board, elevator=True, stand=stand)
    await daemon.start()
    await dispatch_and_load(clock, board, "305")
    asked = dict(zip(stand.done, stand.asked_of_lift, strict=True))
    assert asked["into the car"] == "call"
    assert asked["turning round in the car"] == "send"
    # It stands while it waits for the car and rides: each last move, left in force, was
    # made again whenever the estimate moved past its tolerance (a 3 degree turn).
    turn = instructed.index("turning round in the car")
    assert instructed[turn + 1] == "in the car to floor 3"
    facing = instructed.index("facing the elevator doors")
    assert instructed[facing + 1] == "waiting for the car on floor 2"
    await stop(tasks)


async def test_at_the_door_the_robot_stands_until_the_cup_is_taken(rig) -> None:
    """The move to the door is not left in force: it drove the robot again whenever the
    estimate moved past the stop tolerance, while a person reached for the cup."""
    clock, board, daemon, statuses = rig
    tasks = await run_stand(board, elevator=True)
    await daemon.start()
    await dispatch_and_load(clock, board, "205")
    assert drain(statuses)[-1] is OrderStatus.ARRIVED
    standing = board.latest(MOVE_INSTRUCTION).msg
    assert (standing.action, standing.detail) == (
        "stop",
        "at the door of 205, for the cup to be taken",
    )
    await stop(tasks)


async def test_no_cup_no_delivery(rig) -> None:
    clock, board, daemon, statuses = rig
    await daemon.start()
    board.publish(ORDER_DISPATCH, OrderDispatch(order_id="o2", room="205", drink="tea"))
    await clock.advance(CONFIG.navigation.loading_timeout_s + 1)
    updates = [e.msg for e in iter(statuses.get_nowait, None)]
    assert [u.status for u in updates] == [OrderStatus.PREPARING, OrderStatus.FAILED]
    assert updates[0].ready_for_cup
    assert updates[1].problem is DeliveryProblem.CUP_NOT_LOADED


async def test_nobody_at_the_door_takes_the_cup_back(rig) -> None:
    clock, board, daemon, statuses = rig
    tasks = await run_stand(board, elevator=True)
    await daemon.start()
    board.publish(ORDER_DISPATCH, OrderDispatch(order_id="o3", room="205", drink="tea"))
    await clock.advance(1.0)
    board.publish(OPERATOR_EVENT, OperatorEvent(kind="cup_loaded", order_id="o3"))
    await clock.advance(CONFIG.navigation.pickup_timeout_s + 5)
    updates = [e.msg for e in iter(statuses.get_nowait, None)]
    assert [u.status for u in updates][-1] is OrderStatus.FAILED
    assert updates[-1].problem is DeliveryProblem.NOT_PICKED_UP
    await stop(tasks)


async def test_silent_elevator_retries_then_asks_an_operator(rig) -> None:
    clock, board, daemon, statuses = rig
    tasks = await run_stand(board, elevator=False)
    await daemon.start()
    board.publish(ORDER_DISPATCH, OrderDispatch(order_id="o4", room="305", drink="tea"))
    await clock.advance(1.0)
    board.publish(OPERATOR_EVENT, OperatorEvent(kind="cup_loaded", order_id="o4"))
    elevator = CONFIG.navigation.elevator
    await clock.advance(elevator.call_timeout_s * (elevator.call_retries + 1) + 1)
    updates = [e.msg for e in iter(statuses.get_nowait, None)]
    assert updates[-1].status is OrderStatus.WAITING_FOR_ELEVATOR
    assert updates[-1].problem is DeliveryProblem.ELEVATOR
    # Nobody confirms either: the delivery fails with the reason instead of waiting forever.
    await clock.advance(elevator.operator_timeout_s + 1)
    updates = [e.msg for e in iter(statuses.get_nowait, None)]
    assert updates[0].status is OrderStatus.FAILED
    assert updates[0].problem is DeliveryProblem.ELEVATOR
    await stop(tasks)


async def test_cancel_on_the_way_reports_cancelled(rig) -> None:
    clock, board, daemon, statuses = rig
    tasks = await run_stand(board, elevator=False)
    await daemon.start()
    board.publish(ORDER_DISPATCH, OrderDispatch(order_id="o5", room="305", drink="tea"))
    await clock.advance(1.0)
    board.publish(OPERATOR_EVENT, OperatorEvent(kind="cup_loaded", order_id="o5"))
    await clock.advance(5.0)
    board.publish(OPERATOR_EVENT, OperatorEvent(kind="cancel", order_id="o5"))
    await clock.advance(5.0)
    statuses_seen = [e.msg.status for e in iter(statuses.get_nowait, None)]
    assert statuses_seen[-1] is OrderStatus.CANCELLED
    await stop(tasks)


async def held_by_silent_motors(board: Board) -> None:
    """Motion whose safety gate holds the robot: the motor controller sends no telemetry."""
    with board.subscribe(MOVE_INSTRUCTION) as instructions:
        async for envelope in instructions:
            board.publish(
                MOTION_STATUS,
                MotionStatus(
                    instruction_id=envelope.msg.id,
                    state=MotionState.SAFETY_STOP,
                    remaining_mm=4000.0,
                    detail="no telemetry from the motor controller for 0.6 s",
                    stopped_by=StopCause.MOTOR_SILENT,
                ),
            )


async def test_silent_motor_controller_is_the_orders_reason_at_once(rig) -> None:
    clock, board, daemon, statuses = rig
    motion = asyncio.create_task(held_by_silent_motors(board))
    await daemon.start()
    board.publish(ORDER_DISPATCH, OrderDispatch(order_id="o6", room="205", drink="tea"))
    await clock.advance(1.0)
    board.publish(OPERATOR_EVENT, OperatorEvent(kind="cup_loaded", order_id="o6"))
    await clock.advance(3.0)
    held = [e.msg for e in iter(statuses.get_nowait, None) if e.msg.problem is not None]
    assert [u.problem for u in held] == [DeliveryProblem.MOTOR_CONTROLLER]
    assert held[0].detail == "stopped: no telemetry from the motor controller for 0.6 s"
    await clock.advance(CONFIG.navigation.blocked_give_up_s)
    failed = [e.msg for e in iter(statuses.get_nowait, None) if e.msg.status.final]
    assert [(u.status, u.problem) for u in failed] == [
        (OrderStatus.FAILED, DeliveryProblem.MOTOR_CONTROLLER)
    ]
    await stop([motion])


async def edging_up_while_waiting(board: Board) -> None:
    """Motion that waits for something ahead it cannot pass, and edges 150 mm nearer it
    every minute: never getting on."""
    remaining = 4000.0
    while True:
        for state in (MotionState.WAITING, MotionState.BLOCKED):
            instruction = board.latest(MOVE_INSTRUCTION)
            if instruction is not None:
                board.publish(
                    MOTION_STATUS,
                    MotionStatus(
                        instruction_id=instruction.msg.id,
                        state=state,
                        remaining_mm=remaining,
                        detail="something moving ahead, waiting",
                    ),
                )
            await board.clock.sleep(1.0)
        if int(board.clock.now()) % 60 == 0:
            remaining -= 150.0


async def test_edging_up_to_what_it_waits_for_is_not_getting_on(rig) -> None:
    clock, board, daemon, statuses = rig
    motion = asyncio.create_task(edging_up_while_waiting(board))
    await daemon.start()
    board.publish(ORDER_DISPATCH, OrderDispatch(order_id="o8", room="205", drink="tea"))
    await clock.advance(1.0)
    board.publish(OPERATOR_EVENT, OperatorEvent(kind="cup_loaded", order_id="o8"))
    await clock.advance(CONFIG.navigation.blocked_give_up_s + 60.0)
    failed = [e.msg for e in iter(statuses.get_nowait, None) if e.msg.status.final]
    assert [(u.status, u.problem) for u in failed] == [
        (OrderStatus.FAILED, DeliveryProblem.BLOCKED)
    ]
    await stop([motion])


async def test_a_crash_on_the_way_does_not_strand_the_order(rig) -> None:
    """Navigation crashing in the middle of a delivery is restarted by the supervisor, and
    the delivery goes on from where the robot is: the order is not left "on the way" with
    nobody driving it."""
    clock, board, daemon, statuses = rig
    navigation = daemon.states["navigation"].module
    switch = CrashSwitch(navigation)
    stand = Stand(board, elevator=True)
    held = asyncio.create_task(held_by_silent_motors(board))  # on the way, not getting there
    await daemon.start()
    board.publish(ORDER_DISPATCH, OrderDispatch(order_id="o7", room="205", drink="tea"))
    await clock.advance(1.0)
    board.publish(OPERATOR_EVENT, OperatorEvent(kind="cup_loaded", order_id="o7"))
    await clock.advance(2.0)
    assert drain(statuses)[-1] is OrderStatus.ON_THE_WAY
    await stop([held])
    tasks = [asyncio.create_task(stand.motion()), asyncio.create_task(stand.lift())]
    switch.trip("a bug")
    await clock.advance(CONFIG.supervision.restart_backoff_s + 2.0)
    assert daemon.states["navigation"].restarts == 1
    seen = [e.msg for e in iter(statuses.get_nowait, None)]
    assert seen[0].status is OrderStatus.ON_THE_WAY
    assert seen[0].detail == "going on to 205 after a restart of navigation"
    assert seen[-1].status is OrderStatus.ARRIVED
    board.publish(OPERATOR_EVENT, OperatorEvent(kind="pickup_confirmed", order_id="o7"))
    await clock.advance(5.0)
    assert drain(statuses) == [OrderStatus.DELIVERED]
    assert board.latest(MOVE_INSTRUCTION).msg.action == "stop"  # home and parked
    await stop(tasks)


FLEET = CONFIG.model_copy(
    update={
        "fleet": CONFIG.fleet.model_copy(
            update={"broker": "mqtt://127.0.0.1:1883", "robot_id": "robot-1", "parking_spot": 0}
        )
    }
)
"""A fleet's robot, parked at the tea room's first spot."""


async def grant_every_lease(board: Board) -> None:
    """A fleet bridge whose dispatcher grants every place at once."""
    held: set[str] = set()
    with board.subscribe(LEASE_NEED) as needs:
        async for envelope in needs:
            (held.add if envelope.msg.want else held.discard)(envelope.msg.place)
            board.publish(LEASE_STATE, LeaseState.model_validate(dict.fromkeys(held, True)))


def fleet_robot_on_its_spot() -> tuple[ManualClock, Board, Daemon, Stand]:
    """A fleet's robot parked at the tea room's first spot, its navigation not yet started,
    with a stand that finishes its moves and answers for the elevator."""
    clock = ManualClock(0.0)
    board = Board(ALL_TOPICS, clock=clock)
    spot = PLAN.floor(2).parking[0]
    board.publish(CURRENT_STATE, pose_at(2, spot.x_mm, spot.y_mm, spot.heading_deg))
    return clock, board, Daemon(board, [NavigationModule(FLEET, PLAN)]), Stand(board, True)


async def deliver_in_a_fleet(next_order: bool) -> list[str]:
    """A fleet's robot delivers to 205 from its parking spot and comes home, its next order
    dispatched (``next_order``) while it waits at 205's door; the details of its moves from
    the pickup on."""
    clock, board, daemon, stand = fleet_robot_on_its_spot()
    tasks = [
        asyncio.create_task(stand.motion()),
        asyncio.create_task(grant_every_lease(board)),
    ]
    try:
        await daemon.start()
        await dispatch_and_load(clock, board, "205")
        if next_order:
            board.publish(ORDER_DISPATCH, OrderDispatch(order_id="o2", room="207", drink="tea"))
        picked_at = len(stand.done)
        board.publish(OPERATOR_EVENT, OperatorEvent(kind="pickup_confirmed", order_id="o1"))
        await clock.advance(5.0)
        return stand.done[picked_at:]
    finally:
        await stop(tasks)
        await daemon.shutdown()


async def test_a_fleet_robot_with_its_next_order_waits_on_the_loading_spot() -> None:
    """Home with the next order taken, it turns round on the loading spot for the cup: it
    neither parks nor comes back out of the room (the spot was held twice as long)."""
    with_next = await deliver_in_a_fleet(next_order=True)
    assert "to its parking spot" not in with_next
    assert with_next[-3:] == [
        "facing out",
        "to the loading spot",
        "on the loading spot, for the next cup",
    ]
    without = await deliver_in_a_fleet(next_order=False)
    assert without[-3:] == ["to its parking spot", "parked", "parked"]


async def test_a_fleet_robot_stands_while_it_waits_for_a_place() -> None:
    """Waiting for the loading spot another robot holds, it is told to stand: the last move,
    left in force, turned it again by a few degrees every few seconds of the wait."""
    clock, board, daemon, stand = fleet_robot_on_its_spot()
    tasks = [asyncio.create_task(stand.motion())]  # nobody grants a place
    try:
        await daemon.start()
        board.publish(ORDER_DISPATCH, OrderDispatch(order_id="o1", room="205", drink="tea"))
        await clock.advance(5.0)
        standing = board.latest(MOVE_INSTRUCTION).msg
        assert (standing.action, standing.detail) == ("stop", "waiting for the loading spot")
    finally:
        await stop(tasks)
        await daemon.shutdown()


async def test_a_fleet_robot_calls_the_car_as_soon_as_it_is_its() -> None:
    """The car is called the moment the elevator lease is granted, on the loading spot, so it
    travels while the robot drives out of the tea room to its door; it used to be called
    only once the robot faced the car's doors, and stood waiting for it there."""
    clock, board, daemon, stand = fleet_robot_on_its_spot()
    seen: list[tuple[str, str]] = []

    async def record() -> None:
        with (
            board.subscribe(MOVE_INSTRUCTION) as moves,
            board.subscribe(ELEVATOR_REQUEST) as calls,
        ):
            while True:
                while (move := moves.get_nowait()) is not None:
                    seen.append(("move", move.msg.detail))
                while (call := calls.get_nowait()) is not None:
                    seen.append((call.msg.action, str(call.msg.floor)))
                await asyncio.sleep(0)

    tasks = [
        asyncio.create_task(record()),
        asyncio.create_task(stand.motion()),
        asyncio.create_task(stand.lift()),
        asyncio.create_task(grant_every_lease(board)),
    ]
    try:
        await daemon.start()
        await dispatch_and_load(clock, board, "305")
    finally:
        await stop(tasks)
        await daemon.shutdown()
    out_of_room = seen.index(("move", "out of Tea room"))
    assert ("call", "2") in seen[:out_of_room]
    assert seen.index(("move", "to the loading spot")) < seen.index(("call", "2"))
