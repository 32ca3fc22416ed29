"""The fleet over a real Mosquitto broker: robots' bridges and the dispatcher, started by the
test on a free port with its own users and access rules.

The robots here are their real fleet bridges on a board each, with a stand-in for
navigation that walks a delivery through its statuses when told to (the simulated robots'
own deliveries are test_fleet_sim.py's): what is under test is what crosses the broker.
Everything runs on the machine's clock with short periods; the waits are for conditions,
with generous limits, never for a time.
"""

from __future__ import annotations

import asyncio
import json
import time
from collections.abc import AsyncIterator, Awaitable, Callable
from pathlib import Path

import aiomqtt
import pytest

from coffeebot.board import Board
from coffeebot.clock import MonotonicClock
from coffeebot.config import DispatchConfig, FleetConfig, RobotConfig, load_robot_config
from coffeebot.daemon import Daemon
from coffeebot.fleet.mosquitto import Mosquitto
from coffeebot.fleet.protocol import ConnectionState, robot_topic
from coffeebot.floorplan import load_floorplan
from coffeebot.messages import (
    ALL_TOPICS,
    CURRENT_STATE,
    DELIVERY_STATUS,
    LEASE_NEED,
    LEASE_STATE,
    OPERATOR_EVENT,
    ORDER_DISPATCH,
    TRAFFIC,
    CurrentState,
    DeliveryUpdate,
    HealthStatus,
    LeaseNeed,
    OrderStatus,
    PoseEstimate,
)
from coffeebot.modules.base import Module, ModuleContext
from coffeebot.modules.fleet_bridge import FleetBridge
from coffeebot.runtime.fleet import DispatcherRuntime, dispatcher_runtime
from coffeebot.store import NewOrder, Order, OrderRules, OrderStore

from .conftest import ROBOTS

ROOT = Path(__file__).resolve().parents[2]
PLAN = load_floorplan(ROOT / "floorplans" / "cs-building.toml")
BOARD = load_robot_config(ROOT / "boards" / "coffeebot-v1.toml")
RULES = OrderRules(rooms=set(PLAN.rooms), drinks=set(BOARD.web.drinks))
WAIT_S = 30.0
DISPATCH = DispatchConfig(stale_after_s=3.0, lost_after_s=3.0, ack_timeout_s=1.0, lease_s=10.0)
"""Short enough for the tests' waits, long enough that a loaded machine delaying a state
report or a lease renewal by a second does not make a robot stale or lose its lease."""


class StandInNavigation(Module):
    """Takes the dispatched order and reports it through its statuses: ready for the cup,
    on the way once loaded, arrived after ``drive_s``, delivered once picked up; a cancel
    ends it. Stands in the tea room meanwhile (a pose for the dispatcher's estimates)."""

    name = "navigation"
    inputs = (ORDER_DISPATCH, OPERATOR_EVENT, LEASE_STATE)
    outputs = (DELIVERY_STATUS, CURRENT_STATE, LEASE_NEED)

    def __init__(self, drive_s: float = 0.5, at: tuple[float, float] = (42000, -1650)) -> None:
        self.drive_s = drive_s
        self.at = at

    async def run(self, ctx: ModuleContext) -> None:
        pose = PoseEstimate(
            x_mm=self.at[0],
            y_mm=self.at[1],
            heading_deg=90,
            floor=2,
            sigma_x_mm=30,
            sigma_y_mm=30,
            sigma_heading_deg=1,
        )
        ctx.board.publish(CURRENT_STATE, CurrentState(pose=pose))
        with ctx.board.subscribe(ORDER_DISPATCH) as dispatches:
            async for envelope in dispatches:
                await self._deliver(ctx, envelope.msg.order_id)

    async def _deliver(self, ctx: ModuleContext, order: str) -> None:
        def report(status: OrderStatus, detail: str, ready: bool = False) -> None:
            ctx.board.publish(
                DELIVERY_STATUS,
                DeliveryUpdate(order_id=order, status=status, detail=detail, ready_for_cup=ready),
            )

        report(OrderStatus.PREPARING, "ready for the cup", ready=True)
        if not await self._wait(ctx, order, "cup_loaded"):
            report(OrderStatus.CANCELLED, "cancelled")
            return
        report(OrderStatus.ON_THE_WAY, "on the way")
        await ctx.clock.sleep(self.drive_s)
        report(OrderStatus.ARRIVED, "at the door")
        if await self._wait(ctx, order, "pickup_confirmed"):
            report(OrderStatus.DELIVERED, "picked up")

    @staticmethod
    async def _wait(ctx: ModuleContext, order: str, kind: str) -> bool:
        while True:
            envelope = await ctx.board.next(OPERATOR_EVENT)
            event = envelope.msg
            if event.order_id != order:
                continue
            if event.kind == "cancel":
                return False
            if event.kind == kind:
                return True


