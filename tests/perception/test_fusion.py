"""Seed 004 odometry, the complementary filter, and the EKF's use of each source."""

from __future__ import annotations

import itertools
import math

import numpy as np
import pytest
from perception_helpers import robot

from coffeebot.config import StateConfig
from coffeebot.messages import Odometry
from coffeebot.perception.fusion import EkfPoseFusion, Odometer, OdometryStep
from coffeebot.perception.geometry import wrap_deg
from coffeebot.sim.world.robot import Pose, RobotBody, RobotSpec

CFG = StateConfig(gyro_calibration_samples=5)
MOTOR = robot().motor
TICKS_PER_MM = MOTOR.ticks_per_rev / (math.pi * MOTOR.wheel_diameter_mm)


def odo(t_ms: int, left_mm: float, right_mm: float, gyro: float) -> Odometry:
    return Odometry(
        controller_time_ms=t_ms,
        left_ticks=round(left_mm * TICKS_PER_MM),
        right_ticks=round(right_mm * TICKS_PER_MM),
        gyro_z_dps=gyro,
        left_mm_s=0,
        right_mm_s=0,
    )


def test_gyro_offset_and_noise_band_calibrated_at_rest() -> None:
    o = Odometer(MOTOR, CFG)
    for k, rate in enumerate([0.5, 0.6, 0.4, 0.5, 0.5, 0.5]):
        o.step(odo(20 * k, 0, 0, rate))
    assert o.gyro_offset_dps == pytest.approx(0.5)
    assert o.gyro_noise_dps == pytest.approx(0.1)


def test_encoders_on_straights_gyro_in_turns() -> None:
    o = Odometer(MOTOR, CFG)
    for k in range(6):
        o.step(odo(20 * k, 0, 0, 0.5))
    # Straight: the encoders say no turn, the gyro's 3 dps is ignored (drift on straights).
    straight = o.step(odo(1100, 1000, 1000, 3.5))
    assert straight is not None and straight.heading_change_deg == pytest.approx(0, abs=0.1)
    assert straight.distance_mm == pytest.approx(1000, abs=2)
    # Turning: encoders slip (say 90 deg), the gyro says 80 deg; the blend follows the gyro.
    wb = MOTOR.wheel_base_mm
    arc = math.radians(90) * wb / 2
    turn = o.step(odo(2100, 1000 - arc, 1000 + arc, 80.5))
    assert turn is not None
    assert turn.heading_change_deg == pytest.approx(0.98 * 80 + 0.02 * 90, abs=0.3)


def test_ekf_averages_uwb_noise_down_with_odometry() -> None:
    rng = np.random.default_rng(2)
    ekf = EkfPoseFusion(StateConfig())
    ekf.reset(0, 0, 0, 200, 2)
    errors = []
    for k in range(1, 300):
        ekf.predict(OdometryStep(10.0, 0.0, 0.1))
        ekf.update_position(10.0 * k + rng.normal(0, 100), rng.normal(0, 100), 100)
        errors.append(math.hypot(ekf.pose()[0] - 10.0 * k, ekf.pose()[1]))
    assert np.sqrt(np.mean(np.square(errors[100:]))) < 50
    assert ekf.sigmas()[0] < 50


def test_ekf_rejects_a_wild_fix_then_reseeds_when_lost() -> None:
    ekf = EkfPoseFusion(StateConfig(uwb_max_rejected=3))
    ekf.reset(0, 0, 0, 50, 2)
    assert not ekf.update_position(5000, 0, 100)
    assert ekf.pose()[0] == 0
    ekf.update_position(5000, 0, 100)
    ekf.update_position(5000, 0, 100)
    assert ekf.pose()[0] == 5000


