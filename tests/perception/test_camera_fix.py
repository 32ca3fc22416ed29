"""A ceiling camera's fix in the state estimate: placed, fused, gated, ignored."""

from __future__ import annotations

import math

import numpy as np
import pytest
from perception_helpers import BOARD_FILE, robot

from coffeebot.board import Board
from coffeebot.config import RobotConfig
from coffeebot.daemon import Daemon
from coffeebot.floorplan import load_floorplan
from coffeebot.messages import ALL_TOPICS, CAMERA_FIX, CURRENT_STATE, CameraFix, PoseEstimate
from coffeebot.modules.state import StateModule
from coffeebot.perception.particles import ParticlePoseFusion
from coffeebot.perception.state import StateEstimator, make_fusion

PLAN = load_floorplan(BOARD_FILE.parents[1] / "floorplans" / "cs-building.toml")
X, Y = 20000.0, -295.0
"""On floor 2's hallway centre line; the estimator starts on floor 2."""
PLACED_SIGMA_MM, PLACED_SIGMA_DEG = 50.0, 5.0
"""What ``StateEstimator.place`` gives the fusion."""


def config(fusion: str) -> RobotConfig:
    base = robot()
    return base.model_copy(update={"state": base.state.model_copy(update={"fusion": fusion})})


def estimator(fusion: str) -> StateEstimator:
    cfg = config(fusion)
    assert cfg.state.initial_floor == 2
    return StateEstimator(PLAN, cfg.motor, cfg.state, make_fusion(cfg, PLAN))


def fix(
    x: float = X,
    y: float = Y,
    heading: float = 0.0,
    *,
    sigma_mm: float = 30.0,
    sigma_deg: float = 2.0,
    floor: int = 2,
) -> CameraFix:
    return CameraFix(
        camera_id="lobby-2",
        floor=floor,
        x_mm=x,
        y_mm=y,
        heading_deg=heading,
        sigma_mm=sigma_mm,
        sigma_heading_deg=sigma_deg,
        fit_error_mm=4.0,
        points=40,
        track_id="t7",
    )


def gained(prior_sigma: float, fix_sigma: float) -> float:
    """The Kalman gain of one scalar fix on a scalar prior."""
    return prior_sigma**2 / (prior_sigma**2 + fix_sigma**2)


# --- the Kalman filter ----------------------------------------------------------------------


@pytest.mark.parametrize("sigma_mm", [5.0, 50.0, 200.0])
def test_the_kalman_filter_moves_to_a_fix_by_its_sigma(sigma_mm: float) -> None:
    state = estimator("ekf")
    state.place(X, Y, 0.0, 2)
    assert state.on_camera_fix(fix(X + 100.0, Y + 40.0, 4.0, sigma_mm=sigma_mm), 7.0)
    after = state.pose()
    k = gained(PLACED_SIGMA_MM, sigma_mm)
    assert after.x_mm == pytest.approx(X + k * 100.0, abs=0.01)
    assert after.y_mm == pytest.approx(Y + k * 40.0, abs=0.01)
    assert after.sigma_x_mm == pytest.approx(math.sqrt(1.0 - k) * PLACED_SIGMA_MM, rel=1e-6)
    assert after.sigma_y_mm == pytest.approx(math.sqrt(1.0 - k) * PLACED_SIGMA_MM, rel=1e-6)
    k_heading = gained(PLACED_SIGMA_DEG, 2.0)
    assert after.heading_deg == pytest.approx(k_heading * 4.0, abs=1e-6)
    assert after.sigma_heading_deg < PLACED_SIGMA_DEG
    assert state.stamps["camera"] == 7.0


def test_a_tight_fix_moves_the_kalman_filter_nearly_all_the_way_a_loose_one_little() -> None:
    moved = {}
    for sigma_mm in (5.0, 200.0):
        state = estimator("ekf")
        state.place(X, Y, 0.0, 2)
        assert state.on_camera_fix(fix(X + 100.0, sigma_mm=sigma_mm), 0.0)
        moved[sigma_mm] = state.pose().x_mm - X
    assert moved[5.0] > 95.0
    assert moved[200.0] < 10.0


def test_the_kalman_gate_rejects_a_fix_far_outside_it() -> None:
    state = estimator("ekf")
    state.place(X, Y, 0.0, 2)
    before = state.pose()
    assert not state.on_camera_fix(fix(X + 3000.0), 1.0)
    assert state.pose() == before  # position, heading and covariance
    assert "camera" not in state.stamps


# --- placing a fusion without a pose ---------------------------------------------------------


@pytest.mark.parametrize("fusion", ["ekf", "particles"])
def test_a_fusion_without_a_pose_is_placed_at_the_fix_on_its_floor(fusion: str) -> None:
    state = estimator(fusion)
    assert not state.fusion.initialised
    assert state.on_camera_fix(fix(12000.0, 200.0, 90.0, floor=3), 3.0)
    assert state.floor == 3
    placed = state.pose()
    assert placed.initialised and placed.floor == 3
    tolerance = 0.0 if fusion == "ekf" else 5.0  # the particles' mean of a 30 mm draw
    assert math.hypot(placed.x_mm - 12000.0, placed.y_mm - 200.0) <= tolerance
    assert placed.heading_deg == pytest.approx(90.0, abs=0.5)
    assert placed.sigma_x_mm == pytest.approx(30.0, rel=0.1)
    assert placed.sigma_heading_deg == pytest.approx(2.0, rel=0.1)
    if isinstance(state.fusion, ParticlePoseFusion):
        assert state.fusion.level == 3


