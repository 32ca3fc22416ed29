"""The orders module: arrival order, one delivery at a time, navigation's reports, restarts."""

from __future__ import annotations

import asyncio
import logging
from pathlib import Path

import pytest

from coffeebot.board import Board, Subscription
from coffeebot.config import SupervisionConfig
from coffeebot.daemon import Daemon
from coffeebot.errors import OrderError
from coffeebot.messages import (
    ALL_TOPICS,
    DELIVERY_STATUS,
    ORDER_DISPATCH,
    ORDER_UPDATE,
    DeliveryUpdate,
    HealthStatus,
    OrderStatus,
    OrderUpdate,
)
from coffeebot.modules.base import Module, ModuleContext
from coffeebot.modules.orders import OrdersModule
from coffeebot.orders import OrdersUnavailable
from coffeebot.store import OrderStore
from logged import events

from .conftest import new_order


def report(board: Board, order_id: str, status: OrderStatus, detail: str = "") -> None:
    board.publish(DELIVERY_STATUS, DeliveryUpdate(order_id=order_id, status=status, detail=detail))


async def until(updates: Subscription[OrderUpdate], order_id: str, status: OrderStatus) -> None:
    """Read announcements until ``order_id`` reaches ``status`` (the module stored it first)."""
    async for envelope in updates:
        if (envelope.msg.order_id, envelope.msg.status) == (order_id, status):
            return


async def test_queue_dispatches_one_at_a_time_in_arrival_order(
    board: Board, orders: OrdersModule, updates: Subscription[OrderUpdate]
) -> None:
    with board.subscribe(ORDER_DISPATCH, name="navigation") as dispatches:
        first = await orders.place(new_order(name="A"), client="c")
        second = await orders.place(new_order(name="B", room="302"), client="c")
        assert first.status is OrderStatus.PREPARING
        assert second.status is OrderStatus.QUEUED
        assert second.ahead == 1
        assert (dispatches.get_nowait()).msg.order_id == first.id
        assert dispatches.get_nowait() is None

        for status in (OrderStatus.ON_THE_WAY, OrderStatus.ARRIVED, OrderStatus.DELIVERED):
            report(board, first.id, status)
        await until(updates, second.id, OrderStatus.PREPARING)
        assert (await orders.get(first.id)).status is OrderStatus.DELIVERED
        assert (await dispatches.get()).msg.order_id == second.id


async def test_cancel_only_while_queued(orders: OrdersModule) -> None:
    first = await orders.place(new_order(name="A"), client="c")
    second = await orders.place(new_order(name="B"), client="c")
    cancelled = await orders.cancel(second.id)
    assert cancelled.status is OrderStatus.CANCELLED
    with pytest.raises(OrderError):
        await orders.cancel(first.id)
    with pytest.raises(OrderError):
        await orders.cancel(second.id)


async def test_reports_out_of_sequence_or_for_other_orders_are_ignored(
    board: Board, orders: OrdersModule, updates: Subscription[OrderUpdate]
) -> None:
    first = await orders.place(new_order(name="A"), client="c")
    queued = await orders.place(new_order(name="B"), client="c")
    report(board, queued.id, OrderStatus.ON_THE_WAY)  # not the dispatched order
    report(board, first.id, OrderStatus.DELIVERED)  # cannot skip arriving at the door
    report(board, first.id, OrderStatus.FAILED, "blocked hallway")
    await until(updates, queued.id, OrderStatus.PREPARING)
    failed = await orders.get(first.id)
    assert (failed.status, failed.detail) == (OrderStatus.FAILED, "blocked hallway")


async def test_every_transition_is_logged_once_with_its_cause(
    board: Board,
    orders: OrdersModule,
    updates: Subscription[OrderUpdate],
    caplog: pytest.LogCaptureFixture,
) -> None:
    caplog.set_level(logging.INFO)
    first = await orders.place(new_order(name="A"), client="10.0.0.7")
    second = await orders.place(new_order(name="B"), client="10.0.0.8")
    await orders.cancel(second.id)
    report(board, first.id, OrderStatus.ON_THE_WAY, "left the tea room")
    report(board, first.id, OrderStatus.ARRIVED)
    report(board, first.id, OrderStatus.DELIVERED, "cup taken")
    await until(updates, first.id, OrderStatus.DELIVERED)
    logged = [(r.order, r.status, r.cause) for r in events(caplog, "order")]  # type: ignore[attr-defined]
    assert logged == [
        (first.id, "queued", "placed by 10.0.0.7"),
        (first.id, "preparing", "dispatched to the robot"),
        (second.id, "queued", "placed by 10.0.0.8"),
        (second.id, "cancelled", "cancelled by the customer"),
        (first.id, "on_the_way", "left the tea room"),
        (first.id, "arrived", "reported by navigation"),
        (first.id, "delivered", "cup taken"),
    ]


