"""The VL53L1X as the world sees it: a cone of rays from a mounting pose, and its noise.

Each sensor casts a circular cone sampled as a small grid of rays (``rays_per_axis`` across
the field of view, corners outside the circle dropped). The reading is the nearest hit with
the seed's error model: +/-5 mm up close, growing noise and more invalid readings beyond
~1000 mm (mid-range mode), nothing beyond the range limit. A target that fills only a sliver
of the cone (a pole at its edge, a thin chair leg) returns a weak signal, so it is reported
only part of the time, as the seed saw with the swivel chair's pole.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from typing import NamedTuple

import numpy as np
from pydantic import BaseModel, ConfigDict, Field, field_validator

from coffeebot.messages import ReadingStatus
from coffeebot.sim.world.geometry import cast_rays

# Rays within this depth of the nearest hit count as the same target when judging coverage.
_TARGET_DEPTH_MM = 50.0


class SensorMount(BaseModel):
    """Where a sensor sits on the body: robot frame (x forward, y left), yaw CCW from +x."""

    model_config = ConfigDict(frozen=True, extra="ignore")

    x_mm: float
    y_mm: float
    yaw_deg: float
    height_mm: float = Field(250.0, gt=0)
    fov_deg: float = Field(27.0, ge=15, le=27)


class ToFModel(BaseModel):
    """Error model of one ranging; defaults follow seed 000 (mid-range mode)."""

    model_config = ConfigDict(frozen=True, extra="forbid")

    rays_per_axis: int = Field(5, ge=1, description="odd, so the centre ray exists")
    sigma_mm: float = Field(2.5, ge=0, description="+/-5 mm as two standard deviations")
    noisy_beyond_mm: float = Field(1000.0, gt=0)
    far_sigma_per_mm: float = Field(0.03, ge=0, description="extra sigma per mm beyond that")
    max_range_mm: float = Field(4000.0, gt=0)
    invalid_probability: float = Field(0.002, ge=0, le=1)
    far_invalid_per_m: float = Field(0.08, ge=0, description="extra invalid rate per metre")
    weak_target_fraction: float = Field(0.2, ge=0, le=1)
    weak_target_detect_probability: float = Field(0.5, ge=0, le=1)

    @field_validator("rays_per_axis")
    @classmethod
    def _odd(cls, value: int) -> int:
        if value % 2 == 0:
            raise ValueError("must be odd so that the cone has a centre ray")
        return value

    @classmethod
    def exact(cls, **overrides: float) -> ToFModel:
        """A noiseless sensor that always reports the nearest hit: for hand-computed tests."""
        values = {
            "sigma_mm": 0.0,
            "far_sigma_per_mm": 0.0,
            "invalid_probability": 0.0,
            "far_invalid_per_m": 0.0,
            "weak_target_detect_probability": 1.0,
            **overrides,
        }
        return cls.model_validate(values)


class ToFReading(NamedTuple):
    status: ReadingStatus
    distance_mm: int


class SensorArray:
    """Precomputed cone geometry for a set of mounts, cast from any robot pose at once."""

    def __init__(self, mounts: Sequence[SensorMount], model: ToFModel) -> None:
        self.mounts = tuple(mounts)
        self.model = model
        n = model.rays_per_axis
        unit = np.linspace(-1.0, 1.0, n) if n > 1 else np.zeros(1)
        self.cone_mask = unit[:, None] ** 2 + unit[None, :] ** 2 <= 1.0 + 1e-9  # (A, E)
        half = np.radians([m.fov_deg / 2 for m in self.mounts])[:, None]
        self._yaw = np.radians([m.yaw_deg for m in self.mounts])[:, None] + unit * half
        elevation = unit * half
        self._tan_el, self._cos_el = np.tan(elevation), np.cos(elevation)
        self._mx = np.array([m.x_mm for m in self.mounts])
        self._my = np.array([m.y_mm for m in self.mounts])
        self._mz = np.array([m.height_mm for m in self.mounts])

    @property
    def rays_per_sensor(self) -> int:
        return int(self.cone_mask.sum())

    def ranges(
        self, x: float, y: float, theta: float, segments: np.ndarray, cylinders: np.ndarray
    ) -> np.ndarray:
        """(sensors, rays) ranges in mm from a robot pose (theta in rad); ``inf``: no hit."""
        c, s = math.cos(theta), math.sin(theta)
        origins = np.stack([x + c * self._mx - s * self._my, y + s * self._mx + c * self._my], 1)
        hits = cast_rays(
            segments, cylinders, origins, self._mz, theta + self._yaw, self._tan_el, self._cos_el
        )
        return hits[:, self.cone_mask]

    def measure(self, ranges: np.ndarray, rng: np.random.Generator) -> list[ToFReading]:
        """Turn per-ray ranges of some sensors into readings with the error model."""
        m = self.model
        nearest = ranges.min(axis=1)
        target = ranges <= nearest[:, None] + _TARGET_DEPTH_MM
        background = np.where(target, np.inf, ranges).min(axis=1)
        weak = target.mean(axis=1) < m.weak_target_fraction
        missed = weak & (rng.random(len(ranges)) >= m.weak_target_detect_probability)
        true = np.where(missed, background, nearest)
        far = np.maximum(np.nan_to_num(true, posinf=0.0) - m.noisy_beyond_mm, 0.0)
        sigma = m.sigma_mm + m.far_sigma_per_mm * far
        noisy = np.rint(np.maximum(true + rng.normal(0.0, 1.0, len(true)) * sigma, 0.0))
        invalid = rng.random(len(true)) < m.invalid_probability + m.far_invalid_per_m * far / 1000
        readings = []
        for distance, bad in zip(noisy, invalid, strict=True):
            if not distance <= m.max_range_mm:
                readings.append(ToFReading(ReadingStatus.NO_TARGET, 0))
            elif bad:
                readings.append(ToFReading(ReadingStatus.SIGMA_FAIL, int(distance)))
            else:
                readings.append(ToFReading(ReadingStatus.VALID, int(distance)))
        return readings
