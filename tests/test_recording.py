"""Recording board traffic to MCAP, reading it back with the mcap library, replaying it."""

from __future__ import annotations

import asyncio
import json
import logging
import re
import threading
from collections.abc import Callable
from pathlib import Path
from typing import Any

import pytest
from mcap.reader import make_reader
from mcap.writer import Writer

from coffeebot.board import Board
from coffeebot.board.recording import (
    Player,
    Recorder,
    RecordingError,
    read_recording,
    recording_info,
    schema_name,
)
from coffeebot.clock import SteppedClock
from coffeebot.messages import (
    ALL_TOPICS,
    COLLISION,
    DELIVERY_STATUS,
    HEALTH,
    ODOMETRY,
    RANGE_SCAN,
    DeliveryUpdate,
    Health,
    HealthStatus,
    OrderStatus,
    RangeScan,
)
from manual_clock import ManualClock, settle
from traffic import Published, make_recording, play_through


@pytest.fixture
async def recorded(tmp_path: Path) -> tuple[Path, Published, Recorder]:
    path = tmp_path / "hallway.mcap"
    published, recorder = await make_recording(path)
    return path, published, recorder


async def test_recording_reads_back_with_schemas_and_counts(
    recorded: tuple[Path, Published, Recorder],
):
    path, published, recorder = recorded
    assert (recorder.written, recorder.lost, recorder.missed) == (405, 0, 0)
    with path.open("rb") as stream:
        reader = make_reader(stream)
        summary = reader.get_summary()
        assert summary is not None and summary.statistics is not None
        models = {t.name: t.model for t in ALL_TOPICS}
        by_topic = {c.topic: c for c in summary.channels.values()}
        assert set(by_topic) == set(models)
        for name, channel in by_topic.items():
            schema = summary.schemas[channel.schema_id]
            assert schema.encoding == "jsonschema"
            assert schema.name == schema_name(models[name])
            assert json.loads(schema.data) == models[name].model_json_schema()
            assert channel.message_encoding == "json"
            expected = len(published.get(name, []))
            assert summary.statistics.channel_message_counts.get(channel.id, 0) == expected
        for _schema, channel, message in reader.iter_messages(topics=[RANGE_SCAN.name]):
            original = published[channel.topic][message.sequence - 1]
            assert message.log_time == round(original.stamp * 1e9)
            assert RangeScan.model_validate_json(message.data) == original.msg


def test_info_lists_topics_counts_and_duration(recorded: tuple[Path, Published, Recorder]):
    path, _, _ = recorded
    info = recording_info(path)
    assert info.messages == 405
    assert info.start_s == pytest.approx(100.0)
    assert info.duration_s == pytest.approx(1.99)
    counts = {t.name: t.messages for t in info.topics}
    assert counts[RANGE_SCAN.name] == 100
    assert counts[ODOMETRY.name] == 200
    assert counts[DELIVERY_STATUS.name] == 4
    assert info.metadata["robot"] == "coffeebot-v1"
    text = info.format()
    assert "tof/scan" in text and "coffeebot.messages.RangeScan" in text


async def test_replay_republishes_the_same_messages_at_the_same_stamps(
    recorded: tuple[Path, Published, Recorder],
):
    path, published, _ = recorded
    clock = ManualClock(start=recording_info(path).start_s)
    board = Board(ALL_TOPICS, clock=clock)
    subscriptions = [board.subscribe(t, name="check") for t in ALL_TOPICS]
    replayed: Published = {}

    async def collect() -> None:
        while True:
            for subscription in subscriptions:
                while (envelope := subscription.get_nowait()) is not None:
                    replayed.setdefault(envelope.topic, []).append(envelope)
            await asyncio.sleep(0)

    collector = asyncio.create_task(collect())
    stats = await play_through(Player(board, path), clock)
    collector.cancel()
    assert stats.total == 405
    assert all(s.dropped == 0 for s in subscriptions)
    assert replayed.keys() == published.keys()
    for name, originals in published.items():
        again = replayed[name]
        assert [e.msg for e in again] == [e.msg for e in originals]
        assert [e.stamp for e in again] == pytest.approx([e.stamp for e in originals], abs=1e-6)


async def test_replay_of_chosen_topics_only(recorded: tuple[Path, Published, Recorder]):
    path, _, _ = recorded
    clock = ManualClock(start=1000.0)  # past the end of the recording: no waiting
    board = Board(ALL_TOPICS, clock=clock)
    stats = await play_through(Player(board, path, only=[RANGE_SCAN.name]), clock)
    assert stats.published == {RANGE_SCAN.name: 100}


