"""Geometry shared by the side-sensor algorithms: sensor pairs, world poses, hallway sides."""

from __future__ import annotations

import math
from collections.abc import Iterable
from dataclasses import dataclass

import numpy as np

from coffeebot.config import TofSensorConfig
from coffeebot.floorplan import Floor, Side
from coffeebot.messages import RangeReading, ReadingStatus


def wrap_deg(angle: float) -> float:
    """An angle in degrees folded into [-180, 180)."""
    return (angle + 180.0) % 360.0 - 180.0


@dataclass(frozen=True)
class SidePair:
    """The two sensors on one side of the body, front one first (seed: 277 mm apart)."""

    side: Side
    front: TofSensorConfig
    rear: TofSensorConfig

    @property
    def baseline_mm(self) -> float:
        return self.front.x_mm - self.rear.x_mm

    @property
    def offset_mm(self) -> float:
        """How far the sensors sit from the body's centre line."""
        return abs(self.front.y_mm + self.rear.y_mm) / 2.0


def side_pairs(sensors: Iterable[TofSensorConfig]) -> dict[Side, SidePair]:
    """The left and right pairs of a sensor layout (sides with fewer than two are skipped)."""
    pairs: dict[Side, SidePair] = {}
    for side in ("left", "right"):
        on_side = sorted((s for s in sensors if s.face == side), key=lambda s: s.x_mm)
        if len(on_side) >= 2:
            pairs[side] = SidePair(side, front=on_side[-1], rear=on_side[0])
    return pairs


def valid_distance(reading: RangeReading | None) -> int | None:
    """The distance of a healthy, valid reading, else None."""
    if reading is None or not reading.healthy or reading.status is not ReadingStatus.VALID:
        return None
    return reading.distance_mm


def spread_rad(half_deg: float, num: int) -> np.ndarray:
    """``num`` ray directions across a cone of ``half_deg`` either side of its axis."""
    return np.radians(np.linspace(-half_deg, half_deg, num))


def sensor_origin(
    x_mm: float, y_mm: float, heading_deg: float, sensor: TofSensorConfig
) -> tuple[float, float, float]:
    """Where a sensor sits in the floor frame and which way it looks, for a robot pose."""
    return sensor_origins(x_mm, y_mm, heading_deg, (sensor,))[0]


def sensor_origins(
    x_mm: float, y_mm: float, heading_deg: float, sensors: Iterable[TofSensorConfig]
) -> list[tuple[float, float, float]]:
    """:func:`sensor_origin` of each of ``sensors``, the pose's cosine and sine taken once
    for all of them."""
    h = math.radians(heading_deg)
    c, s = math.cos(h), math.sin(h)
    return [
        (
            x_mm + c * sensor.x_mm - s * sensor.y_mm,
            y_mm + s * sensor.x_mm + c * sensor.y_mm,
            heading_deg + sensor.yaw_deg,
        )
        for sensor in sensors
    ]


@dataclass(frozen=True)
class TravelFrame:
    """The hallway as the robot travels it: direction of travel and which wall is on which side.

    A robot heading against the hallway's start->end direction has its left on the hallway's
    right; every side-sensor rule needs that mapping.
    """

    floor: Floor
    direction_deg: float
    reversed: bool

    @classmethod
    def for_heading(cls, floor: Floor, heading_deg: float) -> TravelFrame:
        axis = floor.hallway.heading_deg
        reversed_ = abs(wrap_deg(heading_deg - axis)) > 90.0
        return cls(floor, wrap_deg(axis + (180.0 if reversed_ else 0.0)), reversed_)

    def hallway_side(self, robot_side: Side) -> Side:
        if not self.reversed:
            return robot_side
        return "right" if robot_side == "left" else "left"

    def angle_deg(self, heading_deg: float) -> float:
        """The seed's angle: heading against the direction of travel, CCW positive."""
        return wrap_deg(heading_deg - self.direction_deg)

    def along(self, x_mm: float, y_mm: float) -> float:
        """Distance along the hallway axis (the floor plan's ``s``)."""
        return self.floor.to_hallway(x_mm, y_mm)[0]

    def lateral(self, x_mm: float, y_mm: float) -> float:
        """Offset from the hallway centre line, positive to the robot's left."""
        d = self.floor.to_hallway(x_mm, y_mm)[1]
        return -d if self.reversed else d
