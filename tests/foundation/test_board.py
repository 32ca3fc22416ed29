from __future__ import annotations

import asyncio

import pytest
from pydantic import BaseModel

from coffeebot.board import Board, BoardError, BoardOverflowError, Delivery, Topic
from coffeebot.messages import Message


class Reading(Message):
    value: int


class Event(Message):
    text: str


class Other(BaseModel):
    value: int


READING = Topic("test/reading", Reading, Delivery.LATEST)
EVENT = Topic("test/event", Event, Delivery.RELIABLE, queue_size=4)


@pytest.fixture
def board(clock) -> Board:
    return Board([READING, EVENT], clock=clock)


def test_publish_rejects_wrong_type_naming_topic_and_types(board: Board) -> None:
    with pytest.raises(BoardError, match=r"test/reading.*Reading.*Event"):
        board.publish(READING, Event(text="x"))  # type: ignore[arg-type]
    with pytest.raises(BoardError, match=r"test/reading.*Reading.*Other"):
        board.publish(READING, Other(value=1))  # type: ignore[arg-type]


def test_publish_rejects_unknown_topic_naming_it(board: Board) -> None:
    with pytest.raises(BoardError, match=r"unknown topic 'nope'.*test/event.*test/reading"):
        board.publish("nope", Reading(value=1))


def test_duplicate_topic_declaration_is_refused() -> None:
    with pytest.raises(BoardError, match="declared twice"):
        Board([READING, Topic("test/reading", Event)])


def test_topic_with_same_name_but_other_model_is_refused(board: Board) -> None:
    impostor = Topic("test/reading", Event)
    with pytest.raises(BoardError, match="different model"):
        board.publish(impostor, Event(text="x"))


def test_publish_stamps_time_and_per_topic_sequence(board: Board, clock) -> None:
    first = board.publish(READING, Reading(value=1))
    second = board.publish(READING, Reading(value=2))
    event = board.publish(EVENT, Event(text="a"))
    assert (first.seq, second.seq, event.seq) == (1, 2, 1)
    assert first.stamp == clock.now()
    assert first.topic == "test/reading"


async def test_latest_delivery_gives_slow_reader_the_newest_and_counts_drops(board: Board) -> None:
    sub = board.subscribe(READING, name="slow")
    for value in range(10):
        board.publish(READING, Reading(value=value))
    envelope = await sub.get()
    assert envelope.msg.value == 9
    assert sub.dropped == 9
    stats = board.snapshot().topic("test/reading")
    assert stats.dropped == 9 and stats.published == 10 and stats.delivered == 1


async def test_reliable_delivery_keeps_every_message_in_order(board: Board) -> None:
    sub = board.subscribe(EVENT, name="reader")
    for i in range(4):
        board.publish(EVENT, Event(text=str(i)))
    received = [(await sub.get()).msg.text for _ in range(4)]
    assert received == ["0", "1", "2", "3"]
    assert sub.dropped == 0


async def test_reliable_overflow_is_reported_not_silent(board: Board) -> None:
    sub = board.subscribe(EVENT, name="stuck")
    for i in range(6):
        board.publish(EVENT, Event(text=str(i)))
    stats = board.snapshot().topic("test/event")
    assert stats.overflowed == 2
    assert stats.subscribers[0].name == "stuck"
    with pytest.raises(BoardOverflowError, match=r"stuck.*lost 2.*test/event.*queue size 4"):
        await sub.get()


async def test_slow_or_dead_subscriber_does_not_delay_others_or_publisher(board: Board) -> None:
    dead = board.subscribe(EVENT, name="dead")  # never read
    slow = board.subscribe(READING, name="slow")  # never read
    fast = board.subscribe(READING, name="fast")
    received: list[int] = []

    async def reader() -> None:
        async for envelope in fast:
            received.append(envelope.msg.value)
            if envelope.msg.value == 99:
                return

    task = asyncio.create_task(reader())
    for value in range(100):
        board.publish(READING, Reading(value=value))  # returns without awaiting anything
        board.publish(EVENT, Event(text="x"))
        await asyncio.sleep(0)
    await asyncio.wait_for(task, 1)
    assert received == list(range(100))
    assert fast.dropped == 0
    assert slow.dropped == 99
    assert dead.overflowed == 96
    del dead


async def test_latest_and_age(board: Board, clock) -> None:
    assert board.latest(READING) is None and board.age(READING) is None
    board.publish(READING, Reading(value=5))
    await clock.advance(0.25)
    assert board.latest(READING).msg.value == 5
    assert board.age(READING) == pytest.approx(0.25)
    assert board.snapshot().topic("test/reading").age_s == pytest.approx(0.25)


async def test_next_waits_for_a_new_message(board: Board) -> None:
    board.publish(READING, Reading(value=1))
    waiter = asyncio.create_task(board.next(READING, timeout=5))
    await asyncio.sleep(0)
    board.publish(READING, Reading(value=2))
    assert (await waiter).msg.value == 2


async def test_next_times_out_on_the_board_clock(board: Board, clock) -> None:
    waiter = asyncio.create_task(board.next(READING, timeout=0.5))
    for _ in range(3):  # let next() start its timer
        await asyncio.sleep(0)
    await clock.advance(0.4)
    assert not waiter.done()
    await clock.advance(0.2)
    with pytest.raises(TimeoutError, match="test/reading"):
        await waiter


async def test_rate_counts_messages_in_the_window(board: Board, clock) -> None:
    for _ in range(50):
        board.publish(READING, Reading(value=1))
        await clock.advance(0.1)
    assert board.snapshot().topic("test/reading").rate_hz == pytest.approx(10.0, rel=0.05)


async def test_closing_a_subscription_ends_iteration_and_detaches(board: Board) -> None:
    sub = board.subscribe(READING, name="gone")
    task = asyncio.create_task(sub.get())
    await asyncio.sleep(0)
    sub.close()
    with pytest.raises(StopAsyncIteration):
        await task
    assert board.snapshot().topic("test/reading").subscribers == []
