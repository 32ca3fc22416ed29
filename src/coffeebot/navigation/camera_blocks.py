"""What the ceiling cameras see standing in the hallway, as navigation and motion act on it
(no I/O).

The map's camera layer (``cameras/layer``) lists what stands still in the cameras' view, each
thing with a conservative footprint on the floor. The robot's own sensors see 1.3-4 m ahead;
a camera sees a cart standing at the far end of the hallway long before. Every question here
is asked in the hallway frame of the object's floor (``s`` along the axis, ``d`` across it,
:meth:`~coffeebot.floorplan.Floor.to_hallway`), whichever way the robot drives:

* **Blocked**: the object stands on the stretch the robot still has to drive on its current
  leg, and the room left beside it, on the wider side, is less than the robot needs to pass:
  its width, motion's ``side_clearance_mm`` to the wall and its ``obstacle_clearance_mm`` to
  the object, the gaps the detour's lanes keep. Navigation then holds ``camera_stop_short_mm``
  short of it and waits until it is gone. Where the route planner had another way it would
  take it instead; it has none today: a :class:`~coffeebot.navigation.route.Route` is the
  shortest way over the hallways, one sequence of steps (the shipped buildings' hallways
  form no loop, so there is no other way to offer).
* **Passable**: everything else on the layer is marked on motion's costmap from afar
  (:meth:`~coffeebot.navigation.costmap.LocalCostmap.mark_camera`), so the detour picks its
  side before the sensors see the thing.

A layer older than ``camera_stale_s`` is no camera information, not "still blocked": the
cameras only ever add caution to what the robot's own sensors, the detour and the collision
monitor do anyway, and a camera service that stopped would otherwise hold the robot for good
in front of a cart that may have left long ago. What is still there is seen again by the
sensors and waited for as any obstacle.
"""

from __future__ import annotations

from collections.abc import Iterable, Sequence
from dataclasses import dataclass

import numpy as np

from coffeebot.config import RobotConfig
from coffeebot.floorplan import Door, Floor
from coffeebot.messages import CameraLayer, CameraObject
from coffeebot.navigation.costmap import CameraMarks
from coffeebot.navigation.others import outline_points
from coffeebot.navigation.route import Lease, Move, Step
from coffeebot.rectangles import corners, sides


def fresh_objects(
    layer: CameraLayer | None, age_s: float | None, stale_s: float
) -> list[CameraObject]:
    """The layer's objects, or none when there is no layer or it is older than ``stale_s``:
    a silent camera service is no information, never a reason to keep waiting."""
    if layer is None or age_s is None or age_s > stale_s:
        return []
    return layer.objects


def outline(obj: CameraObject) -> np.ndarray:
    """The footprint's sides (4, 4: x0, y0, x1, y1 in the floor frame), the long ones along
    ``axis_deg``."""
    return sides(corners(obj.x_mm, obj.y_mm, obj.length_mm, obj.width_mm, obj.axis_deg))


def camera_marks(objects: Iterable[CameraObject], spacing_mm: float) -> CameraMarks:
    """Every object's outline as points at most ``spacing_mm`` apart, by floor, for the
    costmap: the outline is all the planner's gaps and lanes ask about."""
    by_floor: dict[int, list[tuple[np.ndarray, np.ndarray, np.ndarray]]] = {}
    for obj in objects:
        xs, ys = outline_points(outline(obj), spacing_mm)
        by_floor.setdefault(obj.floor, []).append((xs, ys, np.full(xs.size, obj.standing_since_s)))
    marks: CameraMarks = {}
    for level, parts in by_floor.items():
        xs, ys, since = (np.concatenate(column) for column in zip(*parts, strict=True))
        marks[level] = (xs, ys, since)
    return marks


@dataclass(frozen=True)
class Extent:
    """A footprint's bounding box in the hallway frame: along (``s``) and across (``d``)."""

    s_lo: float
    s_hi: float
    d_lo: float
    d_hi: float

    @classmethod
    def of(cls, floor: Floor, obj: CameraObject) -> Extent:
        corners = [floor.to_hallway(x, y) for x, y in outline(obj)[:, :2]]
        s = [c[0] for c in corners]
        d = [c[1] for c in corners]
        return cls(min(s), max(s), min(d), max(d))

    def near_edge(self, direction: float) -> float:
        """Its edge a robot travelling towards ``direction`` (+1/-1 in s) comes to first."""
        return self.s_lo if direction > 0 else self.s_hi

    def far_edge(self, direction: float) -> float:
        return self.s_hi if direction > 0 else self.s_lo

    def free_width_mm(self, floor: Floor) -> float | None:
        """The hallway's width left beside it on the wider side; None when it does not reach
        into the hallway (in a room, in a doorway's recess)."""
        half = floor.hallway.width_mm / 2
        lo, hi = max(self.d_lo, -half), min(self.d_hi, half)
        if lo > hi:
            return None
        return max(lo + half, half - hi)


@dataclass(frozen=True)
class Leg:
    """The hallway the robot drives now: along ``floor``'s hallway towards ``direction``
    (+1/-1 in s), its current move ending at ``target_s_mm`` and the lane moves after it
    without a turn (:func:`leg_ends`) at ``end_s_mm``."""

    floor: Floor
    direction: float
    target_s_mm: float
    end_s_mm: float


