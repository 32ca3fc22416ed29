"""The building: its floors, rooms, pickup points and elevator cars."""

from __future__ import annotations

import math
from functools import cached_property
from typing import NamedTuple

import numpy as np
from pydantic import Field

from coffeebot.floorplan.features import Door, StrictModel
from coffeebot.floorplan.floor import Floor


class RoomLocation(NamedTuple):
    floor: Floor
    door: Door


class FloorPlan(StrictModel):
    name: str = ""
    note: str = ""
    floors: list[Floor] = Field(min_length=1)

    def floor(self, level: int) -> Floor:
        for floor in self.floors:
            if floor.level == level:
                return floor
        raise KeyError(f"no floor {level}; floors are {[f.level for f in self.floors]}")

    def find_room(self, room: str) -> RoomLocation:
        """The floor and (first listed) door of a room, by its name ("205", "Tea room")."""
        return self.room_doors(room)[0]

    def room_doors(self, room: str) -> list[RoomLocation]:
        """Every door of a room (a room may have several, on one floor)."""
        found = [
            RoomLocation(floor, door)
            for floor in self.floors
            for door in floor.doors
            if door.room == room
        ]
        if not found:
            raise KeyError(f"no room {room!r} in floor plan {self.name!r}")
        return found

    @cached_property
    def cars(self) -> dict[str, list[RoomLocation]]:
        """The elevator cars, each named by its first door's id, with its door on each floor
        it serves: elevator doors at one place in the building frame (the leaf's centre
        within ``ELEVATOR_TOLERANCE_MM``), opening the same way, are one car."""
        cars: dict[str, list[RoomLocation]] = {}
        for floor in self.floors:
            for door in floor.elevators:
                front = elevator_front(floor, door)
                car = next(
                    (
                        name
                        for name, stops in cars.items()
                        if same_car(front, elevator_front(*stops[0]))
                        and all(stop.floor.level != floor.level for stop in stops)
                    ),
                    None,
                )
                if car is None:  # a new car, named by its door (and floor, if that is taken)
                    car = door.id if door.id not in cars else f"{door.id} (floor {floor.level})"
                cars.setdefault(car, []).append(RoomLocation(floor, door))
        return cars

    def car_door(self, car: str, level: int) -> Door:
        """Car ``car``'s door on floor ``level``."""
        for stop in self.cars[car]:
            if stop.floor.level == level:
                return stop.door
        raise KeyError(f"elevator {car} does not stop on floor {level}")

    def cars_between(self, a: int, b: int) -> list[str]:
        """The cars that stop on both floors."""
        return [
            car
            for car, stops in self.cars.items()
            if {a, b} <= {stop.floor.level for stop in stops}
        ]

    @property
    def tea_rooms(self) -> list[RoomLocation]:
        """Every pickup point (a door of kind ``tea_room``), in floor then plan order."""
        return [
            RoomLocation(floor, door)
            for floor in self.floors
            for door in floor.doors
            if door.kind == "tea_room"
        ]

    @property
    def tea_room(self) -> RoomLocation:
        """The first pickup point: a fleet's base, where its robots park and are loaded."""
        first = next(iter(self.tea_rooms), None)
        if first is None:
            raise KeyError("floor plan has no tea room")
        return first

    @property
    def rooms(self) -> list[str]:
        """Rooms a delivery can go to: every office door, in floor then hallway order."""
        doors = [
            d.room
            for f in self.floors
            for h in f.hallways
            for d in f.view(h.id).features()
            if isinstance(d, Door) and d.kind == "office"
        ]
        return list(dict.fromkeys(doors))  # a room of two doors once


ELEVATOR_TOLERANCE_MM = 200.0
"""How far apart the elevator doors of two floors may be in the building frame: one car."""


def elevator_front(floor: Floor, door: Door) -> tuple[np.ndarray, np.ndarray]:
    """Where the car's door stands (the leaf's centre) in the building frame, and the unit
    direction from there into the car."""
    centre = np.array(floor.behind_door(door, door.recess_mm))
    inward = np.array(floor.behind_door(door, door.recess_mm + 1.0)) - centre
    return centre, inward / np.linalg.norm(inward)


def facing_alike(inward_a: np.ndarray, inward_b: np.ndarray) -> bool:
    """Whether two elevator doors open the same way (within 45 degrees)."""
    return float(inward_a @ inward_b) >= math.cos(math.radians(45))


def same_car(a: tuple[np.ndarray, np.ndarray], b: tuple[np.ndarray, np.ndarray]) -> bool:
    """Whether two elevator doors (:func:`elevator_front`) open one car."""
    (centre_a, inward_a), (centre_b, inward_b) = a, b
    near = float(np.linalg.norm(centre_a - centre_b)) <= ELEVATOR_TOLERANCE_MM
    return near and facing_alike(inward_a, inward_b)
