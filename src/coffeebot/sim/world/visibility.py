"""Ground truth for "the robot could have known": what an ideal sensor sees, what is in its way.

A safety benchmark times the robot's reaction from the moment an obstacle became detectable,
so that moment must come from geometry, not from the simulated sensor's noise or its sparse
ray grid. An obstacle is *seen* by a sensor when some point of its surface lies inside the
sensor's cone (within half the field of view of its axis, a circular cone), no further than
the sensor's range, and the straight line from the sensor to that point meets nothing first
(walls, other obstacles, the obstacle's own near side). Surfaces are sampled every
``SAMPLE_MM`` (finer than a chair leg) and each line of sight is one ray through the same
caster the simulated sensors use.

An obstacle is *in the way* when some part of it, within the body's height, lies in the
protective field: the rectangle of the body's width ahead of the front face (behind the rear
when reversing), as deep as the distance the robot needs to stop from its speed.

:func:`first_time` finds when such a condition first holds along a recorded trajectory,
refined between samples by bisection on the interpolated pose.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence
from dataclasses import dataclass

import numpy as np

from coffeebot.sim.world.geometry import Surfaces, cast_rays, footprint_contacts
from coffeebot.sim.world.robot import RobotSpec
from coffeebot.sim.world.tof import SensorMount

SAMPLE_MM = 20.0
"""Spacing of the sample points on every surface (along it and up it)."""

CYLINDER_SAMPLES = 24
"""Points around each cylinder: 4 mm apart on a 15 mm chair leg, 47 mm on a torso."""

SIGHT_TOLERANCE_MM = 1.0
"""A line of sight blocked less than this before its point still reaches it (rounding)."""


@dataclass(frozen=True)
class RobotPose:
    """The body centre in the floor frame (theta in rad) and its signed forward speed."""

    x_mm: float
    y_mm: float
    theta: float
    speed_mm_s: float = 0.0


def surface_points(surfaces: Surfaces, z_max_mm: float, step_mm: float = SAMPLE_MM) -> np.ndarray:
    """(P, 3) points on every segment and cylinder, up to ``z_max_mm`` above the floor."""
    points: list[np.ndarray] = []

    def heights(z_bottom: float, z_top: float) -> np.ndarray:
        top = min(z_top, z_max_mm)
        if top < z_bottom:
            return np.zeros(0)
        return np.linspace(z_bottom, top, max(2, math.ceil((top - z_bottom) / step_mm) + 1))

    for x0, y0, x1, y1, zb, zt in surfaces.segments:
        zs = heights(zb, zt)
        n = max(2, math.ceil(math.hypot(x1 - x0, y1 - y0) / step_mm) + 1)
        f = np.linspace(0.0, 1.0, n)
        xy = np.stack([x0 + f * (x1 - x0), y0 + f * (y1 - y0)], axis=1)
        points.append(_grid(xy, zs))
    angles = np.linspace(0.0, 2.0 * math.pi, CYLINDER_SAMPLES, endpoint=False)
    for cx, cy, r, zb, zt in surfaces.cylinders:
        xy = np.stack([cx + r * np.cos(angles), cy + r * np.sin(angles)], axis=1)
        points.append(_grid(xy, heights(zb, zt)))
    return np.concatenate(points) if points else np.zeros((0, 3))


def _grid(xy: np.ndarray, zs: np.ndarray) -> np.ndarray:
    return np.column_stack([np.repeat(xy, len(zs), axis=0), np.tile(zs, len(xy))])


def view_top_mm(mounts: Sequence[SensorMount], max_range_mm: float) -> float:
    """The highest point any cone reaches within range: nothing above it can be seen."""
    return max(m.height_mm + max_range_mm * math.tan(math.radians(m.fov_deg / 2)) for m in mounts)


def seeing_sensors(
    target: Surfaces,
    scene: Surfaces,
    mounts: Sequence[SensorMount],
    pose: RobotPose,
    max_range_mm: float,
) -> list[int]:
    """Indices of the mounts that see some point of ``target`` from ``pose``.

    ``scene`` is everything that can block a line of sight, ``target`` included.
    """
    points = surface_points(target, view_top_mm(mounts, max_range_mm))
    if not len(points):
        return []
    c, s = math.cos(pose.theta), math.sin(pose.theta)
    seen: list[int] = []
    reach = max_range_mm + max(math.hypot(m.x_mm, m.y_mm) for m in mounts)
    near = scene.take(*scene.near(pose.x_mm, pose.y_mm, reach))
    for index, m in enumerate(mounts):
        ox = pose.x_mm + c * m.x_mm - s * m.y_mm
        oy = pose.y_mm + s * m.x_mm + c * m.y_mm
        yaw = pose.theta + math.radians(m.yaw_deg)
        d = points - (ox, oy, m.height_mm)
        dist = np.linalg.norm(d, axis=1)
        with np.errstate(invalid="ignore", divide="ignore"):
            cos_axis = (d[:, 0] * math.cos(yaw) + d[:, 1] * math.sin(yaw)) / dist
        inside = (dist > 0) & (dist <= max_range_mm)
        inside &= cos_axis >= math.cos(math.radians(m.fov_deg / 2))
        if not inside.any():
            continue
        d, dist = d[inside], dist[inside]
        horizontal = np.hypot(d[:, 0], d[:, 1])
        n = len(d)
        hits = cast_rays(
            near.segments,
            near.cylinders,
            np.tile((ox, oy), (n, 1)),
            np.full(n, m.height_mm),
            np.arctan2(d[:, 1], d[:, 0])[:, None],
            (d[:, 2] / horizontal)[:, None],
            (horizontal / dist)[:, None],
        )[:, 0, 0]
        if np.any(hits >= dist - SIGHT_TOLERANCE_MM):
            seen.append(index)
    return seen


def in_the_way(target: Surfaces, pose: RobotPose, robot: RobotSpec, depth_mm: float) -> bool:
    """Whether part of ``target`` (within the body's height) is in the protective field:
    ``depth_mm`` deep, the body's width, ahead of the front face in the direction of travel
    (behind the rear face when the speed is negative)."""
    if depth_mm <= 0:
        return False
    ahead = robot.length_mm / 2 + depth_mm / 2
    sign = -1.0 if pose.speed_mm_s < 0 else 1.0
    cx = pose.x_mm + sign * ahead * math.cos(pose.theta)
    cy = pose.y_mm + sign * ahead * math.sin(pose.theta)
    z_range = (robot.ground_clearance_mm, robot.height_mm)
    hits = footprint_contacts(target, cx, cy, pose.theta, depth_mm / 2, robot.width_mm / 2, z_range)
    return bool(hits)


@dataclass(frozen=True)
class Trajectory:
    """The robot's true pose sampled over a run (world time); linear in between."""

    t_s: np.ndarray
    x_mm: np.ndarray
    y_mm: np.ndarray
    theta: np.ndarray
    """Unwrapped, so that interpolation never turns the long way round."""
    speed_mm_s: np.ndarray

    @classmethod
    def from_samples(cls, samples: Sequence[Sequence[float]]) -> Trajectory:
        """From (t, x, y, theta, speed) rows in time order."""
        a = np.array(samples, dtype=float).reshape(-1, 5)
        return cls(a[:, 0], a[:, 1], a[:, 2], np.unwrap(a[:, 3]), a[:, 4])

    def at(self, t_s: float) -> RobotPose:
        return RobotPose(
            float(np.interp(t_s, self.t_s, self.x_mm)),
            float(np.interp(t_s, self.t_s, self.y_mm)),
            float(np.interp(t_s, self.t_s, self.theta)),
            float(np.interp(t_s, self.t_s, self.speed_mm_s)),
        )


def first_time(
    trajectory: Trajectory,
    holds: Callable[[float, RobotPose], bool],
    after_s: float = -math.inf,
    resolution_s: float = 0.0005,
) -> float | None:
    """The first time at or after ``after_s`` when ``holds(t, pose)`` is true, checked at
    every sample and refined by bisection to ``resolution_s``; None if it never holds."""
    previous: float | None = None
    for t in trajectory.t_s:
        t = float(t)
        if t < after_s:
            continue
        if holds(t, trajectory.at(t)):
            if previous is None:
                return t
            lo, hi = previous, t
            while hi - lo > resolution_s:
                mid = (lo + hi) / 2
                if holds(mid, trajectory.at(mid)):
                    hi = mid
                else:
                    lo = mid
            return hi
        previous = t
    return None
