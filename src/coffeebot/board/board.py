"""The message board: typed publish/subscribe inside one asyncio process.

The board only carries messages. ``publish`` validates the type, stamps the message, hands it
to every subscription without awaiting anything, and returns. Each subscription owns its own
buffer (one slot for LATEST topics, a bounded deque for RELIABLE ones), so a slow or dead
reader only ever affects itself.
"""

from __future__ import annotations

import asyncio
import logging
from collections import deque
from collections.abc import AsyncIterator, Iterable
from typing import Any, Generic, TypeVar, overload

from pydantic import BaseModel

from coffeebot.board.stats import BoardSnapshot, SubscriberStats, TopicStats
from coffeebot.board.topic import Delivery, Envelope, Topic
from coffeebot.clock import Clock, MonotonicClock
from coffeebot.cpu import CpuAccount, board_time
from coffeebot.errors import BoardError

log = logging.getLogger(__name__)

M = TypeVar("M", bound=BaseModel)

RATE_WINDOW_S = 5.0


class BoardOverflowError(BoardError):
    """A reliable subscription fell further behind than its queue allows."""


class Subscription(Generic[M]):
    """One reader's view of one topic. Iterate it with ``async for``."""

    def __init__(self, board: Board, channel: _Channel[M], name: str) -> None:
        self._board = board
        self._channel = channel
        self.name = name
        self.topic = channel.topic
        self.delivered = 0
        self.dropped = 0
        self.overflowed = 0
        self._buffer: deque[Envelope[M]] = deque()
        self._waiter: asyncio.Future[None] | None = None
        self._closed = False

    def _offer(self, envelope: Envelope[M]) -> None:
        """Called by ``publish``: never blocks, never raises."""
        if self.topic.delivery is Delivery.LATEST:
            if self._buffer:
                self._buffer.pop()
                self.dropped += 1
            self._buffer.append(envelope)
        elif len(self._buffer) >= self.topic.queue_size:
            self.overflowed += 1
            if self.overflowed == 1:
                log.error(
                    "board overflow: subscriber %r on reliable topic %r is %d messages behind",
                    self.name,
                    self.topic.name,
                    len(self._buffer),
                )
        else:
            self._buffer.append(envelope)
        waiter = self._waiter
        if waiter is not None and not waiter.done():
            waiter.set_result(None)

    def pending(self) -> int:
        return len(self._buffer)

    def get_nowait(self) -> Envelope[M] | None:
        """The next buffered envelope, or None when nothing is waiting."""
        self._raise_if_overflowed()
        if not self._buffer:
            return None
        self.delivered += 1
        self._channel.delivered += 1
        return self._buffer.popleft()

    async def get(self) -> Envelope[M]:
        while True:
            envelope = self.get_nowait()
            if envelope is not None:
                return envelope
            if self._closed:
                raise StopAsyncIteration
            self._waiter = asyncio.get_running_loop().create_future()
            try:
                await self._waiter
            finally:
                self._waiter = None

    def _raise_if_overflowed(self) -> None:
        if self.overflowed:
            raise BoardOverflowError(
                f"subscriber {self.name!r} lost {self.overflowed} message(s) on reliable topic "
                f"{self.topic.name!r} (queue size {self.topic.queue_size})"
            )

    def __aiter__(self) -> AsyncIterator[Envelope[M]]:
        return self

    async def __anext__(self) -> Envelope[M]:
        return await self.get()

    def close(self) -> None:
        """Detach from the board; a pending ``get`` ends the iteration."""
        if self._closed:
            return
        self._closed = True
        self._channel.subscribers.remove(self)
        if self._waiter is not None and not self._waiter.done():
            self._waiter.set_result(None)

    def __enter__(self) -> Subscription[M]:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()


class _Channel(Generic[M]):
    """Everything the board keeps per topic."""

    __slots__ = (
        "delivered",
        "last",
        "publish_times",
        "published",
        "seq",
        "subscribers",
        "topic",
        "waiters",
    )

    def __init__(self, topic: Topic[M]) -> None:
        self.topic = topic
        self.seq = 0
        self.published = 0
        self.delivered = 0
        self.last: Envelope[M] | None = None
        self.subscribers: list[Subscription[M]] = []
        self.publish_times: deque[float] = deque()
        self.waiters: list[asyncio.Future[Envelope[M]]] = []


