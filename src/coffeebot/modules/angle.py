"""Angle module: heading against the hallway from the side sensors, inside marked zones."""

from __future__ import annotations

from coffeebot.config import RobotConfig
from coffeebot.floorplan import FloorPlan
from coffeebot.messages import ANGLE, COLLISION, CURRENT_STATE, RANGE_SCAN, SafetyState
from coffeebot.modules.base import Module, ModuleContext
from coffeebot.perception.angle import AngleEstimator, Rejection


class AngleModule(Module):
    """Wraps :class:`AngleEstimator`; pose from the current state, obstacles from collision."""

    name = "angle"
    inputs = (RANGE_SCAN, CURRENT_STATE, COLLISION)
    outputs = (ANGLE,)

    def __init__(self, config: RobotConfig, plan: FloorPlan) -> None:
        self.plan = plan
        self.estimator = AngleEstimator(
            config.tof.sensors, config.angle, config.tof.effective_half_fov_deg
        )

    async def run(self, ctx: ModuleContext) -> None:
        self.estimator.reset()
        with ctx.board.subscribe(RANGE_SCAN) as scans:
            async for envelope in scans:
                state = ctx.board.latest(CURRENT_STATE)
                collision = ctx.board.latest(COLLISION)
                pose = state.msg.pose if state is not None and state.msg.pose.initialised else None
                # No verdict yet counts as an obstacle: measure only on a known-clear path.
                obstacle = collision is None or collision.msg.state is not SafetyState.GO
                result = self.estimator.update(
                    envelope.msg,
                    envelope.seq,
                    pose,
                    None
                    if pose is None
                    else self.plan.floor(pose.floor).view_near(pose.x_mm, pose.y_mm),
                    obstacle,
                    envelope.stamp,
                )
                if isinstance(result, Rejection):
                    ctx.log.debug("no angle: %s", result.reason)
                else:
                    ctx.board.publish(ANGLE, result)
