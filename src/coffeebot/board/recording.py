"""Record board traffic to MCAP and play it back onto a board.

MCAP is the container rosbag2 and Foxglove use. Each topic is one channel with message
encoding ``json`` and a ``jsonschema`` schema generated from its pydantic model, so other
tools can read a recording without this package. Times are the board clock's seconds as
integer nanoseconds (``log_time`` = ``publish_time`` = the envelope stamp); ``sequence`` is
the board's per-topic sequence number, so gaps show what the recorder missed.
"""

from __future__ import annotations

import asyncio
import itertools
import json
import logging
import threading
import time
from collections import deque
from collections.abc import Callable, Generator, Iterable, Mapping
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, BinaryIO

from mcap.exceptions import McapError
from mcap.reader import make_reader
from mcap.writer import Writer
from pydantic import BaseModel, ValidationError

from coffeebot import __version__
from coffeebot.board.board import Board, BoardOverflowError, Subscription
from coffeebot.board.topic import Envelope, Topic
from coffeebot.errors import BoardError
from coffeebot.hardware.worker import DeviceWorker
from coffeebot.logs import Event, log_event

log = logging.getLogger(__name__)

SCHEMA_ENCODING = "jsonschema"
MESSAGE_ENCODING = "json"
METADATA_NAME = "coffeebot"
CHUNK_SIZE = 256 * 1024
"""Smaller than the library's 1 MiB so a power cut loses seconds of traffic, not a minute."""

_READ_BATCH = 256
WRITE_PERIOD_S = 0.05
"""The writer thread wakes this often rather than on every message (see :class:`Recorder`)."""


class RecordingError(BoardError, ValueError):
    """A recording that cannot be read or replayed, with the reason."""


def _ns(seconds: float) -> int:
    return round(seconds * 1e9)


def schema_name(model: type[BaseModel]) -> str:
    return f"{model.__module__}.{model.__qualname__}"


def topic_schema(topic: Topic[Any]) -> bytes:
    """The JSON schema of a topic's model, as a recording and the live Foxglove server carry
    it (encoding :data:`SCHEMA_ENCODING`, named by :func:`schema_name`)."""
    return json.dumps(topic.model.model_json_schema()).encode()


