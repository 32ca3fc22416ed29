"""The dispatcher's bookkeeping, fed robots' messages directly (the broker's part is tested
with the real broker in test_fleet_broker.py): assignment on acknowledgement, refusals,
cancel before acknowledgement, stale robots, lost orders, reports applied once, traffic."""

from __future__ import annotations

import time
from collections.abc import AsyncIterator
from pathlib import Path

import pytest

from coffeebot.config import DispatchConfig, load_robot_config
from coffeebot.fleet.dispatcher import Dispatcher
from coffeebot.fleet.estimates import TravelTimes
from coffeebot.fleet.protocol import (
    Ack,
    Assignment,
    Connection,
    ConnectionState,
    DeliveryReport,
    FleetMessage,
    InstantAction,
    LeaseGrant,
    LeaseRequest,
    RobotState,
    Traffic,
)
from coffeebot.floorplan import load_floorplan
from coffeebot.messages import OrderStatus
from coffeebot.store import NewOrder, Order, OrderRules, OrderStore
from coffeebot.web.eta import Pace

ROOT = Path(__file__).resolve().parents[2]
PLAN = load_floorplan(ROOT / "floorplans" / "cs-building.toml")
CONFIG = load_robot_config(ROOT / "boards" / "coffeebot-v1.toml")
RULES = OrderRules(rooms=set(PLAN.rooms), drinks=set(CONFIG.web.drinks))
BASE = (41500.0, -700.0)
"""In the tea room, where free robots stand."""
BOOT_S = 1.7e9
"""When the robots' software started (their wall clock), unless a test restarts it."""


class Clock:
    def __init__(self) -> None:
        self.t = 1000.0

    def __call__(self) -> float:
        return self.t


class Harness:
    def __init__(self, store: OrderStore) -> None:
        self.clock = Clock()
        self.sent: list[tuple[str, FleetMessage]] = []
        self.announced: list[tuple[str, OrderStatus]] = []
        self.dispatcher = Dispatcher(
            store,
            TravelTimes(PLAN, CONFIG, Pace()),
            DispatchConfig(),
            lambda robot, message: self.sent.append((robot, message)),
            lambda order, cause, report=None: self.announced.append((order.id, order.status)),
            self.clock,
        )
        self.dispatcher.link_up_since_s = 0.0
        self.seq = 0
        self.boot_s: dict[str, float] = {}
        """Each robot's software's start (BOOT_S unless restarted)."""
        self.made: dict[str, int] = {}
        """Delivery reports each robot has made in its current run."""

    async def robot_reports(
        self,
        robot: str,
        order_id: str | None = None,
        floor: int = 2,
        latest: DeliveryReport | None = None,
    ) -> None:
        """A state report saying the robot carries ``order_id``, with every report made
        (``latest`` the last of them)."""
        self.seq += 1
        await self.dispatcher.on_connection(
            robot, Connection(state=ConnectionState.ONLINE, at_s=time.time())
        )
        await self.dispatcher.on_state(
            robot,
            RobotState(
                seq=self.seq,
                at_s=time.time(),
                boot_s=self.boot_s.get(robot, BOOT_S),
                reports=self.made.get(robot, 0),
                floor=floor,
                x_mm=BASE[0],
                y_mm=BASE[1],
                heading_deg=0.0,
                order_id=order_id,
                latest_report=latest,
            ),
        )

    async def order(self, room: str = "205") -> Order:
        new = NewOrder.model_validate(
            {"room": room, "drink": CONFIG.web.drinks[0], "name": "Ada"}, context=RULES
        )
        return await self.dispatcher.place(new, "test")

    def report(self, robot: str, order_id: str, status: OrderStatus) -> DeliveryReport:
        """The robot's next delivery report (made: whether it arrives is the test's)."""
        seq = self.made.get(robot, 0)
        self.made[robot] = seq + 1
        boot_s = self.boot_s.get(robot, BOOT_S)
        return DeliveryReport(seq=seq, boot_s=boot_s, order_id=order_id, status=status)

    async def assigned_and_taken(self, robot: str) -> Order:
        """An order placed, assigned to ``robot`` (the only free one) and acknowledged."""
        placed = await self.order()
        await self.dispatcher.tick()
        sent = self.assignments(robot)[-1]
        assert sent.order_id == placed.id
        await self.dispatcher.on_ack(robot, Ack(ref=sent.assignment_id, accepted=True))
        return placed

    def assignments(self, robot: str | None = None) -> list[Assignment]:
        return [
            m for r, m in self.sent if isinstance(m, Assignment) and (robot is None or r == robot)
        ]

    def actions(self, robot: str) -> list[InstantAction]:
        return [m for r, m in self.sent if isinstance(m, InstantAction) and r == robot]


