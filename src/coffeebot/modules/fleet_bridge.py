"""The robot's side of a fleet: its board on one end, the MQTT broker on the other.

In a fleet the dispatcher keeps the orders; this module takes the orders module's place on
the robot's board. Out to the broker (``coffeebot.fleet.protocol``): the connection state
(retained, with the broker's last will saying "connection broken" if the robot vanishes), a
state report a few times a second (pose, motion, safety verdict, health, e-stop, the order it
works on), navigation's delivery reports (numbered, QoS 1), lease requests and acks. In from
the dispatcher: the next order (``orders/dispatch`` on the board; refused while it carries
another), instant actions (``operator/event``, ``operator/estop``), lease grants
(``fleet/leases``) and where the other robots are (``fleet/traffic``, for passing them).
With ``[cameras] enabled`` it also sends the robot's odometry to the fleet's camera service
and puts the service's fixes of it and the map's camera layer on the board (``cameras/fix``,
``cameras/layer``), as the cameras module does on a robot alone
(:mod:`coffeebot.fleet.camera_link`); without the broker there are no fixes and the layer
goes stale, which navigation takes for no camera information.

**Nothing here is part of the safety loop**, and a robot that loses the broker finishes the
delivery it carries: navigation's reports are kept, in order, until the broker has them, and
a shared place it needs is taken on its own sensors' word after ``[fleet] lease_wait_s``
without the broker (its collision monitor still keeps it off whoever is inside). A message
this version does not understand is refused, counted and logged; it changes nothing.
"""

from __future__ import annotations

import asyncio
import contextlib
import itertools
import os
import time
from collections import deque
from collections.abc import Awaitable, Callable
from dataclasses import dataclass
from typing import TypeVar

import aiomqtt
from pydantic import BaseModel

from coffeebot.board import Subscription
from coffeebot.cameras.own_estimate import OwnEstimate
from coffeebot.config import RobotConfig
from coffeebot.fleet.camera_link import BATCH_S, CameraLink
from coffeebot.fleet.client import fleet_session
from coffeebot.fleet.in_step import messages_in_step
from coffeebot.fleet.mosquitto import Credentials
from coffeebot.fleet.protocol import (
    CAMERA_LAYER_TOPIC,
    CAMERAS_TO_ROBOT,
    DISPATCHER_TO_ROBOT,
    QOS,
    Ack,
    ActionKind,
    Assignment,
    BadMessage,
    CameraFixReport,
    CameraLayerReport,
    DeliveryReport,
    FleetClock,
    FleetMessage,
    InstantAction,
    LeaseGrant,
    LeaseRequest,
    RobotState,
    Traffic,
    decode,
    encode,
    fleet_offset,
    parse_robot_topic,
    robot_topic,
)
from coffeebot.logs import Event, Transitions
from coffeebot.messages import (
    CAMERA_FIX,
    CAMERA_LAYER,
    COLLISION,
    CURRENT_STATE,
    DELIVERY_STATUS,
    ESTOP,
    HEALTH,
    LEASE_NEED,
    LEASE_STATE,
    MOTION_STATUS,
    ODOMETRY,
    OPERATOR_EVENT,
    ORDER_DISPATCH,
    TRAFFIC,
    DeliveryUpdate,
    EStop,
    Health,
    HealthStatus,
    LeaseNeed,
    LeaseState,
    MotionState,
    OperatorEvent,
    OperatorKind,
    OrderDispatch,
    OtherRobot,
    PoseEstimate,
    SafetyState,
    SharedPlace,
)
from coffeebot.messages import Traffic as BoardTraffic
from coffeebot.modules.backoff import Backoff
from coffeebot.modules.base import Module, ModuleContext

CONNECTED, DISCONNECTED = "connected", "disconnected"
_WORSE = [
    HealthStatus.RUNNING,
    HealthStatus.STARTING,
    HealthStatus.STOPPED,
    HealthStatus.DEGRADED,
    HealthStatus.RESTARTING,
    HealthStatus.FAILED,
]


M = TypeVar("M", bound=BaseModel)

_PERSON: dict[ActionKind, OperatorKind] = {
    "cancel": "cancel",
    "cup_loaded": "cup_loaded",
    "pickup_confirmed": "pickup_confirmed",
    "elevator_confirm": "elevator_confirm",
}
"""Instant actions that are a person's act on the robot's board (``operator/event``)."""


