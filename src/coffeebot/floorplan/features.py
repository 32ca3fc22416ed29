"""What a floor plan is made of: hallways, doors, openings, walls, frames, zones, anchors,
parking spots and cameras, as the survey writes them, and the error that names one.

Frames: x, y in mm in the floor frame shared by all floors and the UWB anchors. Along a
hallway, ``s`` is the distance from its axis start and ``d`` the lateral offset, positive to
the left when looking from start to end.
"""

from __future__ import annotations

import math
from functools import cached_property
from pathlib import Path
from typing import Annotated, Any, Literal, NamedTuple

import numpy as np
from pydantic import BaseModel, ConfigDict, Field, Strict, StrictFloat, StrictInt, model_validator

from coffeebot.errors import ConfigError

Side = Literal["left", "right"]

PLAN_MM = 1_000_000.0
"""Every coordinate lies within a kilometre of the origin: a survey typo, not a building."""
# Numbers are strict (an integer still passes for a float): pydantic would read a quoted
# "42000" as 42000, and a survey with quoted figures is one nobody has checked.
Coordinate = Annotated[float, Strict(), Field(ge=-PLAN_MM, le=PLAN_MM)]
Size = Annotated[float, Strict(), Field(gt=0, le=100_000)]
"""A width, depth or height: positive and under 100 m."""


class FloorPlanError(ConfigError):
    """A floor plan file that cannot be used, naming the file, the element and the problem.

    A :class:`~coffeebot.config.ConfigError` (so a ``ValueError``): the CLI reports both alike.
    """

    def __init__(self, path: str | Path, element: str, problem: str) -> None:
        self.path = str(path)
        self.element = element
        self.problem = problem
        super().__init__(f"{self.path}: {element}: {problem}")


class StrictModel(BaseModel):
    """Unknown keys, ``nan`` and ``inf`` are refused: a NaN position makes every comparison
    false, so the robot would never reach (or stop at) it."""

    model_config = ConfigDict(frozen=True, extra="forbid", allow_inf_nan=False)


class Hallway(StrictModel):
    """One straight hallway segment: an axis from ``start`` to ``end`` and a width. Its own
    frame: ``s`` along the axis from ``start``, ``d`` across it, left positive looking from
    start to end. Where hallways meet (an L, a T, a width change) is found from their axes
    (:attr:`Floor.meetings`)."""

    id: str = Field(min_length=1)
    start: tuple[Coordinate, Coordinate]
    end: tuple[Coordinate, Coordinate]
    width_mm: Size = 1700.0
    start_closed: bool = True
    end_closed: bool = True

    @property
    def length_mm(self) -> float:
        return math.dist(self.start, self.end)

    @property
    def heading_deg(self) -> float:
        """Direction of travel from start to end, degrees CCW from +x."""
        return math.degrees(math.atan2(self.end[1] - self.start[1], self.end[0] - self.start[0]))

    @cached_property
    def _axis(self) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Origin, unit direction and unit left normal of the axis."""
        origin = np.array(self.start, dtype=float)
        direction = np.array(self.end, dtype=float) - origin
        direction /= np.linalg.norm(direction)
        return origin, direction, np.array([-direction[1], direction[0]])

    @cached_property
    def _axis_floats(self) -> tuple[float, float, float, float, float, float]:
        """:attr:`_axis` as plain floats: origin x, y, direction x, y, normal x, y."""
        origin, u, n = self._axis
        return (
            float(origin[0]),
            float(origin[1]),
            float(u[0]),
            float(u[1]),
            float(n[0]),
            float(n[1]),
        )

    def to_local(self, x_mm: float, y_mm: float) -> tuple[float, float]:
        """Floor-frame point to (s along the axis, d lateral, left positive)."""
        # In scalars, the same operations as the arrays' (a difference, then a two-term dot
        # product summed in order) and so the same result to the bit, at a fraction of the
        # cost: the door detector and the world ask this many times a scan.
        ox, oy, ux, uy, nx, ny = self._axis_floats
        rx, ry = x_mm - ox, y_mm - oy
        return float(rx * ux + ry * uy), float(rx * nx + ry * ny)

    def from_local(self, s_mm: float, d_mm: float) -> tuple[float, float]:
        """(s, d) in this hallway's frame to a floor-frame point."""
        origin, u, n = self._axis
        p = origin + s_mm * u + d_mm * n
        return float(p[0]), float(p[1])


