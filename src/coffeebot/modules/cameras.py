"""Cameras module: the building's ceiling cameras for a robot on its own (seed 003).

At each tick of the cameras' frame rate it takes a frame from every camera (in a worker
thread: a stream blocks, the pipeline computes), follows the blobs, names the robot on the
tracks of the cameras of its floor by its own odometry, and publishes a fix of its pose
(``cameras/fix``) and the map's camera layer (``cameras/layer``: what stands still in view,
every camera's field and whether it works). In a fleet one camera service does this for
every robot instead.
"""

from __future__ import annotations

from collections.abc import Mapping

import numpy as np

from coffeebot.board import Subscription
from coffeebot.cameras.identify import IdentifyRules
from coffeebot.cameras.locate import FixRules, Locator
from coffeebot.cameras.odometry_path import OdometryPath
from coffeebot.cameras.sources import FrameSource
from coffeebot.cameras.standing import StandingObjects, StandingRules
from coffeebot.cameras.watch import CameraWatch
from coffeebot.config import RobotConfig
from coffeebot.floorplan import FloorPlan
from coffeebot.hardware.worker import DeviceWorker
from coffeebot.logs import Event, Transitions
from coffeebot.messages import (
    CAMERA_FIX,
    CAMERA_LAYER,
    CURRENT_STATE,
    ODOMETRY,
    CameraLayer,
    CameraView,
    Odometry,
)
from coffeebot.modules.base import Module, ModuleContext

ROBOT = "robot"
"""The one robot's name in identification."""

WORKING = "working"


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
        self.config = config
        self.settings = config.cameras
        levels = {camera.id: floor.level for floor in plan.floors for camera in floor.cameras}
        unknown = sorted(set(sources) - set(levels))
        if unknown:
            raise ValueError(f"no camera {', '.join(unknown)} in the floor plan")
        self.sources = dict(sources)
        self.watches = {
            camera_id: CameraWatch(
                source.camera,
                levels[camera_id],
                config.geometry.height_mm,
                keep_s=max(self.settings.windows_s),
            )
            for camera_id, source in sources.items()
        }
        self.locator = Locator(
            identify_rules or IdentifyRules(), fix_rules or FixRules(), self.settings.windows_s
        )
        self.standing = StandingObjects(standing_rules or StandingRules())
        self.path = OdometryPath(
            config.motor, config.state, keep_s=max(self.settings.windows_s) + 1.0
        )
        self.fixes = 0
        self._fixed_at: dict[str, float] = {}
        self._problems: dict[str, str | None] = dict.fromkeys(sources)
        self._layer_at: float | None = None
        self._started_s = 0.0

    async def run(self, ctx: ModuleContext) -> None:
        if not self.sources:
            ctx.log.info("no camera streams: nothing to watch")
            return
        worker = DeviceWorker("cameras", ctx.clock)
        self._started_s = ctx.clock.now()
        faults = Transitions(ctx.log, initial=dict.fromkeys(self.sources, WORKING))
        odometry = ctx.board.subscribe(ODOMETRY)
        fps = max(source.camera.fps for source in self.sources.values())
        try:
            with odometry:
                while True:
                    self._take_odometry(odometry, ctx)
                    now = ctx.clock.now()
                    frames = await worker.call(self._grab_all, now)
                    self._take_odometry(odometry, ctx)
                    changed = await worker.call(self._see_all, frames, now, self._robot_at(ctx))
                    self._report(ctx, faults, now)
                    self._locate(ctx, now)
                    self._publish_layer(ctx, now, changed)
                    await ctx.clock.sleep(max(0.0, now + 1.0 / fps - ctx.clock.now()))
        finally:
            worker.close()
            for source in self.sources.values():
                source.close()

    def _take_odometry(self, odometry: Subscription[Odometry], ctx: ModuleContext) -> None:
        while (envelope := odometry.get_nowait()) is not None:
            self.path.add(envelope.msg, envelope.stamp)

    def _grab_all(self, now: float) -> dict[str, np.ndarray | None]:
        return {camera_id: source.grab(now) for camera_id, source in self.sources.items()}

    def _see_all(
        self,
        frames: Mapping[str, np.ndarray | None],
        now: float,
        robot: tuple[int, float, float] | None,
    ) -> bool:
        """Each frame through its camera's pipeline and into the layer; whether it changed."""
        changed = False
        robots = [] if robot is None else [robot]
        for camera_id, frame in frames.items():
            watch = self.watches[camera_id]
            if frame is None:
                continue
            watch.see(frame, now)
            changed |= self.standing.update(watch, now, robots, self.locator.robot_tracks(watch))
        for camera_id, watch in self.watches.items():
            if self._out(watch, now):
                changed |= self.standing.camera_out(camera_id, now)
        return changed

    def _out(self, watch: CameraWatch, now: float) -> bool:
        last = watch.last_frame_s if watch.last_frame_s is not None else self._started_s
        return now - last > self.settings.out_after_s

    def _robot_at(self, ctx: ModuleContext) -> tuple[int, float, float] | None:
        state = ctx.board.latest(CURRENT_STATE)
        if state is None or not state.msg.pose.initialised:
            return None
        pose = state.msg.pose
        return pose.floor, pose.x_mm, pose.y_mm

    def _report(self, ctx: ModuleContext, faults: Transitions, now: float) -> None:
        for camera_id, watch in self.watches.items():
            problem: str | None = None
            since = watch.last_frame_s if watch.last_frame_s is not None else self._started_s
            if now - since > self.settings.out_after_s:
                source_problem = getattr(self.sources[camera_id], "problem", None)
                problem = f"no frames for {now - since:.0f} s" + (
                    f": {source_problem}" if source_problem else ""
                )
            if problem is None:
                faults.update(camera_id, WORKING, Event.RECOVERED, "frames again")
            else:
                faults.update(camera_id, "out", Event.DISCONNECT, problem, camera=camera_id)
            self._problems[camera_id] = problem

    def _locate(self, ctx: ModuleContext, now: float) -> None:
        robot = self._robot_at(ctx)
        for camera_id, watch in self.watches.items():
            if robot is not None and watch.level != robot[0]:
                continue
            fixed_at = self._fixed_at.get(camera_id)
            if fixed_at is not None and now - fixed_at < self.settings.fix_period_s:
                continue
            fixes, _ = self.locator.locate(watch, {ROBOT: self.path})
            fix = fixes.get(ROBOT)
            if fix is not None:
                self._fixed_at[camera_id] = now
                self.fixes += 1
                ctx.board.publish(CAMERA_FIX, fix)

    def _publish_layer(self, ctx: ModuleContext, now: float, changed: bool) -> None:
        if not changed and self._layer_at is not None and now - self._layer_at < 1.0:
            return
        self._layer_at = now
        views = [
            CameraView(
                camera_id=camera_id,
                floor=watch.level,
                corners_mm=[(round(float(x), 1), round(float(y), 1)) for x, y in watch.field()],
                working=self._problems.get(camera_id) is None,
                problem=self._problems.get(camera_id),
            )
            for camera_id, watch in self.watches.items()
        ]
        ctx.board.publish(
            CAMERA_LAYER,
            CameraLayer(
                objects=self.standing.objects,
                cameras=views,
                expiry_s=self.standing.rules.expiry_s,
            ),
        )
