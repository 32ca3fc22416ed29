"""Where the robot's ToF cones look, and where they do not: computed from the robot description.

A sensor sees a point when the point lies within half its nominal field of view of the
optical axis and within ``range_mm`` (nothing in between: an empty scene). What matters for
safety is in the robot frame (x forward, y left, origin at the body centre):

* the **corridor** ahead, as wide as the body plus a margin, which the body sweeps when it
  drives straight: a return there is in the way. ``corridor_full_from_mm`` is how far ahead
  of the front face every lateral position of it is seen by some cone (nearer than that,
  something thin can stand in a gap between the cones);
* the **flanks** diagonally ahead, between the corridor and the hallway's walls, from where
  a person steps into the corridor: ``warning_s`` is how long a person crossing at a given
  speed is seen before reaching the corridor, by how far ahead they cross.

Nothing here knows about the simulator: the same figures describe the real robot.
"""

from __future__ import annotations

from collections.abc import Iterable, Sequence
from dataclasses import dataclass

import numpy as np

from coffeebot.config import TofSensorConfig

GRID_MM = 10.0


@dataclass(frozen=True)
class Coverage:
    """How many cones see each cell of a robot-frame grid (x ahead, y left)."""

    xs: np.ndarray
    ys: np.ndarray
    seen_by: np.ndarray
    """(len(xs), len(ys)) count of sensors whose cone contains the cell."""
    front_mm: float
    """The body's front face, x in the robot frame."""
    half_width_mm: float

    def covered(self, x_mm: float, y_mm: float) -> bool:
        i = int(np.clip(np.searchsorted(self.xs, x_mm), 0, len(self.xs) - 1))
        j = int(np.clip(np.searchsorted(self.ys, y_mm), 0, len(self.ys) - 1))
        return bool(self.seen_by[i, j])

    def corridor_full_from_mm(self, margin_mm: float = 0.0, within_mm: float = 2000.0) -> float:
        """Distance ahead of the front face from which the whole corridor (the body's width
        plus ``margin_mm`` each side) is seen without a gap, out to ``within_mm``."""
        in_corridor = np.abs(self.ys) <= self.half_width_mm + margin_mm
        ahead = (self.xs >= self.front_mm) & (self.xs <= self.front_mm + within_mm)
        full = self.seen_by[:, in_corridor].all(axis=1)
        gaps = np.flatnonzero(~full & ahead)
        if len(gaps) == 0:
            return 0.0
        return float(self.xs[gaps[-1]] + GRID_MM - self.front_mm)

    def gaps_in_corridor(self, within_mm: float, margin_mm: float = 0.0) -> float:
        """Area (m^2) of the corridor within ``within_mm`` of the front face no cone sees."""
        ahead = (self.xs >= self.front_mm) & (self.xs <= self.front_mm + within_mm)
        in_corridor = np.abs(self.ys) <= self.half_width_mm + margin_mm
        blind = ~self.seen_by[np.ix_(ahead, in_corridor)].astype(bool)
        return float(blind.sum() * GRID_MM * GRID_MM / 1e6)

    def first_seen_lateral_mm(self, ahead_mm: float, side: float, start_mm: float) -> float:
        """Walking in from ``start_mm`` off the centre line on the ``side`` (+1 left, -1
        right) at ``ahead_mm`` of the front face, where a cone first sees the person (the
        corridor's edge when none does before)."""
        i = int(np.clip(np.searchsorted(self.xs, self.front_mm + ahead_mm), 0, len(self.xs) - 1))
        lateral = side * self.ys
        path = (lateral >= self.half_width_mm) & (lateral <= start_mm)
        seen = path & self.seen_by[i].astype(bool)
        return float(lateral[seen].max()) if seen.any() else self.half_width_mm

    def warning_s(
        self, ahead_mm: float, side: float, walking_mm_s: float, start_mm: float = 1200.0
    ) -> float:
        """How long a person walking straight across at ``walking_mm_s`` from ``start_mm``
        off the centre line is seen before they reach the corridor's edge at ``ahead_mm``."""
        lateral = self.first_seen_lateral_mm(ahead_mm, side, start_mm)
        return max(0.0, lateral - self.half_width_mm) / walking_mm_s


