"""How likely one ToF scan is from each particle's pose: the particle filter's sensor model.

A VL53L1X does not report the range along its axis: it reports one distance for everything
in its ~27 degree cone (today's simulator: the nearest return; the real part: a
signal-weighted blend of what the cone sees). So a valid reading of ``r`` says "at range
``r`` there is a surface somewhere across the cone": its end point is taken at ``cone_points``
directions across the cone, and the one nearest a wall of the plan is the reading's miss
distance ``d`` (likelihood field, Thrun et al. ch. 6.4, with the cone's arc instead of one
ray). Each reading's likelihood is a mixture, so that a person, a blended reading of a chair
leg and the wall behind it, or a door the plan has closed cannot veto a pose:

    p(r) = z_hit N(d; 0, sigma(r)) + z_short lambda e^(-lambda r) + z_random / max_range

``sigma(r)`` grows with the range (the cone's footprint and the sensor's noise both do).
"No target" readings (nothing within range) are a discrete outcome: likely where the plan has
no wall inside the cone's range, unlikely where it has one. Readings with any other status,
from an unhealthy sensor, beyond the range or with too weak a signal say nothing and are
skipped. Every number is in ``[state.particles]``, to be re-tuned when the sensor model is.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from coffeebot.config import ParticleFilterConfig, TofSensorConfig
from coffeebot.messages import RangeReading, RangeScan, ReadingStatus
from coffeebot.perception.likelihood_field import LikelihoodField

NO_TARGET = (ReadingStatus.NO_TARGET, ReadingStatus.OUT_OF_BOUNDS)


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
        steps = max(1, math.floor(self.max_range_mm / cfg.no_target_step_mm))
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
        self._tan_half = np.tan(np.radians([m.fov_deg / 2 for m in mounts]))

    def _arc(self, mount: TofSensorConfig) -> np.ndarray:
        half = math.radians(mount.fov_deg / 2)
        if self.cfg.cone_points == 1:
            return np.zeros(1)
        return np.linspace(-half, half, self.cfg.cone_points)

    def usable(self, reading: RangeReading) -> bool:
        """Whether a reading says anything about the pose."""
        if not reading.healthy or reading.sensor not in self.mounts:
            return False
        rate = reading.signal_rate_mcps
        if rate is not None and rate < self.cfg.min_signal_rate_mcps:
            return False
        if reading.status in NO_TARGET:
            return True
        return (
            reading.status is ReadingStatus.VALID
            and reading.distance_mm is not None
            and 0 < reading.distance_mm <= self.max_range_mm
        )

    def sigma_mm(self, range_mm: np.ndarray) -> np.ndarray:
        return self.cfg.sigma_hit_mm + self.cfg.sigma_hit_per_m * range_mm / 1000.0

    def hit_likelihood(self, miss_mm: np.ndarray, range_mm: np.ndarray) -> np.ndarray:
        """p(r) of valid readings of ``range_mm`` whose end points miss the plan by ``miss_mm``
        (densities per mm; broadcasts)."""
        sigma = self.sigma_mm(range_mm)
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
        clear = [r for r in readings if r.status in NO_TARGET]
        log_p = np.zeros(n)
        log_fit = np.zeros(n)
        x, y = particles[:, 0:1], particles[:, 1:2]
        c, s = np.cos(particles[:, 2:3]), np.sin(particles[:, 2:3])
        if valid:
            rows = [self._row[rd.sensor] for rd in valid]
            r = np.array([float(rd.distance_mm or 0) for rd in valid])
            mx, my = self._mx[rows], self._my[rows]
            ox, oy = x + c * mx - s * my, y + s * mx + c * my  # (N, V)
            ac, asn = self._arc_cos[rows] * r[:, None], self._arc_sin[rows] * r[:, None]
            c3, s3 = c[:, :, None], s[:, :, None]
            ex = ox[:, :, None] + c3 * ac - s3 * asn  # (N, V, A)
            ey = oy[:, :, None] + s3 * ac + c3 * asn
            miss = field(ex.ravel(), ey.ravel()).reshape(ex.shape).min(axis=2)  # (N, V)
            p = np.log(self.hit_likelihood(miss, r[None, :]))
            best = np.log(self.hit_likelihood(np.zeros_like(r), r))
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
            wall = (near < t * self._tan_half[rows][None, :, None]).any(axis=2)  # (N, W)
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
