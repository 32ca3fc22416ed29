"""A robot's side of the fleet's camera service: its odometry out, its fixes and the map's
camera layer in.

The robot keeps its dead-reckoned path (as the cameras module does on a robot alone) and
sends it in batches; the service names it on a camera's tracks and fixes its pose for the
moment of the newest sample it had, a batch and the broker's latency ago. The robot carries
that pose on to now along its own path, so the state module fuses it as it comes, exactly
as a fix from its own cameras module. The layer's times come on the fleet's time base and
go onto the board's clock; a layer older than navigation's ``camera_stale_s`` (a retained
one a service that stopped left on the broker) is no camera information and is dropped.
"""

from __future__ import annotations

import math

import numpy as np

from coffeebot.cameras.odometry_path import OdometryPath
from coffeebot.cameras.own_estimate import OwnEstimate
from coffeebot.config import RobotConfig
from coffeebot.fleet.protocol import (
    MAX_SAMPLES,
    CameraFixReport,
    CameraLayerReport,
    OdometryBatch,
    OdometrySample,
    PositionSample,
    layer_shifted,
)
from coffeebot.messages import CameraFix, CameraLayer, Odometry

SAMPLE_HZ = 10.0
"""Samples per second on the wire: the cameras' frame rate, at which identification reads
the path (it interpolates between samples, as between frames)."""
BATCH_S = 0.5
"""A batch this often: the lag of the service's odometry, and of its fixes."""
KEEP_S = 10.0
"""How far back the robot keeps its path: a fix is carried on from at most this long ago."""


class CameraLink:
    """The robot's path, batched out; fixes and layers in, made the robot's."""

    def __init__(self, config: RobotConfig) -> None:
        self.path = OdometryPath(config.motor, config.state, keep_s=KEEP_S)
        self.stale_s = config.navigation.camera_stale_s
        self._sent_until: float | None = None

    def take(self, odometry: Odometry, t_s: float) -> None:
        """Telemetry from the board, stamped ``t_s`` on its clock."""
        self.path.add(odometry, t_s)

    def batch(self, offset_s: float, estimate: OwnEstimate | None) -> OdometryBatch | None:
        """The path since the last batch, ``SAMPLE_HZ`` samples a second ending with the
        newest (after an outage, the last ``MAX_SAMPLES`` of it), and the robot's estimate,
        their times moved by ``offset_s`` onto the fleet's time base. None when the path has
        nothing new."""
        latest = self.path.latest
        if latest is None:
            return None
        newest = latest[0]
        since = newest - BATCH_S if self._sent_until is None else self._sent_until
        count = min(math.floor((newest - since) * SAMPLE_HZ), MAX_SAMPLES)
        if count < 1:
            return None
        times = newest - np.arange(count - 1, -1, -1) / SAMPLE_HZ
        self._sent_until = newest
        samples = [
            OdometrySample(
                t_s=float(t) + offset_s,
                x_mm=round(float(x), 1),
                y_mm=round(float(y), 1),
                heading_deg=round(math.degrees(float(heading)), 3),
            )
            for t, (x, y, heading) in zip(times, self.path.at(times), strict=True)
        ]
        return OdometryBatch(samples=samples, estimate=_sample(estimate, offset_s))

    def fix(self, report: CameraFixReport, offset_s: float) -> CameraFix | None:
        """The service's fix carried on from its moment to the path's newest sample; None
        when the path no longer reaches back to that moment."""
        moved = self.path.moved_since(report.odometry_at_s - offset_s)
        if moved is None:
            return None
        ahead, left, turn = moved
        fix = report.fix
        heading = math.radians(fix.heading_deg)
        cos, sin = math.cos(heading), math.sin(heading)
        return fix.model_copy(
            update={
                "x_mm": round(fix.x_mm + cos * ahead - sin * left, 1),
                "y_mm": round(fix.y_mm + sin * ahead + cos * left, 1),
                "heading_deg": round(math.degrees(math.remainder(heading + turn, math.tau)), 2),
            }
        )

    def layer(self, report: CameraLayerReport, offset_s: float, now: float) -> CameraLayer | None:
        """The layer on the board's clock (``now`` on it); None when it is stale already."""
        if now - (report.at_s - offset_s) > self.stale_s:
            return None
        return layer_shifted(report.layer, -offset_s)


def _sample(estimate: OwnEstimate | None, offset_s: float) -> PositionSample | None:
    if estimate is None:
        return None
    (xx, xy), (_, yy) = estimate.covariance_mm2
    return PositionSample(
        t_s=estimate.t_s + offset_s,
        floor=estimate.floor,
        x_mm=round(estimate.x_mm, 1),
        y_mm=round(estimate.y_mm, 1),
        # Sigmas rounded up and the covariance towards zero: still a covariance, no tighter.
        sigma_x_mm=math.ceil(10 * math.sqrt(xx)) / 10,
        sigma_y_mm=math.ceil(10 * math.sqrt(yy)) / 10,
        cov_xy_mm2=math.trunc(10 * xy) / 10,
    )
