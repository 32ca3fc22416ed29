"""Where the fleet's other robots drove: the marks they left behind are forgotten.

A time-of-flight cone marks the whole arc where it reads something, and the costmap keeps a
mark no cone looks at again for ``obstacle_memory_s``, long enough for it to "stand still".
So another robot driving by leaves a trail of marks wherever this robot's cones no longer
look: with four robots (d273d26, seed 1) a robot setting off beside the car found, 1 m ahead
in its new lane, the 7.8 s old trail of a robot that had just driven out of the car, went
round it along the wall for 100 s and stood where its turn into the car had no room.
Counting a mark as standing only once the sensors see it again (tried) also held a robot
behind a person crossing its lane, and the later go-round met the person; this rule touches
only what the fleet's traffic explains. A mark is forgotten when it was last made while the
reported body of another robot, grown by what a cone's arc reaches beyond it, covered it,
and that robot has been reported out of reach of it since: it drove on, and so did what the
sensors saw there. A mark made again after that robot left (someone standing there, seen)
stays; a robot without a fleet gets no traffic, and nothing changes. The collision monitor
knows nothing of this and still stops the robot before anything its sensors see.
"""

from __future__ import annotations

import math
from collections import deque

import numpy as np

from coffeebot.messages import Traffic
from coffeebot.navigation.costmap import MAX_MARK_MM
from coffeebot.navigation.passing import MAX_AGE_S

REPORT_SLACK_S = 0.5
"""How much later than a reported position a mark may be made and still be that robot's:
the traffic comes about twice a second, and a robot between two reports is still there."""

REPORT_ERROR_MM = 100.0
"""How far a reported position may be from where the robot was: its estimate's error."""

PATH_STEP_MM = 50.0
"""Reported positions are joined by points this far apart: a driving robot's reports are
up to half a metre apart."""


class FleetTrails:
    """The other robots' recent ways, from the traffic, and which marks they explain."""

    def __init__(self, reach_mm: float, memory_s: float) -> None:
        """``reach_mm``: how far from a robot's reported centre its readings may mark (half
        its diagonal, a cone's arc beyond it, the report's error); ``memory_s``: how long
        the costmap keeps a mark, and so how far back a way is kept."""
        self.reach_mm = reach_mm
        self.memory_s = memory_s
        self._ways: dict[str, deque[tuple[float, int, float, float]]] = {}
        """Per robot: when (board clock), on which floor and where it was reported."""
        self._present: set[str] = set()
        """The robots of the latest traffic: only their whereabouts are known now."""

    @classmethod
    def of_robots(
        cls, length_mm: float, width_mm: float, half_fov_deg: float, memory_s: float
    ) -> FleetTrails:
        """Trails of robots of this size, read by cones ``half_fov_deg`` wide each side,
        marked out to ``MAX_MARK_MM`` and kept ``memory_s``."""
        arc_mm = MAX_MARK_MM * math.tan(math.radians(half_fov_deg))
        return cls(math.hypot(length_mm, width_mm) / 2 + arc_mm + REPORT_ERROR_MM, memory_s)

    def note(self, traffic: Traffic, now: float) -> None:
        """The fleet's other robots as the dispatcher reported them at ``now``."""
        self._present = set()
        for other in traffic.robots:
            if other.age_s > MAX_AGE_S:
                continue
            way = self._ways.setdefault(other.robot, deque())
            at = now - other.age_s
            if not way or at > way[-1][0]:
                way.append((at, other.floor, other.x_mm, other.y_mm))
            self._present.add(other.robot)
        for name, way in list(self._ways.items()):
            while way and way[0][0] < now - self.memory_s - REPORT_SLACK_S:
                way.popleft()
            if not way:
                del self._ways[name]

    def left_behind(
        self, floor_level: int, xs: np.ndarray, ys: np.ndarray, marked_at: np.ndarray
    ) -> np.ndarray:
        """Which of the marks at (``xs``, ``ys``) on ``floor_level``, each last made at
        ``marked_at``, another robot made there and has since left out of reach."""
        forget = np.zeros(xs.shape, dtype=bool)
        for name in self._present:
            times, px, py, left_floor = self._path(self._ways[name], floor_level)
            if times.size == 0:
                continue
            d2 = (xs[:, None] - px[None, :]) ** 2 + (ys[:, None] - py[None, :]) ** 2
            within = d2 <= self.reach_mm**2
            last_there = np.where(within, times[None, :], -math.inf).max(axis=1)
            if left_floor:
                gone = np.ones(xs.shape, dtype=bool)
            else:
                gone = np.hypot(xs - px[-1], ys - py[-1]) > self.reach_mm
            forget |= gone & (marked_at <= last_there + REPORT_SLACK_S)
        return forget

    @staticmethod
    def _path(
        way: deque[tuple[float, int, float, float]], floor_level: int
    ) -> tuple[np.ndarray, np.ndarray, np.ndarray, bool]:
        """The robot's way on ``floor_level`` as points at most ``PATH_STEP_MM`` apart, with
        when it was at each (reports on the floor joined, consecutive ones only), and
        whether its latest report is on another floor."""
        times: list[np.ndarray] = []
        xs: list[np.ndarray] = []
        ys: list[np.ndarray] = []
        previous: tuple[float, int, float, float] | None = None
        for report in way:
            t, level, x, y = report
            if level == floor_level:
                if previous is not None and previous[1] == floor_level:
                    t0, _, x0, y0 = previous
                    n = max(2, math.ceil(math.hypot(x - x0, y - y0) / PATH_STEP_MM) + 1)
                    part = np.linspace(0.0, 1.0, n)[1:]
                else:
                    t0, x0, y0, part = t, x, y, np.ones(1)
                times.append(t0 + (t - t0) * part)
                xs.append(x0 + (x - x0) * part)
                ys.append(y0 + (y - y0) * part)
            previous = report
        if not times:
            return np.empty(0), np.empty(0), np.empty(0), False
        left_floor = way[-1][1] != floor_level
        return np.concatenate(times), np.concatenate(xs), np.concatenate(ys), left_floor
