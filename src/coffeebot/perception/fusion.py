"""One pose estimate from odometry, UWB, wall angle, wall distance and door landmarks.

Two pieces, kept apart so the fusion method can be swapped without touching odometry:

* :class:`Odometer` turns motor-controller telemetry into (distance, heading change) steps
  with seed 004's rules: the encoder arc model for distance; gyro offset and noise band
  calibrated at rest; encoder heading on straights, a complementary blend weighted to the gyro
  in turns (where wheels slip).
* :class:`PoseFusion` is the protocol the state module talks to; :class:`EkfPoseFusion`
  implements it as an extended Kalman filter over (x, y, heading). Every absolute source is
  one of three measurement kinds: a position (UWB), a heading (wall angle), or a position
  offset along a direction (door landmarks along the hallway, wall distance across it).
  The particle filter (:mod:`~coffeebot.perception.particles`) implements it too, and also
  reads the raw range scans.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass
from typing import Protocol

import numpy as np

from coffeebot.config import MotorConfig, StateConfig
from coffeebot.messages import Odometry, RangeScan
from coffeebot.perception.geometry import wrap_deg

CHI2_1DOF_999 = 10.83
"""Gate for one-dimensional landmark innovations (99.9 %)."""


@dataclass(frozen=True)
class OdometryStep:
    """Motion between two telemetry messages: distance travelled and heading change."""

    distance_mm: float
    heading_change_deg: float
    dt_s: float
    axle_x_mm: float = 0.0
    """Where the driven axle sits ahead of the body centre: the body turns about it, so a
    turn on the spot moves the centre sideways."""

    @property
    def speed_mm_s(self) -> float:
        return self.distance_mm / self.dt_s if self.dt_s > 0 else 0.0

    @property
    def yaw_rate_dps(self) -> float:
        return self.heading_change_deg / self.dt_s if self.dt_s > 0 else 0.0


class Odometer:
    """Seed 004 dead reckoning from cumulative encoder ticks and gyro rate."""

    def __init__(self, motor: MotorConfig, cfg: StateConfig) -> None:
        self.cfg = cfg
        self.mm_per_tick = math.pi * motor.wheel_diameter_mm / motor.ticks_per_rev
        self.wheel_base_mm = motor.wheel_base_mm
        self.axle_x_mm = motor.axle_x_mm
        self._last: Odometry | None = None
        self._rest_samples: list[float] = []
        self.gyro_offset_dps: float | None = None
        self.gyro_noise_dps = 0.0

    def _gyro_rate(self, raw_dps: float, at_rest: bool) -> float | None:
        """Offset-corrected gyro rate inside the noise band zeroed (seed 004 eq. 13-15)."""
        if self.gyro_offset_dps is None:
            if at_rest:
                self._rest_samples.append(raw_dps)
                if len(self._rest_samples) >= self.cfg.gyro_calibration_samples:
                    samples = np.array(self._rest_samples)
                    self.gyro_offset_dps = float(samples.mean())
                    self.gyro_noise_dps = float(np.abs(samples - samples.mean()).max())
            return None
        rate = raw_dps - self.gyro_offset_dps
        return 0.0 if abs(rate) <= self.gyro_noise_dps else rate

    def step(self, odo: Odometry) -> OdometryStep | None:
        """The motion since the previous message (None for the first one)."""
        last, self._last = self._last, odo
        if last is None:
            return None
        dt = (odo.controller_time_ms - last.controller_time_ms) / 1000.0
        if dt <= 0:
            return None
        left = (odo.left_ticks - last.left_ticks) * self.mm_per_tick
        right = (odo.right_ticks - last.right_ticks) * self.mm_per_tick
        at_rest = left == 0 and right == 0
        gyro = self._gyro_rate(odo.gyro_z_dps, at_rest)
        # Seed 004 eq. 3: alpha = (r - l) / W, from the arc both wheels travel.
        encoder_turn = math.degrees((right - left) / self.wheel_base_mm)
        turn = encoder_turn
        # Whether the robot is turning is the gyro's call, not this step's encoder counts:
        # those are whole ticks (one tick of difference in a 20 ms step reads as 5.5 deg/s)
        # and may not have moved since the last message, so judging on them picks steps by
        # their rounding and drops the gyro's turn on the others (a slow turn lost half of
        # itself). Either source alone sums to the whole turn.
        if gyro is not None and abs(gyro) > self.cfg.turn_rate_dps:
            w = self.cfg.gyro_weight
            turn = w * gyro * dt + (1.0 - w) * encoder_turn
        return OdometryStep((left + right) / 2.0, turn, dt, self.axle_x_mm)


class PoseFusion(Protocol):
    """What the state module needs from a fusion method."""

    @property
    def initialised(self) -> bool: ...

    def reset(
        self, x_mm: float, y_mm: float, heading_deg: float, sigma_mm: float, sigma_deg: float
    ) -> None: ...

    def predict(self, step: OdometryStep) -> None: ...

    def update_position(self, x_mm: float, y_mm: float, sigma_mm: float) -> bool: ...

    def update_heading(self, heading_deg: float, sigma_deg: float) -> bool: ...

    def update_offset(self, direction_deg: float, offset_mm: float, sigma_mm: float) -> bool:
        """The position projected on ``direction_deg`` is off by ``offset_mm``."""
        ...

    def pose(self) -> tuple[float, float, float]:
        """(x mm, y mm, heading deg)."""
        ...

    def sigmas(self) -> tuple[float, float, float]:
        """1-sigma of x (mm), y (mm) and heading (deg)."""
        ...

    def covariance(self) -> np.ndarray:
        """3x3 covariance of (x mm, y mm, heading deg)."""
        ...

    def update_ranges(
        self,
        scan: RangeScan,
        shut_doors: frozenset[str] = frozenset(),
        others: Sequence[np.ndarray] = (),
    ) -> bool:
        """A ToF scan against the floor plan (False: not used); ``shut_doors``: the elevator
        doors on this floor known shut, the plan's leaf and nothing behind it; ``others``:
        the outlines (4, 4: sides) of the fleet's other robots standing on this floor, grown
        by ``[state.particles] robot_margin_mm``, which the plan does not have."""
        ...

    def change_floor(self, level: int) -> None:
        """The robot is now on floor ``level``."""
        ...

    def summary(self) -> ParticleSummary | None:
        """Particle count and effective sample size; None for a Kalman filter."""
        ...

    def cloud(self, points: int) -> np.ndarray | None:
        """Up to ``points`` samples (x mm, y mm, heading deg) to draw; None: no samples."""
        ...


@dataclass(frozen=True)
class ParticleSummary:
    count: int
    effective_sample_size: float


class EkfPoseFusion:
    """Extended Kalman filter over (x, y, heading in rad) with a unicycle motion model."""

    def __init__(self, cfg: StateConfig) -> None:
        self.cfg = cfg
        self.x = np.zeros(3)
        self.P = np.diag([1e12, 1e12, math.pi**2])
        self._initialised = False
        self._rejected_fixes = 0

    @property
    def initialised(self) -> bool:
        return self._initialised

    def reset(
        self, x_mm: float, y_mm: float, heading_deg: float, sigma_mm: float, sigma_deg: float
    ) -> None:
        self.x = np.array([x_mm, y_mm, math.radians(heading_deg)])
        self.P = np.diag([sigma_mm**2, sigma_mm**2, math.radians(sigma_deg) ** 2])
        self._initialised = True
        self._rejected_fixes = 0

    def predict(self, step: OdometryStep) -> None:
        ds, dth = step.distance_mm, math.radians(step.heading_change_deg)
        th0 = self.x[2]
        th = th0 + dth / 2.0
        c, s = math.cos(th), math.sin(th)
        # The body turns about the driven axle, ``a`` ahead of the centre.
        a, c0, s0, c1, s1 = (
            step.axle_x_mm,
            math.cos(th0),
            math.sin(th0),
            math.cos(th0 + dth),
            math.sin(th0 + dth),
        )
        self.x = self.x + np.array([ds * c - a * (c1 - c0), ds * s - a * (s1 - s0), dth])
        self.x[2] = math.remainder(self.x[2], math.tau)
        F = np.array(
            [
                [1.0, 0.0, -ds * s + a * (s1 - s0)],
                [0.0, 1.0, ds * c - a * (c1 - c0)],
                [0.0, 0.0, 1.0],
            ]
        )
        G = np.array([[c, -ds * s / 2.0], [s, ds * c / 2.0], [0.0, 1.0]])
        sigma_ds = self.cfg.encoder_sigma_fraction * abs(ds) + 0.1
        sigma_dth = math.radians(self.cfg.heading_sigma_deg_per_m * abs(ds) / 1000.0) + 1e-5
        # Turning loses heading too, on the spot as much as on the move: without this a turn
        # left the heading as certain as before, and wall angles that disagreed with an
        # odometry error from the turn failed the gate for ever.
        var_turn = math.radians(self.cfg.heading_sigma_deg_per_rad_turned) ** 2 * abs(dth)
        Q = G @ np.diag([sigma_ds**2, sigma_dth**2 + var_turn]) @ G.T
        self.P = F @ self.P @ F.T + Q

    def _update(self, innovation: np.ndarray, H: np.ndarray, R: np.ndarray, gate: float) -> bool:
        S = H @ self.P @ H.T + R
        S_inv = np.linalg.inv(S)
        if float(innovation @ S_inv @ innovation) > gate:
            return False
        K = self.P @ H.T @ S_inv
        self.x = self.x + K @ innovation
        self.x[2] = math.remainder(self.x[2], math.tau)
        identity = np.eye(3)
        # Joseph form: stays symmetric and positive through many small updates.
        self.P = (identity - K @ H) @ self.P @ (identity - K @ H).T + K @ R @ K.T
        return True

    def update_position(self, x_mm: float, y_mm: float, sigma_mm: float) -> bool:
        if not self._initialised:
            self.reset(x_mm, y_mm, math.degrees(self.x[2]), sigma_mm, 180.0)
            return True
        H = np.array([[1.0, 0.0, 0.0], [0.0, 1.0, 0.0]])
        innovation = np.array([x_mm, y_mm]) - self.x[:2]
        gate = self.cfg.uwb_gate_sigma**2
        if self._update(innovation, H, np.eye(2) * sigma_mm**2, gate):
            self._rejected_fixes = 0
            return True
        self._rejected_fixes += 1
        if self._rejected_fixes >= self.cfg.uwb_max_rejected:
            # Persistently far from every fix: the estimate is lost, not the fixes wrong.
            sigma_deg = math.degrees(math.sqrt(self.P[2, 2]))
            self.reset(x_mm, y_mm, math.degrees(self.x[2]), sigma_mm, sigma_deg)
        return False

    def update_heading(self, heading_deg: float, sigma_deg: float) -> bool:
        H = np.array([[0.0, 0.0, 1.0]])
        innovation = np.array([math.radians(wrap_deg(heading_deg - math.degrees(self.x[2])))])
        R = np.array([[math.radians(sigma_deg) ** 2]])
        return self._update(innovation, H, R, CHI2_1DOF_999)

    def update_offset(self, direction_deg: float, offset_mm: float, sigma_mm: float) -> bool:
        u = math.radians(direction_deg)
        H = np.array([[math.cos(u), math.sin(u), 0.0]])
        return self._update(np.array([offset_mm]), H, np.array([[sigma_mm**2]]), CHI2_1DOF_999)

    def pose(self) -> tuple[float, float, float]:
        return float(self.x[0]), float(self.x[1]), math.degrees(self.x[2])

    def sigmas(self) -> tuple[float, float, float]:
        d = np.sqrt(np.maximum(np.diag(self.P), 0.0))
        return float(d[0]), float(d[1]), math.degrees(d[2])

    def covariance(self) -> np.ndarray:
        scale = np.array([1.0, 1.0, math.degrees(1.0)])
        return self.P * np.outer(scale, scale)

    def update_ranges(
        self,
        scan: RangeScan,
        shut_doors: frozenset[str] = frozenset(),
        others: Sequence[np.ndarray] = (),
    ) -> bool:
        """The Kalman filter sees the walls through the angle and door modules instead."""
        return False

    def change_floor(self, level: int) -> None:
        """Floors share one frame and the car stands still: nothing changes."""

    def summary(self) -> ParticleSummary | None:
        return None

    def cloud(self, points: int) -> np.ndarray | None:
        return None
