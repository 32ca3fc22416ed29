"""The ceiling cameras at work, for one robot or a whole fleet: each tick, a frame from every
camera, the blobs followed, the robots named on the tracks of the cameras of their floor by
their odometry, the map's layer of what stands still, and every camera's health.

A robot alone runs this in its ``cameras`` module with its own odometry; in a fleet the
dispatcher's daemon runs it once for every robot, with the odometry the robots send over the
broker (:mod:`coffeebot.fleet.camera_service`). The image work runs in a worker thread: a
stream blocks, the pipeline computes, and on the simulated clock the worker keeps lockstep.
"""

from __future__ import annotations

import logging
from collections.abc import Mapping
from dataclasses import dataclass
from typing import NamedTuple

import numpy as np

from coffeebot.cameras.identify import IdentifyRules
from coffeebot.cameras.locate import FixRules, Locator
from coffeebot.cameras.odometry_path import PosePath
from coffeebot.cameras.own_estimate import OwnEstimate
from coffeebot.cameras.sources import FrameSource
from coffeebot.cameras.standing import StandingObjects, StandingRules
from coffeebot.cameras.watch import CameraWatch
from coffeebot.clock import Clock
from coffeebot.config import CamerasConfig
from coffeebot.floorplan import FloorPlan
from coffeebot.hardware.worker import DeviceWorker
from coffeebot.logs import Event, Transitions
from coffeebot.messages import CameraFix, CameraLayer, CameraView

WORKING = "working"
LAYER_EVERY_S = 1.0
"""The layer goes out when it changes and at least this often, so a silent service shows
as a stale layer."""

Frames = dict[str, np.ndarray | None]


@dataclass(frozen=True)
class Robot:
    """One robot as the cameras need it: its odometry, and its own estimate (None while it
    is not localized: then every camera looks for it)."""

    path: PosePath
    estimate: OwnEstimate | None


class RobotFix(NamedTuple):
    """A camera's fix of a robot, and the time of the robot's odometry sample it is for
    (the newest the service had)."""

    robot: str
    odometry_at_s: float
    fix: CameraFix


class Seen(NamedTuple):
    """What one tick found: the fixes, and the layer when it is due (else None)."""

    fixes: list[RobotFix]
    layer: CameraLayer | None


