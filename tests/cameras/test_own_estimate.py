"""A robot's own estimate as the cameras take it: from the state module's pose, tied to the
robot's odometry path at its moment, and over the broker onto the fleet's time base."""

from __future__ import annotations

from pathlib import Path

import pytest

from coffeebot.cameras.odometry_path import PosePath
from coffeebot.cameras.own_estimate import OwnEstimate
from coffeebot.config import load_robot_config
from coffeebot.fleet.camera_link import CameraLink
from coffeebot.messages import Odometry, PoseEstimate

ROOT = Path(__file__).resolve().parents[2]
CONFIG = load_robot_config(ROOT / "boards" / "coffeebot-v1.toml")
POSE = PoseEstimate(
    x_mm=41000.0,
    y_mm=-300.0,
    heading_deg=180.0,
    floor=2,
    sigma_x_mm=20.0,
    sigma_y_mm=12.0,
    sigma_heading_deg=1.0,
    cov_xy_mm2=-30.0,
)


def test_the_estimate_carries_the_poses_covariance_and_none_before_it_is_localized() -> None:
    own = OwnEstimate.of(POSE, 5.0)
    assert own is not None
    assert own.place == (2, 41000.0, -300.0)
    assert own.covariance_mm2 == ((400.0, -30.0), (-30.0, 144.0))
    assert OwnEstimate.of(POSE.model_copy(update={"initialised": False}), 5.0) is None


def test_it_is_tied_to_the_odometry_point_of_its_moment_and_to_nothing_outside_the_path() -> None:
    path = PosePath(keep_s=10.0)
    for k in range(11):
        path.add_pose(k * 0.1, 100.0 * k, 0.0, 0.0)  # 1 m/s along x
    own = OwnEstimate.of(POSE, 0.55)
    assert own is not None
    tied = own.on(path, slack_s=0.1)
    assert tied is not None
    assert tied.odometry_xy == pytest.approx((550.0, 0.0))
    assert tied.floor_xy == (41000.0, -300.0)
    late = OwnEstimate.of(POSE, 1.5)
    assert late is not None and late.on(path, slack_s=0.1) is None
    early = OwnEstimate.of(POSE, -0.5)
    assert early is not None and early.on(path, slack_s=0.1) is None


def standing(t_ms: int) -> Odometry:
    """The motor controller's telemetry of a robot standing still."""
    return Odometry(
        controller_time_ms=t_ms,
        left_ticks=0,
        right_ticks=0,
        gyro_z_dps=0.0,
        left_mm_s=0.0,
        right_mm_s=0.0,
    )


def test_a_batch_carries_the_estimate_on_the_fleets_time_base_its_sigmas_never_tighter() -> None:
    link = CameraLink(CONFIG)
    for k in range(30):
        link.take(standing(20 * k), 0.02 * k)
    pose = POSE.model_copy(update={"sigma_x_mm": 17.34, "sigma_y_mm": 10.01})
    batch = link.batch(offset_s=1000.0, estimate=OwnEstimate.of(pose, 0.5))
    assert batch is not None and batch.estimate is not None
    sample = batch.estimate
    assert sample.t_s == pytest.approx(1000.5)
    assert (sample.floor, sample.x_mm, sample.y_mm) == (2, 41000.0, -300.0)
    assert (sample.sigma_x_mm, sample.sigma_y_mm, sample.cov_xy_mm2) == (17.4, 10.1, -30.0)


def test_a_robot_not_localized_sends_its_path_without_an_estimate() -> None:
    link = CameraLink(CONFIG)
    for k in range(30):
        link.take(standing(20 * k), 0.02 * k)
    batch = link.batch(offset_s=0.0, estimate=None)
    assert batch is not None and batch.estimate is None