async def test_not_running_answers_unavailable(store: OrderStore) -> None:
    with pytest.raises(OrdersUnavailable):
        await OrdersModule(store).place(new_order(), client="c")


def start(db_path: Path) -> tuple[Board, OrderStore, OrdersModule, Daemon]:
    board = Board(ALL_TOPICS)
    store = OrderStore(db_path)
    module = OrdersModule(store)
    return board, store, module, Daemon(board, [module])


@pytest.mark.parametrize(
    "reached", [OrderStatus.ON_THE_WAY, OrderStatus.WAITING_FOR_ELEVATOR, OrderStatus.ARRIVED]
)
async def test_daemon_killed_on_the_way_fails_the_order_with_reason(
    db_path: Path, reached: OrderStatus, caplog: pytest.LogCaptureFixture
) -> None:
    caplog.set_level(logging.INFO)
    board, store, module, daemon = start(db_path)
    await daemon.start()
    order = await module.place(new_order(), client="c")
    waiting = await module.place(new_order(name="B"), client="c")
    with board.subscribe(ORDER_UPDATE) as updates:
        report(board, order.id, reached)
        await until(updates, order.id, reached)
    kill(daemon, store)

    board, store, module, daemon = start(db_path)
    with board.subscribe(ORDER_DISPATCH, name="navigation") as dispatches:
        await daemon.start()
        dispatched = await dispatches.get()
    try:
        failed = await module.get(order.id)
        assert failed.status is OrderStatus.FAILED
        assert reached.value.replace("_", " ") in failed.detail
        assert dispatched.msg.order_id == waiting.id
        [logged] = [r for r in events(caplog, "order") if r.status == "failed"]  # type: ignore[attr-defined]
        assert logged.cause == failed.detail  # type: ignore[attr-defined]
    finally:
        await daemon.shutdown()
        store.close()


async def test_daemon_killed_while_preparing_resumes_the_order_first(db_path: Path) -> None:
    board, store, module, daemon = start(db_path)
    await daemon.start()
    order = await module.place(new_order(), client="c")
    waiting = await module.place(new_order(name="B"), client="c")
    kill(daemon, store)

    board, store, module, daemon = start(db_path)
    with board.subscribe(ORDER_UPDATE) as updates, board.subscribe(ORDER_DISPATCH) as dispatches:
        await daemon.start()
        dispatched = await dispatches.get()
        first = updates.get_nowait()
    try:
        assert dispatched.msg.order_id == order.id
        assert first is not None
        assert (first.msg.status, first.msg.order_id) == (OrderStatus.QUEUED, order.id)
        assert "resumed" in first.msg.detail
        assert (await module.get(waiting.id)).status is OrderStatus.QUEUED
    finally:
        await daemon.shutdown()
        store.close()


def kill(daemon: Daemon, store: OrderStore) -> None:
    """Stop like a killed process: no shutdown hooks, tasks just stop, the file is left as is."""
    for state in daemon.states.values():
        assert state.task is not None
        state.task.cancel()
    store.close()


class CrashingNavigation(Module):
    """Takes the first order it is given, then crashes on every run: the supervisor gives
    it up, as it would a navigation module with a bug that every restart meets again."""

    name = "navigation"
    inputs = (ORDER_DISPATCH,)
    outputs = (DELIVERY_STATUS,)

    def __init__(self) -> None:
        self.runs = 0

    async def run(self, ctx: ModuleContext) -> None:
        self.runs += 1
        if self.runs == 1:
            dispatched = await ctx.board.next(ORDER_DISPATCH)
            ctx.board.publish(
                DELIVERY_STATUS,
                DeliveryUpdate(order_id=dispatched.msg.order_id, status=OrderStatus.ON_THE_WAY),
            )
        raise RuntimeError("no route to room 205")


async def test_navigation_given_up_fails_its_order_and_the_queue_waits(
    board: Board, store: OrderStore, updates: Subscription[OrderUpdate]
) -> None:
    orders = OrdersModule(store)
    navigation = CrashingNavigation()
    supervision = SupervisionConfig(
        restart_backoff_s=0.01, restart_backoff_max_s=0.01, max_restarts=2, failure_window_s=60
    )
    daemon = Daemon(board, [orders, navigation], supervision)
    await daemon.start()
    try:
        first = await orders.place(new_order(name="A"), client="c")
        async with asyncio.timeout(10):
            await until(updates, first.id, OrderStatus.FAILED)
        failed = await orders.get(first.id)
        assert "navigation stopped working" in failed.detail
        assert "no route to room 205" in failed.detail
        assert daemon.states["navigation"].status is HealthStatus.FAILED
        second = await orders.place(new_order(name="B"), client="c")
        assert second.status is OrderStatus.QUEUED, "nothing is handed to a navigation given up"
    finally:
        await daemon.shutdown()