@pytest.fixture
async def harness(tmp_path: Path) -> AsyncIterator[Harness]:
    store = OrderStore(tmp_path / "orders.sqlite3")
    yield Harness(store)
    store.close()


async def test_a_waiting_order_goes_to_a_free_robot_and_counts_once_acknowledged(
    harness: Harness,
) -> None:
    await harness.robot_reports("r1")
    placed = await harness.order()
    await harness.dispatcher.tick()
    (sent,) = harness.assignments("r1")
    assert sent.order_id == placed.id
    order = await harness.dispatcher.get(placed.id)
    assert order.status is OrderStatus.PREPARING and order.robot == "r1"
    harness.clock.t += 5.0  # no acknowledgement yet: sent again
    await harness.dispatcher.tick()
    assert len(harness.assignments("r1")) == 2
    await harness.dispatcher.on_ack("r1", Ack(ref=sent.assignment_id, accepted=True))
    harness.clock.t += 5.0
    await harness.robot_reports("r1", placed.id)
    await harness.dispatcher.tick()
    assert len(harness.assignments("r1")) == 2, "acknowledged: not sent again"


async def test_only_several_free_robots_and_several_waiting_orders_make_a_choice(
    harness: Harness,
) -> None:
    """The benchmark compares joint with greedy dispatch: the two can differ only where a
    choice is made, and the dispatcher counts those."""
    await harness.robot_reports("r1")
    await harness.order()
    await harness.dispatcher.tick()
    assert harness.dispatcher.counters.choices == 0, "one robot, one order: no choice"
    await harness.robot_reports("r2")
    await harness.robot_reports("r3")
    await harness.order("305")
    await harness.order("205")
    await harness.dispatcher.tick()
    assert len(harness.assignments()) == 3
    assert harness.dispatcher.counters.choices == 1


async def test_a_refused_assignment_goes_back_to_the_queue_and_to_another_robot(
    harness: Harness,
) -> None:
    await harness.robot_reports("r1")
    placed = await harness.order()
    await harness.dispatcher.tick()
    (sent,) = harness.assignments("r1")
    refusal = Ack(ref=sent.assignment_id, accepted=False, reason="busy")
    await harness.dispatcher.on_ack("r1", refusal)
    assert (await harness.dispatcher.get(placed.id)).status is OrderStatus.QUEUED
    await harness.robot_reports("r2")
    await harness.dispatcher.tick()
    assert [a.order_id for a in harness.assignments()] == [placed.id, placed.id]


async def test_cancel_works_before_the_robot_has_acknowledged(harness: Harness) -> None:
    await harness.robot_reports("r1")
    placed = await harness.order()
    await harness.dispatcher.tick()
    cancelled = await harness.dispatcher.cancel(placed.id)
    assert cancelled.status is OrderStatus.CANCELLED
    assert [a.kind for a in harness.actions("r1")] == ["cancel"]
    harness.clock.t += 10.0
    await harness.dispatcher.tick()
    assert len(harness.assignments("r1")) == 1, "a cancelled order is not sent again"


async def test_a_silent_robot_turns_stale_its_unstarted_order_is_requeued(
    harness: Harness,
) -> None:
    await harness.robot_reports("r1")
    placed = await harness.order()
    await harness.dispatcher.tick()
    (sent,) = harness.assignments("r1")
    await harness.dispatcher.on_ack("r1", Ack(ref=sent.assignment_id, accepted=True))
    harness.clock.t += 6.0
    await harness.dispatcher.tick()
    (view,) = harness.dispatcher.view()
    assert view.stale and view.heard_ago_s is not None and view.heard_ago_s >= 6.0
    assert (await harness.dispatcher.get(placed.id)).status is OrderStatus.QUEUED


async def test_a_robot_that_dies_carrying_an_order_fails_it_with_the_reason(
    harness: Harness,
) -> None:
    await harness.robot_reports("r1")
    placed = await harness.order()
    await harness.dispatcher.tick()
    (sent,) = harness.assignments("r1")
    await harness.dispatcher.on_ack("r1", Ack(ref=sent.assignment_id, accepted=True))
    report = DeliveryReport(seq=0, boot_s=BOOT_S, order_id=placed.id, status=OrderStatus.ON_THE_WAY)
    await harness.dispatcher.on_delivery("r1", report)
    await harness.dispatcher.on_connection(
        "r1", Connection(state=ConnectionState.CONNECTION_BROKEN, at_s=time.time())
    )
    await harness.dispatcher.tick()
    assert (await harness.dispatcher.get(placed.id)).status is OrderStatus.ON_THE_WAY
    harness.clock.t += DispatchConfig().lost_after_s
    await harness.dispatcher.tick()
    order = await harness.dispatcher.get(placed.id)
    assert order.status is OrderStatus.FAILED and "r1 stopped reporting" in order.detail