def robot_config(broker: Mosquitto, robot: str) -> RobotConfig:
    fleet = FleetConfig(
        broker=broker.address.url,
        robot_id=robot,
        state_hz=10,
        lease_renew_s=0.5,
        lease_wait_s=600,
    )
    return BOARD.model_copy(update={"fleet": fleet})


class Fleet:
    """The broker, the dispatcher and stand-in robots, each robot a daemon of its own."""

    def __init__(self, broker: Mosquitto, store: OrderStore, web: bool = False) -> None:
        """``web``: the dispatcher serves its web UI on a free port."""
        self.broker = broker
        self.store = store
        self.web = web
        clock = self.clock = MonotonicClock()
        self.dispatcher: DispatcherRuntime = self._dispatcher()
        self.robots: dict[str, Daemon] = {}
        self.bridges: dict[str, FleetBridge] = {}
        self.navigation: dict[str, StandInNavigation] = {}
        for index, robot in enumerate(ROBOTS):
            board = Board(ALL_TOPICS, clock=clock)
            bridge = FleetBridge(robot_config(broker, robot), broker.credentials[robot])
            self.bridges[robot] = bridge
            standing = StandInNavigation(at=(42000 - 6000 * index, -300))
            self.navigation[robot] = standing
            self.robots[robot] = Daemon(board, [bridge, standing])

    def _dispatcher(self) -> DispatcherRuntime:
        config = BOARD.model_copy(
            update={
                "fleet": FleetConfig(dispatch=DISPATCH),
                "web": BOARD.web.model_copy(update={"port": 0}),
            }
        )
        return dispatcher_runtime(
            config,
            PLAN,
            self.store,
            self.broker.address.url,
            self.broker.credentials["dispatcher"],
            self.clock,
            web=self.web,
        )

    async def restart_dispatcher(self, meanwhile: Callable[[], Awaitable[None]]) -> None:
        """The dispatcher's software stops, ``meanwhile`` happens, and it starts again on
        the same store with nothing else of what it knew."""
        await self.dispatcher.daemon.shutdown()
        await meanwhile()
        self.dispatcher = self._dispatcher()
        await self.dispatcher.daemon.start()

    async def start(self) -> None:
        await self.dispatcher.daemon.start()
        for daemon in self.robots.values():
            await daemon.start()

    async def stop(self) -> None:
        for daemon in [*self.robots.values(), self.dispatcher.daemon]:
            await daemon.shutdown()

    @property
    def orders(self):  # type: ignore[no-untyped-def]
        return self.dispatcher.module

    async def order(self, room: str = "205") -> Order:
        new = NewOrder.model_validate(
            {"room": room, "drink": BOARD.web.drinks[0], "name": "Ada"}, context=RULES
        )
        return await self.orders.place(new, "test")

    async def until(self, check: Callable[[], Awaitable[bool]], what: str) -> None:
        deadline = time.monotonic() + WAIT_S
        while not await check():
            if time.monotonic() > deadline:
                raise AssertionError(f"not within {WAIT_S} s: {what}")
            await asyncio.sleep(0.05)

    async def status(self, order_id: str) -> OrderStatus:
        return (await self.orders.get(order_id)).status

    async def until_status(self, order_id: str, *status: OrderStatus) -> Order:
        async def reached() -> bool:
            return await self.status(order_id) in status

        await self.until(reached, f"order {order_id} {[s.value for s in status]}")
        return await self.orders.get(order_id)

    def act(self, kind: str, order_id: str) -> None:
        assert self.orders.dispatcher is not None
        assert self.orders.dispatcher.operator(kind, order_id)  # type: ignore[arg-type]


