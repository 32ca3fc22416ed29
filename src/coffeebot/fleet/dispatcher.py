"""The fleet's dispatcher: one order queue, many robots, shared places, told over MQTT.

:class:`Dispatcher` is the logic, fed with what the robots say (``on_*``) and ticked by its
module (:mod:`coffeebot.fleet.module`), which owns the broker connection; what it has to say
to a robot it hands to ``send``. It implements :class:`~coffeebot.orders.Orders` for the web
app, exactly as the single robot's orders module does, over the same SQLite store (each
order also records the robot it went to).

The rules, and why:

- **One order per robot.** A robot carries one cup. Waiting orders stay in the store's queue
  and go to free robots (online, heard of lately, healthy, not e-stopped, localized, without
  an order) by estimated completion time (:mod:`coffeebot.fleet.assignment`).
- **An assignment counts once acknowledged.** Until then it is sent again every
  ``ack_timeout_s``; a robot that refuses it (busy, or told to cancel it) gives it back to
  the queue. A customer's cancel works whatever the robot has said (Open-RMF's users report
  a task never acknowledged that cannot be cancelled and blocks dispatch).
- **A robot that stops reporting** (no message for ``stale_after_s``, or its last will says
  its connection broke) is stale: grey on the map with the time it was last heard of, never
  removed. Its order goes back to the queue if it had not left the tea room; one it was
  carrying out fails after ``lost_after_s`` more with the reason, so it does not stay "on
  the way" forever. Its shared places are freed. While the dispatcher itself has no broker,
  nobody is declared stale: it cannot hear anyone.
- **Reports are applied in order, once.** Each robot numbers its delivery reports afresh in
  each run of its software; a repeat after a reconnect is ignored, and a report for an order
  the robot does not have (any more) is refused and the robot is told to drop it. The
  latest report also comes with every state report: one sent while the dispatcher was not
  subscribed (both reconnecting to a restarted broker) reached nobody, and the latest
  overtakes the earlier ones it skips. A restarted dispatcher applies each robot's latest
  report too, its store perhaps behind what the robot did meanwhile, and takes the robot's
  order from the store (whose it is) into its empty book. A state report's word on the
  robot's order is taken only once every delivery report made before it has been applied:
  the two travel apart, and a robot that has just reported its cup delivered says it
  carries nothing, perhaps before the report arrives. Nothing is served twice: an order
  that left the tea room is never given to another robot.
- **Shared places** (the elevator, the loading spot) are lent by a :class:`LeaseBook`: one
  robot at a time, in the order they asked, expiring unless renewed.
- **Traffic.** Each online robot is told where the others are (:meth:`Dispatcher.traffic`,
  about twice a second), so two meeting head-on in the hallway both keep to their passing
  lanes: their sensors alone see only an obstacle that will not let them by.
"""

from __future__ import annotations

import itertools
import logging
from collections.abc import Callable
from dataclasses import dataclass
from typing import Protocol

from coffeebot.config import DispatchConfig
from coffeebot.errors import OrderError, StoreError
from coffeebot.fleet.assignment import (
    STRATEGIES,
    FreeRobot,
    WaitingOrder,
    completion_s,
    greedy,
    joint,
)
from coffeebot.fleet.estimates import TravelTimes
from coffeebot.fleet.leases import PLACES, LeaseBook
from coffeebot.fleet.protocol import (
    Ack,
    ActionKind,
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
    TrafficRobot,
)
from coffeebot.logs import Event, log_event
from coffeebot.messages import (
    FleetRobot,
    HealthStatus,
    MotionState,
    OperatorKind,
    OrderStatus,
)
from coffeebot.orders import OrderNotFound, OrdersUnavailable, WrongOrderKey
from coffeebot.store import IN_FLIGHT, NewOrder, Order, OrderStore, PlacedOrder

log = logging.getLogger(__name__)

