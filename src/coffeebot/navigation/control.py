"""The motion controller's arithmetic: speed profile, lane keeping, turning, wheel speeds.

Speeds are planned, then rate-limited: the profile's target is the highest speed from which
the robot can still slow to what the next point needs (approach speed before a door, zero at
the stop) with ``accel_mm_s2``; the command then moves towards that target by at most
``accel * dt`` per control period, so the motors never see a step. The motor controller
ramps at its own (higher) limit, so the profile, not the ramp, decides where the robot stops.

Heading is held on the fused pose heading, which is odometry (encoders and gyro, seed 004)
corrected by the wall angle (seed 000's angle correction) in the state module. Lane keeping
steers towards a heading that closes the lateral error at a bounded angle.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

from coffeebot.config import MotionConfig
from coffeebot.perception.geometry import wrap_deg


@dataclass(frozen=True)
class SpeedProfile:
    """Trapezoidal speed along a path with an approach speed before its end."""

    accel_mm_s2: float
    creep_mm_s: float
    stop_band_mm: float
    """Remaining distance counted as "there": a quarter of the stop tolerance."""

    @classmethod
    def from_config(cls, cfg: MotionConfig) -> SpeedProfile:
        return cls(cfg.accel_mm_s2, cfg.creep_speed_mm_s, cfg.stop_tolerance_mm / 4.0)

    def target(
        self,
        remaining_mm: float,
        cruise_mm_s: float,
        *,
        stop: bool = True,
        approach_mm: float = 0.0,
        approach_mm_s: float | None = None,
    ) -> float:
        """The speed to aim for with ``remaining_mm`` to go (zero once there, if stopping)."""
        a = self.accel_mm_s2
        v = cruise_mm_s
        if approach_mm_s is not None and approach_mm > 0:
            ahead = max(0.0, remaining_mm - approach_mm)
            v = min(v, math.sqrt(approach_mm_s**2 + 2.0 * a * ahead))
        if stop:
            if remaining_mm <= self.stop_band_mm:
                return 0.0
            v = min(
                v, max(self.creep_mm_s, math.sqrt(2.0 * a * (remaining_mm - self.stop_band_mm)))
            )
        return max(0.0, v)

    def step(self, current_mm_s: float, target_mm_s: float, dt_s: float) -> float:
        """Move the command towards ``target`` by at most one period's acceleration."""
        limit = self.accel_mm_s2 * dt_s
        return current_mm_s + max(-limit, min(limit, target_mm_s - current_mm_s))


def lane_heading_deg(travel_deg: float, lateral_error_mm: float, cfg: MotionConfig) -> float:
    """Heading that steers back onto the lane: ``lateral_error`` is lane minus position,
    positive to the left of travel.

    It aims at the lane point ``lane_lookahead_mm`` ahead. Linearised, the lateral error then
    obeys ``e'' + h e' + (v h / L) e = 0`` (``h`` the heading gain, ``L`` the lookahead), so
    the default 800 mm keeps the loop well damped at cruise speed (about 0.9) instead of
    weaving on every centimetre of pose noise."""
    offset = math.degrees(math.atan2(lateral_error_mm, cfg.lane_lookahead_mm))
    return travel_deg + max(-cfg.max_lane_angle_deg, min(cfg.max_lane_angle_deg, offset))


def turn_rate_dps(heading_deg: float, wanted_deg: float, cfg: MotionConfig) -> float:
    """Proportional heading hold, limited to the configured turn rate."""
    error = wrap_deg(wanted_deg - heading_deg)
    rate = cfg.heading_gain * error
    return max(-cfg.max_turn_rate_dps, min(cfg.max_turn_rate_dps, rate))


def ramp(current: float, target: float, limit_per_step: float) -> float:
    return current + max(-limit_per_step, min(limit_per_step, target - current))


def wheel_speeds(v_mm_s: float, yaw_rate_dps: float, wheel_base_mm: float) -> tuple[float, float]:
    """Differential drive: left and right wheel speeds for a forward speed and yaw rate."""
    half = math.radians(yaw_rate_dps) * wheel_base_mm / 2.0
    return v_mm_s - half, v_mm_s + half