@pytest.fixture
async def fleet(broker: Mosquitto, tmp_path: Path) -> AsyncIterator[Fleet]:
    store = OrderStore(tmp_path / "orders.sqlite3")
    fleet = Fleet(broker, store)
    await fleet.start()
    yield fleet
    await fleet.stop()
    store.close()


async def test_an_order_goes_to_a_robot_and_is_delivered_over_the_broker(fleet: Fleet) -> None:
    placed = await fleet.order()
    order = await fleet.until_status(placed.id, OrderStatus.PREPARING)
    assert order.robot in ROBOTS
    await fleet.until(lambda: _ready(fleet, placed.id), "the robot reports it is ready for the cup")
    fleet.act("cup_loaded", placed.id)
    await fleet.until_status(placed.id, OrderStatus.ARRIVED)
    fleet.act("pickup_confirmed", placed.id)
    await fleet.until_status(placed.id, OrderStatus.DELIVERED)
    await fleet.until(
        lambda: _states_repeat(fleet, order.robot, OrderStatus.DELIVERED),
        "its state reports repeat its latest delivery report",
    )


async def _states_repeat(fleet: Fleet, robot: str | None, status: OrderStatus) -> bool:
    """Whether ``robot``'s last state report carries its latest delivery report, ``status``
    (a report sent to nobody, after a broker restart, is not lost)."""
    assert fleet.orders.dispatcher is not None and robot is not None
    state = fleet.orders.dispatcher.robots[robot].state
    return state is not None and getattr(state.latest_report, "status", None) is status


async def _ready(fleet: Fleet, order_id: str) -> bool:
    order = await fleet.orders.get(order_id)
    return order.status is OrderStatus.PREPARING and "ready" in order.detail


async def test_two_orders_go_to_two_robots_one_each(fleet: Fleet) -> None:
    first, second = await fleet.order("205"), await fleet.order("212")
    a = await fleet.until_status(first.id, OrderStatus.PREPARING)
    b = await fleet.until_status(second.id, OrderStatus.PREPARING)
    assert {a.robot, b.robot} == set(ROBOTS)


def online(fleet: Fleet, robot: str, wanted: bool = True) -> Callable[[], Awaitable[bool]]:
    """Whether the dispatcher takes ``robot`` for online (``wanted``) or not."""

    async def check() -> bool:
        dispatcher = fleet.orders.dispatcher
        assert dispatcher is not None
        return any(r.robot == robot and r.online for r in dispatcher.view()) is wanted

    return check


async def test_a_robot_shut_down_says_offline_and_is_no_longer_given_orders(
    fleet: Fleet,
) -> None:
    await fleet.until(online(fleet, "robot-2"), "robot-2 comes online")
    await fleet.robots["robot-2"].shutdown()
    assert fleet.orders.dispatcher is not None
    record = fleet.orders.dispatcher.robots["robot-2"]
    await fleet.until(online(fleet, "robot-2", False), "the dispatcher hears robot-2 left")
    assert record.connection is ConnectionState.OFFLINE, "it said goodbye: not a broken link"
    placed = await fleet.order()
    assert (await fleet.until_status(placed.id, OrderStatus.PREPARING)).robot == "robot-1"


