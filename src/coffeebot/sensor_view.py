"""What each time-of-flight sensor sees, for people: its field of view from its mount, as
far as its reading reaches, and the reading in words. The live map and Foxglove draw these.

Drawn from each sensor's configured pose and field of view, so a change of layout in the
robot description shows as it is.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from typing import Literal

from pydantic import BaseModel

from coffeebot.config import TofSensorConfig
from coffeebot.messages import NOTHING_IN_RANGE, RangeReading, ReadingStatus

Reach = Literal["hit", "clear", "fault"]


class ConeShape(BaseModel):
    """One sensor's field of view from its mount, as far as its reading reaches."""

    kind: Literal["cone"] = "cone"
    sensor: int
    reach: Reach
    """``hit``: something at ``range_mm``; ``clear``: nothing in range; ``fault``: no reading."""
    status: str
    text: str
    """The reading in words, for the cone's label and tooltip."""
    x_mm: float
    y_mm: float
    heading_deg: float
    half_fov_deg: float
    range_mm: float


def reach(reading: RangeReading, max_range_mm: float) -> tuple[Reach, float, str]:
    """How far to draw a reading, what it means and its words."""
    fault = f"no reading ({reading.status.value.replace('_', ' ')})"
    if not reading.healthy:
        return "fault", 0.0, fault
    if reading.status is ReadingStatus.VALID and reading.distance_mm is not None:
        return "hit", float(reading.distance_mm), f"{reading.distance_mm} mm"
    if reading.status is ReadingStatus.TOO_CLOSE:
        return "hit", float(reading.distance_mm or 0), "too close to range"
    if reading.status in NOTHING_IN_RANGE:
        return "clear", max_range_mm, "nothing in range"
    return "fault", 0.0, fault


def sensor_cones(
    readings: Sequence[RangeReading],
    sensors: Sequence[TofSensorConfig],
    x_mm: float,
    y_mm: float,
    heading_deg: float,
    max_range_mm: float,
) -> list[ConeShape]:
    """One cone per reading, for a body centred at (x, y) facing ``heading_deg``."""
    mounts = {s.id: s for s in sensors}
    h = math.radians(heading_deg)
    cones = []
    for reading in readings:
        mount = mounts.get(reading.sensor)
        if mount is None:
            continue
        kind, length, text = reach(reading, max_range_mm)
        cones.append(
            ConeShape(
                sensor=reading.sensor,
                reach=kind,
                status=reading.status.value,
                text=f"tof{reading.sensor}: {text}",
                x_mm=x_mm + mount.x_mm * math.cos(h) - mount.y_mm * math.sin(h),
                y_mm=y_mm + mount.x_mm * math.sin(h) + mount.y_mm * math.cos(h),
                heading_deg=heading_deg + mount.yaw_deg,
                half_fov_deg=mount.fov_deg / 2,
                range_mm=length,
            )
        )
    return cones
