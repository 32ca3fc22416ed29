"""The operator's alerts: each condition, its severity, its age and its freshness."""

from __future__ import annotations

import pytest

from coffeebot.board import Board
from coffeebot.messages import (
    ALL_TOPICS,
    DELIVERY_STATUS,
    ESTOP,
    MOTION_STATUS,
    RANGE_SCAN,
    DeliveryProblem,
    DeliveryUpdate,
    EStop,
    Health,
    HealthStatus,
    MotionState,
    MotionStatus,
    OrderStatus,
    OrderUpdate,
    RangeReading,
    RangeScan,
    ReadingStatus,
    StopCause,
)
from coffeebot.web.alerts import (
    AlertList,
    Seen,
    health_alerts,
    order_alerts,
    robot_alerts,
    stale_alerts,
)
from manual_clock import ManualClock


async def test_a_held_robot_is_a_warning_once_the_hold_lasts(clock: ManualClock) -> None:
    board = Board(ALL_TOPICS, clock=clock)
    held = MotionStatus(
        instruction_id=1,
        state=MotionState.SAFETY_STOP,
        since_s=0.5,
        detail="obstacle at 300 mm",
        stopped_by=StopCause.COLLISION_STOP,
    )
    board.publish(MOTION_STATUS, held)
    assert robot_alerts(board) == []  # a person walking past: the gate doing its job
    board.publish(MOTION_STATUS, held.model_copy(update={"since_s": 5.0}))
    await clock.advance(0.3)
    [alert] = robot_alerts(board)
    assert (alert.severity, alert.title) == ("warning", "Robot held by the safety gate")
    assert alert.detail == "obstacle at 300 mm" and alert.fresh_s == pytest.approx(0.3)
    board.publish(MOTION_STATUS, held.model_copy(update={"state": MotionState.BLOCKED}))
    assert [a.title for a in robot_alerts(board)] == ["Robot blocked"]


async def test_the_estop_and_a_held_delivery(clock: ManualClock) -> None:
    board = Board(ALL_TOPICS, clock=clock)
    board.publish(ESTOP, EStop(engaged=True, source="web operator", reason="spill"))
    board.publish(
        DELIVERY_STATUS,
        DeliveryUpdate(
            order_id="a",
            status=OrderStatus.WAITING_FOR_ELEVATOR,
            detail="the elevator does not answer",
            problem=DeliveryProblem.ELEVATOR,
        ),
    )
    estop, elevator = robot_alerts(board)
    assert (estop.severity, estop.detail) == ("critical", "web operator: spill")
    assert elevator.title == "Delivery held: elevator"


async def test_unwell_modules_components_and_sensors(clock: ManualClock) -> None:
    board = Board(ALL_TOPICS, clock=clock)
    seen = Seen(components={}, failed=[])
    seen.note_health(
        Health(module="tof", component="tof3", status=HealthStatus.DEGRADED, detail="NACK"),
        clock.now(),
    )
    seen.note_health(Health(module="tof", component="tof4", status=HealthStatus.RUNNING), 0.0)
    readings = [RangeReading(sensor=5, status=ReadingStatus.HARDWARE_FAIL, healthy=False)]
    board.publish(RANGE_SCAN, RangeScan(cycle_start_s=0, cycle_time_s=0.02, readings=readings))
    modules = [
        Health(module="collision", status=HealthStatus.FAILED, detail="crashed 5 times"),
        Health(module="web", status=HealthStatus.RUNNING),
    ]
    await clock.advance(2.0)
    failed, tof3, tof5 = health_alerts(board, modules, seen)
    assert (failed.severity, failed.title) == ("critical", "Module collision failed")
    assert (tof3.title, tof3.detail, tof3.fresh_s) == ("tof3 (tof) degraded", "NACK", 2.0)
    assert tof5.title == "Sensor tof5 gives no reading" and tof5.detail == "hardware fail"


async def test_failed_orders_are_listed_for_an_hour(clock: ManualClock) -> None:
    board = Board(ALL_TOPICS, clock=clock)
    seen = Seen(components={}, failed=[])
    update = OrderUpdate(order_id="a", status=OrderStatus.FAILED, detail="nobody picked it up")
    seen.note_order(update, clock.now())
    [alert] = order_alerts(board, seen)
    assert (alert.title, alert.detail) == ("An order failed", "nobody picked it up")
    await clock.advance(3601)
    seen.note_order(OrderUpdate(order_id="b", status=OrderStatus.DELIVERED), clock.now())
    assert order_alerts(board, seen) == []


async def test_topics_that_go_quiet_are_stale(clock: ManualClock) -> None:
    board = Board(ALL_TOPICS, clock=clock)
    limits = {"tof/scan": 0.5, "no/such": 1.0}
    [never] = stale_alerts(board, limits)
    assert never.title == "No tof/scan yet"
    board.publish(RANGE_SCAN, RangeScan(cycle_start_s=0, cycle_time_s=0.02, readings=[]))
    assert stale_alerts(board, limits) == []
    await clock.advance(0.8)
    [stale] = stale_alerts(board, limits)
    assert stale.title == "tof/scan is stale" and stale.fresh_s == pytest.approx(0.8)


async def test_alerts_sort_by_severity_then_by_how_long_they_have_held(clock: ManualClock) -> None:
    board = Board(ALL_TOPICS, clock=clock)
    alerts = AlertList()
    board.publish(RANGE_SCAN, RangeScan(cycle_start_s=0, cycle_time_s=0.02, readings=[]))
    await clock.advance(1.0)
    old = stale_alerts(board, {"tof/scan": 0.5})
    alerts.update(old, clock.now())
    await clock.advance(5.0)
    board.publish(ESTOP, EStop(engaged=True, source="web operator"))
    board.publish(RANGE_SCAN, RangeScan(cycle_start_s=0, cycle_time_s=0.02, readings=[]))
    await clock.advance(1.0)
    now = [*stale_alerts(board, {"tof/scan": 0.5, "uwb/fix": 1.0}), *robot_alerts(board)]
    estop, scan, uwb = alerts.update(now, clock.now())
    assert estop.severity == "critical" and estop.since_s == 0.0
    # Still stale since first seen six seconds ago; the new one has only just appeared.
    assert (scan.key, scan.since_s) == ("stale:tof/scan", 6.0)
    assert (uwb.key, uwb.since_s) == ("stale:uwb/fix", 0.0)
