"""How long a robot takes from where it is to a door, for the dispatcher's choices.

The route is the one navigation would drive (:class:`~coffeebot.navigation.route.
RoutePlanner`), measured as the lines a person would draw (``route_legs``), at the pace a
whole delivery keeps (slower than cruising: people, doors and turns), plus a typical time for
each elevator ride: the same estimate a customer's status page gives
(:mod:`coffeebot.web.eta`).
"""

from __future__ import annotations

from functools import cache

from coffeebot.config import RobotConfig
from coffeebot.floorplan import FloorPlan
from coffeebot.navigation.path import polyline_length_mm, route_legs
from coffeebot.navigation.route import Place, RoutePlanner
from coffeebot.web.eta import Pace


class TravelTimes:
    def __init__(self, plan: FloorPlan, config: RobotConfig, pace: Pace) -> None:
        self.plan = plan
        self.pace = pace
        self.planner = RoutePlanner.for_robot(plan, config)
        self.base_to = cache(self._base_to)
        """Seconds from the loading spot to ``room``'s door (the same for every order)."""

    def between(self, floor: int, x_mm: float, y_mm: float, room: str | None) -> float:
        """Seconds from (``x_mm``, ``y_mm``) on ``floor`` to ``room``'s door (None: back to
        the loading spot)."""
        goal = self.planner.base if room is None else self.planner.door_place(room)
        return self._along(floor, x_mm, y_mm, goal)

    def _base_to(self, room: str) -> float:
        base = self.planner.base
        floor = self.plan.floor(base.floor)
        depth = base.door.recess_mm + self.planner.nav.base_depth_mm
        x, y = floor.behind_door(base.door, depth)  # where it parks
        return self._along(base.floor, x, y, self.planner.door_place(room))

    def _along(self, floor: int, x_mm: float, y_mm: float, goal: Place) -> float:
        hallway, s, leave = self.planner.where(floor, x_mm, y_mm)
        route = self.planner.route(floor, s, goal, leave, hallway=hallway)
        legs = route_legs(route, self.plan, floor, (x_mm, y_mm))
        length = sum(polyline_length_mm(leg.points) for leg in legs)
        return length / self.pace.travel_mm_s + (len(legs) - 1) * self.pace.elevator_ride_s
