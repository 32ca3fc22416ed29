"""The order queue: first come, first served, one delivery at a time, every change stored first.

The web calls it through the orders protocol (:class:`~coffeebot.orders.Orders`: place, get,
cancel, active) because a customer needs an answer (the new order's id, or why it cannot be
cancelled). Everything else arrives over the board: navigation reports progress on
``DELIVERY_STATUS``. Each change is committed to the store and only then announced on
``ORDER_UPDATE``; the head of the queue is handed to navigation on ``ORDER_DISPATCH``
(navigation should also read ``latest`` of that topic when it starts, in case the dispatch
was published before it subscribed).

At the first start after a daemon restart, orders that were in flight cannot simply carry on:
the process that knew where the robot and the cup were is gone. An order still being prepared
(the robot had not left the tea room) goes back to the head of the queue; one that had left is
marked failed with the reason, so staff can check on it. Nothing is silently dropped.

Every stored change is logged once, where it is announced, as ``event=order`` with its cause
(who placed or cancelled it, navigation's detail, the restart).
"""

from __future__ import annotations

import asyncio
import logging

from coffeebot.board import Envelope
from coffeebot.errors import OrderError
from coffeebot.logs import Event, log_event
from coffeebot.messages import (
    DELIVERY_STATUS,
    ORDER_DISPATCH,
    ORDER_UPDATE,
    DeliveryUpdate,
    OrderDispatch,
    OrderStatus,
    OrderUpdate,
)
from coffeebot.modules.base import Module, ModuleBoard, ModuleContext
from coffeebot.orders import OrderNotFound, OrdersUnavailable
from coffeebot.store import IN_FLIGHT, NewOrder, Order, OrderStore

log = logging.getLogger(__name__)

# Where each status may come from when navigation reports it: forward only, never back to
# the queue, and nothing after the order has ended.
_REPORTABLE_FROM: dict[OrderStatus, tuple[OrderStatus, ...]] = {
    OrderStatus.PREPARING: (OrderStatus.PREPARING,),
    OrderStatus.ON_THE_WAY: IN_FLIGHT,
    OrderStatus.WAITING_FOR_ELEVATOR: IN_FLIGHT,
    OrderStatus.ARRIVED: IN_FLIGHT,
    OrderStatus.DELIVERED: (OrderStatus.ARRIVED,),
    OrderStatus.FAILED: IN_FLIGHT,
    OrderStatus.CANCELLED: IN_FLIGHT,
}


class OrdersModule(Module):
    """Keeps the durable queue and feeds navigation one order at a time; implements
    :class:`~coffeebot.orders.Orders` for the web."""

    name = "orders"
    inputs = (DELIVERY_STATUS,)
    outputs = (ORDER_DISPATCH, ORDER_UPDATE)

    def __init__(self, store: OrderStore) -> None:
        self.store = store
        self._board: ModuleBoard | None = None
        self._current: str | None = None
        self._recovered = False
        self._lock = asyncio.Lock()

    @property
    def current(self) -> str | None:
        """The id of the order navigation is working on, if any."""
        return self._current

    def _require_board(self) -> ModuleBoard:
        if self._board is None:
            raise OrdersUnavailable("the order queue is not running; try again shortly")
        return self._board

    def _announce(self, order: Order, cause: str, update: DeliveryUpdate | None = None) -> None:
        """Publish a stored change and log it: the one place every transition passes;
        ``update``: navigation's report the change came from."""
        self._require_board().publish(
            ORDER_UPDATE,
            OrderUpdate(
                order_id=order.id,
                status=order.status,
                detail=order.detail,
                ready_for_cup=update is not None and update.ready_for_cup,
                problem=None if update is None else update.problem,
            ),
        )
        log_event(
            log,
            Event.ORDER,
            cause,
            order=order.id,
            room=order.room,
            status=order.status.value,
        )

    async def place(self, new: NewOrder, client: str) -> Order:
        """Queue a validated order; it is dispatched at once if the robot is idle."""
        self._require_board()
        order = await self.store.add(new, client)
        self._announce(order, f"placed by {client}")
        await self._dispatch_next()
        return await self.get(order.id)

    async def get(self, order_id: str) -> Order:
        order = await self.store.get(order_id)
        if order is None:
            raise OrderNotFound(f"no order {order_id!r}")
        return order

    async def active(self) -> list[Order]:
        return await self.store.active()

    async def cancel(self, order_id: str, detail: str = "cancelled by the customer") -> Order:
        """Cancel an order that is still waiting; a dispatched one is navigation's to end."""
        self._require_board()
        cancelled = await self.store.transition(
            order_id, OrderStatus.CANCELLED, detail, (OrderStatus.QUEUED,)
        )
        if cancelled is None:
            order = await self.get(order_id)
            raise OrderError(f"order {order_id!r} is {order.status.value}, not queued")
        self._announce(cancelled, detail)
        return cancelled

    async def _recover(self) -> None:
        for order in await self.store.with_status(IN_FLIGHT):
            if order.status is OrderStatus.PREPARING:
                status = OrderStatus.QUEUED
                detail = "resumed after a restart: the robot had not left the tea room"
            else:
                status = OrderStatus.FAILED
                was = order.status.value.replace("_", " ")
                detail = (
                    f"the robot restarted while the order was {was}; staff will check on the cup"
                )
            updated = await self.store.transition(order.id, status, detail, (order.status,))
            if updated is not None:
                self._announce(updated, detail)

    async def _dispatch_next(self) -> None:
        """Hand the oldest queued order to navigation unless one is already out."""
        async with self._lock:
            while self._current is None:
                queued = await self.store.with_status((OrderStatus.QUEUED,), limit=1)
                if not queued:
                    return
                head = queued[0]
                order = await self.store.transition(
                    head.id,
                    OrderStatus.PREPARING,
                    "dispatched to the robot",
                    (OrderStatus.QUEUED,),
                )
                if order is None:  # cancelled between the read and the update
                    continue
                self._current = order.id
                self._announce(order, order.detail)
                self._require_board().publish(
                    ORDER_DISPATCH,
                    OrderDispatch(
                        order_id=order.id, room=order.room, drink=order.drink, name=order.name
                    ),
                )

    async def _apply(self, envelope: Envelope[DeliveryUpdate]) -> None:
        update = envelope.msg
        if update.order_id != self._current:
            log.warning(
                "delivery update for an order that is not out: ignored",
                extra={"order": update.order_id, "current": self._current},
            )
            return
        allowed = _REPORTABLE_FROM.get(update.status, ())
        order = await self.store.transition(update.order_id, update.status, update.detail, allowed)
        if order is None:
            log.warning(
                "delivery update out of sequence: ignored",
                extra={"order": update.order_id, "status": update.status.value},
            )
            return
        self._announce(order, update.detail or "reported by navigation", update)
        if order.status.final:
            self._current = None
            await self._dispatch_next()

    async def run(self, ctx: ModuleContext) -> None:
        with ctx.board.subscribe(DELIVERY_STATUS) as updates:
            self._board = ctx.board
            try:
                if not self._recovered:
                    await self._recover()
                    self._recovered = True
                await self._dispatch_next()
                async for envelope in updates:
                    await self._apply(envelope)
            finally:
                self._board = None