async def test_cancel_works_before_the_robot_acknowledged_and_reaches_the_robot(
    fleet: Fleet, broker: Mosquitto
) -> None:
    # The real robots go; in robot-1's place, a client with its login that says it is free
    # and then never acknowledges anything (Open-RMF's users meet such tasks).
    for robot in ROBOTS:
        await fleet.until(online(fleet, robot), f"{robot} comes online")
    for robot in ROBOTS:
        await fleet.robots[robot].shutdown()
    login = broker.credentials["robot-1"]
    async with aiomqtt.Client(
        broker.address.host,
        broker.address.port,
        username=login.username,
        password=login.password,
        identifier="test-silent-robot",
    ) as silent:
        await silent.subscribe(robot_topic("robot-1", "#"))
        ticker = asyncio.create_task(_free_robot(silent))
        try:
            await fleet.until(online(fleet, "robot-2", False), "the dispatcher hears robot-2 left")
            placed = await fleet.order()
            order = await fleet.until_status(placed.id, OrderStatus.PREPARING)
            assert order.robot == "robot-1"
            cancelled = await fleet.orders.cancel(placed.id)
            assert cancelled.status is OrderStatus.CANCELLED
            kinds = await _received(silent, {"assignment", "action"})
        finally:
            ticker.cancel()
    assert kinds["assignment"]["order_id"] == placed.id
    assert kinds["action"] == {
        "action_id": kinds["action"]["action_id"],
        "kind": "cancel",
        "order_id": placed.id,
    }


async def _free_robot(client: aiomqtt.Client) -> None:
    """Say robot-1 is online, at the tea room, carrying nothing, a few times a second."""
    from coffeebot.fleet.protocol import Connection, ConnectionState, RobotState, encode

    online = Connection(state=ConnectionState.ONLINE, at_s=time.time())
    await client.publish(robot_topic("robot-1", "connection"), encode(online), qos=1)
    boot_s = time.time()
    for seq in range(10_000):
        state = RobotState(
            seq=seq,
            at_s=time.time(),
            boot_s=boot_s,
            reports=0,
            floor=2,
            x_mm=42000,
            y_mm=-1650,
            heading_deg=90,
            health=HealthStatus.RUNNING,
        )
        await client.publish(robot_topic("robot-1", "state"), encode(state))
        await asyncio.sleep(0.1)


async def _received(client: aiomqtt.Client, kinds: set[str]) -> dict[str, dict[str, object]]:
    """The first message of each kind the client gets on robot-1's topics, as JSON."""
    found: dict[str, dict[str, object]] = {}
    async with asyncio.timeout(WAIT_S):
        async for message in client.messages:
            kind = str(message.topic).rsplit("/", 1)[1]
            if kind in kinds and kind not in found:
                assert isinstance(message.payload, bytes)
                found[kind] = json.loads(message.payload)
            if set(found) == kinds:
                return found
    return found


async def test_a_bad_message_is_refused_counted_and_changes_nothing(
    fleet: Fleet, broker: Mosquitto
) -> None:
    placed = await fleet.order()
    await fleet.until_status(placed.id, OrderStatus.PREPARING)
    login = broker.credentials["robot-1"]
    async with aiomqtt.Client(
        broker.address.host,
        broker.address.port,
        username=login.username,
        password=login.password,
        identifier="test-garbage",
    ) as client:
        await client.publish(robot_topic("robot-1", "delivery"), b'{"seq": "x"}', qos=1)
        await client.publish(robot_topic("robot-1", "state"), b"\xff not json", qos=1)
        await client.publish(robot_topic("robot-1", "shout"), b"{}", qos=1)  # not allowed
    await fleet.until(
        lambda: _refused(fleet, 2), "the dispatcher refuses and counts both bad messages"
    )
    assert (await fleet.orders.get(placed.id)).status is OrderStatus.PREPARING


async def _refused(fleet: Fleet, count: int) -> bool:
    return fleet.orders.refused >= count


async def test_the_broker_restarting_mid_delivery_loses_and_repeats_nothing(
    fleet: Fleet, broker: Mosquitto
) -> None:
    placed = await fleet.order()
    await fleet.until(lambda: _ready(fleet, placed.id), "ready for the cup")
    fleet.act("cup_loaded", placed.id)
    await fleet.until_status(placed.id, OrderStatus.ON_THE_WAY)
    broker.stop()  # the robot arrives while nobody can hear it: its report waits
    await asyncio.sleep(1.5)
    broker.start()
    order = await fleet.until_status(placed.id, OrderStatus.ARRIVED)
    fleet.act("pickup_confirmed", placed.id)
    await fleet.until_status(placed.id, OrderStatus.DELIVERED)
    robot = order.robot
    assert robot is not None
    assert fleet.bridges[robot].counters.connects >= 2
    assert fleet.orders.dispatcher is not None
    assert fleet.orders.dispatcher.counters.assignments == 1, "served once"