@dataclass(frozen=True)
class Block:
    """Something a camera sees blocking the rest of a leg, and where the robot waits for it."""

    object_id: str
    near_s_mm: float
    """Its edge the robot comes to first."""
    free_mm: float
    """The room left beside it, on the wider side."""
    stop_s_mm: float
    """Where the robot's centre holds: short of it, or at the end of the current move if that
    comes first, never behind where the robot stands."""
    place: str | None
    """The place it stands near, for people: "room 207", "the elevator"."""

    @property
    def _where(self) -> str:
        near = "" if self.place is None else f" near {self.place}"
        return f"the hallway{near} (seen by a ceiling camera)"

    @property
    def what(self) -> str:
        """It, for the log and the hold's instruction: "something blocking the hallway..."."""
        return f"something blocking {self._where}"

    @property
    def waiting_detail(self) -> str:
        """What the customer is told while the robot waits for it."""
        return f"Something is blocking {self._where}; the robot waits until it is cleared."


def place_name(door: Door | None) -> str | None:
    """A door as people name the place in front of it (None: a floor without doors)."""
    if door is None:
        return None
    if door.kind == "elevator":
        return "the elevator"
    if door.kind == "tea_room":
        return f"the {door.room.lower()}"
    return f"room {door.room}"


@dataclass(frozen=True)
class BlockRule:
    """Which camera objects block a leg, and where the robot holds short of them."""

    needed_mm: float
    """The width the robot needs to pass: its body, ``side_clearance_mm`` to the wall and
    ``obstacle_clearance_mm`` to the object, the gaps motion keeps going round."""
    stop_short_mm: float
    """Between the body's front and the object's near edge where it holds."""
    half_length_mm: float
    """From the body's centre (the ``s`` the robot drives to) to its front."""
    accel_mm_s2: float
    """Motion's speed profile slows at this: a robot at speed stands still only so far on."""

    @classmethod
    def from_config(cls, config: RobotConfig) -> BlockRule:
        motion = config.motion
        return cls(
            needed_mm=config.geometry.width_mm
            + motion.side_clearance_mm
            + motion.obstacle_clearance_mm,
            stop_short_mm=config.navigation.camera_stop_short_mm,
            half_length_mm=config.geometry.length_mm / 2,
            accel_mm_s2=motion.accel_mm_s2,
        )

    def blocking(
        self, leg: Leg, s_mm: float, speed_mm_s: float, objects: Iterable[CameraObject]
    ) -> Block | None:
        """The nearest object blocking ``leg`` ahead of a robot whose centre is at ``s_mm``:
        on its floor, reaching into the hallway with less room beside it than ``needed_mm``,
        its far edge ahead of the robot's centre (what is beside or behind it is passed) and
        its near edge before where the body's front reaches at the leg's end. None if none.

        The hold is never behind where the robot, at ``speed_mm_s``, can stand still: motion
        given a point behind it would turn round and drive back to it."""
        floor, direction = leg.floor, leg.direction
        reach = leg.end_s_mm + direction * self.half_length_mm
        earliest = s_mm + direction * speed_mm_s**2 / (2 * self.accel_mm_s2)
        nearest: Block | None = None
        for obj in objects:
            if obj.floor != floor.level:
                continue
            extent = Extent.of(floor, obj)
            free = extent.free_width_mm(floor)
            if free is None or free >= self.needed_mm:
                continue
            near = extent.near_edge(direction)
            behind = (extent.far_edge(direction) - s_mm) * direction <= 0
            beyond = (near - reach) * direction > 0
            if behind or beyond:
                continue
            if nearest is not None and (near - nearest.near_s_mm) * direction >= 0:
                continue
            short = near - direction * (self.stop_short_mm + self.half_length_mm)
            stop = min(short, leg.target_s_mm, key=lambda v: v * direction)
            if (stop - earliest) * direction < 0:
                stop = earliest
            centre = floor.to_hallway(obj.x_mm, obj.y_mm)[0]
            nearest = Block(obj.id, near, free, stop, place_name(floor.nearest_door(centre)))
        return nearest


def leg_ends(steps: Sequence[Step]) -> list[float | None]:
    """Per step of a route, for a lane move, where its leg ends: the target of the last lane
    move on the same floor and hallway after it with nothing but leases between (a lease
    moves nothing; a turn, a drive or a ride ends the leg). None for every other step. A
    lane move that passes its point at speed (a lane change) is one leg with the next: a
    blocked stretch just beyond it must be known before, not once the robot is upon it."""
    ends: list[float | None] = [None] * len(steps)
    end: float | None = None
    along: tuple[int | None, str | None] | None = None
    for i in reversed(range(len(steps))):
        step = steps[i]
        if isinstance(step, Lease):
            continue
        ins = step.instruction if isinstance(step, Move) else None
        if ins is None or ins.action != "follow_lane" or ins.target_s_mm is None:
            end = None
            continue
        if end is None or (ins.floor, ins.hallway) != along:
            end, along = ins.target_s_mm, (ins.floor, ins.hallway)
        ends[i] = end
    return ends
