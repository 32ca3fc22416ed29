"""Rectangles on the floor: a body, a cart or a camera's blob from its centre, its size and
the direction of its long side, as corners or as sides. One definition, so the map, the
camera layer and navigation draw and avoid the same footprint."""

from __future__ import annotations

import math

import numpy as np


def corners(
    x_mm: float, y_mm: float, length_mm: float, width_mm: float, axis_deg: float
) -> np.ndarray:
    """The corners (4, 2) in order round the rectangle: ``length_mm`` along ``axis_deg``
    (counter-clockwise from +x), ``width_mm`` across, centred at (x, y)."""
    axis = math.radians(axis_deg)
    along = np.array([math.cos(axis), math.sin(axis)]) * length_mm / 2
    across = np.array([-math.sin(axis), math.cos(axis)]) * width_mm / 2
    centre = np.array([x_mm, y_mm])
    return np.array(
        [
            centre + along + across,
            centre - along + across,
            centre - along - across,
            centre + along - across,
        ]
    )


def sides(points: np.ndarray) -> np.ndarray:
    """A closed polygon's sides (n, 4: x0, y0, x1, y1) from its corners (n, 2)."""
    return np.hstack([points, np.roll(points, -1, axis=0)])