# Where each status may come from when a robot reports it (as on one robot: forward only).
_REPORTABLE_FROM: dict[OrderStatus, tuple[OrderStatus, ...]] = {
    OrderStatus.PREPARING: (OrderStatus.PREPARING,),
    OrderStatus.ON_THE_WAY: IN_FLIGHT,
    OrderStatus.WAITING_FOR_ELEVATOR: IN_FLIGHT,
    OrderStatus.ARRIVED: IN_FLIGHT,
    OrderStatus.DELIVERED: (OrderStatus.ARRIVED,),
    OrderStatus.FAILED: IN_FLIGHT,
    OrderStatus.CANCELLED: IN_FLIGHT,
}
LEFT_BASE = tuple(s for s in IN_FLIGHT if s is not OrderStatus.PREPARING)
DRIVING = (MotionState.MOVING, MotionState.AVOIDING)


@dataclass
class RobotRecord:
    """What the dispatcher knows of one robot."""

    robot: str
    connection: ConnectionState = ConnectionState.OFFLINE
    state: RobotState | None = None
    heard_at_s: float | None = None
    state_at_s: float | None = None
    """When its last state report came (the dispatcher's clock)."""
    stale_since_s: float | None = None
    order_id: str | None = None
    """The order the dispatcher gave it and that has not ended."""
    assignment: Assignment | None = None
    """Sent and not acknowledged yet."""
    sent_at_s: float = 0.0
    boot_s: float | None = None
    """The run of the robot's software last heard from (``RobotState.boot_s``)."""
    last_report: int = -1
    """The sequence number of the last delivery report applied (in that run)."""

    @property
    def stale(self) -> bool:
        return self.stale_since_s is not None


class Announce(Protocol):
    def __call__(self, order: Order, cause: str, report: DeliveryReport | None = None) -> None:
        """Tell the web a stored change; ``report``: the robot's, when it came from one."""


def _pairing(pairs: list[tuple[WaitingOrder, FreeRobot]]) -> set[tuple[str, str]]:
    return {(order.order_id, robot.robot) for order, robot in pairs}


@dataclass
class DispatchCounters:
    assignments: int = 0
    resent: int = 0
    refused_reports: int = 0
    requeued: int = 0
    lost: int = 0
    choices: int = 0
    """Assignments made with several robots free and several orders waiting: where the
    strategy can matter (for the benchmark)."""
    choices_differing: int = 0
    """Of those, how many the other strategy would have paired differently."""


