"""Who caused a contact: the robot moving into something, or something moving into the robot.

In the spirit of ISO 3691-4 (a driverless vehicle must stop before it touches a person it can
detect in its path, and is to blame if it cannot) and ISO 13855 (people approach at up to
1600 mm/s, and the separation must allow for it): a contact is **robot-caused** when the
robot's body, at the point touched, was moving towards the object at more than
``MOVING_MM_S`` (driving, braking too late, turning a corner into it), and also when neither
was moving towards the other (the robot brushing something in its own way). It is counted
as **walked into the robot** only when the robot's body there was standing, moving away or
sliding past, and the object itself came towards the robot. ``docs/safety.md`` has the
argument.

Velocities are the body's true ones just before the touch (world ground truth): the body
turns about its driven axle, so a turning robot's corners move even when its centre barely
does. "Towards" is along the contact normal: from the body to a touched pole's axis, or a
touched face's normal; without the touched shape, the normal of the body's face (diagonal
at a corner).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Literal

import numpy as np

from coffeebot.floorplan import segment_distances
from coffeebot.sim.world.geometry import Surfaces
from coffeebot.sim.world.robot import BodyState, RobotSpec

MOVING_MM_S = 20.0
"""Slower than this towards the object counts as standing: the wheels ramp at 500 mm/s^2,
so this is 40 ms from rest, and the body carries next to no energy."""

CORNER_MM = 50.0
"""A touch this close to both faces of a corner is a corner touch."""

Cause = Literal["robot_caused", "walked_into_robot"]


@dataclass(frozen=True)
class ContactJudgement:
    element: str
    region: str
    """Where on the body: ``front``, ``left side``, ``rear-right corner``..."""
    robot_speed_mm_s: float
    """The body's signed forward speed."""
    robot_towards_mm_s: float
    """The touched point of the body, moving towards the object (negative: away)."""
    object_towards_mm_s: float
    """The object moving towards the body at the touch (negative: away)."""
    cause: Cause

    @property
    def closing_mm_s(self) -> float:
        """The relative speed along the contact normal."""
        return self.robot_towards_mm_s + self.object_towards_mm_s

    @property
    def robot_moving_towards(self) -> bool:
        return self.robot_towards_mm_s > MOVING_MM_S


def body_region(
    local_x: float, local_y: float, robot: RobotSpec
) -> tuple[str, tuple[float, float]]:
    """The face or corner nearest a point in the body frame, and its outward normal there."""
    half_l, half_w = robot.length_mm / 2, robot.width_mm / 2
    along = "front" if local_x >= 0 else "rear"
    side = "left" if local_y >= 0 else "right"
    nx = 1.0 if local_x >= 0 else -1.0
    ny = 1.0 if local_y >= 0 else -1.0
    to_end = half_l - abs(local_x)
    to_side = half_w - abs(local_y)
    if to_end <= CORNER_MM and to_side <= CORNER_MM:
        return f"{along}-{side} corner", (nx / math.sqrt(2), ny / math.sqrt(2))
    if to_end <= to_side:
        return along, (nx, 0.0)
    return f"{side} side", (0.0, ny)


def contact_normal(
    touched: Surfaces, point: tuple[float, float], body: BodyState
) -> tuple[float, float] | None:
    """The floor-frame direction from the body into what it touched at ``point``: towards
    the axis of the nearest touched cylinder, or the nearest touched segment's normal facing
    away from the body's centre. None when the shape does not tell (nothing given, or a
    pole's axis at the touch point)."""
    px, py = point
    best: tuple[float, tuple[float, float] | None] = (math.inf, None)
    for cx, cy, r, _zb, _zt in touched.cylinders:
        gap = math.hypot(cx - px, cy - py)
        if gap > 1e-6 and abs(gap - r) < best[0]:
            best = (abs(gap - r), ((cx - px) / gap, (cy - py) / gap))
    segments = touched.segments
    if len(segments):
        distances = segment_distances(segments, px, py)
        i = int(np.argmin(distances))
        x0, y0, x1, y1 = segments[i, :4]
        length = math.hypot(x1 - x0, y1 - y0)
        if distances[i] < best[0] and length > 1e-6:
            nx, ny = (y0 - y1) / length, (x1 - x0) / length
            if nx * (px - body.x) + ny * (py - body.y) < 0:
                nx, ny = -nx, -ny
            best = (float(distances[i]), (nx, ny))
    return best[1]


def judge_contact(
    element: str,
    point: tuple[float, float],
    body: BodyState,
    robot: RobotSpec,
    object_velocity: tuple[float, float] = (0.0, 0.0),
    touched: Surfaces | None = None,
) -> ContactJudgement:
    """Judge one touch at floor-frame ``point`` by a body in state ``body``; the object's
    velocity at the touch is ``object_velocity`` (mm/s, floor frame; zero for walls and
    anything standing) and ``touched`` its shape then, if known."""
    c, s = math.cos(body.theta), math.sin(body.theta)
    dx, dy = point[0] - body.x, point[1] - body.y
    region, (nx, ny) = body_region(c * dx + s * dy, -s * dx + c * dy, robot)
    found = None if touched is None else contact_normal(touched, point, body)
    normal = found or (c * nx - s * ny, s * nx + c * ny)
    # The body turns about its driven axle: velocity of the touched point.
    ax, ay = body.x + robot.axle_x_mm * c, body.y + robot.axle_x_mm * s
    rx, ry = point[0] - ax, point[1] - ay
    vx = body.speed_mm_s * c - body.yaw_rate_rad_s * ry
    vy = body.speed_mm_s * s + body.yaw_rate_rad_s * rx
    robot_towards = float(vx * normal[0] + vy * normal[1])
    object_towards = -float(object_velocity[0] * normal[0] + object_velocity[1] * normal[1])
    walked_into = robot_towards <= MOVING_MM_S and object_towards > MOVING_MM_S
    return ContactJudgement(
        element=element,
        region=region,
        robot_speed_mm_s=body.speed_mm_s,
        robot_towards_mm_s=robot_towards,
        object_towards_mm_s=object_towards,
        cause="walked_into_robot" if walked_into else "robot_caused",
    )