async def test_a_robot_killed_mid_delivery_fails_its_order_with_the_reason(
    fleet: Fleet,
) -> None:
    placed = await fleet.order()
    await fleet.until(lambda: _ready(fleet, placed.id), "ready for the cup")
    fleet.act("cup_loaded", placed.id)
    order = await fleet.until_status(placed.id, OrderStatus.ON_THE_WAY)
    assert order.robot is not None
    for state in fleet.robots[order.robot].states.values():  # the robot dies, says nothing
        assert state.task is not None
        state.task.cancel()
    failed = await fleet.until_status(placed.id, OrderStatus.FAILED)
    assert f"{order.robot} stopped reporting" in failed.detail


async def test_a_restarted_dispatcher_learns_what_a_robot_did_while_it_was_down(
    fleet: Fleet,
) -> None:
    for navigation in fleet.navigation.values():
        navigation.drive_s = 2.0
    placed = await fleet.order()
    await fleet.until(lambda: _ready(fleet, placed.id), "ready for the cup")
    fleet.act("cup_loaded", placed.id)
    robot = (await fleet.until_status(placed.id, OrderStatus.ON_THE_WAY)).robot
    assert robot is not None
    board = fleet.robots[robot].board

    async def arrives() -> None:
        async def arrived() -> bool:
            latest = board.latest(DELIVERY_STATUS)
            return latest is not None and latest.msg.status is OrderStatus.ARRIVED

        await fleet.until(arrived, f"{robot} arrives while the dispatcher is down")

    await fleet.restart_dispatcher(arrives)
    await fleet.until_status(placed.id, OrderStatus.ARRIVED)
    fleet.act("pickup_confirmed", placed.id)
    await fleet.until_status(placed.id, OrderStatus.DELIVERED)


async def test_a_shared_place_is_one_robots_and_passes_to_the_other_when_given_back(
    fleet: Fleet,
) -> None:
    boards = {robot: daemon.board for robot, daemon in fleet.robots.items()}

    def holds(robot: str) -> bool:
        state = boards[robot].latest(LEASE_STATE)
        return state is not None and state.msg.elevator

    await asyncio.sleep(0.5)  # both bridges connected
    boards["robot-1"].publish(LEASE_NEED, LeaseNeed(place="elevator", want=True))

    async def first() -> bool:
        return holds("robot-1")

    await fleet.until(first, "robot-1 gets the elevator")
    boards["robot-2"].publish(LEASE_NEED, LeaseNeed(place="elevator", want=True))
    await asyncio.sleep(1.0)
    assert not holds("robot-2"), "the elevator is robot-1's"
    boards["robot-1"].publish(LEASE_NEED, LeaseNeed(place="elevator", want=False))

    async def second() -> bool:
        return holds("robot-2") and not holds("robot-1")

    await fleet.until(second, "robot-2 gets it once robot-1 gives it back")


async def test_each_robot_is_told_where_the_other_is(fleet: Fleet) -> None:
    def traffic_names(robot: str, other: str) -> Callable[[], Awaitable[bool]]:
        async def check() -> bool:
            traffic = fleet.robots[robot].board.latest(TRAFFIC)
            return traffic is not None and [r.robot for r in traffic.msg.robots] == [other]

        return check

    for robot, other in [("robot-1", "robot-2"), ("robot-2", "robot-1")]:
        await fleet.until(traffic_names(robot, other), f"{robot}'s board has {other}'s pose")
    traffic = fleet.robots["robot-1"].board.latest(TRAFFIC)
    assert traffic is not None
    seen = traffic.msg.robots[0]
    # Where its StandInNavigation stands it.
    assert (seen.floor, seen.x_mm, seen.y_mm, seen.heading_deg) == (2, 36000, -300, 90)
    assert not seen.moving and seen.age_s < DISPATCH.stale_after_s
