"""Heading against the hallway from a side's sensor pair (seed 000 "angle correction").

Seed rules: measure only inside the floor plan's marked angle zones, only from a side whose
two sensors both read below 850 mm, never while an obstacle is present; angles below 5 degrees
are reported as zero correction. The seed's Situation 4 (a closed door under the front sensor,
19 degrees measured as 36) shows what goes wrong at a door. Beyond the seed, a pair is dropped
when any of these says its rays are not on flat wall:

* the floor plan: a door recess or opening lies under either sensor's cone footprint, widened
  by the pose's along-hallway uncertainty;
* the pose prior: the angle is further from the pose's heading than the gate;
* the other side: when both walls are in range, the two sides must agree;
* the plan's wall line: the measured distance to the wall must be where the plan puts it.

Accepted scans are averaged (each as a residual against the pose heading, so turning between
scans does not blur the average) and a window whose scans disagree is thrown away. Each
emitted angle carries a sigma and a confidence derived from it.
"""

from __future__ import annotations

import math
import statistics
from collections.abc import Iterable
from dataclasses import dataclass, field

from coffeebot.config import AngleConfig, TofSensorConfig
from coffeebot.floorplan import Floor, Side
from coffeebot.messages import AngleEstimate, PoseEstimate, RangeScan
from coffeebot.perception.geometry import (
    SidePair,
    TravelFrame,
    sensor_origin,
    side_pairs,
    valid_distance,
    wrap_deg,
)

RANGE_SIGMA_MM = 5.0
"""VL53L1X ranging accuracy (+/-5 mm) used for the model part of an angle's sigma."""

UNKNOWN_HEADING_SIGMA_DEG = 30.0
"""A pose heading this uncertain is no prior at all: the gate is not applied."""


def pair_angle_deg(delta_mm: float, baseline_mm: float, half_fov_deg: float) -> float | None:
    """Angle of a sensor pair to a flat wall from the difference of its two readings.

    ``delta_mm`` is the front reading minus the rear one, signed so that a positive angle
    turns the front away from the wall. With ``half_fov_deg`` = 0 a reading is the distance
    along the optical axis (``delta = L tan(angle)``); with h > 0 it is the nearest return
    within h of the axis, so up to h it is the perpendicular distance (``delta = L sin``) and
    beyond it ``delta = L sin(a) / cos(a - h)``.
    """
    k = delta_mm / baseline_mm
    h = math.radians(half_fov_deg)
    if abs(k) <= math.sin(h):
        return math.degrees(math.asin(k))
    denominator = 1.0 - abs(k) * math.sin(h)
    if denominator <= 0:
        return None
    return math.copysign(math.degrees(math.atan(abs(k) * math.cos(h) / denominator)), k)


def perpendicular_mm(reading_mm: float, angle_deg: float, half_fov_deg: float) -> float:
    """Perpendicular sensor-to-wall distance for a reading taken at ``angle_deg`` to the wall."""
    off_axis = max(0.0, abs(angle_deg) - half_fov_deg)
    return reading_mm * math.cos(math.radians(off_axis))


@dataclass(frozen=True)
class Rejection:
    """Why a scan gave no angle (kept for tests, the bench and the debug log)."""

    reason: str


@dataclass(frozen=True)
class _Sample:
    time_s: float
    residual_deg: float
    sides: tuple[Side, ...]
    wall_distance_mm: dict[Side, float]


@dataclass
class _Window:
    zone: str = ""
    samples: list[_Sample] = field(default_factory=list)


