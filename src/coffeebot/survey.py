"""Survey check: a recorded pass against the floor plan, wall by wall.

Floor plans are surveyed with a tape measure, and a tape measure errs. A pass recorded with
``--record`` holds every ToF scan and the localized pose; this puts each reading where the
pose says it was and compares it with the surface of the plan it faces:

* only readings that face a plan segment squarely are used (their axis within
  ``max_incidence_deg`` of the segment's normal, and the cone's whole footprint on the
  segment, not straddling its end onto a jamb or the next wall): then the reading is the
  perpendicular distance to that surface whatever the cone's exact ranging model, and a few
  degrees of heading error change it by well under a millimetre;
* each reading gives ``measured - planned`` (positive: the surface is further than planned);
* readings are grouped by segment and by ``bin_mm`` along it; a bin whose median disagrees
  by more than the threshold, on ``min_readings`` readings or more, is reported, adjacent
  bins of one segment that agree in sign merged into one stretch.

The poses were localized against the plan being checked, so a misplaced wall pulls them a
little towards itself: the offset reported is then somewhat smaller than the real one, and
its sign right. Other walls, the opposite one and UWB hold the pose; a whole hallway drawn
too narrow shows on both sides.
"""

from __future__ import annotations

import math
from collections import defaultdict
from collections.abc import Iterable
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from coffeebot.board.recording import read_recording
from coffeebot.config import TofSensorConfig
from coffeebot.floorplan import Floor, FloorPlan
from coffeebot.messages import ALL_TOPICS, CURRENT_STATE, RANGE_SCAN, PoseEstimate, RangeScan
from coffeebot.messages import ReadingStatus as Status

FOOTPRINT_MARGIN_MM = 50.0
"""Kept between the cone's footprint and a segment's end: the pose is not exact either."""


@dataclass(frozen=True)
class Disagreement:
    """A stretch of one plan surface that the readings put elsewhere."""

    floor: int
    element: str
    from_xy_mm: tuple[float, float]
    to_xy_mm: tuple[float, float]
    offset_mm: float
    """Median of measured minus planned distance: positive, the surface is further away."""
    readings: int

    def describe(self) -> str:
        (x0, y0), (x1, y1) = self.from_xy_mm, self.to_xy_mm
        way = "further than planned" if self.offset_mm > 0 else "nearer than planned"
        return (
            f"floor {self.floor}: {self.element} from ({x0:.0f}, {y0:.0f}) to ({x1:.0f}, "
            f"{y1:.0f}) mm: {abs(self.offset_mm):.0f} mm {way} ({self.readings} readings)"
        )


@dataclass(frozen=True)
class Observation:
    floor: int
    segment: int
    along_mm: float
    offset_mm: float


