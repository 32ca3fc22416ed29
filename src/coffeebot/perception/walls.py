"""Where a reading can come from when the floor plan's walls explain it.

A reading is the signal-weighted mean of what a cone sees, so on its own it only says that
something lies somewhere on the arc the cone spans at that range. When the robot knows where
it is, the plan says more: the rays of the cone that meet a wall of the plan at about that
range are where the return comes from. A front sensor toed out towards the hallway's side
wall sees that wall (or a door jamb in it) diagonally ahead; explained, the return lies on
the wall beside the corridor, not in it. A reading no wall explains (a leg in front of the
wall reads nearer than the wall) keeps its whole arc.
"""

from __future__ import annotations

import math
from collections.abc import Callable

import numpy as np

from coffeebot.config import TofSensorConfig
from coffeebot.floorplan import Floor
from coffeebot.messages import PoseEstimate
from coffeebot.perception.geometry import sensor_origin, wrap_deg

RAYS = 15
"""Rays across the (widened) cone when asking which of them meet a wall."""


def wall_ranges(
    floor: Floor, x_mm: float, y_mm: float, angles: np.ndarray, reach_mm: float = math.inf
) -> np.ndarray:
    """Range from (x, y) to the first plan wall along each ray, inf where there is none
    within ``reach_mm`` (the walls whose bounding box lies beyond it are not cast at all:
    the question is asked every scan, and few of a floor's walls are ever that close)."""
    seg = floor.segment_array
    if math.isfinite(reach_mm) and seg.size:
        box = floor.segment_bounds
        close = (
            (box[:, 0] <= x_mm + reach_mm)
            & (box[:, 2] >= x_mm - reach_mm)
            & (box[:, 1] <= y_mm + reach_mm)
            & (box[:, 3] >= y_mm - reach_mm)
        )
        seg = seg[close]
    if seg.size == 0:
        return np.full(np.shape(angles), math.inf)
    dx, dy = np.cos(angles)[:, None], np.sin(angles)[:, None]
    ex, ey = (seg[:, 2] - seg[:, 0])[None, :], (seg[:, 3] - seg[:, 1])[None, :]
    wx, wy = (seg[:, 0] - x_mm)[None, :], (seg[:, 1] - y_mm)[None, :]
    denom = dx * ey - dy * ex
    with np.errstate(divide="ignore", invalid="ignore"):
        t = (wx * ey - wy * ex) / denom
        u = (wx * dy - wy * dx) / denom
    hit = (np.abs(denom) > 1e-9) & (t > 0) & (u >= 0) & (u <= 1) & (t <= reach_mm)
    return np.where(hit, t, math.inf).min(axis=1)


def explained_points(
    floor: Floor,
    pose: PoseEstimate,
    sensor: TofSensorConfig,
    distance_mm: float,
    tolerance_mm: float,
    slack_deg: float,
) -> np.ndarray | None:
    """Robot-frame points (k, 2) where rays of ``sensor``'s cone, widened by ``slack_deg``
    for the pose's heading error, meet a plan wall within ``tolerance_mm`` of the reading's
    range; None when no wall explains it."""
    sx, sy, look = sensor_origin(pose.x_mm, pose.y_mm, pose.heading_deg, sensor)
    half = sensor.fov_deg / 2.0 + slack_deg
    offsets = np.radians(np.linspace(-half, half, RAYS))
    ranges = wall_ranges(floor, sx, sy, math.radians(look) + offsets, distance_mm + tolerance_mm)
    near = np.abs(ranges - distance_mm) <= tolerance_mm
    if not near.any():
        return None
    bearing = math.radians(sensor.yaw_deg) + offsets[near]
    return np.stack(
        [
            sensor.x_mm + ranges[near] * np.cos(bearing),
            sensor.y_mm + ranges[near] * np.sin(bearing),
        ],
        axis=1,
    )


Explainer = Callable[[TofSensorConfig, int], "np.ndarray | None"]
"""Where the plan's walls put a sensor's reading (robot-frame points), or None."""

MAX_HEADING_SIGMA_DEG = 5.0
"""A pose heading less certain than this places no reading on the plan's walls."""


def trusted(pose: PoseEstimate) -> bool:
    """Whether ``pose`` is good enough to place readings on the plan's walls."""
    return pose.initialised and pose.sigma_heading_deg <= MAX_HEADING_SIGMA_DEG


def carried(
    pose: PoseEstimate, forward_mm: float, left_mm: float, turned_rad: float
) -> PoseEstimate:
    """``pose`` moved on by a displacement in its own robot frame (dead reckoning)."""
    h = math.radians(pose.heading_deg)
    c, s = math.cos(h), math.sin(h)
    return pose.model_copy(
        update={
            "x_mm": pose.x_mm + c * forward_mm - s * left_mm,
            "y_mm": pose.y_mm + s * forward_mm + c * left_mm,
            "heading_deg": wrap_deg(pose.heading_deg + math.degrees(turned_rad)),
        }
    )


def explainer(floor: Floor, pose: PoseEstimate, tolerance_mm: float) -> Explainer | None:
    """Wall explanations from ``pose`` (None when its heading is too uncertain to trust): a
    reading within ``tolerance_mm`` of where some ray of the cone, widened by twice the
    heading's sigma, meets a wall."""
    if not trusted(pose):
        return None
    slack = 2.0 * pose.sigma_heading_deg

    def explain(sensor: TofSensorConfig, distance: int) -> np.ndarray | None:
        return explained_points(floor, pose, sensor, distance, tolerance_mm, slack)

    return explain
