"""From a camera's tracks and the robots' odometry to camera fixes: identification (seed
003, IV.B) over the last seconds of one camera, and each match as a pose with its error.

The pose is the match's similarity applied to the robot's newest odometry pose, not to the
frame's: the transform carries the whole odometry frame onto the floor, so the fix is for
the moment it is published and the state module fuses it without looking back.
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence

import numpy as np
from pydantic import BaseModel, ConfigDict, Field

from coffeebot.cameras.identify import IdentifyRules, Similarity, identify
from coffeebot.cameras.odometry_path import PosePath
from coffeebot.cameras.own_estimate import OwnEstimate
from coffeebot.cameras.watch import CameraWatch
from coffeebot.messages import CameraFix


class FixRules(BaseModel):
    """How much a fix is trusted."""

    model_config = ConfigDict(frozen=True, extra="forbid")

    sigma_floor_mm: float = Field(
        20.0,
        gt=0,
        description="the least position sigma a fix claims: a pixel is 10-16 mm on a "
        "robot's top, and odometry's own error since the window grows the gap",
    )
    error_factor: float = Field(
        2.0,
        gt=0,
        description="the position sigma in multiples of the fit's mean error (the seed's "
        "eq 7), at least sigma_floor_mm; the benchmark's fix errors: p95 5 mm, max 18 mm",
    )
    heading_sigma_floor_deg: float = Field(
        1.0, gt=0, description="the least heading sigma a fix claims"
    )
    telemetry_slack_s: float = Field(
        0.1,
        gt=0,
        description="how far the robot's odometry may lag the newest frame (telemetry at "
        "50 Hz, frames at 10 Hz, a serial link between)",
    )


class Locator:
    """Names robots on each camera's tracks; remembers which tracks were robots, so the map
    never takes a robot that stopped for a standing object.

    Identification runs over several windows, shortest first (``windows_s``): a fast robot
    spreads the 150 mm a fit needs in a short one and is named soon after it drives into
    view, a slow one only in a long one. A robot takes its match from the shortest window
    that names it; matches that disagree (one robot on two tracks, two robots on one track)
    are refused, as any ambiguity is.

    The windows end at the newest frame every robot's odometry reaches (within
    ``telemetry_slack_s``): on the robot itself that is the newest frame; the fleet's camera
    service gets the odometry in batches over the broker, a moment later. The robots' own
    estimates, where they have them, break ties motion cannot (:func:`identify`).
    """

    def __init__(
        self, identify_rules: IdentifyRules, fix_rules: FixRules, windows_s: Sequence[float]
    ) -> None:
        if not windows_s:
            raise ValueError("identification needs at least one window")
        self.identify_rules = identify_rules
        self.fix_rules = fix_rules
        self.windows_s = tuple(sorted(windows_s))
        self._robot_tracks: dict[str, set[str]] = {}

    def robot_tracks(self, watch: CameraWatch) -> set[str]:
        """Live tracks of ``watch`` that were matched to a robot at some time."""
        known = self._robot_tracks.setdefault(watch.camera.id, set())
        known &= {t.id for t in watch.tracks}
        return known

    def locate(
        self,
        watch: CameraWatch,
        paths: Mapping[str, PosePath],
        estimates: Mapping[str, OwnEstimate] | None = None,
    ) -> tuple[dict[str, CameraFix], dict[str, str]]:
        """Fixes of the robots named on ``watch``'s tracks now, and for every other robot of
        ``paths`` why it was not named (over the shortest window, in plain words);
        ``estimates``: where robots' own estimates put them."""
        named: dict[str, tuple[str, Similarity, np.ndarray, np.ndarray]] = {}
        refused: dict[str, str] = {}
        clashing: set[str] = set()
        reached = [latest[0] for path in paths.values() if (latest := path.latest) is not None]
        until_s = min(reached) + self.fix_rules.telemetry_slack_s if reached else None
        for window_s in self.windows_s:
            found, reasons = self._identify(watch, paths, estimates or {}, window_s, until_s)
            for robot, reason in reasons.items():
                refused.setdefault(robot, reason)
            for robot, match in found.items():
                earlier = named.get(robot)
                if earlier is None:
                    named[robot] = match
                elif earlier[0] != match[0]:
                    clashing.add(robot)
        owners: dict[str, list[str]] = {}
        for robot, (track_id, *_) in named.items():
            owners.setdefault(track_id, []).append(robot)
        clashing |= {r for robots in owners.values() if len(robots) > 1 for r in robots}
        fixes: dict[str, CameraFix] = {}
        for robot, (track_id, similarity, track, odometry) in named.items():
            if robot in clashing:
                refused[robot] = "named on different tracks over different windows"
                continue
            refused.pop(robot, None)
            self._robot_tracks.setdefault(watch.camera.id, set()).add(track_id)
            newest = paths[robot].latest
            assert newest is not None  # it covered the window
            x, y, heading = similarity.to_floor(newest[1])
            whole = ~np.isnan(track).any(axis=1)
            fixes[robot] = self._fix(
                watch, track_id, similarity.error_mm, (x, y, heading), odometry[whole, :2]
            )
        return fixes, refused

    def _identify(
        self,
        watch: CameraWatch,
        paths: Mapping[str, PosePath],
        estimates: Mapping[str, OwnEstimate],
        window_s: float,
        until_s: float | None,
    ) -> tuple[dict[str, tuple[str, Similarity, np.ndarray, np.ndarray]], dict[str, str]]:
        """One window's matches (track, transform, track path, odometry path) and reasons,
        over the frames up to ``until_s``."""
        window = watch.window(window_s, until_s)
        if window is None:
            return {}, dict.fromkeys(paths, f"the camera has not run for {window_s:g} s")
        times, seen = window
        tracks = {
            track_id: path
            for track_id, path in seen.items()
            if _top_speed_mm_s(times, path) <= self.identify_rules.max_speed_mm_s
        }
        slack = self.fix_rules.telemetry_slack_s
        odometry = {
            robot: path.at(times)
            for robot, path in paths.items()
            if path.covers(float(times[0]), float(times[-1]), slack)
        }
        reasons = dict.fromkeys(
            set(paths) - set(odometry), f"no odometry over the last {window_s:g} s"
        )
        if not tracks:
            reasons.update(dict.fromkeys(odometry, f"no track followed for {window_s:g} s"))
            return {}, reasons
        if not odometry:
            return {}, reasons
        tied = {
            robot: estimate
            for robot, own in estimates.items()
            if robot in odometry and (estimate := own.on(paths[robot], slack)) is not None
        }
        result = identify(tracks, odometry, self.identify_rules, tied)
        reasons.update(result.refused)
        found = {
            robot: (match.track_id, match.similarity, tracks[match.track_id], odometry[robot])
            for robot, match in result.matched.items()
        }
        return found, reasons

    def _fix(
        self,
        watch: CameraWatch,
        track_id: str,
        error_mm: float,
        pose: tuple[float, float, float],
        waypoints: np.ndarray,
    ) -> CameraFix:
        rules = self.fix_rules
        sigma = max(rules.sigma_floor_mm, rules.error_factor * error_mm)
        # The rotation is fixed by the path's spread: sigma over it is its angular error.
        spread = float(np.sqrt(np.mean(np.sum((waypoints - waypoints.mean(axis=0)) ** 2, axis=1))))
        sigma_heading = max(
            rules.heading_sigma_floor_deg, math.degrees(math.atan2(sigma, max(spread, 1.0)))
        )
        x, y, heading = pose
        return CameraFix(
            camera_id=watch.camera.id,
            floor=watch.level,
            x_mm=round(float(x), 1),
            y_mm=round(float(y), 1),
            heading_deg=round(math.degrees(float(heading)), 2),
            sigma_mm=round(sigma, 1),
            sigma_heading_deg=round(sigma_heading, 2),
            fit_error_mm=round(error_mm, 1),
            points=len(waypoints),
            track_id=track_id,
        )


def _top_speed_mm_s(times: np.ndarray, path: np.ndarray) -> float:
    """The fastest a track moved between consecutive frames it saw whole (0 if none)."""
    steps = np.hypot(*np.diff(path, axis=0).T) / np.diff(times)
    steps = steps[~np.isnan(steps)]
    return float(steps.max()) if len(steps) else 0.0
