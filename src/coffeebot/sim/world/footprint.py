"""Which surfaces touch a rectangle, and where, as compiled loops.

The robot's body is tested against what stands around it at every 5 ms physics sub-step,
every robot of a fleet; as whole-array numpy passes over a handful of surfaces that was
mostly the passes' own overhead. The loops here are the same arithmetic in the same order
(numpy's NaN-propagating minimum and maximum included), so the same contacts to the bit.
"""

from __future__ import annotations

import numpy as np
from numba import njit


@njit(cache=True)
def _minimum(a: float, b: float) -> float:
    """``np.minimum``: NaN if either is."""
    if a != a or b != b:
        return np.nan
    return a if a <= b else b


@njit(cache=True)
def _maximum(a: float, b: float) -> float:
    """``np.maximum``: NaN if either is."""
    if a != a or b != b:
        return np.nan
    return a if a >= b else b


@njit(cache=True, error_model="numpy")
def segments_touching(
    segments: np.ndarray,
    x: float,
    y: float,
    c: float,
    s: float,
    half_length: float,
    half_width: float,
    z_low: float,
    z_high: float,
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Indices of the segments (N, 6) that cross a rectangle centred at (x, y) whose axis
    is (``c``, ``s``), and the middles of the crossing pieces (x, y).

    Each segment is moved into the rectangle's frame and clipped against it (Liang-Barsky);
    only segments whose height range overlaps (``z_low``, ``z_high``) count.
    """
    hits = np.empty(len(segments), np.int64)
    px = np.empty(len(segments))
    py = np.empty(len(segments))
    n = 0
    for i in range(len(segments)):
        x0, y0, x1, y1 = segments[i, 0], segments[i, 1], segments[i, 2], segments[i, 3]
        if not (segments[i, 5] > z_low and segments[i, 4] < z_high):
            continue
        p0x = c * (x0 - x) + s * (y0 - y)
        p0y = -s * (x0 - x) + c * (y0 - y)
        p1x = c * (x1 - x) + s * (y1 - y)
        p1y = -s * (x1 - x) + c * (y1 - y)
        ddx, ddy = p1x - p0x, p1y - p0y
        ax, bx = (-half_length - p0x) / ddx, (half_length - p0x) / ddx
        ay, by = (-half_width - p0y) / ddy, (half_width - p0y) / ddy
        enter = _maximum(_maximum(0.0, _minimum(ax, bx)), _minimum(ay, by))
        leave = _minimum(_minimum(1.0, _maximum(ax, bx)), _maximum(ay, by))
        if enter <= leave:
            t = (enter + leave) / 2
            hits[n] = i
            px[n] = x0 + t * (x1 - x0)
            py[n] = y0 + t * (y1 - y0)
            n += 1
    return hits[:n], px[:n], py[:n]


@njit(cache=True)
def cylinders_touching(
    cylinders: np.ndarray,
    x: float,
    y: float,
    c: float,
    s: float,
    half_length: float,
    half_width: float,
    z_low: float,
    z_high: float,
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Indices of the cylinders (M, 5) that reach into the rectangle of
    :func:`segments_touching`, and the rectangle's point nearest each axis (x, y)."""
    hits = np.empty(len(cylinders), np.int64)
    px = np.empty(len(cylinders))
    py = np.empty(len(cylinders))
    n = 0
    for i in range(len(cylinders)):
        if not (cylinders[i, 4] > z_low and cylinders[i, 3] < z_high):
            continue
        lx = c * (cylinders[i, 0] - x) + s * (cylinders[i, 1] - y)
        ly = -s * (cylinders[i, 0] - x) + c * (cylinders[i, 1] - y)
        qx = min(max(lx, -half_length), half_length)
        qy = min(max(ly, -half_width), half_width)
        if np.hypot(lx - qx, ly - qy) <= cylinders[i, 2]:
            hits[n] = i
            px[n] = x + c * qx - s * qy
            py[n] = y + s * qx + c * qy
            n += 1
    return hits[:n], px[:n], py[:n]
