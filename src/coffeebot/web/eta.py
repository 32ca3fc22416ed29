"""When the coffee should arrive: what is left of the planned route, at the robot's pace.

An estimate, said as one ("in about 2 min"): the remaining length of the route navigation
published, from the point on it nearest the robot, at a typical delivery speed (slower than
cruising: the robot slows near people, doors and turns), plus a typical time for each
elevator ride still ahead. It moves as the robot does, so it corrects itself on the way.
"""

from __future__ import annotations

import itertools
import math
from collections.abc import Sequence
from dataclasses import dataclass

from coffeebot.messages import PlannedRoute, PoseEstimate
from coffeebot.navigation.path import polyline_length_mm


@dataclass(frozen=True)
class Pace:
    """How fast deliveries go, for the estimate."""

    travel_mm_s: float = 300.0
    """Average speed over a whole delivery, stops and slow stretches included."""
    elevator_ride_s: float = 60.0
    """Calling the car, riding and getting out."""
    pickup_timeout_s: float = 180.0
    """How long the robot waits at the door (the customer's countdown)."""


def remaining_on(points: Sequence[tuple[float, float]], x: float, y: float) -> float:
    """Length of ``points`` from the point on it nearest (x, y) to its end."""
    if len(points) < 2:
        return 0.0
    best, best_at = math.inf, 0.0
    walked = 0.0
    for (ax, ay), (bx, by) in itertools.pairwise(points):
        dx, dy = bx - ax, by - ay
        seg = math.hypot(dx, dy)
        t = 0.0 if seg == 0 else min(1.0, max(0.0, ((x - ax) * dx + (y - ay) * dy) / seg**2))
        off = math.hypot(x - (ax + t * dx), y - (ay + t * dy))
        if off < best:
            best, best_at = off, walked + t * seg
        walked += seg
    return walked - best_at


def arrival_in_s(route: PlannedRoute, pose: PoseEstimate, pace: Pace) -> float | None:
    """Seconds until the end of ``route`` from ``pose``; None if the robot is on no floor
    the route still passes."""
    for i, leg in enumerate(route.legs):
        if leg.floor != pose.floor:
            continue
        later = route.legs[i + 1 :]
        left_mm = remaining_on(leg.points, pose.x_mm, pose.y_mm)
        left_mm += sum(polyline_length_mm(other.points) for other in later)
        return left_mm / pace.travel_mm_s + len(later) * pace.elevator_ride_s
    return None