def coverage(
    sensors: Iterable[TofSensorConfig],
    length_mm: float,
    width_mm: float,
    range_mm: float = 2500.0,
    extent_mm: tuple[float, float, float] = (2500.0, 1500.0, 500.0),
) -> Coverage:
    """The cones of ``sensors`` on a grid from ``extent_mm[2]`` behind the centre to
    ``extent_mm[0]`` ahead of the front face, ``extent_mm[1]`` to either side."""
    front = length_mm / 2.0
    ahead, side, behind = extent_mm
    xs = np.arange(-behind, front + ahead + GRID_MM, GRID_MM)
    ys = np.arange(-side, side + GRID_MM, GRID_MM)
    gx, gy = np.meshgrid(xs, ys, indexing="ij")
    seen = np.zeros(gx.shape, dtype=np.int8)
    for s in sensors:
        dx, dy = gx - s.x_mm, gy - s.y_mm
        bearing = np.degrees(np.arctan2(dy, dx)) - s.yaw_deg
        off = np.abs((bearing + 180.0) % 360.0 - 180.0)
        seen += ((off <= s.fov_deg / 2.0) & (np.hypot(dx, dy) <= range_mm)).astype(np.int8)
    return Coverage(xs, ys, seen, front, width_mm / 2.0)


def layout_figures(
    sensors: Sequence[TofSensorConfig],
    length_mm: float,
    width_mm: float,
    walking_mm_s: float = 1600.0,
    crossings_mm: Sequence[float] = (500.0, 1000.0, 1500.0),
) -> dict[str, object]:
    """The figures that compare sensor layouts (docs/safety.md)."""
    cov = coverage(sensors, length_mm, width_mm)
    warnings = {
        f"{side_name} {ahead:.0f} mm": round(cov.warning_s(ahead, side, walking_mm_s), 3)
        for side, side_name in ((1.0, "left"), (-1.0, "right"))
        for ahead in crossings_mm
    }
    return {
        "corridor_full_from_mm": cov.corridor_full_from_mm(),
        "corridor_blind_m2_within_1m": round(cov.gaps_in_corridor(1000.0), 4),
        "warning_s": warnings,
    }


def svg(cov: Coverage, scale: float = 0.2, body_length_mm: float | None = None) -> str:
    """The coverage map as an SVG: cells seen by no cone dark, by one light, by several
    lighter; the body outline; x forward is up."""
    rows, cols = cov.seen_by.shape
    step = max(1, int(50.0 / GRID_MM))
    w, h = cols * GRID_MM * scale, rows * GRID_MM * scale
    colours = {0: "#3a3a3a", 1: "#9fd3a8", 2: "#c8ebcd"}
    parts = [
        f'<svg xmlns="http://www.w3.org/2000/svg" width="{w:.0f}" height="{h:.0f}" '
        f'viewBox="0 0 {w:.0f} {h:.0f}">'
    ]
    cell = step * GRID_MM * scale
    for i in range(0, rows, step):
        for j in range(0, cols, step):
            n = min(int(cov.seen_by[i, j]), 2)
            x = (cols - 1 - j) * GRID_MM * scale  # left of the robot on the left of the image
            y = (rows - 1 - i) * GRID_MM * scale
            parts.append(
                f'<rect x="{x:.1f}" y="{y - cell:.1f}" width="{cell:.1f}" height="{cell:.1f}" '
                f'fill="{colours[n]}"/>'
            )
    length = body_length_mm if body_length_mm is not None else 2 * cov.front_mm
    bx0 = (cols - 1 - np.searchsorted(cov.ys, cov.half_width_mm)) * GRID_MM * scale
    bw = 2 * cov.half_width_mm * scale
    by0 = (rows - 1 - np.searchsorted(cov.xs, cov.front_mm)) * GRID_MM * scale
    parts.append(
        f'<rect x="{bx0:.1f}" y="{by0:.1f}" width="{bw:.1f}" height="{length * scale:.1f}" '
        'fill="none" stroke="#d9534f" stroke-width="2"/>'
    )
    # The corridor the body sweeps driving ahead, dashed.
    for edge in (bx0, bx0 + bw):
        parts.append(
            f'<line x1="{edge:.1f}" y1="0" x2="{edge:.1f}" y2="{by0:.1f}" stroke="#d9534f" '
            'stroke-width="1" stroke-dasharray="4 4"/>'
        )
    parts.append(
        '<text x="6" y="16" font-family="sans-serif" font-size="12" fill="#fff">'
        "dark: no cone; green: one; light: several; red: body and its corridor</text>"
    )
    parts.append("</svg>")
    return "\n".join(parts)
