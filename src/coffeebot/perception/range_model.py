"""How likely one ToF scan is from each particle's pose: the particle filter's sensor model.

A VL53L1X reports one distance for everything in its ~27 degree cone: the signal-weighted
mean of the path lengths its returns took (docs/sensor-model.md). On a flat wall that lands
near where the optical axis meets it; where one side of the cone is much nearer (a wall at a
slant, a door jamb), nearer the cone's edge, since a surface's signal falls with the square
of its distance. So a valid reading of ``r`` says "at range ``r`` there is a surface
somewhere across the middle of the cone": its end point is taken at ``cone_points``
directions within ``arc_half_deg`` of the axis, and the one nearest a wall of the plan is the
reading's miss distance ``d`` (likelihood field, Thrun et al. ch. 6.4, with an arc instead of
one ray). Each reading's likelihood is a mixture, so that a person, a blend of a chair leg
and the wall behind it, or a door the plan has closed cannot veto a pose:

    p(r) = z_hit N(d; 0, sigma) + z_short lambda e^(-lambda r) + z_random / max_range
    sigma^2 = (sigma_hit_mm + sigma_hit_per_m r)^2 + reported sigma^2

The first term of ``sigma`` is how far the blend lands from the arc's nearest point; the
chip's own sigma (its shot noise, widened by the spread of depths it blended) carries the
rest, so a far blend of a grazing wall weighs little.

"Nothing in range" (the chip's signal fail: too little light came back; out of bounds; no
target) is a discrete outcome: likely where the plan has no surface within
``no_target_range_mm`` inside ``no_target_half_deg`` of the axis (nearer than that, a painted
wall returns enough light to be ranged), unlikely where it has one. A sigma fail (something
far or dark, nobody knows where), a reading from an unhealthy sensor, beyond the range or with
too weak a signal says nothing and is skipped. Every number is in ``[state.particles]``.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from coffeebot.config import ParticleFilterConfig, TofSensorConfig
from coffeebot.messages import RangeReading, RangeScan, ReadingStatus
from coffeebot.perception.likelihood_field import LikelihoodField

NOTHING_RANGED = (ReadingStatus.NO_TARGET, ReadingStatus.OUT_OF_BOUNDS, ReadingStatus.SIGNAL_FAIL)
"""Statuses that say the cone holds no surface the chip could range."""


@dataclass(frozen=True)
class ScanLikelihood:
    """Per particle: the scan's log-likelihood (each reading raised to ``reading_weight``)
    and its fit, the mean over readings of log(p / best possible p), 0 for a perfect match."""

    log_likelihood: np.ndarray
    log_fit: np.ndarray
    readings: int


class RangeModel:
    """The mixture above for a fixed set of sensor mounts, vectorised over particles."""

    def __init__(
        self, sensors: Sequence[TofSensorConfig], max_range_mm: float, cfg: ParticleFilterConfig
    ) -> None:
        self.cfg = cfg
        self.max_range_mm = float(max_range_mm)
        self.mounts = {s.id: s for s in sensors}
        total = cfg.z_hit + cfg.z_short + cfg.z_random
        self.z_hit, self.z_short, self.z_random = (
            cfg.z_hit / total,
            cfg.z_short / total,
            cfg.z_random / total,
        )
        reach = min(cfg.no_target_range_mm, self.max_range_mm)
        steps = max(1, math.floor(reach / cfg.no_target_step_mm))
        self._march = cfg.no_target_step_mm * np.arange(1, steps + 1)
        # Per sensor id, once: mount offsets, and the cosines and sines of the arc's
        # directions in the robot frame, so a scan costs no trigonometry per particle.
        ids = sorted(self.mounts)
        self._row = {sensor: k for k, sensor in enumerate(ids)}
        mounts = [self.mounts[i] for i in ids]
        self._mx = np.array([m.x_mm for m in mounts])
        self._my = np.array([m.y_mm for m in mounts])
        arc = np.stack([math.radians(m.yaw_deg) + self._arc(m) for m in mounts])  # (S, A)
        self._arc_cos, self._arc_sin = np.cos(arc), np.sin(arc)
        yaw = np.radians([m.yaw_deg for m in mounts])
        self._yaw_cos, self._yaw_sin = np.cos(yaw), np.sin(yaw)
        half = [min(cfg.no_target_half_deg, m.fov_deg / 2) for m in mounts]
        self._tan_half = np.tan(np.radians(half))

    def _arc(self, mount: TofSensorConfig) -> np.ndarray:
        half = math.radians(min(self.cfg.arc_half_deg, mount.fov_deg / 2))
        if self.cfg.cone_points == 1:
            return np.zeros(1)
        return np.linspace(-half, half, self.cfg.cone_points)

    def usable(self, reading: RangeReading) -> bool:
        """Whether a reading says anything about the pose."""
        if not reading.healthy or reading.sensor not in self.mounts:
            return False
        if reading.status in NOTHING_RANGED:
            return True
        rate = reading.signal_rate_mcps
        return (
            reading.status is ReadingStatus.VALID
            and reading.distance_mm is not None
            and 0 < reading.distance_mm <= self.max_range_mm
            and (rate is None or rate >= self.cfg.min_signal_rate_mcps)
            and (reading.sigma_mm is None or math.isfinite(reading.sigma_mm))
        )

    def sigma_mm(self, range_mm: np.ndarray, reported_mm: np.ndarray | float = 0.0) -> np.ndarray:
        """The hit term's 1-sigma for readings of ``range_mm`` the chip gave ``reported_mm``."""
        model = self.cfg.sigma_hit_mm + self.cfg.sigma_hit_per_m * range_mm / 1000.0
        return np.hypot(model, reported_mm)

    def hit_likelihood(
        self, miss_mm: np.ndarray, range_mm: np.ndarray, reported_mm: np.ndarray | float = 0.0
    ) -> np.ndarray:
        """p(r) of valid readings of ``range_mm`` (reported sigma ``reported_mm``) whose end
        points miss the plan by ``miss_mm`` (densities per mm; broadcasts)."""
        sigma = self.sigma_mm(range_mm, reported_mm)
        hit = np.exp(-0.5 * (miss_mm / sigma) ** 2) / (math.sqrt(2 * math.pi) * sigma)
        lam = self.cfg.short_decay_per_m / 1000.0
        short = lam * np.exp(-lam * range_mm)
        return self.z_hit * hit + self.z_short * short + self.z_random / self.max_range_mm

    def evaluate(
        self, field: LikelihoodField, scan: RangeScan, particles: np.ndarray
    ) -> ScanLikelihood:
        """The scan's likelihood from each particle pose ((N, 3): x mm, y mm, heading rad)."""
        n = len(particles)
        readings = [r for r in scan.readings if self.usable(r)]
        valid = [r for r in readings if r.status is ReadingStatus.VALID]
        clear = [r for r in readings if r.status in NOTHING_RANGED]
        log_p = np.zeros(n)
        log_fit = np.zeros(n)
        x, y = particles[:, 0:1], particles[:, 1:2]
        c, s = np.cos(particles[:, 2:3]), np.sin(particles[:, 2:3])
        if valid:
            rows = [self._row[rd.sensor] for rd in valid]
            r = np.array([float(rd.distance_mm or 0) for rd in valid])
            reported = np.array([rd.sigma_mm or 0.0 for rd in valid])
            mx, my = self._mx[rows], self._my[rows]
            ox, oy = x + c * mx - s * my, y + s * mx + c * my  # (N, V)
            ac, asn = self._arc_cos[rows] * r[:, None], self._arc_sin[rows] * r[:, None]
            c3, s3 = c[:, :, None], s[:, :, None]
            ex = ox[:, :, None] + c3 * ac - s3 * asn  # (N, V, A)
            ey = oy[:, :, None] + s3 * ac + c3 * asn
            miss = field(ex.ravel(), ey.ravel()).reshape(ex.shape).min(axis=2)  # (N, V)
            p = np.log(self.hit_likelihood(miss, r[None, :], reported[None, :]))
            best = np.log(self.hit_likelihood(np.zeros_like(r), r, reported))
            log_p += p.sum(axis=1)
            log_fit += (p - best[None, :]).sum(axis=1)
        if clear:
            rows = [self._row[rd.sensor] for rd in clear]
            mx, my = self._mx[rows], self._my[rows]
            ox, oy = x + c * mx - s * my, y + s * mx + c * my  # (N, W)
            yc, ys = self._yaw_cos[rows], self._yaw_sin[rows]
            ux, uy = c * yc - s * ys, s * yc + c * ys  # axis directions (N, W)
            t = self._march[None, None, :]  # (1, 1, J)
            px = ox[:, :, None] + t * ux[:, :, None]
            py = oy[:, :, None] + t * uy[:, :, None]
            near = field.nearest(px.ravel(), py.ravel()).reshape(px.shape)
            width = np.maximum(t * self._tan_half[rows][None, :, None], field.resolution_mm)
            wall = (near < width).any(axis=2)  # (N, W)
            cfg = self.cfg
            p = np.log(np.where(wall, cfg.no_target_when_wall, cfg.no_target_when_clear))
            best = math.log(max(cfg.no_target_when_wall, cfg.no_target_when_clear))
            log_p += p.sum(axis=1)
            log_fit += (p - best).sum(axis=1)
        count = len(valid) + len(clear)
        return ScanLikelihood(
            log_likelihood=self.cfg.reading_weight * log_p,
            log_fit=log_fit / count if count else log_fit,
            readings=count,
        )
