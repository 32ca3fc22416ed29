"""Cameras module: the building's ceiling cameras for a robot on its own (seed 003).

At each tick of the cameras' frame rate it hands every camera's frame and the robot's own
odometry to a :class:`~coffeebot.cameras.service.CameraService`, which follows the blobs and
names the robot on the tracks of the cameras of its floor, and publishes the robot's fixes
(``cameras/fix``) and the map's camera layer (``cameras/layer``: what stands still in view,
every camera's field and whether it works). In a fleet the dispatcher's daemon runs the same
service for every robot instead (:mod:`coffeebot.fleet.camera_service`).
"""

from __future__ import annotations

from collections.abc import Mapping

from coffeebot.board import Subscription
from coffeebot.cameras.identify import IdentifyRules
from coffeebot.cameras.locate import FixRules
from coffeebot.cameras.odometry_path import OdometryPath
from coffeebot.cameras.own_estimate import OwnEstimate
from coffeebot.cameras.service import CameraService, Robot
from coffeebot.cameras.sources import FrameSource
from coffeebot.cameras.standing import StandingRules
from coffeebot.config import RobotConfig
from coffeebot.floorplan import FloorPlan
from coffeebot.messages import (
    CAMERA_FIX,
    CAMERA_LAYER,
    CURRENT_STATE,
    ODOMETRY,
    Odometry,
)
from coffeebot.modules.base import Module, ModuleContext

ROBOT = "robot"
"""The one robot's name in identification."""


class CameraModule(Module):
    """Every camera of the plan that has a frame source; see the module docstring."""

    name = "cameras"
    inputs = (ODOMETRY, CURRENT_STATE)
    outputs = (CAMERA_FIX, CAMERA_LAYER)

    def __init__(
        self,
        config: RobotConfig,
        plan: FloorPlan,
        sources: Mapping[str, FrameSource],
        identify_rules: IdentifyRules | None = None,
        fix_rules: FixRules | None = None,
        standing_rules: StandingRules | None = None,
    ) -> None:
        self.service = CameraService(
            plan,
            sources,
            config.cameras,
            config.geometry.height_mm,
            identify_rules=identify_rules,
            fix_rules=fix_rules,
            standing_rules=standing_rules,
        )
        self.path = OdometryPath(config.motor, config.state, keep_s=self.service.keep_s + 1.0)

    async def run(self, ctx: ModuleContext) -> None:
        service = self.service
        if not service.sources:
            ctx.log.info("no camera streams: nothing to watch")
            return
        service.start(ctx.clock, ctx.log)
        try:
            with ctx.board.subscribe(ODOMETRY) as odometry:
                while True:
                    self._take_odometry(odometry)
                    now = ctx.clock.now()
                    frames = await service.grab(now)
                    self._take_odometry(odometry)
                    robot = Robot(self.path, OwnEstimate.published(ctx.board.latest(CURRENT_STATE)))
                    seen = await service.see(frames, now, {ROBOT: robot})
                    for found in seen.fixes:
                        ctx.board.publish(CAMERA_FIX, found.fix)
                    if seen.layer is not None:
                        ctx.board.publish(CAMERA_LAYER, seen.layer)
                    await ctx.clock.sleep(max(0.0, now + service.period_s - ctx.clock.now()))
        finally:
            service.close()

    def _take_odometry(self, odometry: Subscription[Odometry]) -> None:
        while (envelope := odometry.get_nowait()) is not None:
            self.path.add(envelope.msg, envelope.stamp)
