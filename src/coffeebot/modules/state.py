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
    CURRENT_STATE,
    DELIVERY_STATUS,
    DOOR,
    MOVE_INSTRUCTION,
    ODOMETRY,
    ORDER_DISPATCH,
    UWB_FIX,
    PoseEstimate,
)
from coffeebot.modules.base import Module, ModuleContext
from coffeebot.perception.fusion import PoseFusion
from coffeebot.perception.state import StateEstimator


class StateModule(Module):
    """Wraps :class:`StateEstimator`; publishes after every input that changed it."""

    name = "state"
    inputs = (ODOMETRY, UWB_FIX, ANGLE, DOOR, MOVE_INSTRUCTION, ORDER_DISPATCH, DELIVERY_STATUS)
    outputs = (CURRENT_STATE,)

    def __init__(
        self,
        config: RobotConfig,
        plan: FloorPlan,
        fusion: PoseFusion | None = None,
        start: PoseEstimate | None = None,
    ) -> None:
        self.estimator = StateEstimator(plan, config.motor, config.state, fusion)
        if start is not None:
            self.estimator.place(start.x_mm, start.y_mm, start.heading_deg, start.floor)

    async def _follow(
        self, ctx: ModuleContext, messages: Subscription[Any], apply: Callable[[Any, float], object]
    ) -> None:
        with messages:
            async for envelope in messages:
                if apply(envelope.msg, envelope.stamp) is not False:
                    ctx.board.publish(CURRENT_STATE, self.estimator.current(ctx.clock.now()))

    async def run(self, ctx: ModuleContext) -> None:
        e = self.estimator
        handlers: list[tuple[Topic[Any], Callable[[Any, float], object]]] = [
            (ODOMETRY, e.on_odometry),
            (UWB_FIX, e.on_uwb),
            (ANGLE, e.on_angle),
            (DOOR, e.on_door),
            (MOVE_INSTRUCTION, lambda m, _: e.on_instruction(m)),
            (ORDER_DISPATCH, lambda m, _: e.on_dispatch(m)),
            (DELIVERY_STATUS, lambda m, _: e.on_delivery(m)),
        ]
        # Subscribe to everything before the first await, so nothing published meanwhile is lost.
        subscriptions = [(ctx.board.subscribe(topic), apply) for topic, apply in handlers]
        async with asyncio.TaskGroup() as group:
            for messages, apply in subscriptions:
                group.create_task(self._follow(ctx, messages, apply))
