"""Distance from any point of a floor to its nearest wall, precomputed on a grid.

The particle filter asks this millions of times per second ("how far is this reading's end
point from the plan's walls?", "is there a wall within this cone's range?"), so it is
computed once per floor: the plan's wall segments (hallway walls, door recesses and leaves,
the elevator door, the tea room, side hallways) are rasterised, ``scipy.ndimage``'s Euclidean
distance transform finds each cell's nearest wall cell, and the exact distance from the cell
centre to that cell's segment is stored, so that interpolating between cells is accurate to
well under a millimetre along a flat wall instead of to half a cell.
"""

from __future__ import annotations

import functools
import math

import numpy as np
from scipy import ndimage

from coffeebot.floorplan import Floor

FAR_MM = 1.0e5
"""Distance reported off the grid: nothing the plan knows is near."""


class LikelihoodField:
    """A floor's distance-to-wall grid (float32, mm) with vectorised lookups."""

    def __init__(self, floor: Floor, resolution_mm: float, margin_mm: float) -> None:
        self.level = floor.level
        self.resolution_mm = resolution_mm
        segments = floor.segment_array[:, :4]
        self.segments = segments
        if len(segments):
            xs, ys = segments[:, [0, 2]], segments[:, [1, 3]]
            lo = np.array([xs.min(), ys.min()]) - margin_mm
            hi = np.array([xs.max(), ys.max()]) + margin_mm
        else:
            origin = np.array(floor.hallway.start, dtype=float)
            lo, hi = origin - margin_mm, origin + margin_mm
        self.origin = lo
        self.shape = tuple(int(v) for v in np.ceil((hi - lo) / resolution_mm).astype(int) + 1)
        self.distance = self._distance_grid()
        self._flat = self.distance.ravel()

    def _distance_grid(self) -> np.ndarray:
        """Exact distance from each cell centre to the segment of its nearest wall cell."""
        nx, ny = self.shape
        if not len(self.segments):
            return np.full((nx, ny), FAR_MM, dtype=np.float32)
        owner = np.full((nx, ny), -1, dtype=np.int32)
        step = self.resolution_mm / 2
        for index, (x0, y0, x1, y1) in enumerate(self.segments):
            n = max(2, math.ceil(math.hypot(x1 - x0, y1 - y0) / step) + 1)
            t = np.linspace(0.0, 1.0, n)
            i, j = self.cell(x0 + t * (x1 - x0), y0 + t * (y1 - y0))
            owner[i, j] = index
        _, (ni, nj) = ndimage.distance_transform_edt(owner < 0, return_indices=True)
        seg = self.segments[owner[ni, nj]]
        cx, cy = self.centres()
        return point_segment_distance(cx, cy, seg).astype(np.float32)

    def cell(self, x: np.ndarray, y: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """The grid cell nearest each point (clipped to the grid)."""
        i = np.rint((x - self.origin[0]) / self.resolution_mm).astype(np.int64)
        j = np.rint((y - self.origin[1]) / self.resolution_mm).astype(np.int64)
        return np.clip(i, 0, self.shape[0] - 1), np.clip(j, 0, self.shape[1] - 1)

    def centres(self) -> tuple[np.ndarray, np.ndarray]:
        """Floor-frame coordinates of every cell centre, as two (nx, ny) arrays."""
        nx, ny = self.shape
        gx = self.origin[0] + self.resolution_mm * np.arange(nx)
        gy = self.origin[1] + self.resolution_mm * np.arange(ny)
        return np.meshgrid(gx, gy, indexing="ij")

    def __call__(self, x: np.ndarray, y: np.ndarray) -> np.ndarray:
        """Distance to the nearest wall at each point, bilinear between cell centres
        (``FAR_MM`` off the grid)."""
        nx, ny = self.shape
        fx = (x - self.origin[0]) / self.resolution_mm
        fy = (y - self.origin[1]) / self.resolution_mm
        off = (fx < 0) | (fx > nx - 1) | (fy < 0) | (fy > ny - 1)
        np.clip(fx, 0, nx - 1.001, out=fx)
        np.clip(fy, 0, ny - 1.001, out=fy)
        i, j = fx.astype(np.int64), fy.astype(np.int64)
        u, v = fx - i, fy - j
        k = i * ny + j
        g = self._flat
        a, b, c, d = g.take(k), g.take(k + ny), g.take(k + 1), g.take(k + ny + 1)
        out = (a + (b - a) * u) * (1 - v) + (c + (d - c) * u) * v
        out[off] = FAR_MM
        return out

    def nearest(self, x: np.ndarray, y: np.ndarray) -> np.ndarray:
        """Distance to the nearest wall at each point's cell: coarser than calling the
        field, a third of the cost, for checks that only ask "is a wall near?"."""
        nx, ny = self.shape
        scale = 1.0 / self.resolution_mm
        i = ((x - (self.origin[0] - self.resolution_mm / 2)) * scale).astype(np.int64)
        j = ((y - (self.origin[1] - self.resolution_mm / 2)) * scale).astype(np.int64)
        np.clip(i, 0, nx - 1, out=i)
        np.clip(j, 0, ny - 1, out=j)
        i *= ny
        i += j
        return self._flat.take(i)

    def free_cells(self, clearance_mm: float, inside_of: tuple[float, float]) -> np.ndarray:
        """Centres (k, 2) of the cells a body needing ``clearance_mm`` could stand in,
        connected to the point ``inside_of`` (a hallway point): where global localization
        may put particles. Empty if that point itself has no clearance."""
        free = self.distance >= clearance_mm
        labels, _ = ndimage.label(free)
        i, j = self.cell(np.array([inside_of[0]]), np.array([inside_of[1]]))
        label = labels[i[0], j[0]]
        if label == 0:
            return np.zeros((0, 2))
        i, j = np.nonzero(labels == label)
        return self.origin + self.resolution_mm * np.column_stack([i, j])


def point_segment_distance(x: np.ndarray, y: np.ndarray, segments: np.ndarray) -> np.ndarray:
    """Distance from each point to its own segment (``segments[..., :4]`` = x0, y0, x1, y1)."""
    px, py = segments[..., 0], segments[..., 1]
    ex, ey = segments[..., 2] - px, segments[..., 3] - py
    length2 = np.maximum(ex * ex + ey * ey, 1e-9)
    t = np.clip(((x - px) * ex + (y - py) * ey) / length2, 0.0, 1.0)
    return np.hypot(px + t * ex - x, py + t * ey - y)


def field_for(floor: Floor, resolution_mm: float, margin_mm: float) -> LikelihoodField:
    """A floor's field, built once per process for each distinct floor and grid."""
    return _cached_field(floor.model_dump_json(), resolution_mm, margin_mm)


@functools.lru_cache(maxsize=16)
def _cached_field(floor_json: str, resolution_mm: float, margin_mm: float) -> LikelihoodField:
    return LikelihoodField(Floor.model_validate_json(floor_json), resolution_mm, margin_mm)