class Recorder:
    """Writes every message on the board's topics to an MCAP file, off the event loop.

    Each topic gets its own board subscription and a small task that moves whatever arrived
    onto a bounded deque; a writer thread wakes every ``WRITE_PERIOD_S`` and serialises,
    compresses and writes what is there. On the event loop a message costs a deque pop and a
    deque append: no lock, no thread wake-up, and the thread yields the GIL between messages.
    If the disk falls behind, the deque fills and messages are dropped and counted: the
    recorder never makes the control loop wait.
    """

    def __init__(
        self,
        board: Board,
        path: str | Path,
        topics: Iterable[Topic[Any]] | None = None,
        metadata: Mapping[str, str] | None = None,
        backlog_size: int = 4096,
    ) -> None:
        self.board = board
        self.path = Path(path)
        self.topics = list(board.topics if topics is None else topics)
        self.metadata = dict(metadata or {})
        self.written = 0
        self.dropped = 0
        """Messages refused because the writer thread's backlog was full."""
        self.overflowed = 0
        """Messages lost because a reliable subscription of the recorder overflowed."""
        self.error: BaseException | None = None
        self._disk = DeviceWorker("mcap-file", board.clock)
        """Opens and closes the file: on the simulator's clock a call in the lockstep ledger,
        so the world does not step on while the disk is slow and a recorded run starts (and
        ends) at the same simulated moment as one that is not recorded."""
        self._discarded = 0
        self._backlog: deque[Envelope[Any]] = deque()
        self._backlog_size = backlog_size
        self._closing = threading.Event()
        self._subscriptions: list[Subscription[Any]] = []
        self._pumps: list[asyncio.Task[None]] = []
        self._thread: threading.Thread | None = None

    @property
    def missed(self) -> int:
        """LATEST-topic messages replaced on the board before the recorder took them."""
        return sum(s.dropped for s in self._subscriptions)

    @property
    def lost(self) -> int:
        """Messages that reached the recorder but not the file (writer behind or failed)."""
        return self.dropped + self._discarded

    def _open(self) -> tuple[BinaryIO, Writer, dict[str, int]]:
        """Create the file with its schemas and channels (in a thread: it touches the disk)."""
        stream = self.path.open("wb")
        writer = Writer(stream, chunk_size=CHUNK_SIZE)
        writer.start(library=f"coffeebot {__version__}")
        writer.add_metadata(
            METADATA_NAME,
            {
                "clock": "board clock seconds, stored as nanoseconds",
                "started_utc": time.strftime("%Y-%m-%dT%H:%M:%SZ", time.gmtime()),
                "version": __version__,
                **self.metadata,
            },
        )
        channels: dict[str, int] = {}
        for topic in self.topics:
            schema_id = writer.register_schema(
                name=schema_name(topic.model),
                encoding=SCHEMA_ENCODING,
                data=topic_schema(topic),
            )
            channels[topic.name] = writer.register_channel(
                topic.name, MESSAGE_ENCODING, schema_id, {"delivery": topic.delivery.value}
            )
        return stream, writer, channels

    async def start(self) -> None:
        try:
            opened = await self._disk.call(self._open)
        except BaseException:
            self._disk.close()
            raise
        self._thread = threading.Thread(
            target=self._write, args=opened, name="mcap-recorder", daemon=True
        )
        self._thread.start()
        for topic in self.topics:
            subscription = self.board.subscribe(topic, name="recorder")
            self._subscriptions.append(subscription)
            self._pumps.append(
                asyncio.create_task(self._pump(subscription), name=f"recorder:{topic.name}")
            )
        log.info("recording %d topics to %s", len(self.topics), self.path)

    async def _pump(self, subscription: Subscription[Any]) -> None:
        while True:
            try:
                batch = [await subscription.get()]
                while (envelope := subscription.get_nowait()) is not None:
                    batch.append(envelope)
            except StopAsyncIteration:
                return
            except BoardOverflowError as exc:
                # Only possible if the loop starved this task for a whole queue's worth of
                # messages; resubscribe so the recording goes on, with the loss counted.
                self.overflowed += subscription.overflowed + subscription.pending()
                log_event(log, Event.FAULT, str(exc), recorder=str(self.path))
                index = self._subscriptions.index(subscription)
                subscription.close()
                subscription = self.board.subscribe(subscription.topic, name="recorder")
                self._subscriptions[index] = subscription
                continue
            if len(self._backlog) + len(batch) > self._backlog_size:
                self.dropped += len(batch)
            else:
                self._backlog.extend(batch)

    def _write(self, stream: BinaryIO, writer: Writer, channels: dict[str, int]) -> None:
        """The writer thread: everything slow (JSON, zstd, disk) happens here."""
        backlog = self._backlog
        try:
            while True:
                closing = self._closing.wait(WRITE_PERIOD_S)
                while backlog:
                    envelope = backlog.popleft()
                    if self.error is None:
                        self._write_one(writer, channels[envelope.topic], envelope)
                    else:
                        self._discarded += 1
                    time.sleep(0)  # hand the GIL to the event loop if it is waiting
                if closing:
                    break
            if self.error is None:
                writer.finish()  # type: ignore[no-untyped-call]  # mcap's Writer is untyped
        except Exception as exc:
            self._fail(exc)
        finally:
            try:
                stream.close()
            except OSError as exc:  # the buffered tail could not be written either
                if self.error is None:
                    self._fail(exc)

    def _write_one(self, writer: Writer, channel: int, envelope: Envelope[Any]) -> None:
        stamp = _ns(envelope.stamp)
        try:
            writer.add_message(
                channel,
                log_time=stamp,
                data=envelope.msg.model_dump_json().encode(),
                publish_time=stamp,
                sequence=envelope.seq & 0xFFFFFFFF,
            )
        except Exception as exc:
            self._discarded += 1
            self._fail(exc)
            return
        self.written += 1

    def _fail(self, exc: Exception) -> None:
        """A full disk or a lost USB stick ends the recording, never the robot."""
        self.error = exc
        log_event(log, Event.FAULT, f"recording stopped: {exc}", path=str(self.path))

    def _finish(self) -> None:
        if self._thread is not None:
            self._closing.set()
            self._thread.join()
            self._thread = None

    async def stop(self) -> None:
        """Write out what is queued and close the file."""
        for subscription in self._subscriptions:
            subscription.close()
        for pump in self._pumps:
            # A closed subscription still hands out what it buffered, then ends its pump.
            await pump
        try:
            await self._disk.call(self._finish)
        finally:
            self._disk.close()
        log.info(
            "recording closed: %s: %d messages written, %d lost; %d sensor values skipped "
            "(latest-only topics keep the newest value, the recorder takes what is there)",
            self.path,
            self.written,
            self.lost,
            self.missed,
            extra={"written": self.written, "lost": self.lost, "skipped_latest": self.missed},
        )

    async def __aenter__(self) -> Recorder:
        await self.start()
        return self

    async def __aexit__(self, *exc: object) -> None:
        await self.stop()


@dataclass(frozen=True, slots=True)
class RecordedMessage:
    topic: str
    seq: int
    stamp: float
    msg: BaseModel


