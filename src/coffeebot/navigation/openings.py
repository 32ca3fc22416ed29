"""Slow zones at openings: where someone can step out in front of the robot unseen (no I/O).

A side hallway or a stair lobby opens onto the hallway through a gap in its wall, the
*mouth*. The ToF cones look along the hallway, not round the mouth's corner, so someone
walking out of the opening is seen only once they are past the wall line, and only where a
cone reaches that line: the outer front cone on that side meets it some way ahead of the
front face (``sight_mm``), the side cones beside the body, and between the two lies the
blind wedge (``perception/coverage.py``). Tracking and the collision rules can only act on
what is seen, and from the rated speed the robot needs 1.2 s to stand.

So while the front is before or alongside a mouth, the speed is capped at the highest from
which the robot stands before someone who steps out at the nearest point of the mouth the
outer front cone sees, and walks straight at its front at ``[openings] walking_speed_mm_s``
(ISO 13855's 1600 mm/s), reaches it: :func:`~coffeebot.perception.collision.safe_speed_mm_s`
over the distance ``D`` from the front face's corner to that point, less the collision
config's margin, with the walker closing at that speed. Far ahead of the mouth ``D`` is the
distance to its near edge, and the cap is above the cruise speed; from where the near edge
passes out of the outer cone's sight, ``D`` is the distance to the point where the cone's
edge meets the wall line, and the cap holds until the front face is past the mouth's far
edge. Someone stepping out beside the body, behind the front face, meets its side: a body
sliding past is not driving into them.

The zone follows the robot's lateral position: an opening on the robot's own side (keeping
right, 300 mm beside the body) is seen late and close, one across the hallway early and far.
"""

from __future__ import annotations

import math
from collections.abc import Iterable
from dataclasses import dataclass

from coffeebot.config import CollisionConfig, OpeningsConfig, TofSensorConfig
from coffeebot.floorplan import Floor, Opening
from coffeebot.perception.collision import safe_speed_mm_s


@dataclass(frozen=True)
class ZoneLimit:
    """The speed cap of the opening that binds, and why."""

    speed_mm_s: float
    opening: str
    """The opening's id."""
    distance_mm: float
    """``D``: from the front face's corner to the nearest point of the mouth seen."""

    @property
    def reason(self) -> str:
        return f"opening {self.opening}: someone may step out {self.distance_mm:.0f} mm away"


@dataclass(frozen=True)
class _Cone:
    """A front sensor's cone edge furthest to one side, in the robot frame."""

    x_mm: float
    lateral_mm: float
    """The sensor's offset towards that side."""
    edge_rad: float
    """The cone's outer edge's angle off the body's axis, towards that side."""


class OpeningZones:
    """Speed caps near the floor plan's openings, from the robot's braking and its cones."""

    def __init__(
        self,
        cfg: OpeningsConfig,
        collision: CollisionConfig,
        sensors: Iterable[TofSensorConfig],
        body_width_mm: float,
        body_length_mm: float,
    ) -> None:
        self.cfg = cfg
        self.collision = collision
        self.half_width_mm = body_width_mm / 2.0
        self.front_mm = body_length_mm / 2.0
        front = [s for s in sensors if s.face == "front"]
        self._cones: dict[float, _Cone] = {}
        for side in (1.0, -1.0):
            # The cone reaching furthest to that side: its outer edge and where it starts.
            best = max(front, key=lambda s: side * s.yaw_deg + s.fov_deg / 2.0)
            self._cones[side] = _Cone(
                best.x_mm,
                side * best.y_mm,
                math.radians(side * best.yaw_deg + best.fov_deg / 2.0),
            )

    def sight_mm(self, side: float, wall_mm: float) -> float:
        """How far ahead of the front face the outer front cone on ``side`` (+1 left, -1
        right) first reaches a wall line ``wall_mm`` off the robot's centre line (inf: it
        never does)."""
        cone = self._cones[side]
        if cone.edge_rad <= 0.0:
            return math.inf
        reach = cone.x_mm - self.front_mm
        if cone.edge_rad < math.pi / 2:
            reach += max(0.0, wall_mm - cone.lateral_mm) / math.tan(cone.edge_rad)
        return max(0.0, reach)

    def cap_mm_s(self, side: float, wall_mm: float, near_ahead_mm: float) -> tuple[float, float]:
        """The cap (and ``D``) for a mouth on ``side`` of the robot whose wall line is
        ``wall_mm`` off its centre line and whose near edge is ``near_ahead_mm`` ahead of the
        front face (negative: the front is alongside)."""
        gap = max(0.0, wall_mm - self.half_width_mm)
        ahead = max(near_ahead_mm, self.sight_mm(side, wall_mm))
        distance = math.hypot(max(0.0, ahead), gap)
        cfg = self.collision
        cap = safe_speed_mm_s(cfg, distance - cfg.margin_mm, self.cfg.walking_speed_mm_s)
        return cap, distance

    def limit(
        self, floor: Floor, s_mm: float, d_mm: float, direction: float, max_mm_s: float
    ) -> ZoneLimit | None:
        """The binding cap for a robot at hallway position (``s_mm``, ``d_mm``) driving
        towards ``direction`` (+1: increasing ``s``) along the hallway, if any is below
        ``max_mm_s``. Outside the hallway there is none: the cones see a room's walls."""
        if not self.cfg.slow_zones or abs(d_mm) > floor.hallway.width_mm / 2.0:
            return None
        front_s = s_mm + direction * self.front_mm
        found: ZoneLimit | None = None
        # The openings along this hallway, and the mouths of the hallways that join it.
        for opening in floor.features():
            if not isinstance(opening, Opening):
                continue
            lo, hi = opening.span
            near, far = (lo, hi) if direction > 0 else (hi, lo)
            if (far - front_s) * direction < 0:
                continue  # the front is past it
            wall_d = floor.hallway.width_mm / 2.0 * (1.0 if opening.side == "left" else -1.0)
            side = 1.0 if (wall_d - d_mm) * direction > 0 else -1.0
            cap, distance = self.cap_mm_s(side, abs(wall_d - d_mm), (near - front_s) * direction)
            if cap < max_mm_s and (found is None or cap < found.speed_mm_s):
                found = ZoneLimit(cap, opening.id, distance)
        return found
