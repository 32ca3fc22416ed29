"""Shared places a robot must hold alone: the elevator car, the tea room's loading spot, the
holding point where a robot out of the car waits for that spot, the crossing in front of the
car's and the tea room's doors where they face each other, and the landing in front of the
car's door on the other floors.

The dispatcher keeps one :class:`LeaseBook`. A robot asks for a place before it goes in and
gives it back when it is out; while inside it asks again now and then, which renews the
lease. A lease that is not renewed expires, so no lease outlives a robot that died or lost
the broker while holding it (Open-RMF's users report lift sessions that never end). Robots
that ask while the place is taken wait in the order they asked; the place goes to the first
of them when it frees.
"""

from __future__ import annotations

from collections import deque
from dataclasses import dataclass, field

from coffeebot.fleet.protocol import Place

PLACES: tuple[Place, ...] = ("elevator", "loading_spot", "holding_point", "crossing", "landing")


@dataclass
class Lease:
    holder: str
    expires_at_s: float


@dataclass
class PlaceState:
    lease: Lease | None = None
    waiting: deque[str] = field(default_factory=deque)


@dataclass(frozen=True)
class Answer:
    granted: bool
    holder: str | None
    """Who holds the place after this request (the asker, if granted)."""


class LeaseBook:
    """Who holds each place until when; ``duration_s`` is how long a grant or renewal
    lasts (on the dispatcher's clock)."""

    def __init__(self, duration_s: float) -> None:
        self.duration_s = duration_s
        self.places = {place: PlaceState() for place in PLACES}

    def request(self, robot: str, place: Place, now_s: float) -> Answer:
        """Grant (or renew) ``place`` to ``robot`` if it is free, expired or already its and
        nobody asked before; otherwise ``robot`` waits its turn."""
        state = self.places[place]
        self._expire(state, now_s)
        lease = state.lease
        if lease is not None and lease.holder == robot:
            lease.expires_at_s = now_s + self.duration_s
            return Answer(True, robot)
        first = state.waiting[0] if state.waiting else robot
        if lease is None and first == robot:
            if state.waiting:
                state.waiting.popleft()
            state.lease = Lease(robot, now_s + self.duration_s)
            return Answer(True, robot)
        if robot not in state.waiting:
            state.waiting.append(robot)
        return Answer(False, None if lease is None else lease.holder)

    def release(self, robot: str, place: Place) -> None:
        """``robot`` is out of ``place`` (or no longer waits for it)."""
        state = self.places[place]
        if state.lease is not None and state.lease.holder == robot:
            state.lease = None
        if robot in state.waiting:
            state.waiting.remove(robot)

    def forget(self, robot: str) -> None:
        """``robot`` is gone (its connection broke, it stopped reporting): every place it
        held or waited for is free for the next."""
        for place in PLACES:
            self.release(robot, place)

    def holder(self, place: Place, now_s: float) -> str | None:
        state = self.places[place]
        self._expire(state, now_s)
        return None if state.lease is None else state.lease.holder

    @staticmethod
    def _expire(state: PlaceState, now_s: float) -> None:
        if state.lease is not None and now_s >= state.lease.expires_at_s:
            state.lease = None
