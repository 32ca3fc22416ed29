"""Where a floor point shows in a ceiling camera's image, and back.

A camera looking straight down maps each horizontal plane to its image by a homography: the
floor (``plane_mm`` 0) for what lies on it, the plane of a robot's top for the robot's
outline. The nominal homography follows from the camera's pose and lens in the floor plan
(a pinhole); a calibrated one comes from floor marks (:mod:`coffeebot.cameras.calibration`).
Off the camera's nadir a tall object's top shows further out than its footprint, by
``height / (camera height - height)`` of its distance from the nadir: 25 % for a robot's
800 mm top under a camera at 4 m, so positions are read on the plane of what is seen.
"""

from __future__ import annotations

import math

import numpy as np

from coffeebot.floorplan.features import Camera


def focal_px(camera: Camera) -> float:
    """The pinhole's focal length in pixels, from the horizontal field of view."""
    return camera.width_px / 2 / math.tan(math.radians(camera.fov_deg) / 2)


def mm_per_px(camera: Camera, plane_mm: float = 0.0) -> float:
    """Size of a pixel on the plane ``plane_mm`` above the floor (12.5 mm on the floor for
    the seed's camera)."""
    return (camera.height_mm - plane_mm) / focal_px(camera)


def nominal_homography(camera: Camera, plane_mm: float = 0.0) -> np.ndarray:
    """3 x 3 homography from floor-frame (x, y, 1) on the plane ``plane_mm`` high to pixel
    (u, v, 1), from the camera's pose and lens alone."""
    if plane_mm >= camera.height_mm:
        raise ValueError(f"a plane {plane_mm:.0f} mm high is not below camera {camera.id!r}")
    k = 1.0 / mm_per_px(camera, plane_mm)
    yaw = math.radians(camera.yaw_deg)
    c, s = math.cos(yaw), math.sin(yaw)
    # Image +u along the yaw; image +v (rows, downwards) 90 degrees clockwise of it.
    rotate = np.array([[c, s], [s, -c]])
    offset = -rotate @ np.array([camera.x_mm, camera.y_mm])
    centre = np.array([camera.width_px / 2, camera.height_px / 2])
    h = np.eye(3)
    h[:2, :2] = k * rotate
    h[:2, 2] = k * offset + centre
    return h


def project(homography: np.ndarray, points: np.ndarray) -> np.ndarray:
    """Apply a homography to (N, 2) points."""
    pts = np.asarray(points, dtype=float).reshape(-1, 2)
    ones = np.ones((pts.shape[0], 1))
    mapped = np.hstack([pts, ones]) @ homography.T
    return mapped[:, :2] / mapped[:, 2:3]


def to_plane(homography: np.ndarray, pixels: np.ndarray) -> np.ndarray:
    """Pixels (N, 2) back to the plane the homography maps from."""
    return project(np.linalg.inv(homography), pixels)


def raise_plane(homography: np.ndarray, camera: Camera, plane_mm: float) -> np.ndarray:
    """The homography of the plane ``plane_mm`` above the floor, from the floor's (nominal
    or calibrated): the same view scaled about the camera's nadir by the heights' ratio.
    The nadir is where the homography itself puts the image's centre, not the surveyed
    position: with calibrated marks, the marks know better where the lens hangs."""
    ratio = camera.height_mm / (camera.height_mm - plane_mm)
    centre = np.array([[camera.width_px / 2, camera.height_px / 2]])
    nadir = to_plane(homography, centre)[0]
    scale = np.eye(3)
    scale[:2, :2] *= ratio
    scale[:2, 2] = nadir * (1.0 - ratio)
    return homography @ scale
