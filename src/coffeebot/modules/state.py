"""State module: the seed's "current state", one fused pose and the rest, always the freshest."""

from __future__ import annotations

import asyncio
from collections.abc import Callable
from typing import Any

from coffeebot.board import Subscription, Topic
from coffeebot.config import RobotConfig
from coffeebot.floorplan import FloorPlan
from coffeebot.messages import (
    ANGLE,
    CAMERA_FIX,
    CURRENT_STATE,
    DELIVERY_STATUS,
    DOOR,
    ELEVATOR_STATE,
    MOVE_INSTRUCTION,
    ODOMETRY,
    ORDER_DISPATCH,
    PARTICLES,
    RANGE_SCAN,
    TRAFFIC,
    UWB_FIX,
    PoseEstimate,
)
from coffeebot.modules.base import Module, ModuleContext
from coffeebot.perception.fusion import PoseFusion
from coffeebot.perception.state import StateEstimator, make_fusion


class StateModule(Module):
    """Wraps :class:`StateEstimator`; publishes after every input that changed it, and (with
    the particle filter) a sample of its particles every ``cloud_period_s``."""

    name = "state"
    inputs = (
        ODOMETRY,
        UWB_FIX,
        CAMERA_FIX,
        RANGE_SCAN,
        ANGLE,
        DOOR,
        ELEVATOR_STATE,
        MOVE_INSTRUCTION,
        ORDER_DISPATCH,
        DELIVERY_STATUS,
        TRAFFIC,
    )
    outputs = (CURRENT_STATE, PARTICLES)

    def __init__(
        self,
        config: RobotConfig,
        plan: FloorPlan,
        fusion: PoseFusion | None = None,
        start: PoseEstimate | None = None,
    ) -> None:
        self.estimator = StateEstimator(
            plan,
            config.motor,
            config.state,
            fusion or make_fusion(config, plan),
            body=config.geometry,
        )
        self.cloud = config.state.particles
        self._cloud_at: float | None = None
        if start is not None:
            self.estimator.place(start.x_mm, start.y_mm, start.heading_deg, start.floor)

    async def _follow(
        self, ctx: ModuleContext, messages: Subscription[Any], apply: Callable[[Any, float], object]
    ) -> None:
        with messages:
            async for envelope in messages:
                if apply(envelope.msg, envelope.stamp) is not False:
                    now = ctx.clock.now()
                    ctx.board.publish(CURRENT_STATE, self.estimator.current(now))
                    self._publish_cloud(ctx, now)

    def _publish_cloud(self, ctx: ModuleContext, now: float) -> None:
        if self._cloud_at is not None and now - self._cloud_at < self.cloud.cloud_period_s:
            return
        cloud = self.estimator.cloud(self.cloud.cloud_points)
        if cloud is not None:
            self._cloud_at = now
            ctx.board.publish(PARTICLES, cloud)

    async def run(self, ctx: ModuleContext) -> None:
        e = self.estimator
        handlers: list[tuple[Topic[Any], Callable[[Any, float], object]]] = [
            (ODOMETRY, e.on_odometry),
            (UWB_FIX, e.on_uwb),
            (CAMERA_FIX, e.on_camera_fix),
            (RANGE_SCAN, e.on_scan),
            (ANGLE, e.on_angle),
            (DOOR, e.on_door),
            (ELEVATOR_STATE, e.on_elevator),
            (MOVE_INSTRUCTION, lambda m, _: e.on_instruction(m)),
            (ORDER_DISPATCH, lambda m, _: e.on_dispatch(m)),
            (DELIVERY_STATUS, lambda m, _: e.on_delivery(m)),
            (TRAFFIC, e.on_traffic),
        ]
        # Subscribe to everything before the first await, so nothing published meanwhile is lost.
        subscriptions = [(ctx.board.subscribe(topic), apply) for topic, apply in handlers]
        async with asyncio.TaskGroup() as group:
            for messages, apply in subscriptions:
                group.create_task(self._follow(ctx, messages, apply))
