"""A simulated elevator: one car behind every floor's elevator door, answering the robot.

The car's doors replace the floor plan's elevator door leaf: closed, the leaf is a wall;
open (car at that floor), the doorway leads into the car, whose walls are always there. The
car moves between floors only with its doors closed; a robot inside when it arrives is
carried along (the world places it at the same spot on the new floor). Timings are those of
an ordinary office lift and can be slowed or broken to test the robot's timeouts.
"""

from __future__ import annotations

from typing import Literal

import numpy as np

from coffeebot.floorplan import Door, Floor, FloorPlan
from coffeebot.messages import ElevatorRequest, ElevatorState
from coffeebot.sim.world import materials
from coffeebot.sim.world.geometry import Surfaces

Phase = Literal["idle", "opening", "open", "closing", "travelling"]


class SimElevator:
    def __init__(
        self,
        plan: FloorPlan,
        *,
        car: str | None = None,
        car_floor: int | None = None,
        car_width_mm: float = 1400.0,
        car_depth_mm: float = 1500.0,
        door_time_s: float = 3.0,
        travel_time_s: float = 8.0,
        answering: bool = True,
    ) -> None:
        self.plan = plan
        self.car = car if car is not None else next(iter(plan.cars), "")
        """Which of the plan's cars this is (None: the first)."""
        # Each floor it serves as seen along the hallway its door opens on.
        self.doors: dict[int, tuple[Floor, Door]] = {
            stop.floor.level: (stop.floor.view_of(stop.door), stop.door)
            for stop in plan.cars.get(self.car, [])
        }
        self.car_floor = car_floor if car_floor is not None else min(self.doors)
        self.car_width_mm = car_width_mm
        self.car_depth_mm = car_depth_mm
        self.door_time_s = door_time_s
        self.travel_time_s = travel_time_s
        self.answering = answering
        """False: requests are ignored (a broken interface), to exercise the fallbacks."""
        self.phase: Phase = "idle"
        self.target: int | None = None
        self._timer = 0.0
        self._cache: dict[tuple[int, bool], Surfaces] = {}
        self.requests: list[ElevatorRequest] = []

    @classmethod
    def bank(cls, plan: FloorPlan, floor: int) -> list[SimElevator]:
        """Every car of ``plan``, each waiting at ``floor`` if it stops there (else at the
        lowest floor it serves)."""
        return [
            cls(plan, car=car, car_floor=floor if floor in levels else min(levels))
            for car, stops in plan.cars.items()
            for levels in [{stop.floor.level for stop in stops}]
        ]

    # --- interface (what the elevator module calls) ----------------------------------------

    def request(self, request: ElevatorRequest) -> None:
        self.requests.append(request)
        if not self.answering:
            return
        if request.action == "release":
            self.target = None
            if self.phase in ("open", "opening"):
                self._start("closing", self.door_time_s)
            return
        self.target = request.floor
        if self.phase == "open" and request.floor != self.car_floor:
            self._start("closing", self.door_time_s)

    def state(self) -> ElevatorState:
        doors: Literal["open", "closed", "moving"] = "closed"
        if self.phase == "open":
            doors = "open"
        elif self.phase in ("opening", "closing"):
            doors = "moving"
        return ElevatorState(
            car=self.car,
            car_floor=None if self.phase == "travelling" else self.car_floor,
            doors=doors,
            moving=self.phase == "travelling",
            source="sim",
        )

    # --- time ------------------------------------------------------------------------------

    def _start(self, phase: Phase, duration: float) -> None:
        self.phase, self._timer = phase, duration

    def step(self, dt_s: float) -> int | None:
        """Advance; returns the floor the car has just arrived at, if any."""
        self._timer -= dt_s
        arrived = None
        if self.phase == "idle" and self.target is not None:
            if self.target == self.car_floor:
                self._start("opening", self.door_time_s)
            else:
                self._start("travelling", self.travel_time_s * abs(self.target - self.car_floor))
        elif self._timer > 0:
            return None
        elif self.phase == "opening":
            self.phase = "open"
        elif self.phase == "closing":
            self.phase = "idle"
        elif self.phase == "travelling":
            assert self.target is not None
            self.car_floor = arrived = self.target
            self._start("opening", self.door_time_s)
        return arrived

    # --- geometry --------------------------------------------------------------------------

    def door_element(self, level: int) -> str | None:
        """The floor plan element the car's doors replace on ``level``."""
        entry = self.doors.get(level)
        return None if entry is None else f"door {entry[1].id}"

    def _frame(self, level: int) -> tuple[Floor, Door, float, float]:
        floor, door = self.doors[level]
        sign = 1.0 if door.side == "left" else -1.0
        front = sign * (floor.hallway.width_mm / 2 + door.recess_mm)
        return floor, door, sign, front

    def inside(self, level: int, x_mm: float, y_mm: float) -> bool:
        if level not in self.doors:
            return False
        floor, door, sign, front = self._frame(level)
        s, d = floor.to_hallway(x_mm, y_mm)
        depth = (d - front) * sign
        return abs(s - door.at_mm) < self.car_width_mm / 2 and 0 < depth < self.car_depth_mm

    def surfaces(self, level: int) -> Surfaces:
        """Car walls and, unless the car stands here with open doors, the closed door leaf."""
        if level not in self.doors:
            return Surfaces.empty()
        open_here = self.phase == "open" and self.car_floor == level
        key = (level, open_here)
        if key not in self._cache:
            floor, door, sign, front = self._frame(level)
            back = front + sign * self.car_depth_mm
            lo, hi = door.span
            c_lo, c_hi = door.at_mm - self.car_width_mm / 2, door.at_mm + self.car_width_mm / 2
            outline = [
                ((lo, front), (c_lo, front)),
                ((c_lo, front), (c_lo, back)),
                ((c_lo, back), (c_hi, back)),
                ((c_hi, back), (c_hi, front)),
                ((c_hi, front), (hi, front)),
            ]
            if not open_here:
                outline.append(((lo, front), (hi, front)))
            height = floor.wall_height_mm
            rows = [
                (*floor.from_hallway(*a), *floor.from_hallway(*b), 0.0, height) for a, b in outline
            ]
            self._cache[key] = Surfaces(
                np.array(rows, dtype=float),
                tuple(f"elevator car {level}" for _ in rows),
                np.zeros((0, 5)),
                (),
                np.full(len(rows), materials.STEEL),
            )
        return self._cache[key]