class Door(StrictModel):
    """A door in a hallway wall, recessed ``recess_mm`` behind the wall line."""

    id: str
    room: str
    side: Side
    at_mm: Coordinate = Field(description="distance of the door centre along the hallway axis")
    width_mm: Size = 900.0
    recess_mm: StrictFloat = Field(100.0, ge=0, le=10_000)
    height_mm: Size = 2100.0
    kind: Literal["office", "elevator", "tea_room", "other"] = "office"
    open: bool = False
    hallway: str | None = Field(None, description="the hallway's id (a floor of one: none)")

    @model_validator(mode="before")
    @classmethod
    def _id_defaults_to_room(cls, data: Any) -> Any:
        if isinstance(data, dict) and "id" not in data and "room" in data:
            return {**data, "id": str(data["room"])}
        return data

    @property
    def span(self) -> tuple[float, float]:
        return (self.at_mm - self.width_mm / 2, self.at_mm + self.width_mm / 2)


class Opening(StrictModel):
    """A gap in a hallway wall: a side hallway, a stairwell, a lobby."""

    id: str
    side: Side
    at_mm: Coordinate
    width_mm: Size = 1700.0
    depth_mm: Size = Field(3000.0, description="how far its side walls run")
    end: Literal["open", "wall"] = "open"
    name: str = ""
    hallway: str | None = Field(None, description="the hallway's id (a floor of one: none)")

    @property
    def span(self) -> tuple[float, float]:
        return (self.at_mm - self.width_mm / 2, self.at_mm + self.width_mm / 2)


class Junction(Opening):
    """Where another hallway meets this one from the side: the gap in this one's wall that
    the other's walls run from. Found from the hallways' axes, never written in a plan."""

    joins: str


class Wall(StrictModel):
    """A free-form wall as a polyline of floor-frame points."""

    id: str
    points: list[tuple[Coordinate, Coordinate]] = Field(min_length=2)
    height_mm: Size | None = None
    closed: bool = False


class ParkingSpot(StrictModel):
    """Where one robot of a fleet waits for orders: inside the room with the loading spot,
    out of the way of the door (a single robot parks on the loading spot itself)."""

    x_mm: Coordinate
    y_mm: Coordinate
    heading_deg: StrictFloat = Field(0.0, ge=-360, le=360)


class FloorMark(StrictModel):
    """A mark on the floor seen by a ceiling camera: where it lies in the floor frame,
    surveyed, and the pixel it shows at in the camera's image (the calibration's input)."""

    x_mm: Coordinate
    y_mm: Coordinate
    u_px: StrictFloat = Field(ge=0, le=10_000)
    v_px: StrictFloat = Field(ge=0, le=10_000)


class Camera(StrictModel):
    """A fixed camera on the ceiling looking straight down (seed 003: 320 x 240 px at 10 fps
    from 4 m, 1.25 cm a pixel). ``yaw_deg`` is the floor-frame heading of the image's +u
    axis; its +v axis points 90 degrees clockwise of that (image rows grow downwards)."""

    id: str = Field(min_length=1)
    x_mm: Coordinate
    y_mm: Coordinate
    height_mm: Size = 4000.0
    yaw_deg: StrictFloat = Field(0.0, ge=-360, le=360)
    width_px: StrictInt = Field(320, ge=16, le=8192)
    height_px: StrictInt = Field(240, ge=16, le=8192)
    fov_deg: StrictFloat = Field(
        53.13, gt=1, lt=170, description="horizontal field of view (53.13: 4 m wide from 4 m)"
    )
    fps: StrictFloat = Field(10.0, gt=0, le=120)
    marks: list[FloorMark] = Field(
        [],
        description="floor marks and their pixels, four or more: the calibration's "
        "homography from them (none: the nominal one from the pose and lens above)",
    )