def write_raw(path: Path, topic: str, data: bytes) -> None:
    with path.open("wb") as stream:
        writer = Writer(stream)
        writer.start()
        channel = writer.register_channel(topic, "json", 0)
        writer.add_message(channel, log_time=1, data=data, publish_time=1, sequence=1)
        writer.finish()


def test_a_message_that_no_longer_fits_its_model_is_a_clear_error(tmp_path: Path):
    path = tmp_path / "old.mcap"
    write_raw(path, COLLISION.name, b'{"state": "go"}')
    with pytest.raises(RecordingError, match=r"safety/collision.*CollisionStatus"):
        list(read_recording(path, ALL_TOPICS))


def test_topics_this_build_does_not_know_are_skipped(tmp_path: Path):
    path = tmp_path / "newer.mcap"
    write_raw(path, "lidar/points", b"{}")
    assert list(read_recording(path, ALL_TOPICS)) == []


def test_a_cut_short_recording_is_reported(recorded: tuple[Path, Published, Recorder]):
    path, _, _ = recorded
    data = path.read_bytes()
    path.write_bytes(data[: len(data) // 2])
    with pytest.raises(RecordingError, match=re.escape(str(path))):
        recording_info(path)


async def test_a_failing_disk_ends_the_recording_not_the_caller(caplog: pytest.LogCaptureFixture):
    board = Board(ALL_TOPICS)
    recorder = Recorder(board, "/dev/full")
    async with recorder:
        for _ in range(5):
            board.publish(HEALTH, Health(module="tof", status=HealthStatus.RUNNING))
            await asyncio.sleep(0)
    assert isinstance(recorder.error, OSError)
    (line,) = [r for r in caplog.records if getattr(r, "event", None) == "fault"]
    assert "No space left on device" in line.getMessage()


async def test_an_overflowing_reliable_subscription_is_counted_and_recording_goes_on(
    tmp_path: Path,
):
    clock = ManualClock()
    board = Board(ALL_TOPICS, clock=clock)
    path = tmp_path / "burst.mcap"
    update = DeliveryUpdate(order_id="A1", status=OrderStatus.QUEUED)
    async with Recorder(board, path, topics=[DELIVERY_STATUS]) as recorder:
        for _ in range(DELIVERY_STATUS.queue_size + 44):  # without yielding to the recorder
            board.publish(DELIVERY_STATUS, update)
        await settle()
        board.publish(DELIVERY_STATUS, update)
        await settle()
    assert recorder.overflowed == DELIVERY_STATUS.queue_size + 44
    assert [t.messages for t in recording_info(path).topics] == [1]


async def test_the_closing_line_says_what_its_counts_mean(
    tmp_path: Path, caplog: pytest.LogCaptureFixture
) -> None:
    caplog.set_level(logging.INFO, logger="coffeebot.board.recording")
    await make_recording(tmp_path / "pass.mcap")
    [closed] = [r.getMessage() for r in caplog.records if "recording closed" in r.getMessage()]
    assert "405 messages written, 0 lost; 0 sensor values skipped" in closed
    assert "keep the newest value" in closed


async def test_simulated_time_waits_while_the_file_is_opened(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """A slow disk must not let the simulated world step on: a recorded run would start at
    another simulated moment than an unrecorded one, and take another course."""
    clock = SteppedClock()
    clock.lockstep.engage(True)
    opening, release = threading.Event(), threading.Event()
    open_file = Recorder._open

    def slow_open(self: Recorder) -> Any:
        opening.set()
        release.wait(5.0)
        return open_file(self)

    monkeypatch.setattr(Recorder, "_open", slow_open)
    recorder = Recorder(Board(ALL_TOPICS, clock=clock), tmp_path / "slow.mcap")
    start = asyncio.create_task(recorder.start())
    assert await asyncio.to_thread(opening.wait, 5.0)
    results: list[Callable[[], None]] = []
    settled = threading.Thread(target=lambda: results.extend(clock.lockstep.settle()), daemon=True)
    settled.start()
    settled.join(0.2)
    assert settled.is_alive(), "the world could step while the file was being opened"
    release.set()
    await asyncio.to_thread(settled.join, 5.0)
    assert not settled.is_alive()
    for deliver in results:
        deliver()
    await asyncio.wait_for(start, 5.0)
    clock.lockstep.engage(False)  # the world has stopped: the closing call is not held
    await asyncio.wait_for(recorder.stop(), 5.0)
    assert [t.name for t in recording_info(tmp_path / "slow.mcap").topics] == [
        t.name for t in ALL_TOPICS
    ]