def test_a_fix_for_a_floor_the_plan_does_not_have_places_nothing() -> None:
    state = estimator("ekf")
    assert not state.on_camera_fix(fix(floor=9), 0.0)
    assert not state.fusion.initialised and state.floor == 2


# --- the particle filter ---------------------------------------------------------------------


def test_a_fix_far_from_the_particle_cloud_is_not_used() -> None:
    """A robot that knows where it is is not carried 3 m off by one fix: it may be a wrong
    match, and the filter's own recovery finds a robot really kidnapped."""
    state = estimator("particles")
    state.place(X, Y, 0.0, 2)
    before = state.pose()
    assert not state.on_camera_fix(fix(X - 3000.0, Y, 180.0, sigma_mm=30.0), 0.0)
    assert state.pose() == before
    assert "camera" not in state.stamps


def test_a_fix_within_the_particle_cloud_is_weighed_not_reseeded() -> None:
    fusion = ParticlePoseFusion(PLAN, robot().tof, config("particles").state)
    fusion.change_floor(2)
    fusion.reset(X, Y, 0.0, PLACED_SIGMA_MM, PLACED_SIGMA_DEG)
    cloud = fusion.particles.copy()
    assert fusion.update_pose_fix(X + 40.0, Y, 0.0, 50.0, 5.0)
    # The same particles, weighed (no resample: half the cloud explains the fix) ...
    assert np.array_equal(fusion.particles, cloud)
    # ... to about the product of the two Gaussians: halfway, sigma / sqrt(2).
    x, y, _ = fusion.pose()
    assert x == pytest.approx(X + 20.0, abs=5.0)
    assert y == pytest.approx(Y, abs=5.0)
    sigma_x, sigma_y, _ = fusion.sigmas()
    assert sigma_x == pytest.approx(50.0 / math.sqrt(2.0), rel=0.1)
    assert sigma_y == pytest.approx(50.0 / math.sqrt(2.0), rel=0.1)


def test_a_fix_much_tighter_than_the_particle_cloud_pulls_it_onto_the_fix() -> None:
    fusion = ParticlePoseFusion(PLAN, robot().tof, config("particles").state)
    fusion.change_floor(2)
    fusion.reset(X, Y, 0.0, 100.0, PLACED_SIGMA_DEG)
    # 2.5 combined sigmas away: weighed, not re-seeded, and the fix's 5 mm wins.
    assert fusion.update_pose_fix(X + 250.0, Y, 0.0, 5.0, 1.0)
    x, y, heading = fusion.pose()
    assert math.hypot(x - (X + 250.0), y - Y) < 15.0
    assert max(fusion.sigmas()[:2]) < 15.0
    assert abs(heading) < 1.0


def test_a_fix_picks_the_mode_of_a_split_particle_cloud_it_agrees_with() -> None:
    fusion = ParticlePoseFusion(PLAN, robot().tof, config("particles").state)
    fusion.change_floor(2)
    fusion.reset(X, Y, 0.0, 50.0, PLACED_SIGMA_DEG)
    # A hallway's symmetry: a third of the particles 2 m back, facing the other way.
    third = len(fusion.particles) // 3
    fusion.particles[:third, 0] -= 2000.0
    fusion.particles[:third, 2] += math.pi
    assert fusion.pose()[0] == pytest.approx(X, abs=10.0)
    # The fix is 2 m from the estimate, but within the cloud: weighed, not re-seeded, so
    # the estimate lands between that mode and the fix, not on the fix.
    assert fusion.update_pose_fix(X - 1950.0, Y, 180.0, 50.0, 5.0)
    x, _, heading = fusion.pose()
    assert x == pytest.approx(X - 1975.0, abs=10.0)
    assert abs(math.remainder(heading - 180.0, 360.0)) < 3.0


# --- floors and sources ----------------------------------------------------------------------


@pytest.mark.parametrize("fusion", ["ekf", "particles"])
def test_a_fix_for_another_floor_is_ignored_while_tracking(fusion: str) -> None:
    state = estimator(fusion)
    state.place(X, Y, 0.0, 2)
    before = state.pose()
    assert not state.on_camera_fix(fix(X + 100.0, floor=3), 0.0)
    assert state.floor == 2
    assert state.pose() == before
    assert "camera" not in state.stamps


@pytest.mark.parametrize("fusion", ["ekf", "particles"])
async def test_the_state_module_publishes_the_camera_fix(fusion: str) -> None:
    board = Board(ALL_TOPICS)
    start = PoseEstimate(
        x_mm=X,
        y_mm=Y,
        heading_deg=0.0,
        floor=2,
        sigma_x_mm=PLACED_SIGMA_MM,
        sigma_y_mm=PLACED_SIGMA_MM,
        sigma_heading_deg=PLACED_SIGMA_DEG,
    )
    daemon = Daemon(board, [StateModule(config(fusion), PLAN, start=start)])
    await daemon.start()
    board.publish(CAMERA_FIX, fix(X + 60.0, Y + 20.0, sigma_mm=5.0))
    state = await board.next(CURRENT_STATE, timeout=1.0)
    await daemon.shutdown()
    assert "camera" in state.msg.sources
    pose = state.msg.pose
    assert pose.floor == 2
    assert math.hypot(pose.x_mm - (X + 60.0), pose.y_mm - (Y + 20.0)) < 10.0