def test_ekf_heading_and_offset_updates() -> None:
    ekf = EkfPoseFusion(StateConfig())
    ekf.reset(1000, 0, 3.0, 100, 3)
    assert ekf.update_heading(0.0, 0.3)
    assert abs(ekf.pose()[2]) < 0.2
    assert ekf.update_offset(0.0, -80.0, 20.0)  # a door says: 80 mm less along +x
    assert ekf.pose()[0] == pytest.approx(920, abs=10)
    assert ekf.update_offset(90.0, 50.0, 20.0)  # a wall says: 50 mm further left
    assert ekf.pose()[1] == pytest.approx(47, abs=5)


def _turn_on_the_spot(
    rate_dps: float, turn_deg: float, *, lag_every: int = 0
) -> tuple[float, float]:
    """(true, odometry) heading change of the simulated body turning on the spot, sampled at
    50 Hz like the motor controller. ``lag_every``: every n-th message is taken before the
    world has stepped (the world then catches up), as when the simulation runs behind."""
    spec = RobotSpec.from_config(robot())
    body = RobotBody(spec, Pose(0.0, 0.0, 0.0))
    rng = np.random.default_rng(4)
    odometer = Odometer(MOTOR, StateConfig())
    period_ms, physics_s = 20, 0.005
    owed = 0

    def message(k: int) -> OdometryStep | None:
        nonlocal owed
        owed += 4
        if not (lag_every and k % lag_every == 0):
            for _ in range(owed):
                body.state = body.propose(physics_s, rng)
            owed = 0
        left, right = body.encoder_ticks
        sample = Odometry(
            controller_time_ms=k * period_ms,
            left_ticks=left,
            right_ticks=right,
            gyro_z_dps=body.gyro_z_dps(rng),
            left_mm_s=0,
            right_mm_s=0,
        )
        return odometer.step(sample)

    ticks = itertools.count(1)
    for _ in range(50):  # at rest: the gyro calibrates
        message(next(ticks))
    start, total = body.state.theta, 0.0
    wheel = math.radians(rate_dps) * spec.wheel_base_mm / 2
    body.command(-wheel, wheel)
    for _ in range(round(turn_deg / rate_dps * 1000 / period_ms)):
        step = message(next(ticks))
        total += step.heading_change_deg if step else 0.0
    body.command(0.0, 0.0)
    for _ in range(50):
        step = message(next(ticks))
        total += step.heading_change_deg if step else 0.0
    return math.degrees(body.state.theta - start), total


@pytest.mark.parametrize("rate_dps", [2.0, 4.0, 8.0, 45.0])
def test_a_turn_on_the_spot_is_counted_whole_at_any_rate(rate_dps: float) -> None:
    # One tick of difference in a 20 ms step reads as 5.5 deg/s: a slow turn shows as steps
    # with and without a tick, and each source alone must still add up to the whole turn.
    true, counted = _turn_on_the_spot(rate_dps, 90.0)
    assert true == pytest.approx(90.0, abs=3.0)
    assert counted == pytest.approx(true, abs=1.5)


def test_a_turn_sampled_before_the_world_stepped_is_counted_whole() -> None:
    # Every third message repeats the last encoder counts while the gyro reads the turn.
    true, counted = _turn_on_the_spot(45.0, 180.0, lag_every=3)
    assert counted == pytest.approx(true, abs=2.0)


def test_wall_angles_correct_the_heading_after_a_turn_on_the_spot() -> None:
    # Odometry counts 171 of a true 180 degree turn on the spot (5 % short, as a gyro's scale
    # error would); the walls then say where the robot really faces.
    ekf = EkfPoseFusion(StateConfig())
    ekf.reset(1000, 0, 0.0, 30, 1.0)
    for _ in range(180):
        ekf.predict(OdometryStep(0.0, 171.0 / 180, 0.02, MOTOR.axle_x_mm))
    assert ekf.sigmas()[2] > 3.0
    accepted = [ekf.update_heading(180.0, 1.0) for _ in range(5)]
    assert all(accepted)
    assert abs(wrap_deg(ekf.pose()[2] - 180.0)) < 1.0
