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
from collections.abc import Callable, Sequence

import numpy as np

from coffeebot.config import TofSensorConfig
from coffeebot.floorplan import Floor
from coffeebot.messages import PoseEstimate
from coffeebot.perception.geometry import sensor_origins, spread_rad, wrap_deg

RAYS = 15
"""Rays across the (widened) cone when asking which of them meet a wall."""


def wall_ranges(
    floor: Floor, origins: np.ndarray, angles: np.ndarray, reach_mm: float | np.ndarray = math.inf
) -> np.ndarray:
    """Range (n, r) from each origin (n, 2) to the first plan wall along each of its rays
    ``angles`` (n, r), inf where there is none within its ``reach_mm`` (n,). All origins are
    cast in one go, and walls whose bounding box lies beyond every reach not at all: the
    question is asked for every sensor every scan, and few of a floor's walls are that close."""
    reach = np.asarray(reach_mm, dtype=float)
    if reach.shape != (len(origins),):
        reach = np.broadcast_to(reach, (len(origins),))
    seg = floor.segment_array
    if seg.size and len(origins) and np.isfinite(reach).all():
        box = floor.segment_bounds
        close = (
            (box[:, 0] <= (origins[:, 0] + reach).max())
            & (box[:, 2] >= (origins[:, 0] - reach).min())
            & (box[:, 1] <= (origins[:, 1] + reach).max())
            & (box[:, 3] >= (origins[:, 1] - reach).min())
        )
        seg = seg[close]
    return segment_ranges(seg, origins, angles, reach)


def segment_ranges(
    seg: np.ndarray, origins: np.ndarray, angles: np.ndarray, reach: np.ndarray
) -> np.ndarray:
    """Range (n, r) from each origin (n, 2) to the first of the segments ``seg`` (k, 4:
    x0, y0, x1, y1) along each of its rays ``angles`` (n, r), inf where there is none within
    its ``reach`` (n,)."""
    if seg.size == 0:
        return np.full(np.shape(angles), math.inf)
    x, y = origins[:, 0, None, None], origins[:, 1, None, None]  # (n, 1, 1)
    dx, dy = np.cos(angles)[..., None], np.sin(angles)[..., None]  # (n, r, 1)
    ex, ey = seg[:, 2] - seg[:, 0], seg[:, 3] - seg[:, 1]  # (k,)
    wx, wy = seg[:, 0] - x, seg[:, 1] - y  # (n, 1, k)
    denom = dx * ey - dy * ex
    with np.errstate(divide="ignore", invalid="ignore"):
        t = (wx * ey - wy * ex) / denom
        u = (wx * dy - wy * dx) / denom
    hit = (np.abs(denom) > 1e-9) & (t > 0) & (u >= 0) & (u <= 1) & (t <= reach[:, None, None])
    return np.where(hit, t, math.inf).min(axis=-1)


def explained_points(
    floor: Floor,
    pose: PoseEstimate,
    readings: Sequence[tuple[TofSensorConfig, float]],
    tolerance_mm: float,
    slack_deg: float,
) -> dict[int, np.ndarray]:
    """For each (sensor, distance) reading whose sensor's cone, widened by ``slack_deg`` for
    the pose's heading error, meets a plan wall within ``tolerance_mm`` of the distance
    along some of its rays: the robot-frame points (k, 2) where they do, by sensor id."""
    if not readings:
        return {}
    spreads: dict[float, np.ndarray] = {}
    origins, angles, offsets = [], [], []
    placed = sensor_origins(pose.x_mm, pose.y_mm, pose.heading_deg, [s for s, _ in readings])
    for (sensor, _), (sx, sy, look) in zip(readings, placed, strict=True):
        half = sensor.fov_deg / 2.0 + slack_deg
        if half not in spreads:
            spreads[half] = spread_rad(half, RAYS)
        origins.append((sx, sy))
        angles.append(math.radians(look) + spreads[half])
        offsets.append(spreads[half])
    distances = np.array([distance for _, distance in readings], dtype=float)
    ranges = wall_ranges(floor, np.array(origins), np.array(angles), distances + tolerance_mm)
    near = np.abs(ranges - distances[:, None]) <= tolerance_mm
    # Every sensor's rays placed in the robot frame at once, then each one's near rays.
    mounts = np.array([(s.x_mm, s.y_mm, s.yaw_deg) for s, _ in readings])
    bearing = np.radians(mounts[:, 2:]) + np.array(offsets)
    hit = np.where(near, ranges, 0.0)
    points = np.empty((*hit.shape, 2))
    points[..., 0] = mounts[:, :1] + hit * np.cos(bearing)
    points[..., 1] = mounts[:, 1:2] + hit * np.sin(bearing)
    any_near = near.any(axis=1).tolist()
    return {sensor.id: points[k][near[k]] for k, (sensor, _) in enumerate(readings) if any_near[k]}


Explainer = Callable[[Sequence[tuple[TofSensorConfig, float]]], dict[int, np.ndarray]]
"""Where the plan's walls put the readings they explain of those given as (sensor,
distance): robot-frame points by sensor id."""

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

    def explain(readings: Sequence[tuple[TofSensorConfig, float]]) -> dict[int, np.ndarray]:
        return explained_points(floor, pose, readings, tolerance_mm, slack)

    return explain
