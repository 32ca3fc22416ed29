"""The fleet's other robots as the planner sees them: outlines where they say they stand.

A time-of-flight cone says only that something lies on an arc about as wide as a third of
its range, so another robot standing in its own lane, 1 to 1.5 m ahead, marks cells across
half the hallway, in the lane of a robot that would pass it: that robot saw no way past a
robot waiting beside the elevator and stood there until the order failed. The dispatcher's
traffic says where each other robot stands, to a few centimetres, and the robots are all one
model: a reading that outline explains is marked as the outline, not as its arc
(:class:`coffeebot.navigation.costmap.LocalCostmap`). Only robots standing still count (a
driving robot's report is half a metre old at walking pace: its readings are marked as
anything's), only fresh reports, and the collision monitor, which knows nothing of this,
still stops the robot in front of anything its sensors see.
"""

from __future__ import annotations

import math
from collections.abc import Iterable

import numpy as np

from coffeebot.messages import OtherRobot
from coffeebot.navigation.passing import MAX_AGE_S
from coffeebot.rectangles import corners, sides


def standing_outlines(
    others: Iterable[OtherRobot],
    floor_level: int,
    length_mm: float,
    width_mm: float,
    age_s: float = 0.0,
) -> list[np.ndarray]:
    """The body outline (4, 4: the sides as x0, y0, x1, y1) of each other robot standing on
    ``floor_level``, reported within ``MAX_AGE_S`` (``age_s``: how old the traffic message
    is, added to each robot's own age)."""
    return [
        sides(corners(other.x_mm, other.y_mm, length_mm, width_mm, other.heading_deg))
        for other in others
        if other.floor == floor_level and not other.moving and other.age_s + age_s <= MAX_AGE_S
    ]


def outline_points(outline: np.ndarray, spacing_mm: float) -> tuple[np.ndarray, np.ndarray]:
    """Points along an outline's sides, at most ``spacing_mm`` apart."""
    xs, ys = [], []
    for x0, y0, x1, y1 in outline:
        n = max(2, math.ceil(math.hypot(x1 - x0, y1 - y0) / spacing_mm) + 1)
        xs.append(np.linspace(x0, x1, n))
        ys.append(np.linspace(y0, y1, n))
    return np.concatenate(xs), np.concatenate(ys)
