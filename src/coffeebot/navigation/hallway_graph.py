"""The way between two hallways of one floor: along one to where it meets the next, and so on.

Hallways meet where one's end lies on another's axis (:attr:`~coffeebot.floorplan.Floor.meetings`).
Each meeting is a node of a graph, as are where the robot starts and where it is going; nodes
along one hallway are joined by the distance between them along it. The shortest way is then
scipy's Dijkstra over that graph: one speed on every hallway makes the shortest the quickest.
"""

from __future__ import annotations

import itertools
from dataclasses import dataclass

import numpy as np
from scipy.sparse import csr_matrix
from scipy.sparse.csgraph import dijkstra

from coffeebot.floorplan import Floor, Meeting


@dataclass(frozen=True)
class Hop:
    """Along ``hallway`` to ``s_mm``, where it meets ``next_hallway``, at ``next_s_mm`` of it."""

    hallway: str
    s_mm: float
    next_hallway: str
    next_s_mm: float


@dataclass(frozen=True)
class _Node:
    """A point of the graph, and where it lies along each hallway it is on."""

    at: dict[str, float]


def _meeting_node(meeting: Meeting) -> _Node:
    joining = meeting.joining
    on_joining = 0.0 if meeting.joining_end == "start" else joining.length_mm
    return _Node({meeting.through.id: meeting.s_mm, joining.id: on_joining})


def hops(
    floor: Floor, from_hallway: str, from_s_mm: float, to_hallway: str, to_s_mm: float
) -> list[Hop]:
    """The hallways between (``from_hallway``, ``from_s_mm``) and (``to_hallway``,
    ``to_s_mm``), shortest first; none when both lie along one hallway."""
    if from_hallway == to_hallway:
        return []
    nodes = [_Node({from_hallway: from_s_mm}), _Node({to_hallway: to_s_mm})]
    nodes += [_meeting_node(m) for m in floor.meetings]
    size = len(nodes)
    lengths = np.zeros((size, size))
    for hallway in floor.hallways:
        on = [(i, node.at[hallway.id]) for i, node in enumerate(nodes) if hallway.id in node.at]
        for i, s_i in on:
            for j, s_j in on:
                if i != j:
                    # A meeting's own point is a node: nil lengths mean "no edge" to scipy.
                    lengths[i, j] = max(abs(s_i - s_j), 1e-6)
    _, predecessors = dijkstra(csr_matrix(lengths), indices=[0], return_predecessors=True)
    previous = predecessors[0]
    if previous[1] < 0:
        raise ValueError(
            f"floor {floor.level}: no way from hallway {from_hallway} to hallway {to_hallway}"
        )
    path = [1]
    while path[-1] != 0:
        path.append(int(previous[path[-1]]))
    path.reverse()
    found = []
    along = from_hallway
    for here, there in itertools.pairwise(path):
        shared = set(nodes[here].at) & set(nodes[there].at)
        following = next(iter(sorted(shared - {along})), along)
        if following != along:
            found.append(Hop(along, nodes[here].at[along], following, nodes[here].at[following]))
            along = following
    return found
