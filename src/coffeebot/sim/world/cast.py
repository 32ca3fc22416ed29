"""What each direction of every ToF cone meets, as compiled loops.

Every direction of a cone is a ray; the horizontal solve against every segment is shared by
the elevations of one azimuth column, then each elevation keeps the nearest of the floor, the
nearest wall standing on the floor and reaching above the cone (met by every elevation that
has not met the floor first) and the faces that stop within the cone (a box, a shelf, another
robot: per elevation, against its height range); poles in front of that cover a share of each
column. As numpy arrays this was some hundred whole-array passes over small (sensor, azimuth,
segment) temporaries per scan, mostly the passes' own overhead; as loops (numba) it is the
same arithmetic in the same order, the same answers to the bit, in well under half the time.
The chip's sums over the grid stay numpy (``tof.py``).
"""

from __future__ import annotations

import numpy as np
from numba import njit


@njit(cache=True, error_model="numpy")
def first_surfaces(
    ox: np.ndarray,
    oy: np.ndarray,
    oz: np.ndarray,
    dx: np.ndarray,
    dy: np.ndarray,
    tan_el: np.ndarray,
    cos_el: np.ndarray,
    segments: np.ndarray,
    reflectance: np.ndarray,
    tan_reach: float,
    eps: float,
    best_t: np.ndarray,
    best_gain: np.ndarray,
) -> None:
    """Lower ``best_t`` (S, A, E: horizontal distance, the floor's on entry) to the first
    segment each direction meets and set ``best_gain`` there to its reflectance x
    cos(incidence) x cos(elevation).

    Sensor s sits at (``ox[s]``, ``oy[s]``), ``oz[s]`` high; its azimuth column a points
    along (``dx[s, a]``, ``dy[s, a]``); elevation e has tangent ``tan_el[e]``. ``segments``
    are (K, 6) rows x0 y0 x1 y1 z_bottom z_top; a wall stands on the floor and is tall for a
    column when its top is above the cone's edge (``tan_reach``) where the column meets it.
    """
    n_s, n_a = dx.shape
    n_k = segments.shape[0]
    n_e = tan_el.shape[0]
    ex = segments[:, 2] - segments[:, 0]
    ey = segments[:, 3] - segments[:, 1]
    length = np.maximum(np.hypot(ex, ey), eps)
    t = np.empty((n_s, n_a, n_k))
    gain = np.empty((n_s, n_a, n_k))
    crossed = np.zeros(n_k, np.bool_)
    column_crossed = np.zeros((n_s, n_a), np.bool_)
    for s in range(n_s):
        for a in range(n_a):
            nearest = np.inf
            k_nearest = 0
            for k in range(n_k):
                wx = segments[k, 0] - ox[s]
                wy = segments[k, 1] - oy[s]
                denom = dx[s, a] * ey[k] - dy[s, a] * ex[k]
                tk = (wx * ey[k] - wy * ex[k]) / denom
                uk = (wx * dy[s, a] - wy * dx[s, a]) / denom
                if not (tk > eps and uk >= 0.0 and uk <= 1.0):
                    tk = np.inf
                t[s, a, k] = tk
                gain[s, a, k] = reflectance[k] * (abs(denom) / length[k])
                if segments[k, 4] <= 0.0 and segments[k, 5] >= oz[s] + tk * tan_reach:
                    if tk < nearest:
                        nearest, k_nearest = tk, k
                elif np.isfinite(tk):
                    crossed[k] = True
                    column_crossed[s, a] = True
            for e in range(n_e):
                if nearest < best_t[s, a, e]:
                    best_t[s, a, e] = nearest
                    best_gain[s, a, e] = gain[s, a, k_nearest] * cos_el[e]
    # The faces that stop within the cone, in the columns that cross one (about one in ten),
    # against every such face of the scan (a tall wall among them never wins a tie).
    partial = np.flatnonzero(crossed)
    for s in range(n_s):
        for a in range(n_a):
            if not column_crossed[s, a]:
                continue
            for e in range(n_e):
                near = np.inf
                k_near = 0
                for face in partial:
                    tk = t[s, a, face]
                    finite = np.isfinite(tk)
                    z = oz[s] + (tk if finite else 0.0) * tan_el[e]
                    if finite and segments[face, 4] <= z <= segments[face, 5] and tk < near:
                        near, k_near = tk, int(face)
                if near < best_t[s, a, e]:
                    best_t[s, a, e] = near
                    best_gain[s, a, e] = gain[s, a, k_near] * cos_el[e]