async def test_reports_apply_once_and_only_from_the_robot_that_has_the_order(
    harness: Harness,
) -> None:
    await harness.robot_reports("r1")
    await harness.robot_reports("r2")
    placed = await harness.order()
    await harness.dispatcher.tick()
    (sent,) = harness.assignments()
    holder = "r1" if harness.assignments("r1") else "r2"
    other = "r2" if holder == "r1" else "r1"
    await harness.dispatcher.on_ack(holder, Ack(ref=sent.assignment_id, accepted=True))
    on_the_way = DeliveryReport(
        seq=3, boot_s=BOOT_S, order_id=placed.id, status=OrderStatus.ON_THE_WAY
    )
    arrived = DeliveryReport(seq=4, boot_s=BOOT_S, order_id=placed.id, status=OrderStatus.ARRIVED)
    await harness.dispatcher.on_delivery(holder, on_the_way)
    await harness.dispatcher.on_delivery(holder, arrived)
    await harness.dispatcher.on_delivery(holder, on_the_way)  # a repeat after a reconnect
    assert (await harness.dispatcher.get(placed.id)).status is OrderStatus.ARRIVED
    foreign = DeliveryReport(seq=0, boot_s=BOOT_S, order_id=placed.id, status=OrderStatus.DELIVERED)
    await harness.dispatcher.on_delivery(other, foreign)
    assert (await harness.dispatcher.get(placed.id)).status is OrderStatus.ARRIVED
    assert [a.kind for a in harness.actions(other)] == ["cancel"]


async def test_a_state_report_overtaking_the_delivered_report_fails_nothing(
    harness: Harness,
) -> None:
    """The two travel apart: a robot that has just delivered says it carries nothing, and
    that state may arrive first (found under load: the order failed "restarted without
    it", then the delivered report was refused)."""
    await harness.robot_reports("r1")
    placed = await harness.assigned_and_taken("r1")
    for status in (OrderStatus.ON_THE_WAY, OrderStatus.ARRIVED):
        await harness.dispatcher.on_delivery("r1", harness.report("r1", placed.id, status))
    delivered = harness.report("r1", placed.id, OrderStatus.DELIVERED)
    await harness.robot_reports("r1", None)  # made after the delivered report, here first
    assert (await harness.dispatcher.get(placed.id)).status is OrderStatus.ARRIVED
    await harness.dispatcher.on_delivery("r1", delivered)
    assert (await harness.dispatcher.get(placed.id)).status is OrderStatus.DELIVERED


async def test_a_report_that_reached_nobody_is_taken_from_the_next_state_report(
    harness: Harness,
) -> None:
    """A restarted broker keeps no sessions: a robot that reconnects before the dispatcher
    and sends at once sends to nobody (found with the broker killed: its cup stood at the
    door, nobody was told, and the order failed after three minutes)."""
    await harness.robot_reports("r1")
    placed = await harness.assigned_and_taken("r1")
    await harness.dispatcher.on_delivery(
        "r1", harness.report("r1", placed.id, OrderStatus.ON_THE_WAY)
    )
    harness.report("r1", placed.id, OrderStatus.WAITING_FOR_ELEVATOR)  # both reach nobody
    arrived = harness.report("r1", placed.id, OrderStatus.ARRIVED)
    await harness.robot_reports("r1", placed.id, latest=arrived)
    assert (await harness.dispatcher.get(placed.id)).status is OrderStatus.ARRIVED
    await harness.robot_reports("r1", placed.id, latest=arrived)
    await harness.dispatcher.on_delivery("r1", arrived)  # a copy that did go, late
    assert harness.announced.count((placed.id, OrderStatus.ARRIVED)) == 1, "applied once"
    assert harness.actions("r1") == [], "nothing to drop"


