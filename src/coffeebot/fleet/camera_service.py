"""The fleet's camera service: one :class:`~coffeebot.cameras.service.CameraService` for every
robot, fed over the broker, a module of the dispatcher's daemon (``coffeebot fleet`` with
``[cameras] enabled``).

Each robot sends its dead-reckoned path twice a second (``robots/{robot}/odometry``); the
service keeps the last seconds of every robot's, names the robots on the tracks of the
cameras of their floors, sends each its fixes (``robots/{robot}/camera_fix``) and everyone
the map's camera layer (``cameras/layer``, retained), which also goes on the dispatcher's
own board for its map. It is a module of its own, beside the dispatcher module and with a
broker connection of its own (the dispatcher's login): the image work is the heaviest and
most fault-prone work of the daemon, and the daemon's supervision restarts it alone, never
the orders.

A robot's odometry comes a batch and the broker's latency late, so the service names the
robots over windows that end where every robot's odometry reaches (the locator's rule), and
each fix is for the moment of the robot's newest sample: the robot carries it on to now
(:mod:`coffeebot.fleet.camera_link`).
"""

from __future__ import annotations

import asyncio
import contextlib
import math
import time
from collections.abc import Mapping
from dataclasses import dataclass

import aiomqtt

from coffeebot.cameras.odometry_path import PosePath
from coffeebot.cameras.own_estimate import OwnEstimate
from coffeebot.cameras.service import CameraService, Robot
from coffeebot.cameras.sources import FrameSource
from coffeebot.config import RobotConfig
from coffeebot.fleet.client import mqtt_client
from coffeebot.fleet.in_step import messages_in_step
from coffeebot.fleet.mosquitto import Credentials
from coffeebot.fleet.protocol import (
    CAMERA_LAYER_TOPIC,
    QOS,
    ROBOT_TO_CAMERAS,
    ROOT,
    BadMessage,
    CameraFixReport,
    CameraLayerReport,
    FleetClock,
    FleetMessage,
    OdometryBatch,
    PositionSample,
    encode,
    fleet_offset,
    layer_shifted,
    robot_report,
    robot_topic,
)
from coffeebot.floorplan import FloorPlan
from coffeebot.logs import Event, Transitions
from coffeebot.messages import CAMERA_LAYER, HEALTH, Health, HealthStatus
from coffeebot.modules.backoff import Backoff
from coffeebot.modules.base import Module, ModuleContext

FORGET_S = 5.0
"""A robot whose odometry has not come for this long (gone, or cut off from the broker) is
left out. Until then the windows of the cameras of its floor end where its odometry does, so
that no other robot is named on its track while it cannot be there to rival it."""
GAP_S = 1.0
"""A robot's path that resumes after a longer gap (two batches lost, a reconnect) starts
afresh: interpolated across the gap it would be a straight line the robot may not have
driven."""
CONNECTED, DISCONNECTED = "connected", "disconnected"


@dataclass
class RobotPath:
    """What the service knows of one robot: its odometry and its own estimate (on the
    service's clock), as of ``heard_s``."""

    path: PosePath
    estimate: OwnEstimate | None
    heard_s: float


