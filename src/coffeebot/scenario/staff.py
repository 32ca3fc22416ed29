"""The people around simulated deliveries, for runs nobody watches (the fleet's tests and
benchmark): the tea-room staff put the cup on once the robot says it is ready for it, the
customer takes it once the robot has arrived, each after the scenario's delay. They act
where people act, on the board of whoever owns the orders (a robot's or the dispatcher's),
and keep the moments a benchmark needs."""

from __future__ import annotations

from dataclasses import dataclass, field

from coffeebot.messages import OPERATOR_EVENT, ORDER_UPDATE, OperatorEvent, OrderStatus
from coffeebot.modules.base import Module, ModuleContext
from coffeebot.scenario.spec import Staff

TICK_S = 0.1
"""How often the people look whether a delay is over."""


@dataclass
class OrderTimes:
    """When an order got where (simulated seconds), as the people saw it."""

    ready_s: float | None = None
    arrived_s: float | None = None
    ended_s: float | None = None
    status: OrderStatus = OrderStatus.QUEUED
    told: set[str] = field(default_factory=set)


class StaffModule(Module):
    name = "staff"
    inputs = (ORDER_UPDATE,)
    outputs = (OPERATOR_EVENT,)

    def __init__(self, staff: Staff) -> None:
        self.staff = staff
        self.orders: dict[str, OrderTimes] = {}

    async def run(self, ctx: ModuleContext) -> None:
        with ctx.board.subscribe(ORDER_UPDATE) as updates:
            while True:
                now = ctx.clock.now()
                while (envelope := updates.get_nowait()) is not None:
                    update = envelope.msg
                    times = self.orders.setdefault(update.order_id, OrderTimes())
                    times.status = update.status
                    if update.ready_for_cup and times.ready_s is None:
                        times.ready_s = now
                    if update.status is OrderStatus.ARRIVED and times.arrived_s is None:
                        times.arrived_s = now
                    if update.status.final and times.ended_s is None:
                        times.ended_s = now
                for order_id, times in self.orders.items():
                    self._act(ctx, order_id, times, now)
                await ctx.clock.sleep(TICK_S)

    def _act(self, ctx: ModuleContext, order_id: str, times: OrderTimes, now: float) -> None:
        if times.status.final:
            return
        act(ctx, self.staff, order_id, times.ready_s, times.arrived_s, times.told, now)


def act(
    ctx: ModuleContext,
    staff: Staff,
    order_id: str,
    ready_s: float | None,
    arrived_s: float | None,
    told: set[str],
    now: float,
) -> None:
    """Load the cup ``load_after_s`` after the robot was ready for it and take it
    ``pickup_after_s`` after it arrived, once each (``told``)."""
    due = (
        ("cup_loaded", ready_s, staff.load_after_s),
        ("pickup_confirmed", arrived_s, staff.pickup_after_s),
    )
    for kind, since, delay in due:
        if since is None or delay is None or kind in told or now < since + delay:
            continue
        told.add(kind)
        ctx.board.publish(
            OPERATOR_EVENT,
            OperatorEvent.model_validate(
                {"kind": kind, "order_id": order_id, "source": "scenario"}
            ),
        )
