"""The dispatcher as a board task: the broker connection around :class:`Dispatcher`.

It runs in the dispatcher's own daemon (``coffeebot fleet``), beside the web module, the way
the orders module runs on a single robot: the web places, reads and cancels orders through
it (it is the :class:`~coffeebot.orders.Orders` the web app is given), people's acts on the
web (``operator/event``, ``operator/estop``) go to the robots concerned, and the fleet's state
is on the board for the map (``fleet/robots``). A message on the broker that is not this
version's, or comes from a robot about another, is refused, counted and logged.
"""

from __future__ import annotations

import asyncio
from collections.abc import Callable

import aiomqtt

from coffeebot.board import Subscription
from coffeebot.fleet.client import fleet_session
from coffeebot.fleet.dispatcher import Announce, Dispatcher
from coffeebot.fleet.in_step import messages_in_step
from coffeebot.fleet.mosquitto import Credentials
from coffeebot.fleet.protocol import (
    DISPATCHER_CONNECTION,
    DISPATCHER_TO_ROBOT,
    QOS,
    ROBOT_TO_DISPATCHER,
    ROOT,
    Ack,
    BadMessage,
    Connection,
    DeliveryReport,
    FleetMessage,
    LeaseRequest,
    RobotState,
    encode,
    robot_report,
    robot_topic,
)
from coffeebot.logs import Event, Transitions
from coffeebot.messages import (
    ESTOP,
    FLEET,
    HEALTH,
    OPERATOR_EVENT,
    ORDER_UPDATE,
    EStop,
    FleetView,
    Health,
    HealthStatus,
    OperatorEvent,
    OrderUpdate,
)
from coffeebot.modules.backoff import Backoff
from coffeebot.modules.base import Module, ModuleContext
from coffeebot.orders import OrdersUnavailable
from coffeebot.store import NewOrder, Order, OrderStore, PlacedOrder

Send = Callable[[str, FleetMessage], None]
MakeDispatcher = Callable[[Send, Announce, Callable[[], float]], Dispatcher]

TICK_S = 1.0
"""How often time-driven rules run (stale robots, resends, assignment)."""
TRAFFIC_S = 0.5
"""How often each robot is told where the others are: two robots meeting head-on close at
1 m/s, and a robot looks 6 m ahead for them."""
CONNECTED, DISCONNECTED = "connected", "disconnected"


