"""Collision module: every scan becomes a stop/slow/go verdict in the same loop turn.

With a fresh, confident pose the floor plan's walls place the front readings they explain
(``perception/walls.py``); without one every reading keeps its whole arc, the safe side.
"""

from __future__ import annotations

import math
from typing import ClassVar

from coffeebot.config import RobotConfig
from coffeebot.floorplan import FloorPlan
from coffeebot.logs import Event, Transitions
from coffeebot.messages import (
    COLLISION,
    CURRENT_STATE,
    ODOMETRY,
    RANGE_SCAN,
    PoseEstimate,
    SafetyState,
)
from coffeebot.modules.base import Module, ModuleContext
from coffeebot.perception.collision import CollisionMonitor
from coffeebot.perception.walls import Explainer, carried, explainer, trusted

ODOMETRY_STALE_S = 0.5
"""Odometry older than this is no speed: the monitor assumes the worst."""


class CollisionModule(Module):
    """Wraps :class:`CollisionMonitor`; speed comes from the latest odometry."""

    name = "collision"
    inputs = (RANGE_SCAN, ODOMETRY, CURRENT_STATE)
    outputs = (COLLISION,)
    critical: ClassVar[bool] = True

    def __init__(self, config: RobotConfig, plan: FloorPlan) -> None:
        self.config = config
        self.plan = plan
        self.monitor = self._new_monitor()
        self._trusted: tuple[PoseEstimate, tuple[float, float, float], float] | None = None
        """The last pose good enough for the walls, the odometry then, and when."""

    def _new_monitor(self) -> CollisionMonitor:
        cfg = self.config
        return CollisionMonitor(
            cfg.tof.sensors,
            cfg.collision,
            max_speed_mm_s=cfg.collision.unknown_speed_mm_s or cfg.motor.max_speed_mm_s,
            max_range_mm=cfg.tof.max_range_mm,
            body_width_mm=cfg.geometry.width_mm,
            body_length_mm=cfg.geometry.length_mm,
            tracking=cfg.tracking,
            axle_x_mm=cfg.motor.axle_x_mm,
        )

    def _motion(self, ctx: ModuleContext) -> tuple[float | None, float]:
        """Forward speed (None without fresh odometry) and yaw rate from the wheel speeds."""
        last = ctx.board.latest(ODOMETRY)
        age = ctx.board.age(ODOMETRY)
        if last is None or age is None or age > ODOMETRY_STALE_S:
            return None, 0.0
        left, right = last.msg.left_mm_s, last.msg.right_mm_s
        yaw_rate = math.degrees((right - left) / self.config.motor.wheel_base_mm)
        return (left + right) / 2.0, yaw_rate

    def _explainer(self, ctx: ModuleContext) -> Explainer | None:
        """Wall explanations from the latest pose, if it is fresh and its heading good; else
        from the last good one carried on by the wheels, for up to ``stale_pose_s``.

        A particle filter that injects fresh hypotheses reports a wide heading sigma for a
        few cycles while its estimate stays where it was: the robot has not lost its heading
        in 25 ms, and without the walls every wall return would become a track whose first,
        noisy velocities look like someone stepping into the way.
        """
        state, age = ctx.board.latest(CURRENT_STATE), ctx.board.age(CURRENT_STATE)
        stale_s = self.config.motion.stale_pose_s
        if state is None or age is None or age > stale_s:
            return None
        pose, now = state.msg.pose, ctx.clock.now()
        odometry = self.monitor.tracker.odometry
        if trusted(pose):
            self._trusted = (pose, odometry.snapshot(), now)
        elif self._trusted is not None and now - self._trusted[2] <= stale_s:
            last, then, _ = self._trusted
            if last.floor != pose.floor:
                return None
            pose = carried(last, *odometry.since(then))
        return explainer(self.plan.floor(pose.floor), pose, self.config.motion.wall_margin_mm)

    async def run(self, ctx: ModuleContext) -> None:
        # A restart forgets everything: back to "stop" until every face is clear again.
        self.monitor = self._new_monitor()
        self._trusted = None
        # Starting in "stop" is the rule, not an event; every change after it is logged once.
        safety = Transitions(ctx.log, initial={"collision": SafetyState.STOP.value})
        with ctx.board.subscribe(RANGE_SCAN) as scans:
            async for envelope in scans:
                # No await between reading the scan and publishing the verdict.
                speed, yaw_rate = self._motion(ctx)
                status = self.monitor.update(
                    envelope.msg, speed, envelope.seq, yaw_rate, self._explainer(ctx)
                )
                ctx.board.publish(COLLISION, status)
                stopped = status.state is SafetyState.STOP
                safety.update(
                    "collision",
                    SafetyState.STOP.value if stopped else SafetyState.GO.value,
                    Event.SAFETY_STOP if stopped else Event.SAFETY_CLEAR,
                    status.reason,
                    sensor=status.sensor,
                    distance_mm=status.distance_mm,
                )
