"""A route as the lines a person would draw: the points it passes on each floor.

Motion follows instructions, not lines; this is for people (the live map draws it, the
customer's arrival estimate measures it). A lane-following move ends at its target on its
lane, a drive ends at its point, turns and leases add nothing, and an elevator ride starts a
new leg on the floor it arrives at.
"""

from __future__ import annotations

import itertools
import math
from collections.abc import Mapping, Sequence
from typing import TypeVar

from coffeebot.floorplan import FloorPlan
from coffeebot.messages import MoveInstruction, RouteLeg
from coffeebot.navigation.route import ElevatorRide, Lease, Move, Route


def polyline_length_mm(points: Sequence[tuple[float, float]]) -> float:
    return sum(math.dist(a, b) for a, b in itertools.pairwise(points))


def _point(plan: FloorPlan, ins: MoveInstruction) -> tuple[float, float] | None:
    if ins.floor is None:
        return None
    if ins.action == "follow_lane" and ins.target_s_mm is not None:
        along = plan.floor(ins.floor).view(ins.hallway)
        return along.from_hallway(ins.target_s_mm, ins.lane_mm or 0.0)
    if ins.action == "drive_to" and ins.x_mm is not None and ins.y_mm is not None:
        return ins.x_mm, ins.y_mm
    return None


def route_legs(
    route: Route, plan: FloorPlan, floor: int, start: tuple[float, float]
) -> list[RouteLeg]:
    """The route's points from ``start`` on ``floor``, one leg per floor in order."""
    legs: list[tuple[int, list[tuple[float, float]]]] = [(floor, [start])]

    def add(steps: Sequence[Move | Lease]) -> None:
        for move in steps:
            if isinstance(move, Lease):
                continue
            point = _point(plan, move.instruction)
            if point is not None:
                legs[-1][1].append(point)

    for step in route.steps:
        if isinstance(step, ElevatorRide):
            add(step.enter)
            # The car rides straight up or down: the next floor's leg starts where it stood.
            legs.append((step.to_floor, [legs[-1][1][-1]]))
            add(step.exit)
        elif isinstance(step, Move):
            add([step])
    return [RouteLeg(floor=level, points=points) for level, points in legs]


Way = TypeVar("Way")


def nearest(
    routes: Mapping[Way, Route], plan: FloorPlan, floor: int, start: tuple[float, float]
) -> Way:
    """The key of the route with the fewest elevator rides and then the shortest lines (a
    ride, calling the car included, takes longer than any hallway of a building)."""

    def rides_and_length(key: Way) -> tuple[int, float]:
        legs = route_legs(routes[key], plan, floor, start)
        return len(legs) - 1, sum(polyline_length_mm(leg.points) for leg in legs)

    return min(routes, key=rides_and_length)