def read_recording(
    path: str | Path, topics: Iterable[Topic[Any]], only: Iterable[str] | None = None
) -> Generator[RecordedMessage]:
    """Messages in time order, each validated into the model of its topic in ``topics``.

    Channels whose topic is not in ``topics`` are skipped (a recording may be older or newer
    than this build); a message its model refuses raises :class:`RecordingError`.
    """
    models = {t.name: t.model for t in topics}
    wanted = None if only is None else list(only)
    with Path(path).open("rb") as stream:
        try:
            for _schema, channel, message in make_reader(stream).iter_messages(topics=wanted):
                model = models.get(channel.topic)
                if model is None:
                    continue
                try:
                    msg = model.model_validate_json(message.data)
                except ValidationError as exc:
                    raise RecordingError(
                        f"{path}: message {message.sequence} on {channel.topic!r} does not fit "
                        f"{model.__name__}: {exc}"
                    ) from None
                yield RecordedMessage(channel.topic, message.sequence, message.log_time / 1e9, msg)
        except McapError as exc:
            raise RecordingError(f"{path}: not a readable MCAP file: {exc}") from None


@dataclass
class PlayStats:
    published: dict[str, int] = field(default_factory=dict)

    @property
    def total(self) -> int:
        return sum(self.published.values())


class Player:
    """Republishes a recording onto a board, each message when the board clock reaches its stamp.

    Give the board a ``ScaledClock(speed)`` and ``on_start=clock.restart`` and the replay keeps
    the recorded timing at ``speed`` times real time, with the republished stamps matching the
    recorded ones. The file is read in a thread, in
    batches, so the event loop never waits for the disk.
    """

    def __init__(
        self,
        board: Board,
        path: str | Path,
        only: Iterable[str] | None = None,
        on_start: Callable[[float], None] | None = None,
    ) -> None:
        self.board = board
        self.path = Path(path)
        self.only = None if only is None else [board.topic(name).name for name in only]
        self.on_start = on_start
        """Called with the first stamp once the file is open, e.g. ``ScaledClock.restart``."""
        self.stats = PlayStats()

    async def run(self) -> PlayStats:
        messages = read_recording(self.path, self.board.topics, self.only)
        clock = self.board.clock
        published = self.stats.published
        try:
            batch = await asyncio.to_thread(list, itertools.islice(messages, _READ_BATCH))
            if batch and self.on_start is not None:
                self.on_start(batch[0].stamp)
            while batch:
                for recorded in batch:
                    # Sleep even when behind schedule (zero seconds then), so subscribers get
                    # to run between two messages as they would have live.
                    await clock.sleep(max(0.0, recorded.stamp - clock.now()))
                    self.board.publish(recorded.topic, recorded.msg)
                    published[recorded.topic] = published.get(recorded.topic, 0) + 1
                batch = await asyncio.to_thread(list, itertools.islice(messages, _READ_BATCH))
        finally:
            messages.close()
        return self.stats


class TopicInfo(BaseModel):
    name: str
    schema_name: str
    messages: int


class RecordingInfo(BaseModel):
    path: str
    messages: int
    start_s: float
    end_s: float
    topics: list[TopicInfo]
    metadata: dict[str, str]

    @property
    def duration_s(self) -> float:
        return self.end_s - self.start_s

    def format(self) -> str:
        """The table ``coffeebot record --info`` prints."""
        fields = {
            "file": self.path,
            "messages": str(self.messages),
            "duration": f"{self.duration_s:.3f} s  (board clock {self.start_s:.3f} .. "
            f"{self.end_s:.3f} s)",
            **dict(sorted(self.metadata.items())),
        }
        label = max(len(key) for key in fields)
        lines = [f"{key:<{label}}  {value}" for key, value in fields.items()]
        width = max([len(t.name) for t in self.topics] + [5])
        lines.append(f"{'topic':<{width}}  {'messages':>8}  {'rate_hz':>8}  schema")
        for t in self.topics:
            rate = t.messages / self.duration_s if self.duration_s > 0 else 0.0
            lines.append(f"{t.name:<{width}}  {t.messages:>8}  {rate:>8.1f}  {t.schema_name}")
        return "\n".join(lines)


def recording_info(path: str | Path) -> RecordingInfo:
    """Topics, counts and time span from the file's summary section."""
    with Path(path).open("rb") as stream:
        try:
            reader = make_reader(stream)
            summary = reader.get_summary()
            metadata = {
                k: v
                for m in reader.iter_metadata()
                if m.name == METADATA_NAME
                for k, v in m.metadata.items()
            }
        except Exception as exc:
            raise RecordingError(f"{path}: not a readable MCAP file: {exc}") from None
    if summary is None or summary.statistics is None:
        raise RecordingError(f"{path}: no summary section (was the recording cut short?)")
    stats = summary.statistics
    topics = [
        TopicInfo(
            name=channel.topic,
            schema_name=summary.schemas[channel.schema_id].name,
            messages=stats.channel_message_counts.get(channel_id, 0),
        )
        for channel_id, channel in sorted(summary.channels.items())
    ]
    return RecordingInfo(
        path=str(path),
        messages=stats.message_count,
        start_s=stats.message_start_time / 1e9,
        end_s=stats.message_end_time / 1e9,
        topics=topics,
        metadata=metadata,
    )
