"""Which free robot takes which waiting order: by estimated completion time.

A robot carries one cup, so the dispatcher keeps the queue and gives each free robot one
order at a time. An order's cost on a robot is when it would be delivered if that robot took
it: how soon the robot can be in the tea room (at once if it stands there, else the way back
from where it is), the loading, and the route to the door (route length on the floor plan
at the fleet's delivery pace, elevator rides included: :class:`~coffeebot.fleet.estimates.
TravelTimes`).

When several orders wait and several robots are free, the assignment is solved jointly (the
Hungarian method, ``scipy.optimize.linear_sum_assignment``). Its objective is the sum of
the *squares* of each order's whole wait (how long it has waited plus how long until it is
delivered): every delivery starts at the one loading spot, so the plain sum of completion
times is the same for every pairing, while the squares give the soonest robots to the orders
that would otherwise wait longest, which is what the wait's 95th percentile feels.
:func:`greedy` is the first-come alternative it is measured against (``bench/fleet.py``):
each order in arrival order takes the robot that finishes it soonest.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import dataclass

import numpy as np
from scipy.optimize import linear_sum_assignment


@dataclass(frozen=True)
class WaitingOrder:
    order_id: str
    room: str
    waited_s: float = 0.0
    """Since it was placed."""


@dataclass(frozen=True)
class FreeRobot:
    robot: str
    ready_in_s: float
    """Seconds until it can stand at the loading spot (0: it does)."""


CostFn = Callable[[WaitingOrder, FreeRobot], float]


def completion_s(loading_s: float, to_room_s: Callable[[str], float]) -> CostFn:
    """Seconds from now until ``order`` would be at its door if ``robot`` took it."""

    def cost(order: WaitingOrder, robot: FreeRobot) -> float:
        return robot.ready_in_s + loading_s + to_room_s(order.room)

    return cost


def joint(
    orders: Sequence[WaitingOrder], robots: Sequence[FreeRobot], cost: CostFn
) -> list[tuple[WaitingOrder, FreeRobot]]:
    """Pairs minimising the sum of squared whole waits; with more orders than robots the
    oldest orders are considered first (``orders`` in arrival order), so none waits forever."""
    if not orders or not robots:
        return []
    considered = list(orders[: len(robots)])
    matrix = np.array([[(o.waited_s + cost(o, r)) ** 2 for r in robots] for o in considered])
    rows, cols = linear_sum_assignment(matrix)
    return [(considered[int(i)], robots[int(j)]) for i, j in zip(rows, cols, strict=True)]


def greedy(
    orders: Sequence[WaitingOrder], robots: Sequence[FreeRobot], cost: CostFn
) -> list[tuple[WaitingOrder, FreeRobot]]:
    """First come, first served: each order in arrival order takes the free robot that
    would finish it soonest."""
    free = list(robots)
    pairs = []
    for order in orders:
        if not free:
            break
        best = min(free, key=lambda r: cost(order, r))
        free.remove(best)
        pairs.append((order, best))
    return pairs


STRATEGIES = {"joint": joint, "greedy": greedy}
