"""The obstacles of the seed's evaluation, built from boxes and poles with heights.

Dimensions are typical of the furniture named in seed 000 (section V.A); what matters for the
sensors at ~250 mm is what exists at that height: the mail cart's lower shelf tops out 20 mm
below it and only its four corner bars cross it; the swivel chair shows a single pole with
fabric under the seat above; the wooden chair shows four thin legs.
"""

from __future__ import annotations

import bisect
import itertools
import math
from dataclasses import dataclass
from typing import Literal

import numpy as np
from pydantic import BaseModel, ConfigDict, Field

from coffeebot.sim.world.geometry import Surfaces

ObstacleKind = Literal[
    "mail_cart", "swivel_chair", "sofa", "wooden_chair", "cardboard_box", "person"
]


@dataclass(frozen=True)
class Box:
    """An upright box in the obstacle's frame (x along its heading): four vertical faces."""

    part: str
    cx: float
    cy: float
    length: float
    width: float
    z_bottom: float
    z_top: float


@dataclass(frozen=True)
class Pole:
    """An upright cylinder in the obstacle's frame."""

    part: str
    cx: float
    cy: float
    radius: float
    z_bottom: float
    z_top: float


def _corners(half_x: float, half_y: float) -> list[tuple[float, float]]:
    return [(sx * half_x, sy * half_y) for sx, sy in itertools.product((1, -1), (1, -1))]


SHAPES: dict[str, tuple[Box | Pole, ...]] = {
    # Two shelves joined by thick plastic bars at the corners; 900 x 500 mm.
    "mail_cart": (
        Box("lower shelf", 0, 0, 900, 500, 100, 230),
        Box("upper shelf", 0, 0, 900, 500, 750, 900),
        *(Pole("corner bar", x, y, 15, 100, 900) for x, y in _corners(435, 235)),
    ),
    # One large pole from the wheeled base to the seat, fabric under the seat, a backrest.
    "swivel_chair": (
        Pole("pole", 0, 0, 30, 100, 400),
        Box("seat fabric", 0, 0, 440, 440, 400, 430),
        Box("seat", 0, 0, 480, 480, 430, 500),
        Box("backrest", -215, 0, 50, 440, 550, 1000),
    ),
    # Solid armrests and base: a box from the side.
    "sofa": (Box("body", 0, 0, 2000, 900, 0, 850),),
    "wooden_chair": (
        *(Pole("leg", x, y, 15, 0, 450) for x, y in _corners(190, 190)),
        Box("seat", 0, 0, 420, 420, 430, 470),
        Box("backrest", -200, 0, 20, 420, 470, 900),
    ),
    "cardboard_box": (Box("box", 0, 0, 500, 400, 0, 400),),
    # What a 250 mm sensor sees of a person is two legs; the torso matters for collisions.
    "person": (
        Pole("leg", 0, 100, 60, 0, 850),
        Pole("leg", 0, -100, 60, 0, 850),
        Pole("torso", 0, 0, 180, 850, 1750),
    ),
}


class ObstacleSpec(BaseModel):
    """An obstacle placed on a floor, optionally moving along a path at a constant speed."""

    model_config = ConfigDict(frozen=True, extra="forbid", allow_inf_nan=False)

    id: str
    kind: ObstacleKind
    floor: int
    x_mm: float
    y_mm: float
    heading_deg: float = 0.0
    path: list[tuple[float, float]] = Field(
        default=[], description="waypoints visited after the start point"
    )
    speed_mm_s: float = Field(0.0, ge=0)
    path_mode: Literal["once", "loop", "back_and_forth"] = "back_and_forth"

    @property
    def moving(self) -> bool:
        return bool(self.path) and self.speed_mm_s > 0

    def pose_at(self, t_s: float) -> tuple[float, float, float]:
        """(x, y, heading in rad) at simulated time ``t_s``; a pure function of time."""
        if not self.moving:
            return self.x_mm, self.y_mm, math.radians(self.heading_deg)
        points = [(self.x_mm, self.y_mm), *self.path]
        if self.path_mode == "loop":
            points.append(points[0])
        lengths = [math.dist(a, b) for a, b in itertools.pairwise(points)]
        cumulative = list(itertools.accumulate(lengths))
        total = cumulative[-1]
        travelled = self.speed_mm_s * t_s
        backwards = False
        if self.path_mode == "once":
            travelled = min(travelled, total)
        elif self.path_mode == "loop":
            travelled %= total
        else:
            travelled %= 2 * total
            if travelled > total:
                travelled, backwards = 2 * total - travelled, True
        i = min(bisect.bisect_left(cumulative, travelled), len(lengths) - 1)
        start = cumulative[i] - lengths[i]
        (ax, ay), (bx, by) = points[i], points[i + 1]
        f = (travelled - start) / lengths[i] if lengths[i] else 0.0
        heading = math.atan2(by - ay, bx - ax) + (math.pi if backwards else 0.0)
        return ax + f * (bx - ax), ay + f * (by - ay), heading


def obstacle_surfaces(spec: ObstacleSpec, t_s: float = 0.0) -> Surfaces:
    """The obstacle's boxes and poles in the floor frame at time ``t_s``."""
    x, y, heading = spec.pose_at(t_s)
    c, s = math.cos(heading), math.sin(heading)

    def place(lx: float, ly: float) -> tuple[float, float]:
        return x + c * lx - s * ly, y + s * lx + c * ly

    segments: list[tuple[float, ...]] = []
    segment_ids: list[str] = []
    cylinders: list[tuple[float, ...]] = []
    cylinder_ids: list[str] = []
    for part in SHAPES[spec.kind]:
        element = f"{spec.id} {part.part}"
        if isinstance(part, Pole):
            cylinders.append((*place(part.cx, part.cy), part.radius, part.z_bottom, part.z_top))
            cylinder_ids.append(element)
            continue
        hx, hy = part.length / 2, part.width / 2
        ring = [place(part.cx + px, part.cy + py) for px, py in _corners(hx, hy)]
        ring = [ring[0], ring[1], ring[3], ring[2]]  # product order -> around the box
        for a, b in itertools.pairwise([*ring, ring[0]]):
            segments.append((*a, *b, part.z_bottom, part.z_top))
            segment_ids.append(element)
    return Surfaces(
        np.array(segments, dtype=float).reshape(-1, 6),
        tuple(segment_ids),
        np.array(cylinders, dtype=float).reshape(-1, 5),
        tuple(cylinder_ids),
    )