@njit(cache=True, error_model="numpy")
def poles_in_view(
    cylinders: np.ndarray,
    reflectance: np.ndarray,
    ox: np.ndarray,
    oy: np.ndarray,
    oz: np.ndarray,
    azimuths: np.ndarray,
    tan_el: np.ndarray,
    cos_el: np.ndarray,
    bg_t: np.ndarray,
    half_column: float,
    eps: float,
) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """The poles (``cylinders``, nearest first: cx cy r z_bottom z_top) some column of some
    cone covers, in front of the background (``bg_t``, S x A x E).

    A pole covers a share of each azimuth column (its angular width against the column's,
    centred on its bearing), met at the middle of the visible sliver. Returns the indices of
    the poles seen (P), the columns (sensor, azimuth: N each) some pole covers, each pole's
    horizontal distance there (N x P), its gain per elevation (N x E x P: the share it
    covers and the light the nearer poles let through, x reflectance x cos(incidence) x
    cos(elevation)) and the share of each direction (S x A x E) that gets through them all.
    """
    n_s, n_a = azimuths.shape
    n_k = cylinders.shape[0]
    n_e = tan_el.shape[0]
    dist = np.empty((n_s, n_k))
    half = np.empty((n_s, n_k))
    bearing = np.empty((n_s, n_k))
    for s in range(n_s):
        for k in range(n_k):
            cx = cylinders[k, 0] - ox[s]
            cy = cylinders[k, 1] - oy[s]
            r = cylinders[k, 2]
            dist[s, k] = max(np.hypot(cx, cy), r + eps)
            half[s, k] = np.arcsin(min(max(r / dist[s, k], 0.0), 1.0))
            bearing[s, k] = np.arctan2(cy, cx)
    width = 2 * half_column
    offset = np.empty((n_s, n_a, n_k))
    cover = np.empty((n_s, n_a, n_k))
    seen = np.zeros(n_k, np.bool_)
    covered = np.zeros((n_s, n_a), np.bool_)
    for s in range(n_s):
        for a in range(n_a):
            for k in range(n_k):
                off = (bearing[s, k] - azimuths[s, a] + np.pi) % (2 * np.pi) - np.pi
                lo = max(off - half[s, k], -half_column)
                hi = min(off + half[s, k], half_column)
                share = min(max((hi - lo) / width, 0.0), 1.0)
                offset[s, a, k] = off
                cover[s, a, k] = share
                if share != 0.0:
                    seen[k] = True
                    covered[s, a] = True
    poles = np.flatnonzero(seen)
    rows, azs = np.nonzero(covered)
    n_p, n_n = len(poles), len(rows)
    t = np.empty((n_n, n_p))
    gain = np.empty((n_n, n_e, n_p))
    through = np.ones((n_s, n_a, n_e))
    for n in range(n_n):
        s, a = rows[n], azs[n]
        cos_h = np.empty(n_p)
        for j in range(n_p):
            k = poles[j]
            r = cylinders[k, 2]
            off = offset[s, a, k]
            lo = max(off - half[s, k], -half_column)
            hi = min(off + half[s, k], half_column)
            mid = min(max((lo + hi) / 2 - off, -half[s, k]), half[s, k])
            side = dist[s, k] * np.sin(mid)
            depth = np.sqrt(max(r * r - side * side, 0.0))
            t[n, j] = dist[s, k] * np.cos(mid) - depth
            cos_h[j] = depth / r
        for e in range(n_e):
            passed = 1.0
            for j in range(n_p):
                k = poles[j]
                tk = t[n, j]
                z = oz[s] + tk * tan_el[e]
                share = 0.0
                if z >= cylinders[k, 3] and z <= cylinders[k, 4] and tk < bg_t[s, a, e] and tk > 0:
                    share = cover[s, a, k]
                gain[n, e, j] = share * passed * (reflectance[k] * cos_h[j]) * cos_el[e]
                passed = passed * (1.0 - share)
            through[s, a, e] = passed
    return poles, rows, azs, t, gain, through


@njit(cache=True, error_model="numpy")
def visible(
    horizontal: np.ndarray,
    gain: np.ndarray,
    tilt: np.ndarray,
    max_path_mm: float,
    path: np.ndarray,
    strength: np.ndarray,
) -> None:
    """Fill ``path`` (along the ray, mm) and ``strength`` (``gain`` / path^2, m) of what lies
    ``horizontal`` away, 0 where nothing within the optics' reach is; ``tilt`` is each
    direction's cos(elevation). Every argument is three-dimensional, of one shape."""
    n_x, n_y, n_z = horizontal.shape
    for i in range(n_x):
        for j in range(n_y):
            for k in range(n_z):
                h = horizontal[i, j, k]
                finite = np.isfinite(h)
                along = (h if finite else 0.0) / tilt[i, j, k]
                g = gain[i, j, k]
                if finite and g > 0.0 and along <= max_path_mm:
                    metres = along / 1000.0
                    path[i, j, k] = along
                    strength[i, j, k] = g / (metres * metres)
                else:
                    path[i, j, k] = 0.0
                    strength[i, j, k] = 0.0
