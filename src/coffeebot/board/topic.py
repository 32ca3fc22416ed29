"""Topic declarations: a name, the pydantic model it carries, and how it is delivered."""

from __future__ import annotations

from dataclasses import dataclass
from enum import StrEnum
from typing import Generic, TypeVar

from pydantic import BaseModel

M = TypeVar("M", bound=BaseModel)


class Delivery(StrEnum):
    """How a topic reaches a subscriber that reads slower than it is written.

    ``LATEST``: sensor data. A slow reader sees the newest value; the older ones it never read
    are dropped and counted. ``RELIABLE``: orders and events. Every message is queued up to
    ``queue_size``; overflowing that is an error that is counted, logged and raised in the
    reader, never silent loss.
    """

    LATEST = "latest"
    RELIABLE = "reliable"


@dataclass(frozen=True, slots=True)
class Topic(Generic[M]):
    name: str
    model: type[M]
    delivery: Delivery = Delivery.LATEST
    queue_size: int = 256

    def __post_init__(self) -> None:
        if not self.name or self.name != self.name.strip():
            raise ValueError(f"topic name must be non-empty, unpadded: {self.name!r}")
        if self.queue_size < 1:
            raise ValueError(f"topic {self.name}: queue_size must be >= 1")


class Envelope(Generic[M]):
    """A message as the board delivered it: topic name, per-topic sequence number, stamp."""

    __slots__ = ("msg", "seq", "stamp", "topic")

    def __init__(self, topic: str, seq: int, stamp: float, msg: M) -> None:
        self.topic = topic
        self.seq = seq
        self.stamp = stamp
        self.msg = msg

    def __repr__(self) -> str:
        return f"Envelope({self.topic!r}, seq={self.seq}, stamp={self.stamp:.6f}, msg={self.msg!r})"
