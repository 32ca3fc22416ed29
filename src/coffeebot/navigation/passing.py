"""The passing lane: two robots of a fleet meeting head-on in the hallway (no I/O).

Each robot keeps right at ``wall_distance_mm`` (300 mm) from the wall; in the 1700 mm
hallway two 510 mm bodies in their lanes then have 80 mm between them, and each one's
collision monitor stops it in front of the other: they end face to face, blocked (measured
with two simulated robots: one goes round, the other stays blocked). Both at 150 mm from the
wall they pass with no contact and lose a scan or two to the monitor; at 100 mm they pass
too, but with the wall 73 mm from a side, 23 mm outside the side radius (when a stop ahead
still raised every face's threshold by the hysteresis, the side then held one of them for
good). So while another robot comes the other way (or stands) in the hallway ahead, a
robot keeps to its passing lane, on the same side at ``passing_wall_distance_mm``, and goes
back to its lane once it is past.
Only the dispatcher's traffic tells a robot from an obstacle: without a fleet there is none,
and nothing changes.
"""

from __future__ import annotations

import math
from collections.abc import Iterable

from coffeebot.floorplan import Floor
from coffeebot.messages import OtherRobot

LOOKAHEAD_MM = 6000.0
"""Another robot this far ahead is met: two robots closing at 1 m/s have six seconds, time
for both to move over by 150 mm."""

MAX_AGE_S = 2.0
"""Older positions are no traffic: a robot at 500 mm/s has moved a metre since."""

ONCOMING_COS = -0.5
"""Coming the other way: heading within 60 degrees of against the direction of travel."""


def oncoming(
    others: Iterable[OtherRobot],
    floor: Floor,
    s_mm: float,
    direction: float,
    passed_mm: float,
    age_s: float = 0.0,
    standing: bool = True,
) -> str | None:
    """The first robot that calls for the passing lane of a robot at ``s_mm`` along
    ``floor``'s hallway travelling towards ``direction`` (+1/-1 in s), if any: on this floor,
    in the hallway (not in a room or a door recess), ahead within ``LOOKAHEAD_MM`` or not yet
    ``passed_mm`` behind, and coming the other way or standing (one driving the same way is
    followed, and one in the way is gone round, as any obstacle). ``age_s``: how old the
    traffic message is, added to each robot's own age; ``standing``: whether one standing
    counts."""
    half_width = floor.hallway.width_mm / 2
    travel = floor.travel_deg(direction)
    for other in others:
        if other.floor != floor.level or other.age_s + age_s > MAX_AGE_S:
            continue
        s, d = floor.to_hallway(other.x_mm, other.y_mm)
        ahead = (s - s_mm) * direction
        if abs(d) > half_width or not -passed_mm < ahead <= LOOKAHEAD_MM:
            continue
        facing = math.cos(math.radians(other.heading_deg - travel))
        if (facing <= ONCOMING_COS and other.moving) or (standing and not other.moving):
            return other.robot
    return None


def right_lane_mm(
    floor: Floor, direction: float, wall_distance_mm: float, body_width_mm: float
) -> float:
    """The centre (``d``) of a lane on the right travelling towards ``direction``, the body's
    side ``wall_distance_mm`` from the wall: the keep-right lane at ``wall_distance_mm``, the
    passing lane at ``passing_wall_distance_mm``."""
    offset = floor.hallway.width_mm / 2 - wall_distance_mm - body_width_mm / 2
    return -direction * max(0.0, offset)