class Dispatcher:
    def __init__(
        self,
        store: OrderStore,
        travel: TravelTimes,
        config: DispatchConfig,
        send: Callable[[str, FleetMessage], None],
        announce: Announce,
        now: Callable[[], float],
    ) -> None:
        """``send(robot, message)`` goes out to the robot; ``announce(order, cause)`` tells
        the web a stored change; ``now`` is the dispatcher's clock."""
        self.store = store
        self.travel = travel
        self.cfg = config
        self.send = send
        self.announce = announce
        self.now = now
        self.robots: dict[str, RobotRecord] = {}
        self.leases = LeaseBook(config.lease_s)
        self.counters = DispatchCounters()
        self.link_up_since_s: float | None = None
        """When the dispatcher's own broker connection came up (None: it has none)."""
        self._ids = itertools.count(1)

    # --- robots ---------------------------------------------------------------------------

    def robot(self, robot: str) -> RobotRecord:
        if robot not in self.robots:
            self.robots[robot] = RobotRecord(robot)
        return self.robots[robot]

    def _heard(self, record: RobotRecord) -> None:
        record.heard_at_s = self.now()
        if record.stale_since_s is not None:
            log_event(
                log, Event.RECONNECT, f"robot {record.robot} reports again", robot=record.robot
            )
        record.stale_since_s = None

    async def on_connection(self, robot: str, connection: Connection) -> None:
        record = self.robot(robot)
        record.connection = connection.state
        if connection.state is ConnectionState.ONLINE:
            self._heard(record)
            if record.assignment is not None:
                self._send_assignment(record)  # it may have restarted and lost it
        else:
            self._went_stale(record, f"its connection is {connection.state.value}")

    @staticmethod
    def _current_run(record: RobotRecord, boot_s: float, reports_before: int) -> bool:
        """False for a message from an earlier run of the robot's software, delivered late.
        A later run numbers its reports afresh; ``reports_before``: how many it says it made
        before this message (everything the dispatcher missed is taken as known)."""
        if record.boot_s is not None and boot_s < record.boot_s:
            return False
        if boot_s != record.boot_s:
            record.boot_s = boot_s
            record.last_report = reports_before - 1
            record.state = None
        return True

    async def on_state(self, robot: str, state: RobotState) -> None:
        record = self.robot(robot)
        latest = state.latest_report
        # Heard first (the dispatcher restarted): every report before the latest is taken
        # as known, the latest is applied, since the store may not have it.
        if not self._current_run(
            record, state.boot_s, state.reports if latest is None else latest.seq
        ):
            return
        if (
            record.state is not None
            and state.seq <= record.state.seq
            and state.at_s <= record.state.at_s
        ):
            return  # an old report delivered late
        record.state = state
        record.state_at_s = self.now()
        record.connection = ConnectionState.ONLINE
        self._heard(record)
        if latest is not None and latest.seq > record.last_report:
            await self.on_delivery(robot, latest)  # its own copy reached nobody
        await self._reconcile(record)

    async def _reconcile(self, record: RobotRecord) -> None:
        """The robot's word on its order against the dispatcher's book."""
        state = record.state
        assert state is not None
        if state.reports - 1 != record.last_report:
            return  # reports it had made are still on their way, or came after it
        theirs, ours = state.order_id, record.order_id
        if theirs == ours or (theirs is None and record.assignment is not None):
            return
        if theirs is not None and theirs != ours:
            if self._store_gives(record, await self._get(theirs)):
                record.order_id = theirs  # the dispatcher restarted: its book catches up
                return
            self._action(record.robot, "cancel", theirs)  # not its order (any more)
            return
        # It carries nothing, the book says it does: the robot restarted and lost it.
        assert ours is not None
        await self._lost_order(record, ours, f"robot {record.robot} restarted without it")

    @staticmethod
    def _store_gives(record: RobotRecord, order: Order | None) -> bool:
        """Whether the store gives the robot ``order``, not yet ended: what a restarted
        dispatcher's empty book takes back from it."""
        return order is not None and order.robot == record.robot and not order.status.final

    async def on_delivery(self, robot: str, report: DeliveryReport) -> None:
        record = self.robot(robot)
        self._heard(record)
        if not self._current_run(record, report.boot_s, report.seq):
            return
        if report.seq <= record.last_report:
            return  # a repeat after a reconnect
        record.last_report = report.seq
        if report.order_id != record.order_id:
            order = await self._get(report.order_id)
            if record.order_id is None and order is not None and order.robot == robot:
                # The dispatcher restarted: its store says whose the order is.
                if self._store_gives(record, order):
                    record.order_id = order.id  # the book catches up
                if order.status is report.status:
                    return  # the store has it already
            if report.order_id != record.order_id:
                self.counters.refused_reports += 1
                log.warning(
                    "robot %s reports on order %s, which is not its: told to drop it",
                    robot,
                    report.order_id,
                )
                if order is not None and not order.status.final:
                    self._action(robot, "cancel", report.order_id)
                return
        allowed = _REPORTABLE_FROM.get(report.status, ())
        order = await self.store.transition(report.order_id, report.status, report.detail, allowed)
        if order is None:
            log.warning("report from %s out of sequence: ignored", robot)
            return
        self.announce(order, report.detail or f"reported by {robot}", report)
        if order.status.final:
            record.order_id = None
            record.assignment = None

    async def on_ack(self, robot: str, ack: Ack) -> None:
        record = self.robot(robot)
        self._heard(record)
        sent = record.assignment
        if sent is None or ack.ref != sent.assignment_id:
            return  # an action's ack, or a repeat
        record.assignment = None
        if not ack.accepted:
            log.info("robot %s refused order %s: %s", robot, sent.order_id, ack.reason)
            record.order_id = None
            await self._requeue(sent.order_id, f"robot {robot} could not take it ({ack.reason})")

    def on_lease(self, robot: str, request: LeaseRequest) -> None:
        record = self.robot(robot)
        self._heard(record)
        if not request.want:
            self.leases.release(robot, request.place)
            log.info("robot %s gave back the %s", robot, request.place)
            self._hand_on_places()
            return
        before = self.leases.holder(request.place, self.now())
        answer = self.leases.request(robot, request.place, self.now())
        if not answer.granted:
            log.info("robot %s waits for the %s: %s has it", robot, request.place, answer.holder)
        elif before != robot:
            log.info("robot %s has the %s", robot, request.place)
        self.send(
            robot,
            LeaseGrant(
                request_id=request.request_id,
                place=request.place,
                granted=answer.granted,
                expires_in_s=self.cfg.lease_s if answer.granted else 0.0,
                holder=answer.holder,
            ),
        )

    def _hand_on_places(self) -> None:
        """A place came free: the first robot waiting for it gets it now, unasked."""
        for place in PLACES:
            state = self.leases.places[place]
            if state.lease is not None or not state.waiting:
                continue
            robot = state.waiting[0]
            if self.leases.request(robot, place, self.now()).granted:
                log.info("robot %s has the %s, handed on", robot, place)
                self.send(
                    robot,
                    LeaseGrant(
                        request_id=f"handed-{next(self._ids)}",
                        place=place,
                        granted=True,
                        expires_in_s=self.cfg.lease_s,
                        holder=robot,
                    ),
                )

    # --- time -----------------------------------------------------------------------------

    async def tick(self) -> None:
        """Everything time decides: stale robots, lost orders, unanswered assignments, expired
        leases, and the assignment of waiting orders to free robots."""
        now = self.now()
        listening = (
            self.link_up_since_s is not None
            and now - self.link_up_since_s >= self.cfg.stale_after_s
        )
        for record in list(self.robots.values()):
            heard = record.heard_at_s
            if listening and heard is not None and not record.stale:
                silent = now - heard
                if silent > self.cfg.stale_after_s:
                    self._went_stale(record, f"not heard of for {silent:.0f} s")
            if record.stale and record.order_id is not None:
                await self._stale_order(record)
            if record.assignment is not None and now - record.sent_at_s > self.cfg.ack_timeout_s:
                self.counters.resent += 1
                self._send_assignment(record)
        for place in PLACES:
            self.leases.holder(place, now)  # lets expired leases go
        self._hand_on_places()
        if self.link_up_since_s is not None:
            await self._assign()

    def _went_stale(self, record: RobotRecord, why: str) -> None:
        if record.stale:
            return
        record.stale_since_s = self.now()
        log_event(
            log, Event.DISCONNECT, f"robot {record.robot} is stale: {why}", robot=record.robot
        )
        self.leases.forget(record.robot)

    async def _stale_order(self, record: RobotRecord) -> None:
        assert record.order_id is not None and record.stale_since_s is not None
        order = await self._get(record.order_id)
        if order is None or order.status.final:
            record.order_id = None
            return
        if order.status in (OrderStatus.QUEUED, OrderStatus.PREPARING):
            record.order_id = record.assignment = None
            await self._requeue(order.id, f"robot {record.robot} stopped reporting before it left")
        elif self.now() - record.stale_since_s >= self.cfg.lost_after_s:
            await self._lost_order(
                record, order.id, f"robot {record.robot} stopped reporting while it was out"
            )

    async def _lost_order(self, record: RobotRecord, order_id: str, why: str) -> None:
        record.order_id = record.assignment = None
        order = await self._get(order_id)
        if order is None or order.status.final:
            return
        if order.status is OrderStatus.PREPARING:
            await self._requeue(order_id, why)
            return
        self.counters.lost += 1
        failed = await self.store.transition(
            order_id, OrderStatus.FAILED, f"{why}; staff will check on the cup", (order.status,)
        )
        if failed is not None:
            self.announce(failed, why)

    async def _requeue(self, order_id: str, why: str) -> None:
        order = await self.store.transition(
            order_id,
            OrderStatus.QUEUED,
            f"waiting for a robot ({why})",
            (OrderStatus.PREPARING,),
            robot=None,
        )
        if order is not None:
            self.counters.requeued += 1
            self.announce(order, why)

    # --- assignment -----------------------------------------------------------------------

    def free_robots(self) -> list[FreeRobot]:
        free = []
        for record in self.robots.values():
            state = record.state
            if (
                record.stale
                or record.connection is not ConnectionState.ONLINE
                or state is None
                or state.order_id is not None
                or record.order_id is not None
                or record.assignment is not None
                or state.estop
                or state.health is HealthStatus.FAILED
                or state.floor is None
                or state.x_mm is None
                or state.y_mm is None
            ):
                continue
            ready_in = self.travel.between(state.floor, state.x_mm, state.y_mm, None)
            free.append(FreeRobot(record.robot, ready_in))
        return sorted(free, key=lambda r: r.robot)

    async def _assign(self) -> None:
        free = self.free_robots()
        if not free:
            return
        queued = await self.store.with_status((OrderStatus.QUEUED,), limit=len(free) * 4)
        if not queued:
            return
        now_wall = self.store.now()
        waiting = [WaitingOrder(o.id, o.room, max(0.0, now_wall - o.created_at)) for o in queued]
        cost = completion_s(self.cfg.loading_s, self.travel.base_to)
        pairs = STRATEGIES[self.cfg.strategy](waiting, free, cost)
        if len(free) > 1 and len(waiting) > 1:
            other = greedy if self.cfg.strategy == "joint" else joint
            self.counters.choices += 1
            self.counters.choices_differing += _pairing(pairs) != _pairing(
                other(waiting, free, cost)
            )
        for order, robot in pairs:
            stored = await self.store.transition(
                order.order_id,
                OrderStatus.PREPARING,
                f"assigned to robot {robot.robot}",
                (OrderStatus.QUEUED,),
                robot=robot.robot,
            )
            if stored is None:
                continue  # cancelled meanwhile
            record = self.robot(robot.robot)
            record.order_id = stored.id
            record.assignment = Assignment(
                assignment_id=f"a{next(self._ids)}-{stored.id}",
                order_id=stored.id,
                room=stored.room,
                drink=stored.drink,
            )
            self.counters.assignments += 1
            self.announce(stored, f"assigned to robot {robot.robot}")
            self._send_assignment(record)

    def _send_assignment(self, record: RobotRecord) -> None:
        assert record.assignment is not None
        record.sent_at_s = self.now()
        self.send(record.robot, record.assignment)

    def _action(self, robot: str, kind: ActionKind, order_id: str = "") -> None:
        self.send(
            robot, InstantAction(action_id=f"x{next(self._ids)}", kind=kind, order_id=order_id)
        )

    # --- traffic ----------------------------------------------------------------------------

    def traffic(self) -> None:
        """Tell every online robot where the others with a known pose are: those on its
        floor (a robot acts only on those, and a fleet's traffic grew with the square of its
        size), every one while its own floor is unknown."""
        now = self.now()
        placed: dict[str, TrafficRobot] = {}
        for record in self.robots.values():
            s = record.state
            if (
                record.stale
                or s is None
                or record.state_at_s is None
                or s.floor is None
                or s.x_mm is None
                or s.y_mm is None
                or s.heading_deg is None
            ):
                continue
            placed[record.robot] = TrafficRobot(
                robot=record.robot,
                floor=s.floor,
                x_mm=s.x_mm,
                y_mm=s.y_mm,
                heading_deg=s.heading_deg,
                moving=s.motion in DRIVING,
                reported_at_s=s.at_s,
                age_s=max(0.0, now - record.state_at_s),
            )
        for record in self.robots.values():
            if record.stale or record.connection is not ConnectionState.ONLINE:
                continue
            own = placed.get(record.robot)
            others = [
                p
                for robot, p in sorted(placed.items())
                if robot != record.robot and (own is None or p.floor == own.floor)
            ]
            self.send(record.robot, Traffic(robots=others))

    # --- people -----------------------------------------------------------------------------

    def operator(self, kind: OperatorKind, order_id: str) -> bool:
        """A person acted on an order (cup loaded, picked up, cancel, elevator): to the robot
        that has it; False if none has."""
        for record in self.robots.values():
            if record.order_id == order_id:
                self._action(record.robot, kind, order_id)
                return True
        return False

    def estop(self, engaged: bool) -> None:
        """The operator's e-stop reaches every robot."""
        for robot in self.robots:
            self._action(robot, "estop" if engaged else "release_estop")

    def view(self) -> list[FleetRobot]:
        """Every robot ever heard of, for the map: stale ones stay, greyed, with their age."""
        now = self.now()
        robots = []
        for r in sorted(self.robots.values(), key=lambda r: r.robot):
            s = r.state
            robots.append(
                FleetRobot(
                    robot=r.robot,
                    online=r.connection is ConnectionState.ONLINE,
                    stale=r.stale,
                    heard_ago_s=None if r.heard_at_s is None else now - r.heard_at_s,
                    order_id=r.order_id,
                    floor=None if s is None else s.floor,
                    x_mm=None if s is None else s.x_mm,
                    y_mm=None if s is None else s.y_mm,
                    heading_deg=None if s is None else s.heading_deg,
                    motion=None if s is None else s.motion,
                    safety=None if s is None else s.safety,
                    health=None if s is None else s.health,
                    unwell=[] if s is None else s.unwell,
                    estop=s is not None and s.estop,
                )
            )
        return robots

    # --- the orders protocol ----------------------------------------------------------------

    async def _get(self, order_id: str) -> Order | None:
        return await self.store.get(order_id)

    async def place(self, new: NewOrder, client: str) -> PlacedOrder:
        try:
            placed = await self.store.add(new, client)
        except StoreError as exc:
            raise OrdersUnavailable("the order database cannot be used right now") from exc
        self.announce(placed, f"placed by {client}")
        return placed

    async def get(self, order_id: str) -> Order:
        try:
            order = await self.store.get(order_id)
        except StoreError as exc:
            raise OrdersUnavailable("the order database cannot be used right now") from exc
        if order is None:
            raise OrderNotFound(f"no order {order_id!r}")
        return order

    async def authorize(self, order_id: str, key: str) -> Order:
        order = await self.get(order_id)
        if not await self.store.key_matches(order_id, key):
            raise WrongOrderKey(
                f"order {order_id!r} needs its key: use the link you were given when you ordered"
            )
        return order

    async def active(self) -> list[Order]:
        return await self.store.active()

    async def cancel(self, order_id: str, detail: str = "cancelled by the customer") -> Order:
        """Cancel an order that has not left the tea room, whether or not a robot has
        acknowledged it: the robot is told to drop it."""
        cancelled = await self.store.transition(
            order_id, OrderStatus.CANCELLED, detail, (OrderStatus.QUEUED, OrderStatus.PREPARING)
        )
        if cancelled is None:
            order = await self.get(order_id)
            raise OrderError(
                f"order {order_id!r} is {order.status.value}: it has left the tea room"
            )
        for record in self.robots.values():
            if record.order_id == order_id:
                record.order_id = record.assignment = None
                self._action(record.robot, "cancel", order_id)
        self.announce(cancelled, detail)
        return cancelled
