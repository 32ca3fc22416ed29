"""The robot's body: differential drive on two front wheels, encoders and a gyro (seed 004).

The two motors answer the same command differently (``*_motor_gain``), which is why the seed's
robot drifted; the encoders see that, since they count wheel turns. Wheels whose real diameter
differs from the nominal one (``*_wheel_scale``) and random slip move the body without the
encoders knowing; only the gyro, the walls and UWB can tell. The gyro reads the true yaw rate
plus a constant bias and white noise, which is what seed 004 calibrates away.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, replace
from typing import TYPE_CHECKING, NamedTuple

import numpy as np
from pydantic import BaseModel, ConfigDict, Field

from coffeebot.sim.world.tof import SensorMount

if TYPE_CHECKING:
    from coffeebot.config import RobotConfig


class Pose(NamedTuple):
    """Floor-frame pose of the body centre: mm, and heading in degrees CCW from +x."""

    x_mm: float
    y_mm: float
    heading_deg: float


class RobotSpec(BaseModel):
    """The physical robot as the simulator needs it, independent of the daemon's config."""

    model_config = ConfigDict(frozen=True, extra="forbid")

    length_mm: float = Field(610.0, gt=0)
    width_mm: float = Field(510.0, gt=0)
    height_mm: float = Field(900.0, gt=0)
    ground_clearance_mm: float = Field(20.0, ge=0)
    wheel_base_mm: float = Field(450.0, gt=0)
    axle_x_mm: float = Field(150.0, description="driven axle ahead of the body centre")
    wheel_diameter_mm: float = Field(100.0, gt=0)
    ticks_per_rev: int = Field(360, gt=0)
    max_speed_mm_s: float = Field(1000.0, gt=0)
    max_accel_mm_s2: float = Field(500.0, gt=0)
    brake_mm_s2: float = Field(1000.0, gt=0, description="active braking on a stop line")
    left_motor_gain: float = Field(1.0, gt=0)
    right_motor_gain: float = Field(0.98, gt=0)
    left_wheel_scale: float = Field(1.0, gt=0)
    right_wheel_scale: float = Field(1.0, gt=0)
    slip_sigma: float = Field(0.005, ge=0, description="relative wheel slip per step")
    gyro_bias_dps: float = 0.5
    gyro_noise_dps: float = Field(0.2, ge=0)
    sensors: tuple[SensorMount, ...] = ()
    uwb_tag_mm: tuple[float, float, float] = (0.0, 0.0, 900.0)

    @classmethod
    def from_config(cls, config: RobotConfig, **overrides: object) -> RobotSpec:
        """The robot a board file describes: its sensors, body and wheels."""
        values: dict[str, object] = {
            "length_mm": config.geometry.length_mm,
            "width_mm": config.geometry.width_mm,
            "height_mm": config.geometry.height_mm,
            "wheel_base_mm": config.motor.wheel_base_mm,
            "axle_x_mm": config.motor.axle_x_mm,
            "wheel_diameter_mm": config.motor.wheel_diameter_mm,
            "ticks_per_rev": config.motor.ticks_per_rev,
            "max_speed_mm_s": config.motor.max_speed_mm_s,
            "max_accel_mm_s2": config.motor.max_accel_mm_s2,
            "brake_mm_s2": config.motor.brake_mm_s2,
            "sensors": tuple(
                SensorMount.model_validate(s, from_attributes=True)
                for s in sorted(config.tof.sensors, key=lambda s: s.id)
            ),
            **overrides,
        }
        return cls.model_validate(values)

    @property
    def ticks_per_mm(self) -> float:
        return self.ticks_per_rev / (math.pi * self.wheel_diameter_mm)


@dataclass(frozen=True)
class BodyState:
    """Ground truth of the body. Wheel speeds are motor outputs in nominal mm/s."""

    x: float
    y: float
    theta: float
    left_mm_s: float = 0.0
    right_mm_s: float = 0.0
    left_turned_mm: float = 0.0
    right_turned_mm: float = 0.0
    speed_mm_s: float = 0.0
    yaw_rate_rad_s: float = 0.0