def credentials_from_env(robot: str) -> Credentials:
    """The robot's broker login: its id, and ``COFFEEBOT_MQTT_PASSWORD``."""
    return Credentials(
        os.environ.get("COFFEEBOT_MQTT_USERNAME", robot),
        os.environ.get("COFFEEBOT_MQTT_PASSWORD", ""),
    )


@dataclass
class BridgeCounters:
    received: int = 0
    refused: int = 0
    """Messages that were not this version's, or not for this robot."""
    reports_sent: int = 0
    connects: int = 0


class FleetBridge(Module):
    name = "fleet"
    inputs = (
        DELIVERY_STATUS,
        CURRENT_STATE,
        MOTION_STATUS,
        COLLISION,
        HEALTH,
        ESTOP,
        LEASE_NEED,
        ODOMETRY,
    )
    outputs = (
        ORDER_DISPATCH,
        OPERATOR_EVENT,
        ESTOP,
        LEASE_STATE,
        HEALTH,
        TRAFFIC,
        CAMERA_FIX,
        CAMERA_LAYER,
    )

    def __init__(
        self,
        config: RobotConfig,
        credentials: Credentials | None = None,
        fleet_clock: FleetClock = time.time,
    ) -> None:
        """``fleet_clock``: the fleet's shared time base (the simulated clock when one
        process simulates the whole fleet)."""
        self.robot = config.robot_id
        self.cfg = config.fleet
        self.credentials = credentials or credentials_from_env(self.robot)
        self.fleet_clock = fleet_clock
        self.cameras = CameraLink(config) if config.cameras.enabled else None
        self._from_broker = DISPATCHER_TO_ROBOT | (CAMERAS_TO_ROBOT if self.cameras else {})
        self.counters = BridgeCounters()
        self._outbox: deque[DeliveryReport] = deque()
        self._sent = asyncio.Event()
        self.boot_s = time.time()
        self._latest_report: DeliveryReport | None = None
        self._state_seq = itertools.count()
        self._order: str | None = None
        self._cancelled: set[str] = set()
        self._wanted: set[SharedPlace] = set()
        self._granted: dict[SharedPlace, float] = {}
        """Places held, with when the grant runs out (the board clock)."""
        self._client: aiomqtt.Client | None = None
        self._offline_since: float | None = None
        self._health: dict[tuple[str, str | None], Health] = {}
        self._link: Transitions | None = None

    def topic(self, kind: str) -> str:
        return robot_topic(self.robot, kind)

    # --- the task ---------------------------------------------------------------------------

    async def run(self, ctx: ModuleContext) -> None:
        self._link = Transitions(ctx.log, initial={"broker": CONNECTED})
        self._offline_since = ctx.clock.now()
        reports = ctx.board.subscribe(DELIVERY_STATUS)
        needs = ctx.board.subscribe(LEASE_NEED)
        health = ctx.board.subscribe(HEALTH)
        with reports, needs, health:
            async with asyncio.TaskGroup() as group:
                group.create_task(self._keep(reports, self._report))
                group.create_task(self._keep(needs, lambda need: self._need(ctx, need)))
                group.create_task(self._keep(health, self._note_health))
                group.create_task(self._lease_watch(ctx))
                if self.cameras is not None:
                    group.create_task(self._keep_path(ctx, self.cameras))
                await self._connect_forever(ctx)

    @staticmethod
    async def _keep(subscription: Subscription[M], handle: Callable[[M], object]) -> None:
        async for envelope in subscription:
            result = handle(envelope.msg)
            if isinstance(result, Awaitable):
                await result

    async def _connect_forever(self, ctx: ModuleContext) -> None:
        backoff = Backoff(0.5, self.cfg.reconnect_max_s)
        while True:
            try:
                async with fleet_session(
                    self.cfg.broker,
                    self.credentials,
                    f"coffeebot-{self.robot}",
                    self.topic("connection"),
                    messages_in_step(ctx.clock),
                ) as client:
                    await self._online(ctx, client)
                    backoff.reset()
                    async with asyncio.TaskGroup() as group:
                        group.create_task(self._receive(ctx, client))
                        group.create_task(self._report_state(ctx, client))
                        group.create_task(self._send_reports(client))
                        group.create_task(self._renew_leases(ctx, client))
                        if self.cameras is not None:
                            group.create_task(self._send_odometry(ctx, client, self.cameras))
            except* aiomqtt.MqttError as errors:
                self._offline(ctx, str(errors.exceptions[0]))
            await ctx.clock.sleep(backoff.next_delay())

    async def _online(self, ctx: ModuleContext, client: aiomqtt.Client) -> None:
        topics = [(self.topic(kind), QOS.get(kind, 1)) for kind in self._from_broker]
        if self.cameras is not None:
            topics.append((CAMERA_LAYER_TOPIC, QOS["camera_layer"]))
        await client.subscribe(topics)
        self._client = client
        self._offline_since = None
        self.counters.connects += 1
        assert self._link is not None
        self._link.update("broker", CONNECTED, Event.RECONNECT, f"connected to {self.cfg.broker}")
        self._health_report(ctx, HealthStatus.RUNNING, f"connected to {self.cfg.broker}")
        self._sent.set()  # what waited for the broker goes now

    def _offline(self, ctx: ModuleContext, why: str) -> None:
        self._client = None
        if self._offline_since is None:
            self._offline_since = ctx.clock.now()
        assert self._link is not None
        cause = f"{self.cfg.broker}: {why}; the robot finishes what it carries"
        self._link.update("broker", DISCONNECTED, Event.DISCONNECT, cause)
        self._health_report(ctx, HealthStatus.DEGRADED, f"no broker: {why}")

    def _health_report(self, ctx: ModuleContext, status: HealthStatus, detail: str) -> None:
        ctx.board.publish(
            HEALTH, Health(module=self.name, component="broker", status=status, detail=detail)
        )

    # --- out ----------------------------------------------------------------------------------

    @property
    def _reports(self) -> int:
        """Delivery reports made in this run (the next one's number)."""
        return 0 if self._latest_report is None else self._latest_report.seq + 1

    def _report(self, update: DeliveryUpdate) -> None:
        if update.status.final and update.order_id == self._order:
            self._order = None
        self._latest_report = DeliveryReport(
            seq=self._reports,
            boot_s=self.boot_s,
            order_id=update.order_id,
            status=update.status,
            detail=update.detail[:500],
            ready_for_cup=update.ready_for_cup,
            problem=update.problem,
        )
        self._outbox.append(self._latest_report)
        self._sent.set()

    async def _send_reports(self, client: aiomqtt.Client) -> None:
        """Navigation's reports in order, each removed only once the broker has it."""
        while True:
            await self._sent.wait()
            self._sent.clear()
            while self._outbox:
                await client.publish(self.topic("delivery"), encode(self._outbox[0]), qos=1)
                self._outbox.popleft()
                self.counters.reports_sent += 1

    def _note_health(self, health: Health) -> None:
        self._health[(health.module, health.component)] = health

    def state(self, ctx: ModuleContext) -> RobotState:
        """What the dispatcher and the fleet's map need to know of this robot now."""
        board = ctx.board
        motion = board.latest(MOTION_STATUS)
        verdict = board.latest(COLLISION)
        estop = board.latest(ESTOP)
        pose = self._pose(ctx)
        unwell = sorted(
            f"{h.module}{'/' + h.component if h.component else ''}: {h.status.value}"
            for h in self._health.values()
            if h.status not in (HealthStatus.RUNNING, HealthStatus.STARTING)
            and h.module != self.name
        )
        worst = max((h.status for h in self._health.values()), key=_WORSE.index, default=None)
        return RobotState(
            seq=next(self._state_seq),
            at_s=time.time(),
            boot_s=self.boot_s,
            reports=self._reports,
            floor=None if pose is None else pose.floor,
            x_mm=None if pose is None else pose.x_mm,
            y_mm=None if pose is None else pose.y_mm,
            heading_deg=None if pose is None else pose.heading_deg,
            sigma_mm=None if pose is None else max(pose.sigma_x_mm, pose.sigma_y_mm),
            motion=MotionState.IDLE if motion is None else motion.msg.state,
            safety=SafetyState.STOP if verdict is None else verdict.msg.state,
            health=HealthStatus.STARTING if worst is None else worst,
            unwell=unwell[:32],
            order_id=self._order,
            estop=estop is not None and estop.msg.engaged,
            latest_report=self._latest_report,
        )

    @staticmethod
    def _pose(ctx: ModuleContext) -> PoseEstimate | None:
        """The state module's estimate, once it has one."""
        current = ctx.board.latest(CURRENT_STATE)
        return None if current is None or not current.msg.pose.initialised else current.msg.pose

    async def _report_state(self, ctx: ModuleContext, client: aiomqtt.Client) -> None:
        period = 1.0 / self.cfg.state_hz
        while True:
            report = self.state(ctx)
            await client.publish(self.topic("state"), encode(report), qos=QOS.get("state", 1))
            await ctx.clock.sleep(period)

    async def _keep_path(self, ctx: ModuleContext, cameras: CameraLink) -> None:
        with ctx.board.subscribe(ODOMETRY) as odometry:
            async for envelope in odometry:
                cameras.take(envelope.msg, envelope.stamp)

    async def _send_odometry(
        self, ctx: ModuleContext, client: aiomqtt.Client, cameras: CameraLink
    ) -> None:
        """The path to the camera service every ``BATCH_S``, with the robot's estimate."""
        while True:
            estimate = OwnEstimate.published(ctx.board.latest(CURRENT_STATE))
            batch = cameras.batch(fleet_offset(ctx.clock, self.fleet_clock), estimate)
            if batch is not None:
                await client.publish(self.topic("odometry"), encode(batch), qos=QOS["odometry"])
            await ctx.clock.sleep(BATCH_S)

    # --- in -----------------------------------------------------------------------------------

    async def _receive(self, ctx: ModuleContext, client: aiomqtt.Client) -> None:
        async for message in client.messages:
            self.counters.received += 1
            topic = str(message.topic)
            try:
                decoded = decode(self._model(topic), topic, message.payload)
            except BadMessage as exc:
                self.counters.refused += 1
                ctx.log.warning(
                    "refused a message from the broker (%d so far): %s", self.counters.refused, exc
                )
                continue
            ack = self._take(ctx, decoded)
            if ack is not None:
                await client.publish(self.topic("ack"), encode(ack), qos=1)

    def _model(self, topic: str) -> type[FleetMessage]:
        """What a message on ``topic`` must be, or :class:`BadMessage` if it is not this
        robot's to take."""
        if topic == CAMERA_LAYER_TOPIC and self.cameras is not None:
            return CameraLayerReport
        robot, kind = parse_robot_topic(topic)
        model = self._from_broker.get(kind)
        if robot != self.robot or model is None:
            raise BadMessage(f"{topic}: not a message for {self.robot}")
        return model

    def _take(self, ctx: ModuleContext, message: FleetMessage) -> Ack | None:
        if isinstance(message, Assignment):
            return self._assigned(ctx, message)
        if isinstance(message, InstantAction):
            return self._act(ctx, message)
        if isinstance(message, LeaseGrant):
            self._grant(ctx, message)
        if isinstance(message, Traffic):
            others = [OtherRobot(**robot.model_dump()) for robot in message.robots]
            ctx.board.publish(TRAFFIC, BoardTraffic(robots=others))
        if isinstance(message, CameraFixReport | CameraLayerReport):
            self._camera_message(ctx, message)
        return None

    def _camera_message(
        self, ctx: ModuleContext, message: CameraFixReport | CameraLayerReport
    ) -> None:
        """A fix carried on to now, the layer onto the board's clock: onto the board, as the
        cameras module would publish them (what is too old to use is dropped)."""
        assert self.cameras is not None  # subscribed to only with the cameras on
        offset = fleet_offset(ctx.clock, self.fleet_clock)
        if isinstance(message, CameraFixReport):
            fix = self.cameras.fix(message, offset)
            if fix is not None:
                ctx.board.publish(CAMERA_FIX, fix)
        else:
            layer = self.cameras.layer(message, offset, ctx.clock.now())
            if layer is not None:
                ctx.board.publish(CAMERA_LAYER, layer)

    def _assigned(self, ctx: ModuleContext, assignment: Assignment) -> Ack:
        ref, order = assignment.assignment_id, assignment.order_id
        if order in self._cancelled:
            return Ack(ref=ref, accepted=False, reason=f"order {order} was cancelled")
        if self._order == order:
            return Ack(ref=ref, accepted=True, reason="already delivering it")
        if self._order is not None:
            return Ack(ref=ref, accepted=False, reason=f"busy with order {self._order}")
        self._order = order
        ctx.board.publish(
            ORDER_DISPATCH,
            OrderDispatch(order_id=order, room=assignment.room, drink=assignment.drink),
        )
        ctx.log.info("took order %s for %s from the dispatcher", order, assignment.room)
        return Ack(ref=ref, accepted=True)

    def _act(self, ctx: ModuleContext, action: InstantAction) -> Ack:
        ref = action.action_id
        if action.kind in ("estop", "release_estop"):
            engaged = action.kind == "estop"
            ctx.board.publish(
                ESTOP, EStop(engaged=engaged, source="fleet", reason="the fleet's operator")
            )
            return Ack(ref=ref, accepted=True)
        if action.kind == "cancel":
            self._cancelled.add(action.order_id)
        if action.order_id != self._order:
            # Nothing to do here: a cancel of an order this robot never started, or an
            # event for an order it no longer carries. A cancel is never refused.
            return Ack(ref=ref, accepted=action.kind == "cancel", reason="not carrying it")
        event = OperatorEvent(kind=_PERSON[action.kind], order_id=action.order_id, source="fleet")
        ctx.board.publish(OPERATOR_EVENT, event)
        return Ack(ref=ref, accepted=True)

    # --- leases -------------------------------------------------------------------------------

    async def _need(self, ctx: ModuleContext, need: LeaseNeed) -> None:
        if need.want:
            self._wanted.add(need.place)
        else:
            self._wanted.discard(need.place)
            self._granted.pop(need.place, None)
            self._publish_leases(ctx, f"out of the {need.place}")
        client = self._client
        if client is not None:
            with contextlib.suppress(aiomqtt.MqttError):
                await self._ask(client, need.place, need.want)

    async def _ask(self, client: aiomqtt.Client, place: SharedPlace, want: bool) -> None:
        request = LeaseRequest(request_id=f"{place}-{time.time_ns()}", place=place, want=want)
        await client.publish(self.topic("lease"), encode(request), qos=1)

    async def _renew_leases(self, ctx: ModuleContext, client: aiomqtt.Client) -> None:
        """Ask again for every place wanted: a renewal for a place held, a reminder of the
        queue for one waited for (and what a dispatcher that restarted needs to know)."""
        while True:
            for place in sorted(self._wanted):
                await self._ask(client, place, True)
            await ctx.clock.sleep(self.cfg.lease_renew_s)

    def _grant(self, ctx: ModuleContext, grant: LeaseGrant) -> None:
        if grant.place not in self._wanted:
            return
        if grant.granted:
            self._granted[grant.place] = ctx.clock.now() + grant.expires_in_s
            self._publish_leases(ctx, f"the {grant.place} is the robot's")
        else:
            self._granted.pop(grant.place, None)
            holder = grant.holder or "another robot"
            self._publish_leases(ctx, f"waiting: {holder} has the {grant.place}")

    async def _lease_watch(self, ctx: ModuleContext) -> None:
        """Grants run out unless renewed; without the broker for ``lease_wait_s``, a wanted
        place is taken on the robot's own sensors' word."""
        while True:
            now = ctx.clock.now()
            expired = [p for p, until in self._granted.items() if now >= until]
            for place in expired:
                del self._granted[place]
            if expired:
                self._publish_leases(ctx, "a grant ran out")
            offline = self._offline_since
            if offline is not None and now - offline >= self.cfg.lease_wait_s:
                for place in self._wanted - self._granted.keys():
                    self._granted[place] = float("inf")
                    self._publish_leases(
                        ctx,
                        f"no broker for {now - offline:.0f} s: going into the {place} on the "
                        "robot's own sensors",
                    )
            await ctx.clock.sleep(1.0)

    def _publish_leases(self, ctx: ModuleContext, detail: str) -> None:
        state = LeaseState(
            elevator="elevator" in self._granted,
            loading_spot="loading_spot" in self._granted,
            holding_point="holding_point" in self._granted,
            crossing="crossing" in self._granted,
            landing="landing" in self._granted,
            detail=detail,
        )
        previous = ctx.board.latest(LEASE_STATE)
        if previous is None or previous.msg.model_copy(update={"detail": detail}) != state:
            ctx.log.info("%s leases: %s", self.robot, detail)  # a change, not a renewal
        ctx.board.publish(LEASE_STATE, state)