class CameraServiceModule(Module):
    """Every camera of the plan that has a frame source, for every robot that sends its
    odometry; see the module docstring."""

    name = "cameras"
    outputs = (CAMERA_LAYER, HEALTH)

    def __init__(
        self,
        config: RobotConfig,
        plan: FloorPlan,
        sources: Mapping[str, FrameSource],
        broker: str,
        credentials: Credentials,
        fleet_clock: FleetClock = time.time,
    ) -> None:
        """``config``: the fleet's robots' description (their height, the cameras'
        settings); ``fleet_clock``: the fleet's shared time base."""
        self.service = CameraService(
            plan, sources, config.cameras, config.geometry.height_mm, lag_s=FORGET_S
        )
        self.broker = broker
        self.credentials = credentials
        self.fleet_clock = fleet_clock
        self.robots: dict[str, RobotPath] = {}
        self.refused = 0
        self.fixes: dict[str, int] = {}
        """Fixes sent, by robot."""
        self._client: aiomqtt.Client | None = None

    async def run(self, ctx: ModuleContext) -> None:
        if not self.service.sources:
            ctx.log.info("no camera streams: nothing to watch")
            return
        self.service.start(ctx.clock, ctx.log)
        try:
            async with asyncio.TaskGroup() as group:
                group.create_task(self._watch(ctx))
                await self._connect_forever(ctx)
        finally:
            self.service.close()

    # --- the cameras ------------------------------------------------------------------------

    async def _watch(self, ctx: ModuleContext) -> None:
        service = self.service
        while True:
            now = ctx.clock.now()
            frames = await service.grab(now)
            seen = await service.see(frames, now, self._robots_now(ctx.clock.now()))
            offset = fleet_offset(ctx.clock, self.fleet_clock)
            for found in seen.fixes:
                report = CameraFixReport(odometry_at_s=found.odometry_at_s + offset, fix=found.fix)
                if await self._send(robot_topic(found.robot, "camera_fix"), report, "camera_fix"):
                    self.fixes[found.robot] = self.fixes.get(found.robot, 0) + 1
            if seen.layer is not None:
                ctx.board.publish(CAMERA_LAYER, seen.layer)
                layer = CameraLayerReport(
                    at_s=self.fleet_clock(), layer=layer_shifted(seen.layer, offset)
                )
                await self._send(CAMERA_LAYER_TOPIC, layer, "camera_layer", retain=True)
            await ctx.clock.sleep(max(0.0, now + service.period_s - ctx.clock.now()))

    def _robots_now(self, now: float) -> dict[str, Robot]:
        return {
            name: Robot(robot.path, robot.estimate)
            for name, robot in self.robots.items()
            if now - robot.heard_s <= FORGET_S
        }

    async def _send(
        self, topic: str, message: FleetMessage, kind: str, *, retain: bool = False
    ) -> bool:
        """Out if the broker is there (else lost: a fix is soon stale, the layer comes again
        within a second); whether it went."""
        client = self._client
        if client is None:
            return False
        with contextlib.suppress(aiomqtt.MqttError):
            await client.publish(topic, encode(message), qos=QOS[kind], retain=retain)
            return True
        return False

    # --- the broker -------------------------------------------------------------------------

    async def _connect_forever(self, ctx: ModuleContext) -> None:
        link = Transitions(ctx.log, initial={"broker": CONNECTED})
        backoff = Backoff(0.5, 10.0)
        while True:
            try:
                async with mqtt_client(
                    self.broker,
                    self.credentials,
                    "coffeebot-cameras",
                    in_step=messages_in_step(ctx.clock),
                ) as client:
                    await client.subscribe(
                        [(f"{ROOT}/robots/+/{kind}", QOS[kind]) for kind in ROBOT_TO_CAMERAS]
                    )
                    self._client = client
                    backoff.reset()
                    link.update("broker", CONNECTED, Event.RECONNECT, f"connected to {self.broker}")
                    self._health(ctx, HealthStatus.RUNNING, f"connected to {self.broker}")
                    await self._receive(ctx, client)
            except aiomqtt.MqttError as exc:
                link.update("broker", DISCONNECTED, Event.DISCONNECT, f"{self.broker}: {exc}")
                self._health(ctx, HealthStatus.DEGRADED, f"no broker: {exc}")
            finally:
                self._client = None
            await ctx.clock.sleep(backoff.next_delay())

    def _health(self, ctx: ModuleContext, status: HealthStatus, detail: str) -> None:
        ctx.board.publish(
            HEALTH, Health(module=self.name, component="broker", status=status, detail=detail)
        )

    async def _receive(self, ctx: ModuleContext, client: aiomqtt.Client) -> None:
        async for message in client.messages:
            topic = str(message.topic)
            try:
                robot, batch = robot_report(topic, message.payload, ROBOT_TO_CAMERAS)
            except BadMessage as exc:
                self.refused += 1
                ctx.log.warning(
                    "refused a message from the broker (%d so far): %s", self.refused, exc
                )
                continue
            self._take(ctx, robot, batch)

    def _take(self, ctx: ModuleContext, robot: str, batch: OdometryBatch) -> None:
        """A robot's batch onto its path, on the service's clock."""
        now = ctx.clock.now()
        offset = fleet_offset(ctx.clock, self.fleet_clock)
        first_s = batch.samples[0].t_s - offset
        known = self.robots.get(robot)
        latest = None if known is None else known.path.latest
        if known is None or latest is None or first_s - latest[0] > GAP_S:
            known = self.robots[robot] = RobotPath(PosePath(self.service.keep_s + 1.0), None, now)
        for sample in batch.samples:
            known.path.add_pose(
                sample.t_s - offset, sample.x_mm, sample.y_mm, math.radians(sample.heading_deg)
            )
        known.estimate = _own(batch.estimate, offset)
        known.heard_s = now


def _own(sample: PositionSample | None, offset_s: float) -> OwnEstimate | None:
    """A robot's estimate from the wire, on the service's clock."""
    if sample is None:
        return None
    return OwnEstimate.from_sigmas(
        sample.t_s - offset_s,
        sample.floor,
        sample.x_mm,
        sample.y_mm,
        sample.sigma_x_mm,
        sample.sigma_y_mm,
        sample.cov_xy_mm2,
    )