class Frame(StrictModel):
    """A door frame across a hallway, or a fire door held open in one: two jambs standing
    in from the walls, ``clear_width_mm`` apart about the axis, ``depth_mm`` thick along
    the hallway. A fire door's two leaves stand folded back against the walls on the side
    of increasing ``s`` (``opens = "end"``) or the other (``"start"``)."""

    id: str
    hallway: str | None = Field(None, description="the hallway's id (a floor of one: none)")
    at_mm: Coordinate = Field(description="the frame's centre along the hallway")
    clear_width_mm: Size = Field(description="between the jambs")
    depth_mm: StrictFloat = Field(150.0, gt=0, le=2000)
    kind: Literal["frame", "fire_door"] = "frame"
    opens: Literal["start", "end"] = "end"
    leaf_mm: StrictFloat = Field(60.0, gt=0, le=300, description="a fire door leaf's thickness")

    @property
    def jambs(self) -> tuple[float, float]:
        """Along the hallway: where the jambs stand."""
        return self.at_mm - self.depth_mm / 2, self.at_mm + self.depth_mm / 2

    @property
    def span(self) -> tuple[float, float]:
        """Along the hallway: the jambs and, for a fire door, the leaves folded back."""
        lo, hi = self.jambs
        if self.kind == "fire_door":
            if self.opens == "end":
                hi += self.clear_width_mm / 2
            else:
                lo -= self.clear_width_mm / 2
        return lo, hi


class AngleZone(StrictModel):
    """A stretch of hallway where both walls are flat, so side sensors can measure heading."""

    id: str
    from_mm: Coordinate
    to_mm: Coordinate
    hallway: str | None = Field(None, description="the hallway's id (a floor of one: none)")

    @model_validator(mode="after")
    def _ordered(self) -> AngleZone:
        if self.to_mm <= self.from_mm:
            raise ValueError(f"to_mm ({self.to_mm}) must be greater than from_mm ({self.from_mm})")
        return self


class Anchor(StrictModel):
    """A UWB anchor at a surveyed position."""

    id: str = Field(
        pattern=r"^[0-9A-F]{4}$",
        description="the anchor's UWB short address, 4 upper-case hex digits, as the tag "
        "reports it (this is how a fix's anchors are matched to a floor)",
    )
    x_mm: Coordinate
    y_mm: Coordinate
    z_mm: StrictFloat = Field(2400.0, ge=-10_000, le=100_000)


class WallSegment(NamedTuple):
    """One straight piece of surface: what sensors see and what the robot can hit."""

    element: str
    x0: float
    y0: float
    x1: float
    y1: float
    z_bottom: float
    z_top: float


def segment_distances(
    segments: np.ndarray, x: float | np.ndarray, y: float | np.ndarray
) -> np.ndarray:
    """Distance from (x, y) to each segment of an (N, >=4) array of x0, y0, x1, y1 rows.

    ``x`` and ``y`` may be column arrays (P, 1): the result is then (P, N), one row per point.
    """
    px, py = segments[:, 0], segments[:, 1]
    ex, ey = segments[:, 2] - px, segments[:, 3] - py
    length2 = np.maximum(ex * ex + ey * ey, 1e-9)
    t = np.clip(((x - px) * ex + (y - py) * ey) / length2, 0.0, 1.0)
    return np.hypot(px + t * ex - x, py + t * ey - y)


def segments_crossed(
    segments: np.ndarray,
    x0: np.ndarray,
    y0: np.ndarray,
    x1: np.ndarray,
    y1: np.ndarray,
) -> np.ndarray:
    """Whether the segment from (``x0``, ``y0``) to (``x1``, ``y1``) crosses each segment of
    an (N, >=4) array of x0, y0, x1, y1 rows. With (N,) points, row by row; with column
    arrays (P, 1), every point against every row: (P, N). Touching (an end on the other
    segment) is not crossing."""
    ax, ay, bx, by = segments[:, 0], segments[:, 1], segments[:, 2], segments[:, 3]
    ex, ey = bx - ax, by - ay
    dx, dy = x1 - x0, y1 - y0
    start_side = ex * (y0 - ay) - ey * (x0 - ax)
    end_side = ex * (y1 - ay) - ey * (x1 - ax)
    a_side = dx * (ay - y0) - dy * (ax - x0)
    b_side = dx * (by - y0) - dy * (bx - x0)
    return np.asarray((start_side * end_side < 0.0) & (a_side * b_side < 0.0))
