"""The readings that may have looked into an elevator car: the particle filter leaves them out.

The plan has each elevator's closed leaf, not the car behind it: with the doors open, a cone
through the doorway reads the car's back wall or a robot riding in it, and weighed against
the leaf those readings slid the cloud sideways into the jamb (docs/localization.md). Every
scan used to be dropped within ``blind_mm`` (2 m) of the door, which left a robot leaving
the tea room opposite the elevator on odometry and UWB alone for the turn into the hallway
and the first metres after it: its heading a few degrees off from the turn, its estimate
drifted 60-110 mm across the hallway where lane keeping put it, in the fleet, 70 mm from the
wall.

So the whole scan is left out near a door only while the robot may be looking into the car
with most of its cones: within ``blind_mm`` of the door with its heading more than
``ALONG_HALLWAY_DEG`` off the hallway's (facing the car, driving into it or out, turning in
front of it), or with the body centre within ``margin_mm`` of the wall line in the doorway.
Along the hallway only a reading that may have looked through the doorway is left out: one
whose cone, from the estimate and widened by the estimate's heading uncertainty, crosses the
door's mouth (the wall line between the jambs, widened by ``margin_mm`` each side for the
position's) or its leaf's line behind it, before the reading's range plus ``margin_mm`` or,
when nothing was ranged, within ``reach_mm``.

A door the elevator interface reports shut (its car elsewhere, travelling, or here with the
doors closed) is the plan's leaf and nothing behind it: the readings towards it are weighed
like any wall's, facing it too, and only the doorway rule stays (a robot in the doorway or
in the car sees the car's walls, which the plan does not have). The caller says which doors
are shut; a door it knows nothing of may be open.
"""

from __future__ import annotations

import math
from collections.abc import Sequence

import numpy as np

from coffeebot.config import TofSensorConfig
from coffeebot.floorplan import Floor
from coffeebot.messages import RangeScan
from coffeebot.perception.cones import cones_meeting

ALONG_HALLWAY_DEG = 45.0
"""Heading this close to the hallway's, either way, only the cones on the car's side can
see into it, and the mask leaves those out; further off, most cones can."""


class ElevatorMask:
    """The readings of a scan that may have looked into an elevator car, per floor."""

    def __init__(
        self,
        sensors: Sequence[TofSensorConfig],
        margin_mm: float,
        blind_mm: float,
        reach_mm: float,
    ) -> None:
        self.sensors = {s.id: s for s in sensors}
        self.margin_mm = margin_mm
        self.blind_mm = blind_mm
        self.reach_mm = reach_mm
        body = max((math.hypot(s.x_mm, s.y_mm) for s in sensors), default=0.0)
        self._longest_mm = reach_mm + margin_mm + body
        """How far from the body centre a widened reading can reach."""
        self._mouths: dict[int, np.ndarray] = {}
        self._doors: dict[int, list[str]] = {}
        """Per floor: the door each row of the mouths belongs to."""
        self._centres: dict[int, tuple[np.ndarray, np.ndarray]] = {}
        """Per floor: each mouth's midpoint (k, 2) and half its length (k,)."""

    def mouths(self, floor: Floor) -> np.ndarray:
        """Each elevator door's mouth and its leaf's line on ``floor`` (k, 4: x0, y0, x1,
        y1), widened along the wall by ``margin_mm`` each side."""
        if floor.level not in self._mouths:
            rows, doors = [], []
            for door in floor.elevators:
                hallway = floor.hallway_of(door)
                sign = 1.0 if door.side == "left" else -1.0
                lo, hi = door.span
                for d in (hallway.width_mm / 2, hallway.width_mm / 2 + door.recess_mm):
                    rows.append(
                        (
                            *hallway.from_local(lo - self.margin_mm, sign * d),
                            *hallway.from_local(hi + self.margin_mm, sign * d),
                        )
                    )
                    doors.append(door.id)
            mouths = np.array(rows, dtype=float).reshape(-1, 4)
            self._mouths[floor.level] = mouths
            self._doors[floor.level] = doors
            self._centres[floor.level] = (
                (mouths[:, 0:2] + mouths[:, 2:4]) / 2,
                np.hypot(mouths[:, 2] - mouths[:, 0], mouths[:, 3] - mouths[:, 1]) / 2,
            )
        return self._mouths[floor.level]

    def blind(
        self,
        floor: Floor,
        x_mm: float,
        y_mm: float,
        heading_deg: float,
        shut: frozenset[str] = frozenset(),
    ) -> bool:
        """Whether the whole scan is to be left out, the estimate being at ``x_mm``,
        ``y_mm`` looking along ``heading_deg``: in a doorway, or near one that is not in
        ``shut`` (door ids) and not looking along the hallway."""
        for door in floor.elevators:
            hallway = floor.hallway_of(door)
            s, d = hallway.to_local(x_mm, y_mm)
            lo, hi = door.span
            outward = d if door.side == "left" else -d
            wall = hallway.width_mm / 2
            if lo - self.margin_mm <= s <= hi + self.margin_mm and outward > wall - self.margin_mm:
                return True
            if door.id in shut:
                continue
            off_axis = abs(math.remainder(heading_deg - hallway.heading_deg, 180.0))
            near = math.dist(floor.behind_door(door, 0.0), (x_mm, y_mm)) < self.blind_mm
            if near and off_axis > ALONG_HALLWAY_DEG:
                return True
        return False

    def _near(self, floor: Floor, x_mm: float, y_mm: float) -> np.ndarray:
        """Which mouths on ``floor`` lie within the longest reach of the body centre (a
        cheap test first: most scans are taken nowhere near an elevator)."""
        middles, halves = self._centres[floor.level]
        gaps = np.hypot(middles[:, 0] - x_mm, middles[:, 1] - y_mm) - halves
        return gaps <= self._longest_mm

    def masked(
        self,
        floor: Floor,
        scan: RangeScan,
        pose: tuple[float, float, float],
        heading_margin_deg: float,
        shut: frozenset[str] = frozenset(),
    ) -> frozenset[int]:
        """The sensors whose reading in ``scan`` may have looked through a doorway not in
        ``shut`` (door ids), from ``pose`` (x mm, y mm, heading deg) with its heading
        ``heading_margin_deg`` uncertain."""
        mouths = self.mouths(floor)
        near = self._near(floor, pose[0], pose[1])
        if shut:
            near &= np.array([door not in shut for door in self._doors[floor.level]], dtype=bool)
        if not near.any():
            return frozenset()
        return cones_meeting(
            self.sensors,
            scan,
            pose,
            heading_margin_deg,
            mouths[near],
            self.margin_mm,
            self.reach_mm,
        )