class SurveyCheck:
    """Accumulates observations from scans at poses; :meth:`disagreements` reports."""

    def __init__(
        self,
        plan: FloorPlan,
        sensors: Iterable[TofSensorConfig],
        *,
        max_range_mm: float = 2000.0,
        max_incidence_deg: float = 10.0,
        gate_mm: float = 300.0,
        max_pose_sigma_mm: float = 100.0,
    ) -> None:
        self.plan = plan
        self.mounts = {s.id: s for s in sensors}
        self.max_range_mm = max_range_mm
        self.cos_incidence = math.cos(math.radians(max_incidence_deg))
        self.gate_mm = gate_mm
        self.max_pose_sigma_mm = max_pose_sigma_mm
        self.observations: list[Observation] = []

    def add(self, scan: RangeScan, pose: PoseEstimate) -> None:
        if not pose.initialised or max(pose.sigma_x_mm, pose.sigma_y_mm) > self.max_pose_sigma_mm:
            return
        try:
            floor = self.plan.floor(pose.floor)
        except KeyError:
            return
        segments = floor.segment_array[:, :4]
        if not len(segments):
            return
        th = math.radians(pose.heading_deg)
        c, s = math.cos(th), math.sin(th)
        for reading in scan.readings:
            mount = self.mounts.get(reading.sensor)
            distance = reading.distance_mm
            if (
                mount is None
                or not reading.healthy
                or reading.status is not Status.VALID
                or distance is None
                or not 0 < distance <= self.max_range_mm
            ):
                continue
            ox = pose.x_mm + c * mount.x_mm - s * mount.y_mm
            oy = pose.y_mm + s * mount.x_mm + c * mount.y_mm
            yaw = th + math.radians(mount.yaw_deg)
            spread = math.tan(math.radians(mount.fov_deg / 2))
            ray = (ox, oy, math.cos(yaw), math.sin(yaw), spread)
            self._observe(floor, segments, ray, distance)

    def _observe(
        self,
        floor: Floor,
        seg: np.ndarray,
        ray: tuple[float, float, float, float, float],
        r: float,
    ) -> None:
        """One reading from ``ray`` (origin, axis, tan of the half cone) of range ``r``."""
        ox, oy, ux, uy, spread = ray
        ex, ey = seg[:, 2] - seg[:, 0], seg[:, 3] - seg[:, 1]
        length = np.maximum(np.hypot(ex, ey), 1e-9)
        t = ((ox - seg[:, 0]) * ex + (oy - seg[:, 1]) * ey) / length**2
        fx, fy = seg[:, 0] + t * ex - ox, seg[:, 1] + t * ey - oy  # origin -> foot
        perpendicular = np.hypot(fx, fy)
        facing = (fx * ux + fy * uy) >= self.cos_incidence * np.maximum(perpendicular, 1e-9)
        along = t * length
        footprint = perpendicular * spread + FOOTPRINT_MARGIN_MM
        inside = (along >= footprint) & (along <= length - footprint)
        ok = inside & facing & (np.abs(r - perpendicular) <= self.gate_mm)
        if not ok.any():
            return
        index = int(np.flatnonzero(ok)[np.argmin(perpendicular[ok])])
        self.observations.append(
            Observation(
                floor.level,
                index,
                float(t[index] * length[index]),
                float(r - perpendicular[index]),
            )
        )

    def disagreements(
        self, threshold_mm: float = 50.0, *, bin_mm: float = 500.0, min_readings: int = 10
    ) -> list[Disagreement]:
        bins: dict[tuple[int, int, int], list[float]] = defaultdict(list)
        for o in self.observations:
            bins[(o.floor, o.segment, int(o.along_mm // bin_mm))].append(o.offset_mm)
        flagged: dict[tuple[int, int], list[tuple[int, float, int]]] = defaultdict(list)
        for (level, segment, k), offsets in sorted(bins.items()):
            median = float(np.median(offsets))
            if len(offsets) >= min_readings and abs(median) > threshold_mm:
                flagged[(level, segment)].append((k, median, len(offsets)))
        found = []
        for (level, segment), rows in flagged.items():
            floor = self.plan.floor(level)
            stretch: list[tuple[int, float, int]] = []
            for row in rows:
                if stretch and (row[0] != stretch[-1][0] + 1 or row[1] * stretch[-1][1] < 0):
                    found.append(self._stretch(floor, segment, stretch, bin_mm))
                    stretch = []
                stretch.append(row)
            found.append(self._stretch(floor, segment, stretch, bin_mm))
        return sorted(found, key=lambda d: -abs(d.offset_mm))

    @staticmethod
    def _stretch(
        floor: Floor, segment: int, rows: list[tuple[int, float, int]], bin_mm: float
    ) -> Disagreement:
        wall = floor.segments[segment]
        length = math.hypot(wall.x1 - wall.x0, wall.y1 - wall.y0)

        def at(along: float) -> tuple[float, float]:
            f = min(max(along / length, 0.0), 1.0) if length > 0 else 0.0
            return (wall.x0 + f * (wall.x1 - wall.x0), wall.y0 + f * (wall.y1 - wall.y0))

        weights = np.array([n for _, _, n in rows], dtype=float)
        medians = np.array([m for _, m, _ in rows])
        return Disagreement(
            floor=floor.level,
            element=wall.element,
            from_xy_mm=at(rows[0][0] * bin_mm),
            to_xy_mm=at((rows[-1][0] + 1) * bin_mm),
            offset_mm=round(float(np.average(medians, weights=weights)), 1),
            readings=int(weights.sum()),
        )


def check_recording(
    path: str | Path, plan: FloorPlan, sensors: Iterable[TofSensorConfig], **options: float
) -> SurveyCheck:
    """Every scan of a recording at the latest pose published before it."""
    check = SurveyCheck(plan, sensors, **options)
    pose: PoseEstimate | None = None
    for message in read_recording(path, ALL_TOPICS, only=[RANGE_SCAN.name, CURRENT_STATE.name]):
        if message.topic == CURRENT_STATE.name:
            pose = message.msg.pose  # type: ignore[attr-defined]
        elif pose is not None:
            check.add(message.msg, pose)  # type: ignore[arg-type]
    return check
