"""The obstacles of the seed's evaluation, built from boxes and poles with heights.

Dimensions are typical of the furniture named in seed 000 (section V.A); what matters for the
sensors at ~250 mm is what exists at that height: the mail cart's lower shelf tops out 20 mm
below it and only its four corner bars cross it; the swivel chair shows a single pole with
fabric under the seat above; the wooden chair shows four thin legs.

An obstacle can be scripted against the robot: its own clock starts when the robot comes
within ``trigger_mm`` of a point (a person who steps out as the robot approaches), and it can
be absent until a time on that clock (a box dropped into the lane).
"""

from __future__ import annotations

import bisect
import itertools
import math
from dataclasses import dataclass
from typing import Literal

import numpy as np
from pydantic import BaseModel, ConfigDict, Field, model_validator

from coffeebot.sim.world import materials
from coffeebot.sim.world.geometry import Surfaces

ObstacleKind = Literal[
    "mail_cart", "swivel_chair", "sofa", "wooden_chair", "cardboard_box", "person", "child"
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
    reflectance: float = materials.DEFAULT


@dataclass(frozen=True)
class Pole:
    """An upright cylinder in the obstacle's frame."""

    part: str
    cx: float
    cy: float
    radius: float
    z_bottom: float
    z_top: float
    reflectance: float = materials.DEFAULT


def _corners(half_x: float, half_y: float) -> list[tuple[float, float]]:
    return [(sx * half_x, sy * half_y) for sx, sy in itertools.product((1, -1), (1, -1))]


CHILD: tuple[Box | Pole, ...] = (
    *(Pole("leg", 0, y, 37, 0, 510) for y in (55, -55)),
    Box("torso", 0, 0, 140, 210, 510, 910),
    Pole("head", 0, 0, 80, 910, 1150),
)
"""An average six-year-old, rounded from published anthropometry: stature about 1150 mm (CDC
2000 growth charts, 50th percentile at 6 years: about 115 cm for boys and girls); crotch
height about 510 mm and shoulder height about 910 mm (Snyder et al. 1977, "Anthropometry of
Infants, Children, and Youths to Age 18 for Product Safety Design", UM-HSRI-77-17 for the
CPSC, the 5.5-6.5 year group: at that age the legs are a little shorter than the body above
the pubis); calf circumference about 23 cm, so a leg ~74 mm thick at the sensors' 250 mm,
the legs ~110 mm apart (hip breadth ~200 mm); chest breadth ~210 mm and depth ~140 mm (same
source). What matters here: legs little more than half as thick as an adult's at the
sensors' height, and a torso from ~510 mm up, well inside the robot's 900 mm height, where an
adult's starts at 850 mm."""


SHAPES: dict[str, tuple[Box | Pole, ...]] = {
    # Two grey plastic shelves joined by black plastic bars at the corners; 900 x 500 mm.
    "mail_cart": (
        Box("lower shelf", 0, 0, 900, 500, 100, 230, materials.GREY),
        Box("upper shelf", 0, 0, 900, 500, 750, 900, materials.GREY),
        *(Pole("corner bar", x, y, 15, 100, 900, materials.BLACK) for x, y in _corners(435, 235)),
    ),
    # One chromed pole from the wheeled base to the seat, dark fabric under and on the seat.
    "swivel_chair": (
        Pole("pole", 0, 0, 30, 100, 400, materials.STEEL),
        Box("seat fabric", 0, 0, 440, 440, 400, 430, 0.1),
        Box("seat", 0, 0, 480, 480, 430, 500, 0.1),
        Box("backrest", -215, 0, 50, 440, 550, 1000, 0.1),
    ),
    # Solid armrests and base: a box from the side, upholstered.
    "sofa": (Box("body", 0, 0, 2000, 900, 0, 850, 0.3),),
    "wooden_chair": (
        *(Pole("leg", x, y, 15, 0, 450, 0.4) for x, y in _corners(190, 190)),
        Box("seat", 0, 0, 420, 420, 430, 470, 0.4),
        Box("backrest", -200, 0, 20, 420, 470, 900, 0.4),
    ),
    # Brown kraft cardboard.
    "cardboard_box": (Box("box", 0, 0, 500, 400, 0, 400, 0.6),),
    # What a 250 mm sensor sees of a person is two legs in trousers (cotton or denim: their
    # dyes absorb visible light, not 940 nm); the torso matters for collisions.
    "person": (
        Pole("leg", 0, 100, 60, 0, 850, 0.45),
        Pole("leg", 0, -100, 60, 0, 850, 0.45),
        Pole("torso", 0, 0, 180, 850, 1750, 0.45),
    ),
    "child": CHILD,
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
    trigger_mm: float | None = Field(
        None,
        gt=0,
        description="its clock starts when the robot's centre first comes this close to "
        "trigger_at (None: at the world's start); until then it stands at its start point",
    )
    trigger_at: tuple[float, float] | None = Field(
        None, description="the point the trigger distance is measured from; None: its start"
    )
    appear_s: float | None = Field(
        None, description="absent until this time on its own clock (None: always there)"
    )
    gone_s: float | None = Field(
        None,
        description="absent from this time on its own clock (someone wheels it away; None: "
        "there to the end)",
    )

    @model_validator(mode="after")
    def _gone_after_it_appears(self) -> ObstacleSpec:
        if self.gone_s is not None and self.gone_s <= (self.appear_s or 0.0):
            raise ValueError("gone_s must come after appear_s (and after 0)")
        return self

    @property
    def moving(self) -> bool:
        return bool(self.path) and self.speed_mm_s > 0

    @property
    def timed(self) -> bool:
        """Whether what it looks like changes with time (so the world cannot cache it)."""
        return (
            self.moving
            or self.trigger_mm is not None
            or self.appear_s is not None
            or self.gone_s is not None
        )

    def present_at(self, clock_s: float | None) -> bool:
        """Whether it exists at ``clock_s`` on its own clock (None: not started yet)."""
        if self.gone_s is not None and clock_s is not None and clock_s >= self.gone_s:
            return False
        if self.appear_s is None:
            return True
        return clock_s is not None and clock_s >= self.appear_s

    def pose_at(self, t_s: float) -> tuple[float, float, float]:
        """(x, y, heading in rad) at ``t_s`` on its own clock; a pure function of time. Before
        its clock starts (``t_s`` <= 0) it stands at its start point, facing along its path."""
        if not self.moving:
            return self.x_mm, self.y_mm, math.radians(self.heading_deg)
        points = [(self.x_mm, self.y_mm), *self.path]
        if self.path_mode == "loop":
            points.append(points[0])
        lengths = [math.dist(a, b) for a, b in itertools.pairwise(points)]
        cumulative = list(itertools.accumulate(lengths))
        total = cumulative[-1]
        travelled = self.speed_mm_s * max(0.0, t_s)
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
    segment_reflectance: list[float] = []
    cylinders: list[tuple[float, ...]] = []
    cylinder_ids: list[str] = []
    cylinder_reflectance: list[float] = []
    for part in SHAPES[spec.kind]:
        element = f"{spec.id} {part.part}"
        if isinstance(part, Pole):
            cylinders.append((*place(part.cx, part.cy), part.radius, part.z_bottom, part.z_top))
            cylinder_ids.append(element)
            cylinder_reflectance.append(part.reflectance)
            continue
        hx, hy = part.length / 2, part.width / 2
        ring = [place(part.cx + px, part.cy + py) for px, py in _corners(hx, hy)]
        ring = [ring[0], ring[1], ring[3], ring[2]]  # product order -> around the box
        for a, b in itertools.pairwise([*ring, ring[0]]):
            segments.append((*a, *b, part.z_bottom, part.z_top))
            segment_ids.append(element)
            segment_reflectance.append(part.reflectance)
    return Surfaces(
        np.array(segments, dtype=float).reshape(-1, 6),
        tuple(segment_ids),
        np.array(cylinders, dtype=float).reshape(-1, 5),
        tuple(cylinder_ids),
        np.array(segment_reflectance, dtype=float),
        np.array(cylinder_reflectance, dtype=float),
    )