async def test_a_restarted_dispatcher_catches_up_with_what_its_robots_did_meanwhile(
    harness: Harness,
) -> None:
    """Its book starts empty; its store is behind: one robot arrived, one failed its order,
    one had long delivered (the latest report each state repeats says so)."""
    done = {}
    for robot in ("r3", "r1", "r2"):  # one at a time, so each is the only free robot
        await harness.robot_reports(robot)
        placed = await harness.assigned_and_taken(robot)
        await harness.dispatcher.on_delivery(
            robot, harness.report(robot, placed.id, OrderStatus.ON_THE_WAY)
        )
        done[robot] = placed
    for status in (OrderStatus.ARRIVED, OrderStatus.DELIVERED):
        await harness.dispatcher.on_delivery("r3", harness.report("r3", done["r3"].id, status))
    delivered = DeliveryReport(
        seq=harness.made["r3"] - 1,
        boot_s=BOOT_S,
        order_id=done["r3"].id,
        status=OrderStatus.DELIVERED,
    )
    restarted = Harness(harness.dispatcher.store)
    restarted.made, restarted.seq = harness.made, harness.seq
    arrived = restarted.report("r1", done["r1"].id, OrderStatus.ARRIVED)
    failed = restarted.report("r2", done["r2"].id, OrderStatus.FAILED)
    await restarted.robot_reports("r1", done["r1"].id, latest=arrived)
    await restarted.robot_reports("r2", None, latest=failed)
    await restarted.robot_reports("r3", None, latest=delivered)
    status = {r: (await restarted.dispatcher.get(o.id)).status for r, o in done.items()}
    assert status == {
        "r1": OrderStatus.ARRIVED,
        "r2": OrderStatus.FAILED,
        "r3": OrderStatus.DELIVERED,
    }
    assert restarted.dispatcher.operator("pickup_confirmed", done["r1"].id), "r1's, again"
    assert restarted.dispatcher.counters.refused_reports == 0
    assert [a.kind for r in ("r1", "r2", "r3") for a in restarted.actions(r)] == [
        "pickup_confirmed"
    ]


async def test_a_restarted_robot_numbers_its_reports_afresh_and_they_apply(
    harness: Harness,
) -> None:
    await harness.robot_reports("r1")
    first = await harness.assigned_and_taken("r1")
    for status in (OrderStatus.ON_THE_WAY, OrderStatus.ARRIVED, OrderStatus.DELIVERED):
        await harness.dispatcher.on_delivery("r1", harness.report("r1", first.id, status))
    old_run = harness.report("r1", first.id, OrderStatus.DELIVERED)
    harness.boot_s["r1"], harness.made["r1"] = BOOT_S + 60.0, 0  # the software restarts
    await harness.robot_reports("r1")
    second = await harness.assigned_and_taken("r1")
    await harness.dispatcher.on_delivery(
        "r1", harness.report("r1", second.id, OrderStatus.ON_THE_WAY)
    )
    assert (await harness.dispatcher.get(second.id)).status is OrderStatus.ON_THE_WAY
    await harness.dispatcher.on_delivery("r1", old_run)  # the old run's, delivered late
    assert (await harness.dispatcher.get(second.id)).status is OrderStatus.ON_THE_WAY
    assert harness.actions("r1") == [], "nothing to drop"


async def test_a_place_freed_goes_to_the_next_robot_unasked(harness: Harness) -> None:
    harness.dispatcher.on_lease("r1", LeaseRequest(request_id="1", place="elevator"))
    harness.dispatcher.on_lease("r2", LeaseRequest(request_id="2", place="elevator"))
    grants = [m for _, m in harness.sent if isinstance(m, LeaseGrant)]
    assert [(g.granted, g.holder) for g in grants] == [(True, "r1"), (False, "r1")]
    harness.dispatcher.on_lease("r1", LeaseRequest(request_id="3", place="elevator", want=False))
    robot, handed = harness.sent[-1]
    assert robot == "r2" and isinstance(handed, LeaseGrant) and handed.granted


async def test_traffic_tells_each_online_robot_the_others_with_their_age(
    harness: Harness,
) -> None:
    await harness.robot_reports("r1")
    await harness.robot_reports("r2")
    await harness.dispatcher.on_connection(
        "r3", Connection(state=ConnectionState.ONLINE, at_s=time.time())
    )  # no pose yet: told of the others, but in nobody's traffic
    harness.clock.t += 0.4
    harness.dispatcher.traffic()
    traffic = {r: m for r, m in harness.sent if isinstance(m, Traffic)}
    assert [o.robot for o in traffic["r1"].robots] == ["r2"]
    assert [o.robot for o in traffic["r2"].robots] == ["r1"]
    assert [o.robot for o in traffic["r3"].robots] == ["r1", "r2"]
    seen = traffic["r1"].robots[0]
    assert (seen.floor, seen.x_mm, seen.y_mm) == (2, *BASE)
    assert seen.age_s == pytest.approx(0.4)
    assert not seen.moving


async def test_traffic_tells_a_robot_of_the_others_on_its_floor(harness: Harness) -> None:
    """A robot acts only on robots on its own floor: the others are not sent to it."""
    await harness.robot_reports("r1")
    await harness.robot_reports("r2", floor=3)
    await harness.robot_reports("r3", floor=3)
    harness.dispatcher.traffic()
    traffic = {r: m for r, m in harness.sent if isinstance(m, Traffic)}
    assert [o.robot for o in traffic["r1"].robots] == []
    assert [o.robot for o in traffic["r2"].robots] == ["r3"]
    assert [o.robot for o in traffic["r3"].robots] == ["r2"]
