"""Which sensors' cones meet given segments short of what they read (no I/O).

The particle filter leaves a reading out when something the floor plan does not have may
have made it: the car behind an open elevator door (:mod:`coffeebot.perception.elevator_mask`),
another robot of the fleet (:mod:`coffeebot.perception.robot_mask`). Both ask the same
question of the scan: from the estimate, with its heading uncertain, does the cone cross one
of these segments before the reading's range?
"""

from __future__ import annotations

import math
from collections.abc import Mapping

import numpy as np

from coffeebot.config import TofSensorConfig
from coffeebot.messages import RangeScan, ReadingStatus
from coffeebot.perception.geometry import sensor_origins, spread_rad
from coffeebot.perception.walls import segment_ranges

CONE_RAYS = 9
"""Rays across each widened cone: at 1.5 m they lie at most ~100 mm apart, a tenth of a
doorway."""


def cones_meeting(
    sensors: Mapping[int, TofSensorConfig],
    scan: RangeScan,
    pose: tuple[float, float, float],
    heading_margin_deg: float,
    segments: np.ndarray,
    margin_mm: float,
    reach_mm: float | None,
) -> frozenset[int]:
    """The sensors of ``scan`` whose cone, from ``pose`` (x mm, y mm, heading deg) and
    widened by ``heading_margin_deg``, meets one of ``segments`` (k, 4: x0, y0, x1, y1)
    before a valid reading's range plus ``margin_mm``, or, when nothing was ranged, within
    ``reach_mm`` (None: such a reading is kept)."""
    if segments.size == 0:
        return frozenset()
    ids, mounts, reach = [], [], []
    for reading in scan.readings:
        mount = sensors.get(reading.sensor)
        if mount is None:
            continue
        if reading.status is ReadingStatus.VALID and reading.distance_mm is not None:
            reach.append(reading.distance_mm + margin_mm)
        elif reach_mm is not None:
            reach.append(reach_mm)
        else:
            continue
        ids.append(reading.sensor)
        mounts.append(mount)
    if not ids:
        return frozenset()
    placed = sensor_origins(*pose, mounts)
    origins = np.array([(x, y) for x, y, _ in placed])
    spread = [spread_rad(mount.fov_deg / 2 + heading_margin_deg, CONE_RAYS) for mount in mounts]
    angles = np.stack(
        [math.radians(look) + rays for (_, _, look), rays in zip(placed, spread, strict=True)]
    )
    ranges = segment_ranges(segments, origins, angles, np.array(reach)).min(axis=1)
    return frozenset(i for i, r in zip(ids, ranges, strict=True) if math.isfinite(r))
