"""A robot's dead-reckoned path as identification reads it: interpolated at frame times,
its heading unwrapped, kept for a bounded time."""

from __future__ import annotations

import math

import numpy as np
import pytest

from coffeebot.cameras.odometry_path import OdometryPath
from coffeebot.config import MotorConfig, StateConfig
from coffeebot.messages import Odometry

MOTOR = MotorConfig(port="sim://motor")
TICKS_PER_MM = MOTOR.ticks_per_rev / (math.pi * MOTOR.wheel_diameter_mm)


def telemetry(t_s: float, left_mm: float, right_mm: float, speed_mm_s: float) -> Odometry:
    return Odometry(
        controller_time_ms=round(t_s * 1000),
        left_ticks=round(left_mm * TICKS_PER_MM),
        right_ticks=round(right_mm * TICKS_PER_MM),
        gyro_z_dps=0.0,
        left_mm_s=speed_mm_s,
        right_mm_s=speed_mm_s,
    )


def straight_path(seconds: float, speed_mm_s: float = 500.0, keep_s: float = 10.0) -> OdometryPath:
    path = OdometryPath(MOTOR, StateConfig(), keep_s=keep_s)
    for k in range(round(seconds * 50) + 1):
        t = k / 50
        path.add(telemetry(t, speed_mm_s * t, speed_mm_s * t, speed_mm_s), t)
    return path


def test_a_straight_drive_is_read_back_at_any_time_between_samples() -> None:
    path = straight_path(4.0)
    poses = path.at(np.array([1.0, 2.51, 3.0]))
    assert poses[:, 0] == pytest.approx([500.0, 1255.0, 1500.0], abs=5.0)
    assert np.abs(poses[:, 1]).max() < 5.0
    latest = path.latest
    assert latest is not None and latest[0] == 4.0
    assert latest[1][0] == pytest.approx(2000.0, abs=5.0)


def test_it_covers_a_window_only_from_its_first_sample_to_near_its_last() -> None:
    path = straight_path(4.0)
    assert path.covers(0.0, 4.0, slack_s=0.1)
    assert path.covers(1.0, 4.08, slack_s=0.1)
    assert not path.covers(1.0, 4.2, slack_s=0.1)
    assert not path.covers(-0.5, 3.0, slack_s=0.1)


def test_only_the_last_keep_s_is_kept() -> None:
    path = straight_path(20.0, keep_s=5.0)
    assert not path.covers(10.0, 20.0, slack_s=0.1)
    assert path.covers(15.0, 20.0, slack_s=0.1)


def test_a_heading_through_plus_minus_180_is_interpolated_the_short_way() -> None:
    path = OdometryPath(MOTOR, StateConfig(), keep_s=60.0)
    # Turning on the spot to the left: the right wheel forwards, the left back.
    for k in range(0, 20 * 50 + 1):
        t = k / 50
        arc = 150.0 * t
        path.add(telemetry(t, -arc, arc, 150.0), t)
    times = np.linspace(0.0, 20.0, 401)
    headings = path.at(times)[:, 2]
    assert np.all(np.diff(headings) > 0)  # unwrapped: never jumps back by a turn
    assert headings[-1] - headings[0] > math.pi  # it went past +-180 degrees
    with pytest.raises(ValueError, match="no odometry"):
        OdometryPath(MOTOR, StateConfig(), keep_s=1.0).at(times)
