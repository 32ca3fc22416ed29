"""The order queue: first come, first served, one delivery at a time, every change stored first.

The web calls it through the orders protocol (:class:`~coffeebot.orders.Orders`: place, get,
authorize, cancel, active) because a customer needs an answer (the new order's id and key, or
why it cannot be cancelled). Everything else arrives over the board: navigation reports
progress on ``DELIVERY_STATUS``. Each change is committed to the store and only then announced
on ``ORDER_UPDATE``; the head of the queue is handed to navigation on ``ORDER_DISPATCH``
(navigation should also read ``latest`` of that topic when it starts, in case the dispatch
was published before it subscribed).

**Nothing navigation reports is lost.** Its reports are kept, in order, until they are
stored: a store that fails (locked by another process, read only, full) is retried with
backoff, and the queue moves on as soon as the writes go through again. While the store fails
the orders' health on ``system/health`` says so (``degraded``, then ``failed`` after
``[store] failed_after_s``), with one ``event=fault`` line when it begins and one
``event=recovered`` when the changes are stored. A customer placing, reading or cancelling an
order meanwhile is told the orders are unavailable (nothing they were told was stored is
lost either). The board subscription outlives a crash of this module, so what navigation
reports while it restarts is still applied.

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
from collections import deque

from coffeebot.board import Subscription
from coffeebot.config import StoreConfig
from coffeebot.errors import OrderError, StoreError
from coffeebot.logs import Event, Transitions, log_event
from coffeebot.messages import (
    DELIVERY_STATUS,
    HEALTH,
    ORDER_DISPATCH,
    ORDER_UPDATE,
    DeliveryUpdate,
    Health,
    HealthStatus,
    OrderDispatch,
    OrderStatus,
    OrderUpdate,
)
from coffeebot.modules.backoff import Backoff
from coffeebot.modules.base import Module, ModuleBoard, ModuleContext
from coffeebot.orders import OrderNotFound, OrdersUnavailable, WrongOrderKey
from coffeebot.store import IN_FLIGHT, NewOrder, Order, OrderStore, PlacedOrder

log = logging.getLogger(__name__)

FIRST_RETRY_S = 0.1

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

WRITABLE, UNWRITABLE = "writable", "unwritable"
NAVIGATION = "navigation"
"""The module that carries the dispatched order (its health is watched)."""


class OrdersModule(Module):
    """Keeps the durable queue and feeds navigation one order at a time; implements
    :class:`~coffeebot.orders.Orders` for the web."""

    name = "orders"
    inputs = (DELIVERY_STATUS, HEALTH)
    outputs = (ORDER_DISPATCH, ORDER_UPDATE, HEALTH)

    def __init__(self, store: OrderStore, config: StoreConfig | None = None) -> None:
        self.store = store
        self.config = config or StoreConfig()
        self._board: ModuleBoard | None = None
        self._current: str | None = None
        self._recovered = False
        self._lock = asyncio.Lock()
        self._reports: Subscription[DeliveryUpdate] | None = None
        self._healths: Subscription[Health] | None = None
        self._unwritten: deque[DeliveryUpdate] = deque()
        """Navigation's reports for the current order, in order, until each is stored."""
        self._wake = asyncio.Event()
        """Set when a placed order could not be dispatched at once (the store failed)."""
        self._failing_since: float | None = None
        self._health: HealthStatus | None = None
        self._store_log: Transitions | None = None
        self._navigation_failed: str | None = None
        """Why the supervisor gave navigation up; no order is dispatched to it after that."""

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

    # --- the orders protocol ---------------------------------------------------------------

    async def place(self, new: NewOrder, client: str) -> PlacedOrder:
        """Queue a validated order; it is dispatched at once if the robot is idle (or as soon
        as the store takes the dispatch, if it fails just then: the order is stored)."""
        self._require_board()
        try:
            placed = await self.store.add(new, client)
        except StoreError as exc:
            raise _unavailable(exc) from exc
        self._announce(placed, f"placed by {client}")
        try:
            await self._dispatch_next()
            order = await self.get(placed.id)
        except (StoreError, OrdersUnavailable):
            self._wake.set()
            return placed
        return PlacedOrder(**order.model_dump(), key=placed.key)

    async def get(self, order_id: str) -> Order:
        try:
            order = await self.store.get(order_id)
        except StoreError as exc:
            raise _unavailable(exc) from exc
        if order is None:
            raise OrderNotFound(f"no order {order_id!r}")
        return order

    async def authorize(self, order_id: str, key: str) -> Order:
        order = await self.get(order_id)
        try:
            matches = await self.store.key_matches(order_id, key)
        except StoreError as exc:
            raise _unavailable(exc) from exc
        if not matches:
            raise WrongOrderKey(
                f"order {order_id!r} needs its key: use the link you were given when you ordered"
            )
        return order

    async def active(self) -> list[Order]:
        try:
            return await self.store.active()
        except StoreError as exc:
            raise _unavailable(exc) from exc

    async def cancel(self, order_id: str, detail: str = "cancelled by the customer") -> Order:
        """Cancel an order that is still waiting; a dispatched one is navigation's to end."""
        self._require_board()
        try:
            cancelled = await self.store.transition(
                order_id, OrderStatus.CANCELLED, detail, (OrderStatus.QUEUED,)
            )
        except StoreError as exc:
            raise _unavailable(exc) from exc
        if cancelled is None:
            order = await self.get(order_id)
            raise OrderError(f"order {order_id!r} is {order.status.value}, not queued")
        self._announce(cancelled, detail)
        return cancelled

    # --- the queue -------------------------------------------------------------------------

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
            while self._current is None and self._navigation_failed is None:
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
                    OrderDispatch(order_id=order.id, room=order.room, drink=order.drink),
                )

    def _receive(self, update: DeliveryUpdate) -> None:
        """Keep a report for the order that is out until it is stored; ignore the rest."""
        if update.order_id != self._current:
            log.warning(
                "delivery update for an order that is not out: ignored",
                extra={"order": update.order_id, "current": self._current},
            )
            return
        self._unwritten.append(update)

    def _on_health(self, health: Health) -> None:
        """Navigation given up by the supervisor (it crashed too often) cannot end the order
        it carries: the order fails with that reason instead of staying "on the way", and
        the queue waits for a restart rather than feeding orders to nobody."""
        if health.module != NAVIGATION or health.component:
            return
        if health.status is not HealthStatus.FAILED or self._navigation_failed is not None:
            return
        self._navigation_failed = health.detail or "failed"
        log.error(
            "navigation failed: no order is dispatched until the daemon restarts",
            extra={"event": Event.FAULT.value, "cause": self._navigation_failed},
        )
        if self._current is not None:
            self._unwritten.append(
                DeliveryUpdate(
                    order_id=self._current,
                    status=OrderStatus.FAILED,
                    detail=(
                        f"the robot's navigation stopped working ({self._navigation_failed}); "
                        "staff will check on the cup"
                    ),
                )
            )

    async def _store(self, update: DeliveryUpdate) -> None:
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

    async def _catch_up(self) -> None:
        """Everything the store has not taken yet, in order: the restart recovery, then
        navigation's reports, then the next dispatch. Raises ``StoreError`` where it stops."""
        if not self._recovered:
            await self._recover()
            self._recovered = True
        while self._unwritten:
            await self._store(self._unwritten[0])
            self._unwritten.popleft()
        await self._dispatch_next()

    # --- health ----------------------------------------------------------------------------

    def _report_health(self, ctx: ModuleContext, status: HealthStatus, detail: str) -> None:
        self._health = status
        ctx.board.publish(
            HEALTH,
            Health(module=self.name, component=str(self.store.path), status=status, detail=detail),
        )

    def _store_failed(self, ctx: ModuleContext, store: Transitions, exc: StoreError) -> None:
        now = ctx.clock.now()
        if self._failing_since is None:
            self._failing_since = now
        store.update(
            "store",
            UNWRITABLE,
            Event.FAULT,
            f"{exc}; retrying, every change is kept until it is stored",
            waiting=len(self._unwritten),
        )
        failing_s = now - self._failing_since
        status = (
            HealthStatus.FAILED
            if failing_s >= self.config.failed_after_s
            else HealthStatus.DEGRADED
        )
        self._report_health(
            ctx,
            status,
            f"order database not writable for {failing_s:.0f} s ({exc}); "
            f"{len(self._unwritten)} delivery report(s) waiting, retrying",
        )

    def _store_written(self, ctx: ModuleContext, store: Transitions) -> None:
        if self._failing_since is not None:
            failing_s = ctx.clock.now() - self._failing_since
            self._failing_since = None
            store.update(
                "store",
                WRITABLE,
                Event.RECOVERED,
                f"order database written again after {failing_s:.1f} s; every change stored",
            )
        if self._health is not HealthStatus.RUNNING:
            self._report_health(ctx, HealthStatus.RUNNING, f"order database {self.store.path}")

    # --- the task --------------------------------------------------------------------------

    async def _next_event(
        self, reports: Subscription[DeliveryUpdate], health: Subscription[Health]
    ) -> None:
        """Wait for a report from navigation, a module's health, or a placed order waiting
        for its dispatch."""
        if self._wake.is_set():
            self._wake.clear()
            return
        report = asyncio.ensure_future(reports.get())
        unwell = asyncio.ensure_future(health.get())
        wake = asyncio.ensure_future(self._wake.wait())
        try:
            done, _ = await asyncio.wait(
                {report, unwell, wake}, return_when=asyncio.FIRST_COMPLETED
            )
        finally:
            report.cancel()
            unwell.cancel()
            wake.cancel()
        self._wake.clear()
        if report in done:
            self._receive(report.result().msg)
        if unwell in done:
            self._on_health(unwell.result().msg)

    async def run(self, ctx: ModuleContext) -> None:
        if self._reports is None or self._reports.overflowed:
            if self._reports is not None:
                self._reports.close()
            self._reports = ctx.board.subscribe(DELIVERY_STATUS)
        reports = self._reports
        if self._healths is None or self._healths.overflowed:
            if self._healths is not None:
                self._healths.close()
            self._healths = ctx.board.subscribe(HEALTH)
        healths = self._healths
        self._board = ctx.board
        if self._store_log is None:
            self._store_log = Transitions(ctx.log, initial={"store": WRITABLE})
        store = self._store_log
        retry = Backoff(FIRST_RETRY_S, max(FIRST_RETRY_S, self.config.retry_max_s))
        try:
            while True:
                while (envelope := reports.get_nowait()) is not None:
                    self._receive(envelope.msg)
                while (unwell := healths.get_nowait()) is not None:
                    self._on_health(unwell.msg)
                try:
                    await self._catch_up()
                except StoreError as exc:
                    self._store_failed(ctx, store, exc)
                    await ctx.clock.sleep(retry.next_delay())
                    continue
                retry.reset()
                self._store_written(ctx, store)
                await self._next_event(reports, healths)
        finally:
            self._board = None


def _unavailable(exc: StoreError) -> OrdersUnavailable:
    """What a customer is told: the store's trouble in general terms (the operator's health
    report and log name the file and the error)."""
    log.warning("order request refused: %s", exc)
    return OrdersUnavailable("the order database cannot be used right now; try again shortly")
