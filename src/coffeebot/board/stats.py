"""Plain-data statistics of the board, as the inspector and the logs see them."""

from __future__ import annotations

from pydantic import BaseModel

from coffeebot.board.topic import Delivery


class SubscriberStats(BaseModel):
    name: str
    pending: int
    delivered: int
    dropped: int
    overflowed: int


class TopicStats(BaseModel):
    name: str
    model: str
    delivery: Delivery
    published: int
    delivered: int
    dropped: int
    overflowed: int
    rate_hz: float
    age_s: float | None
    last_seq: int
    subscribers: list[SubscriberStats]


class BoardSnapshot(BaseModel):
    time_s: float
    topics: list[TopicStats]

    def topic(self, name: str) -> TopicStats:
        return next(t for t in self.topics if t.name == name)