class CameraService:
    """Every camera of ``plan`` that has a frame source. ``lag_s``: how far behind the
    frames the robots' odometry may reach the service (none on the robot itself; the
    batching and the broker in a fleet): frames are kept that much longer, so that a window
    can end where the odometry does."""

    def __init__(
        self,
        plan: FloorPlan,
        sources: Mapping[str, FrameSource],
        settings: CamerasConfig,
        robot_height_mm: float,
        *,
        lag_s: float = 0.0,
        identify_rules: IdentifyRules | None = None,
        fix_rules: FixRules | None = None,
        standing_rules: StandingRules | None = None,
    ) -> None:
        levels = {camera.id: floor.level for floor in plan.floors for camera in floor.cameras}
        unknown = sorted(set(sources) - set(levels))
        if unknown:
            raise ValueError(f"no camera {', '.join(unknown)} in the floor plan")
        self.settings = settings
        self.sources = dict(sources)
        self.keep_s = max(settings.windows_s) + lag_s
        """How much odometry identification may look back at."""
        self.watches = {
            camera_id: CameraWatch(
                source.camera, levels[camera_id], robot_height_mm, keep_s=self.keep_s
            )
            for camera_id, source in sources.items()
        }
        self.locator = Locator(
            identify_rules or IdentifyRules(), fix_rules or FixRules(), settings.windows_s
        )
        self.standing = StandingObjects(standing_rules or StandingRules())
        self.period_s = 1.0 / max((s.camera.fps for s in sources.values()), default=1.0)
        """One tick per frame of the fastest camera."""
        self._fixed_at: dict[str, float] = {}
        self._problems: dict[str, str | None] = dict.fromkeys(sources)
        self._layer_at: float | None = None
        self._started_s = 0.0
        self._worker: DeviceWorker | None = None
        self._faults: Transitions | None = None

    def start(self, clock: Clock, log: logging.Logger) -> None:
        """Before the first tick: the worker thread on ``clock``, camera faults logged to
        ``log`` once each."""
        self._worker = DeviceWorker("cameras", clock)
        self._faults = Transitions(log, initial=dict.fromkeys(self.sources, WORKING))
        self._started_s = clock.now()

    def close(self) -> None:
        if self._worker is not None:
            self._worker.close()
        for source in self.sources.values():
            source.close()

    async def grab(self, now: float) -> Frames:
        """A frame from every camera, exposed at about ``now`` (None where there is none)."""
        return await self._running().call(self._grab_all, now)

    async def see(self, frames: Frames, now: float, robots: Mapping[str, Robot]) -> Seen:
        """``frames`` (grabbed at ``now``) through the pipelines and into the layer; the
        robots named on the cameras' tracks, at most one fix per camera every
        ``fix_period_s``; the layer when it changed or has not gone out for a second."""
        places = [robot.estimate.place for robot in robots.values() if robot.estimate is not None]
        changed = await self._running().call(self._see_all, frames, now, places)
        self._report(now)
        return Seen(self._locate(now, robots), self._layer(now, changed))

    def _running(self) -> DeviceWorker:
        if self._worker is None:
            raise RuntimeError("the camera service was not started")
        return self._worker

    def _grab_all(self, now: float) -> Frames:
        return {camera_id: source.grab(now) for camera_id, source in self.sources.items()}

    def _see_all(self, frames: Frames, now: float, robots: list[tuple[int, float, float]]) -> bool:
        """Each frame through its camera's pipeline and into the layer; whether it changed."""
        changed = False
        for camera_id, frame in frames.items():
            watch = self.watches[camera_id]
            if frame is None:
                continue
            watch.see(frame, now)
            changed |= self.standing.update(watch, now, robots, self.locator.robot_tracks(watch))
        for camera_id, watch in self.watches.items():
            if self._silent_s(watch, now) > self.settings.out_after_s:
                changed |= self.standing.camera_out(camera_id, now)
        return changed

    def _silent_s(self, watch: CameraWatch, now: float) -> float:
        last = watch.last_frame_s if watch.last_frame_s is not None else self._started_s
        return now - last

    def _report(self, now: float) -> None:
        assert self._faults is not None
        for camera_id, watch in self.watches.items():
            problem: str | None = None
            silent_s = self._silent_s(watch, now)
            if silent_s > self.settings.out_after_s:
                source_problem = getattr(self.sources[camera_id], "problem", None)
                problem = f"no frames for {silent_s:.0f} s" + (
                    f": {source_problem}" if source_problem else ""
                )
            if problem is None:
                self._faults.update(camera_id, WORKING, Event.RECOVERED, "frames again")
            else:
                self._faults.update(camera_id, "out", Event.DISCONNECT, problem, camera=camera_id)
            self._problems[camera_id] = problem

    def _locate(self, now: float, robots: Mapping[str, Robot]) -> list[RobotFix]:
        fixes: list[RobotFix] = []
        for camera_id, watch in self.watches.items():
            looked_for = {
                name: robot
                for name, robot in robots.items()
                if robot.estimate is None or robot.estimate.floor == watch.level
            }
            paths = {name: robot.path for name, robot in looked_for.items()}
            fixed_at = self._fixed_at.get(camera_id)
            if not paths or (fixed_at is not None and now - fixed_at < self.settings.fix_period_s):
                continue
            estimates = {
                name: robot.estimate
                for name, robot in looked_for.items()
                if robot.estimate is not None
            }
            found, _ = self.locator.locate(watch, paths, estimates)
            for name, fix in found.items():
                newest = paths[name].latest
                assert newest is not None  # it covered the window
                fixes.append(RobotFix(name, newest[0], fix))
            if found:
                self._fixed_at[camera_id] = now
        return fixes

    def _layer(self, now: float, changed: bool) -> CameraLayer | None:
        if not changed and self._layer_at is not None and now - self._layer_at < LAYER_EVERY_S:
            return None
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
        return CameraLayer(
            objects=self.standing.objects, cameras=views, expiry_s=self.standing.rules.expiry_s
        )