class AngleEstimator:
    """Feed it every scan with the current pose; it returns an estimate once a window is full."""

    def __init__(
        self, sensors: Iterable[TofSensorConfig], cfg: AngleConfig, half_fov_deg: float = 0.0
    ) -> None:
        self.cfg = cfg
        self.half_fov_deg = half_fov_deg
        """The ranging model (``TofConfig.effective_half_fov_deg``)."""
        self.pairs = side_pairs(sensors)
        self._window = _Window()

    def reset(self) -> None:
        self._window = _Window()

    def _side_angle(
        self,
        pair: SidePair,
        scan: dict[int, int | None],
        pose: PoseEstimate,
        frame: TravelFrame,
        prior_deg: float,
    ) -> tuple[float, float] | Rejection:
        """One side's (angle, centre-to-wall distance) for this scan, or why not."""
        cfg = self.cfg
        front, rear = scan.get(pair.front.id), scan.get(pair.rear.id)
        if front is None or rear is None:
            return Rejection(f"{pair.side}: no valid reading")
        if max(front, rear) >= cfg.max_side_distance_mm:
            return Rejection(f"{pair.side}: wall beyond {cfg.max_side_distance_mm:.0f} mm")
        # Right side: turning left (positive) takes the front sensor away from the wall.
        delta = front - rear if pair.side == "right" else rear - front
        angle = pair_angle_deg(delta, pair.baseline_mm, self.half_fov_deg)
        if angle is None:
            return Rejection(f"{pair.side}: readings inconsistent with a flat wall")
        # The plan: no door recess or opening under either cone, pose uncertainty included.
        along_sigma = max(pose.sigma_x_mm, pose.sigma_y_mm)
        hall_side = frame.hallway_side(pair.side)
        for sensor, reading in ((pair.front, front), (pair.rear, rear)):
            sx, sy, look = sensor_origin(pose.x_mm, pose.y_mm, pose.heading_deg, sensor)
            hit_x = sx + reading * math.cos(math.radians(look))
            hit_y = sy + reading * math.sin(math.radians(look))
            half_fov = math.radians(sensor.fov_deg / 2)
            off_axis = math.radians(min(abs(angle), 60.0))
            footprint = reading * (math.tan(off_axis + half_fov) - math.tan(off_axis))
            margin = footprint + cfg.footprint_margin_mm + 2.0 * along_sigma
            feature = frame.floor.feature_at(frame.along(hit_x, hit_y), hall_side, margin)
            if feature is not None:
                return Rejection(f"{pair.side}: sensor {sensor.id} cone on {feature.id}")
        wall = perpendicular_mm((front + rear) / 2, angle, self.half_fov_deg)
        wall += pair.offset_mm * math.cos(math.radians(angle))
        lateral = frame.lateral(pose.x_mm, pose.y_mm)
        expected = frame.floor.hallway.width_mm / 2 + (
            lateral if pair.side == "right" else -lateral
        )
        lateral_sigma = max(pose.sigma_x_mm, pose.sigma_y_mm)
        if pose.initialised and abs(wall - expected) > 100.0 + 3.0 * lateral_sigma:
            return Rejection(f"{pair.side}: wall at {wall:.0f} mm, plan says {expected:.0f} mm")
        if pose.sigma_heading_deg < UNKNOWN_HEADING_SIGMA_DEG:
            gate = max(cfg.prior_gate_deg, 3.0 * pose.sigma_heading_deg)
            if abs(angle - prior_deg) > gate:
                return Rejection(
                    f"{pair.side}: {angle:.1f} deg is {abs(angle - prior_deg):.1f} deg "
                    f"from the pose heading"
                )
        return angle, wall

    def update(
        self,
        scan: RangeScan,
        scan_seq: int,
        pose: PoseEstimate | None,
        floor: Floor | None,
        obstacle: bool,
        time_s: float,
    ) -> AngleEstimate | Rejection:
        """Add one scan; an :class:`AngleEstimate` when a window completes, else why not."""
        cfg = self.cfg
        if pose is None or floor is None:
            return Rejection("no pose")
        zone = floor.angle_zone_at(pose.x_mm, pose.y_mm)
        if zone is None:
            self.reset()
            return Rejection("outside the angle zones")
        if obstacle:
            return Rejection("obstacle present")
        if zone.id != self._window.zone:
            self._window = _Window(zone.id)
        frame = TravelFrame.for_heading(floor, pose.heading_deg)
        prior = frame.angle_deg(pose.heading_deg)
        # A reading the chip is unsure of (a weak or blended return) is no wall to measure.
        distances = {
            r.sensor: valid_distance(r)
            if r.sigma_mm is None or r.sigma_mm <= cfg.max_sigma_mm
            else None
            for r in scan.readings
        }
        found: dict[Side, tuple[float, float]] = {}
        reasons: list[str] = []
        for side, pair in self.pairs.items():
            result = self._side_angle(pair, distances, pose, frame, prior)
            if isinstance(result, Rejection):
                reasons.append(result.reason)
            else:
                found[side] = result
        if not found:
            return Rejection("; ".join(reasons))
        angles = [a for a, _ in found.values()]
        if max(angles) - min(angles) > cfg.side_agreement_deg:
            return Rejection(f"sides disagree: {angles[0]:.1f} vs {angles[1]:.1f} deg")
        window = self._window
        window.samples = [s for s in window.samples if time_s - s.time_s <= cfg.max_window_s]
        window.samples.append(
            _Sample(
                time_s,
                wrap_deg(statistics.fmean(angles) - prior),
                tuple(found),
                {side: wall for side, (_, wall) in found.items()},
            )
        )
        if len(window.samples) < cfg.scans_per_estimate:
            return Rejection(f"collecting {len(window.samples)}/{cfg.scans_per_estimate}")
        samples, window.samples = window.samples, []
        return self._estimate(samples, scan_seq, zone.id, frame, pose)

    def _estimate(
        self,
        samples: list[_Sample],
        scan_seq: int,
        zone: str,
        frame: TravelFrame,
        pose: PoseEstimate,
    ) -> AngleEstimate | Rejection:
        cfg = self.cfg
        median = statistics.median(s.residual_deg for s in samples)
        kept = [s for s in samples if abs(s.residual_deg - median) <= cfg.scan_outlier_deg]
        if 2 * len(kept) <= len(samples):
            return Rejection("scans in the window disagree")
        residual = statistics.fmean(s.residual_deg for s in kept)
        angle = wrap_deg(frame.angle_deg(pose.heading_deg) + residual)
        # Model sigma of one pair (two +/-5 mm readings over the baseline), reduced by the
        # number of independent pairs; the scatter of the scans bounds it from below.
        baseline = min(p.baseline_mm for p in self.pairs.values())
        pairs_used = sum(len(s.sides) for s in kept)
        model = math.degrees(math.sqrt(2.0) * RANGE_SIGMA_MM / baseline) / math.sqrt(pairs_used)
        scatter = (
            statistics.stdev(s.residual_deg for s in kept) / math.sqrt(len(kept))
            if len(kept) > 1
            else model
        )
        sigma = max(model, scatter)
        confidence = (len(kept) / len(samples)) / (1.0 + sigma * sigma)
        sides = {side for s in kept for side in s.sides}
        last = kept[-1]
        return AngleEstimate(
            scan_seq=scan_seq,
            zone=zone,
            side="both" if len(sides) == 2 else next(iter(sides)),
            angle_deg=angle,
            correction_deg=0.0 if abs(angle) < cfg.min_angle_deg else -angle,
            heading_deg=wrap_deg(frame.direction_deg + angle),
            confidence=confidence,
            sigma_deg=sigma,
            scans=len(kept),
            wall_distance_mm=last.wall_distance_mm,
        )