class DispatcherModule(Module):
    name = "dispatcher"
    inputs = (OPERATOR_EVENT, ESTOP)
    outputs = (ORDER_UPDATE, FLEET, HEALTH)

    def __init__(
        self,
        broker: str,
        credentials: Credentials,
        make: MakeDispatcher,
        store: OrderStore,
    ) -> None:
        """``make(send, announce, now)`` builds the :class:`Dispatcher` once the board and
        the clock are there."""
        self.broker = broker
        self.credentials = credentials
        self.make = make
        self.store = store
        self.dispatcher: Dispatcher | None = None
        self.refused = 0
        self._outbox: asyncio.Queue[tuple[str, FleetMessage]] = asyncio.Queue()
        self._wake = asyncio.Event()

    # --- the orders protocol, for the web -----------------------------------------------------

    def _running(self) -> Dispatcher:
        if self.dispatcher is None:
            raise OrdersUnavailable("the dispatcher is starting; try again shortly")
        return self.dispatcher

    async def place(self, new: NewOrder, client: str) -> PlacedOrder:
        placed = await self._running().place(new, client)
        self._wake.set()
        return placed

    async def get(self, order_id: str) -> Order:
        return await self._running().get(order_id)

    async def authorize(self, order_id: str, key: str) -> Order:
        return await self._running().authorize(order_id, key)

    async def cancel(self, order_id: str, detail: str = "cancelled by the customer") -> Order:
        return await self._running().cancel(order_id, detail)

    async def active(self) -> list[Order]:
        return await self._running().active()

    # --- the task -----------------------------------------------------------------------------

    async def run(self, ctx: ModuleContext) -> None:
        def send(robot: str, message: FleetMessage) -> None:
            self._outbox.put_nowait((robot, message))

        def announce(order: Order, cause: str, report: DeliveryReport | None = None) -> None:
            ctx.board.publish(
                ORDER_UPDATE,
                OrderUpdate(
                    order_id=order.id,
                    status=order.status,
                    detail=order.detail,
                    ready_for_cup=report is not None and report.ready_for_cup,
                    problem=None if report is None else report.problem,
                ),
            )
            ctx.log.info("order %s: %s (%s)", order.id, order.status.value, cause)

        dispatcher = self.dispatcher = self.make(send, announce, ctx.clock.now)
        link = Transitions(ctx.log, initial={"broker": CONNECTED})
        events = ctx.board.subscribe(OPERATOR_EVENT)
        estops = ctx.board.subscribe(ESTOP)
        with events, estops:
            async with asyncio.TaskGroup() as group:
                group.create_task(self._tick(ctx, dispatcher))
                group.create_task(self._traffic(ctx, dispatcher))
                group.create_task(self._people(ctx, dispatcher, events, estops))
                await self._connect_forever(ctx, dispatcher, link)

    async def _tick(self, ctx: ModuleContext, dispatcher: Dispatcher) -> None:
        while True:
            await dispatcher.tick()
            self._publish_view(ctx, dispatcher)
            self._wake.clear()
            waiting = asyncio.ensure_future(self._wake.wait())
            sleeping = asyncio.ensure_future(ctx.clock.sleep(TICK_S))
            try:
                await asyncio.wait({waiting, sleeping}, return_when=asyncio.FIRST_COMPLETED)
            finally:
                waiting.cancel()
                sleeping.cancel()

    async def _traffic(self, ctx: ModuleContext, dispatcher: Dispatcher) -> None:
        """Traffic while the broker is there: queued without it, it would all go at once,
        stale, on the reconnect."""
        while True:
            if dispatcher.link_up_since_s is not None:
                dispatcher.traffic()
            await ctx.clock.sleep(TRAFFIC_S)

    def _publish_view(self, ctx: ModuleContext, dispatcher: Dispatcher) -> None:
        linked = dispatcher.link_up_since_s is not None
        ctx.board.publish(FLEET, FleetView(robots=dispatcher.view(), broker=linked))

    async def _people(
        self,
        ctx: ModuleContext,
        dispatcher: Dispatcher,
        events: Subscription[OperatorEvent],
        estops: Subscription[EStop],
    ) -> None:
        async def acts() -> None:
            async for envelope in events:
                event = envelope.msg
                if event.source == "fleet":
                    continue
                if event.kind == "cancel":
                    dispatcher.operator("cancel", event.order_id)
                elif not dispatcher.operator(event.kind, event.order_id):
                    ctx.log.warning("%s for order %s: no robot has it", event.kind, event.order_id)

        async def stops() -> None:
            async for envelope in estops:
                dispatcher.estop(envelope.msg.engaged)

        await asyncio.gather(acts(), stops())

    async def _connect_forever(
        self, ctx: ModuleContext, dispatcher: Dispatcher, link: Transitions
    ) -> None:
        backoff = Backoff(0.5, 10.0)
        while True:
            try:
                async with fleet_session(
                    self.broker,
                    self.credentials,
                    "coffeebot-dispatcher",
                    DISPATCHER_CONNECTION,
                    messages_in_step(ctx.clock),
                ) as client:
                    await client.subscribe(
                        [(f"{ROOT}/robots/+/{kind}", 1) for kind in ROBOT_TO_DISPATCHER]
                    )
                    dispatcher.link_up_since_s = ctx.clock.now()
                    backoff.reset()
                    link.update("broker", CONNECTED, Event.RECONNECT, f"connected to {self.broker}")
                    self._health(ctx, HealthStatus.RUNNING, f"connected to {self.broker}")
                    async with asyncio.TaskGroup() as group:
                        group.create_task(self._send(client))
                        await self._receive(ctx, dispatcher, client)
            except* aiomqtt.MqttError as errors:
                dispatcher.link_up_since_s = None
                why = str(errors.exceptions[0])
                link.update("broker", DISCONNECTED, Event.DISCONNECT, f"{self.broker}: {why}")
                self._health(ctx, HealthStatus.DEGRADED, f"no broker: {why}")
            await ctx.clock.sleep(backoff.next_delay())

    def _health(self, ctx: ModuleContext, status: HealthStatus, detail: str) -> None:
        ctx.board.publish(
            HEALTH, Health(module=self.name, component="broker", status=status, detail=detail)
        )

    async def _send(self, client: aiomqtt.Client) -> None:
        while True:
            robot, message = await self._outbox.get()
            kind = _KIND_OF[type(message)]
            await client.publish(robot_topic(robot, kind), encode(message), qos=QOS.get(kind, 1))

    async def _receive(
        self, ctx: ModuleContext, dispatcher: Dispatcher, client: aiomqtt.Client
    ) -> None:
        async for message in client.messages:
            topic = str(message.topic)
            try:
                robot, decoded = robot_report(topic, message.payload, ROBOT_TO_DISPATCHER)
            except BadMessage as exc:
                self.refused += 1
                ctx.log.warning(
                    "refused a message from the broker (%d so far): %s", self.refused, exc
                )
                continue
            await self._take(dispatcher, robot, decoded)
            self._wake.set()

    @staticmethod
    async def _take(dispatcher: Dispatcher, robot: str, message: FleetMessage) -> None:
        if isinstance(message, Connection):
            await dispatcher.on_connection(robot, message)
        elif isinstance(message, RobotState):
            await dispatcher.on_state(robot, message)
        elif isinstance(message, DeliveryReport):
            await dispatcher.on_delivery(robot, message)
        elif isinstance(message, Ack):
            await dispatcher.on_ack(robot, message)
        elif isinstance(message, LeaseRequest):
            dispatcher.on_lease(robot, message)


_KIND_OF = {model: kind for kind, model in DISPATCHER_TO_ROBOT.items()}
"""The topic each message the dispatcher sends goes out on."""
