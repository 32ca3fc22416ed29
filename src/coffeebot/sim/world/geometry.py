"""Surfaces as flat numpy arrays, and the two queries on them: lines of sight and
footprints (how the sensors range is ``tof.py``).

Everything a sensor can see or the robot can hit is a vertical surface with a height range:
a straight segment (walls, door leaves, box sides) or a vertical cylinder (poles, legs, bars).
Horizontal faces (floor, shelf tops, seat undersides) are not modelled: at the sensors'
grazing angles they return little light, and leaving them out is what lets a shelf just
below sensor height vanish from the cone at close range, as it did in the seed's experiment.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from coffeebot.floorplan import segment_distances
from coffeebot.sim.world.footprint import cylinders_touching, segments_touching
from coffeebot.sim.world.materials import DEFAULT

_EPS = 1e-6


@dataclass(frozen=True)
class Surfaces:
    """Segments (N, 6: x0 y0 x1 y1 z_bottom z_top) and cylinders (M, 5: cx cy r z_bottom
    z_top), each row named by the element it belongs to (for collision reports) and with the
    diffuse reflectance at 940 nm the ToF sensors see (``materials.py``; default when left
    out)."""

    segments: np.ndarray
    segment_ids: tuple[str, ...]
    cylinders: np.ndarray
    cylinder_ids: tuple[str, ...]
    segment_reflectance: np.ndarray = field(default_factory=lambda: np.zeros(0))
    cylinder_reflectance: np.ndarray = field(default_factory=lambda: np.zeros(0))

    def __post_init__(self) -> None:
        # Surfaces built without optics (tests, the robot's footprint) get the default.
        if len(self.segment_reflectance) != len(self.segments):
            object.__setattr__(self, "segment_reflectance", np.full(len(self.segments), DEFAULT))
        if len(self.cylinder_reflectance) != len(self.cylinders):
            object.__setattr__(self, "cylinder_reflectance", np.full(len(self.cylinders), DEFAULT))

    @classmethod
    def empty(cls) -> Surfaces:
        return cls(np.zeros((0, 6)), (), np.zeros((0, 5)), ())

    def __add__(self, other: Surfaces) -> Surfaces:
        return Surfaces(
            np.concatenate([self.segments, other.segments]),
            self.segment_ids + other.segment_ids,
            np.concatenate([self.cylinders, other.cylinders]),
            self.cylinder_ids + other.cylinder_ids,
            np.concatenate([self.segment_reflectance, other.segment_reflectance]),
            np.concatenate([self.cylinder_reflectance, other.cylinder_reflectance]),
        )

    def take(self, segment_index: np.ndarray, cylinder_index: np.ndarray) -> Surfaces:
        """A subset, keeping the names and reflectances."""
        return Surfaces(
            self.segments[segment_index],
            tuple(self.segment_ids[i] for i in segment_index),
            self.cylinders[cylinder_index],
            tuple(self.cylinder_ids[i] for i in cylinder_index),
            self.segment_reflectance[segment_index],
            self.cylinder_reflectance[cylinder_index],
        )

    def near(self, x: float, y: float, radius: float) -> tuple[np.ndarray, np.ndarray]:
        """Indices of segments and cylinders that come within ``radius`` of (x, y)."""
        seg_d = segment_distances(self.segments, x, y)
        c = self.cylinders
        cyl_d = np.hypot(c[:, 0] - x, c[:, 1] - y) - c[:, 2]
        return np.flatnonzero(seg_d <= radius), np.flatnonzero(cyl_d <= radius)


def cast_rays(
    segments: np.ndarray,
    cylinders: np.ndarray,
    origins: np.ndarray,
    heights: np.ndarray,
    azimuths: np.ndarray,
    tan_el: np.ndarray,
    cos_el: np.ndarray,
) -> np.ndarray:
    """Range to the nearest surface along every ray, ``inf`` where nothing is hit: the lines of
    sight ground truth asks about (what a sensor could see), not how a sensor ranges.

    ``origins`` (S, 2) and ``heights`` (S,) place S sensors; ray (s, a, e) leaves sensor s at
    floor-frame azimuth ``azimuths[s, a]`` (rad) and elevation with tangent ``tan_el[s, e]``.
    The horizontal intersection is shared by all elevations of one azimuth, so the work is
    one (S, A, K) solve plus an (S, A, E, K) height test. Returns (S, A, E) ranges along the
    3-D ray, in mm.
    """
    n_sensors, n_az = azimuths.shape
    dx, dy = np.cos(azimuths)[:, :, None], np.sin(azimuths)[:, :, None]
    ox, oy = origins[:, 0, None], origins[:, 1, None]
    parts: list[np.ndarray] = []
    with np.errstate(divide="ignore", invalid="ignore"):
        if len(segments):
            ex = segments[:, 2] - segments[:, 0]
            ey = segments[:, 3] - segments[:, 1]
            wx = (segments[:, 0] - ox)[:, None, :]
            wy = (segments[:, 1] - oy)[:, None, :]
            denom = dx * ey - dy * ex
            t = (wx * ey - wy * ex) / denom
            u = (wx * dy - wy * dx) / denom
            parts.append(np.where((t > _EPS) & (u >= 0.0) & (u <= 1.0), t, np.inf))
        if len(cylinders):
            wx = (ox - cylinders[:, 0])[:, None, :]
            wy = (oy - cylinders[:, 1])[:, None, :]
            b = dx * wx + dy * wy
            c = wx * wx + wy * wy - cylinders[:, 2] ** 2
            disc = b * b - c
            t = -b - np.sqrt(np.maximum(disc, 0.0))
            parts.append(np.where((disc >= 0.0) & (c > 0.0) & (t > _EPS), t, np.inf))
        if not parts:
            return np.full((n_sensors, n_az, tan_el.shape[1]), np.inf)
        t_h = np.concatenate(parts, axis=-1)  # (S, A, K) horizontal distance
        z_bottom = np.concatenate([segments[:, 4], cylinders[:, 3]])
        z_top = np.concatenate([segments[:, 5], cylinders[:, 4]])
        z = heights[:, None, None, None] + t_h[:, :, None, :] * tan_el[:, None, :, None]
        hit = (z >= z_bottom) & (z <= z_top)
        nearest = np.where(hit, t_h[:, :, None, :], np.inf).min(axis=-1)
    return nearest / cos_el[:, None, :]


@dataclass(frozen=True)
class Contact:
    element: str
    x_mm: float
    y_mm: float


def footprint_contacts(
    surfaces: Surfaces,
    x: float,
    y: float,
    theta: float,
    half_length: float,
    half_width: float,
    z_range: tuple[float, float],
) -> list[Contact]:
    """Surfaces touching a rectangle centred at (x, y) with heading ``theta`` (rad).

    Segments are moved into the rectangle's frame and clipped against it (Liang-Barsky);
    the contact point is the middle of the clipped piece. Only surfaces whose height range
    overlaps ``z_range`` count, so a robot can pass under a table top.
    """
    c, s = math.cos(theta), math.sin(theta)
    contacts: list[Contact] = []
    if len(surfaces.segments):
        found = segments_touching(surfaces.segments, x, y, c, s, half_length, half_width, *z_range)
        for i, px, py in zip(*found, strict=True):
            contacts.append(Contact(surfaces.segment_ids[i], float(px), float(py)))
    if len(surfaces.cylinders):
        found = cylinders_touching(
            surfaces.cylinders, x, y, c, s, half_length, half_width, *z_range
        )
        for i, px, py in zip(*found, strict=True):
            contacts.append(Contact(surfaces.cylinder_ids[i], float(px), float(py)))
    return contacts