class RobotBody:
    """Integrates the drive; the world decides whether a proposed motion is allowed."""

    def __init__(self, spec: RobotSpec, pose: Pose) -> None:
        self.spec = spec
        self.state = BodyState(pose.x_mm, pose.y_mm, math.radians(pose.heading_deg))
        self._target = (0.0, 0.0)
        self._ramp_mm_s2 = spec.max_accel_mm_s2

    @property
    def pose(self) -> Pose:
        s = self.state
        return Pose(s.x, s.y, math.degrees(s.theta))

    def place(self, pose: Pose) -> None:
        """Put the body somewhere at rest (start of a run, after an elevator ride)."""
        self.state = replace(
            self.state,
            x=pose.x_mm,
            y=pose.y_mm,
            theta=math.radians(pose.heading_deg),
            left_mm_s=0.0,
            right_mm_s=0.0,
            speed_mm_s=0.0,
            yaw_rate_rad_s=0.0,
        )

    def command(self, left_mm_s: float, right_mm_s: float, brake: bool = False) -> None:
        """Wheel speeds the motor controller drives towards, clamped to the motors' limit: on
        its ramp, or braking actively to a stop (``brake``, both speeds 0)."""
        limit = self.spec.max_speed_mm_s
        self._target = (
            max(-limit, min(limit, left_mm_s)),
            max(-limit, min(limit, right_mm_s)),
        )
        self._ramp_mm_s2 = self.spec.brake_mm_s2 if brake else self.spec.max_accel_mm_s2

    def propose(self, dt: float, rng: np.random.Generator) -> BodyState:
        """The state after ``dt`` seconds if nothing is in the way (arc model, exact)."""
        spec, s = self.spec, self.state
        step = self._ramp_mm_s2 * dt
        left = s.left_mm_s + max(-step, min(step, self._target[0] - s.left_mm_s))
        right = s.right_mm_s + max(-step, min(step, self._target[1] - s.right_mm_s))
        # Mean motor speed over the step: exact while accelerating uniformly.
        turn_l = (s.left_mm_s + left) / 2 * spec.left_motor_gain
        turn_r = (s.right_mm_s + right) / 2 * spec.right_motor_gain
        slip_l, slip_r = (1.0 + spec.slip_sigma * rng.standard_normal(2)).tolist()
        ground_l = turn_l * spec.left_wheel_scale * slip_l
        ground_r = turn_r * spec.right_wheel_scale * slip_r
        v = (ground_l + ground_r) / 2
        omega = (ground_r - ground_l) / spec.wheel_base_mm
        # The body turns about the driven axle, not its centre.
        a = spec.axle_x_mm
        ax, ay = s.x + a * math.cos(s.theta), s.y + a * math.sin(s.theta)
        theta = s.theta + omega * dt
        if abs(omega) < 1e-9:
            ax += v * dt * math.cos(s.theta)
            ay += v * dt * math.sin(s.theta)
        else:
            radius = v / omega
            ax += radius * (math.sin(theta) - math.sin(s.theta))
            ay -= radius * (math.cos(theta) - math.cos(s.theta))
        return BodyState(
            x=ax - a * math.cos(theta),
            y=ay - a * math.sin(theta),
            theta=math.remainder(theta, math.tau),
            left_mm_s=left,
            right_mm_s=right,
            left_turned_mm=s.left_turned_mm + turn_l * dt,
            right_turned_mm=s.right_turned_mm + turn_r * dt,
            speed_mm_s=v,
            yaw_rate_rad_s=omega,
        )

    def stall(self) -> None:
        """Blocked by contact: the body stays put and the wheels stop."""
        self.state = replace(
            self.state, left_mm_s=0.0, right_mm_s=0.0, speed_mm_s=0.0, yaw_rate_rad_s=0.0
        )

    @property
    def encoder_ticks(self) -> tuple[int, int]:
        """Cumulative quadrature counts of the left and right wheels."""
        k = self.spec.ticks_per_mm
        return (
            math.floor(self.state.left_turned_mm * k),
            math.floor(self.state.right_turned_mm * k),
        )

    @property
    def wheel_speeds_mm_s(self) -> tuple[float, float]:
        """Wheel surface speeds as the encoders see them (nominal diameter)."""
        s = self.state
        return s.left_mm_s * self.spec.left_motor_gain, s.right_mm_s * self.spec.right_motor_gain

    def gyro_z_dps(self, rng: np.random.Generator) -> float:
        """One gyro sample: true yaw rate plus bias and white noise, deg/s."""
        true_rate = math.degrees(self.state.yaw_rate_rad_s)
        return (
            true_rate + self.spec.gyro_bias_dps + self.spec.gyro_noise_dps * rng.standard_normal()
        )