class Board:
    """Typed publish/subscribe between the daemon's modules."""

    def __init__(self, topics: Iterable[Topic[Any]], clock: Clock | None = None) -> None:
        self.clock: Clock = clock or MonotonicClock()
        self.cpu_account: CpuAccount | None = None
        """Where publishing's CPU time is booked when metered (:mod:`coffeebot.cpu`)."""
        self._channels: dict[str, _Channel[Any]] = {}
        for topic in topics:
            if topic.name in self._channels:
                raise BoardError(f"topic {topic.name!r} declared twice")
            self._channels[topic.name] = _Channel(topic)

    @property
    def topics(self) -> list[Topic[Any]]:
        return [channel.topic for channel in self._channels.values()]

    def topic(self, name: str) -> Topic[Any]:
        return self._channel(name).topic

    def _channel(self, topic: Topic[M] | str) -> _Channel[M]:
        name = topic if isinstance(topic, str) else topic.name
        try:
            channel = self._channels[name]
        except KeyError:
            raise BoardError(
                f"unknown topic {name!r}; declared topics: {', '.join(sorted(self._channels))}"
            ) from None
        if not isinstance(topic, str) and channel.topic is not topic and channel.topic != topic:
            raise BoardError(f"topic {name!r} is declared with a different model or delivery")
        return channel

    def publish(self, topic: Topic[M] | str, msg: M) -> Envelope[M]:
        """Stamp ``msg`` and hand it to every subscriber. Never blocks."""
        with board_time(self.cpu_account):
            return self._publish(topic, msg)

    def _publish(self, topic: Topic[M] | str, msg: M) -> Envelope[M]:
        channel = self._channel(topic)
        model = channel.topic.model
        if type(msg) is not model:
            raise BoardError(
                f"topic {channel.topic.name!r} carries {model.__name__}, got {type(msg).__name__}"
            )
        now = self.clock.now()
        channel.seq += 1
        channel.published += 1
        envelope = Envelope(channel.topic.name, channel.seq, now, msg)
        channel.last = envelope
        times = channel.publish_times
        times.append(now)
        horizon = now - RATE_WINDOW_S
        while times[0] < horizon:
            times.popleft()
        for subscription in channel.subscribers:
            subscription._offer(envelope)
        if channel.waiters:
            waiters, channel.waiters = channel.waiters, []
            for waiter in waiters:
                if not waiter.done():
                    waiter.set_result(envelope)
        return envelope

    def subscribe(self, topic: Topic[M] | str, name: str = "anonymous") -> Subscription[M]:
        channel = self._channel(topic)
        subscription = Subscription(self, channel, name)
        channel.subscribers.append(subscription)
        return subscription

    def latest(self, topic: Topic[M] | str) -> Envelope[M] | None:
        """The newest envelope on ``topic`` (its age is ``board.age(topic)``), or None."""
        return self._channel(topic).last

    def age(self, topic: Topic[M] | str) -> float | None:
        last = self._channel(topic).last
        return None if last is None else self.clock.now() - last.stamp

    @overload
    async def next(self, topic: Topic[M], timeout: float | None = None) -> Envelope[M]: ...

    @overload
    async def next(self, topic: str, timeout: float | None = None) -> Envelope[Any]: ...

    async def next(self, topic: Topic[M] | str, timeout: float | None = None) -> Envelope[M]:
        """Wait for the next message published on ``topic``; ``TimeoutError`` after ``timeout``.

        The timeout is in the board clock's seconds.
        """
        channel = self._channel(topic)
        waiter: asyncio.Future[Envelope[M]] = asyncio.get_running_loop().create_future()
        channel.waiters.append(waiter)
        try:
            if timeout is None:
                return await waiter
            timeout_task: asyncio.Future[None] = asyncio.ensure_future(self.clock.sleep(timeout))
            racing: set[asyncio.Future[Any]] = {waiter, timeout_task}
            try:
                done, _ = await asyncio.wait(racing, return_when=asyncio.FIRST_COMPLETED)
            finally:
                timeout_task.cancel()
            if waiter in done:
                return waiter.result()
            raise TimeoutError(f"no message on {channel.topic.name!r} within {timeout} s")
        finally:
            if waiter in channel.waiters:
                channel.waiters.remove(waiter)
            waiter.cancel()

    def snapshot(self) -> BoardSnapshot:
        """Per-topic statistics as plain data, for the inspector and the logs."""
        now = self.clock.now()
        topics = []
        for channel in self._channels.values():
            times = channel.publish_times
            recent = [t for t in times if t >= now - RATE_WINDOW_S]
            last = channel.last
            topics.append(
                TopicStats(
                    name=channel.topic.name,
                    model=channel.topic.model.__name__,
                    delivery=channel.topic.delivery,
                    published=channel.published,
                    delivered=channel.delivered,
                    dropped=sum(s.dropped for s in channel.subscribers),
                    overflowed=sum(s.overflowed for s in channel.subscribers),
                    rate_hz=len(recent) / RATE_WINDOW_S,
                    age_s=None if last is None else now - last.stamp,
                    last_seq=channel.seq,
                    subscribers=[
                        SubscriberStats(
                            name=s.name,
                            pending=s.pending(),
                            delivered=s.delivered,
                            dropped=s.dropped,
                            overflowed=s.overflowed,
                        )
                        for s in channel.subscribers
                    ],
                )
            )
        return BoardSnapshot(time_s=now, topics=topics)
