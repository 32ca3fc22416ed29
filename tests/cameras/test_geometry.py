"""The pinhole view of a ceiling camera: floor to pixel and back, and tall objects."""

from __future__ import annotations

import numpy as np
import pytest

from coffeebot.cameras.geometry import (
    mm_per_px,
    nominal_homography,
    project,
    raise_plane,
    to_plane,
)
from coffeebot.floorplan import Camera

SEED = Camera(id="lab", x_mm=2000.0, y_mm=1500.0, height_mm=4000.0)
"""The seed's camera: 320 x 240 px from 4 m, over a 4 m x 3 m patch of floor."""


def test_the_seeds_camera_sees_4_by_3_m_at_12_5_mm_a_pixel() -> None:
    assert mm_per_px(SEED) == pytest.approx(12.5, abs=0.01)
    h = nominal_homography(SEED)
    corners = project(h, np.array([[0.0, 3000.0], [4000.0, 0.0]]))
    np.testing.assert_allclose(corners, [[0.0, 0.0], [320.0, 240.0]], atol=0.2)


def test_a_turned_camera_maps_back_to_the_same_floor_point() -> None:
    turned = SEED.model_copy(update={"yaw_deg": 73.0, "x_mm": -500.0})
    h = nominal_homography(turned)
    floor = np.array([[-500.0, 1500.0], [300.0, 900.0], [-1800.0, 2400.0]])
    np.testing.assert_allclose(to_plane(h, project(h, floor)), floor, atol=1e-6)
    np.testing.assert_allclose(project(h, floor[:1]), [[160.0, 120.0]], atol=1e-6)


def test_a_robots_top_shows_further_out_than_its_footprint() -> None:
    """800 mm up under a camera at 4 m: 25 % further from the nadir on the image."""
    floor_h = nominal_homography(SEED)
    top_h = raise_plane(floor_h, SEED, 800.0)
    np.testing.assert_allclose(top_h, nominal_homography(SEED, 800.0), atol=1e-9)
    seen = to_plane(floor_h, project(top_h, np.array([[3000.0, 1500.0]])))
    np.testing.assert_allclose(seen, [[3250.0, 1500.0]], atol=1e-6)


def test_a_calibrated_view_is_raised_about_its_own_nadir_not_the_surveyed_one() -> None:
    """The lens hangs 100 mm from where the plan says: the marks' homography knows it, and
    a robot's top is placed from there (about the surveyed point it was ~50 mm off)."""
    hung = SEED.model_copy(update={"x_mm": SEED.x_mm + 100.0})
    calibrated = nominal_homography(hung)
    np.testing.assert_allclose(
        raise_plane(calibrated, SEED, 800.0), nominal_homography(hung, 800.0), atol=1e-9
    )
