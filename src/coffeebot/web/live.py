"""Live data for the pages: change notification, inspector frames, server-sent events.

Server-sent events rather than WebSockets: every live page only listens, EventSource
reconnects by itself, and it is plain HTTP for the benchmark client too.

One board subscription per topic of interest feeds the whole web app (:class:`Changes`);
each open page waits on a version number instead of holding its own subscription, so a
slow browser can never make a board queue overflow.
"""

from __future__ import annotations

import asyncio
import contextlib

from aiohttp import web
from pydantic import BaseModel

from coffeebot.board import BoardSnapshot
from coffeebot.messages import ESTOP, ORDER_UPDATE, EStop, Health
from coffeebot.web.deps import BoardIO, WebDeps
from coffeebot.web.livemap import MapFrame, map_frame

VALUE_CHARS = 600
"""Last values longer than this are cut in the inspector: it shows values, it is no recorder."""

HEARTBEAT_S = 15.0


class Changes:
    """A version number that moves whenever an order changes, and the app's closing flag."""

    def __init__(self) -> None:
        self.version = 0
        self.closed = asyncio.Event()
        self._changed = asyncio.Event()

    def bump(self) -> None:
        self.version += 1
        self._changed.set()
        self._changed = asyncio.Event()

    async def wait(self, seen: int, timeout: float) -> None:
        """Return once ``version`` has moved past ``seen``, on close, or after ``timeout``."""
        if self.version != seen or self.closed.is_set():
            return
        changed = asyncio.ensure_future(self._changed.wait())
        closed = asyncio.ensure_future(self.closed.wait())
        try:
            await asyncio.wait(
                {changed, closed}, timeout=timeout, return_when=asyncio.FIRST_COMPLETED
            )
        finally:
            changed.cancel()
            closed.cancel()

    def close(self) -> None:
        self.closed.set()

    async def pump(self, bus: BoardIO) -> None:
        """Follow order updates until cancelled."""
        with bus.subscribe(ORDER_UPDATE) as sub:
            async for _ in sub:
                self.bump()


class TopicValue(BaseModel):
    seq: int
    text: str


class InspectorFrame(BaseModel):
    """Everything the inspector shows at one moment (also the body of ``GET /api/board``)."""

    board: BoardSnapshot
    values: dict[str, TopicValue]
    health: list[Health]
    estop: EStop | None
    map: MapFrame


def inspector_frame(deps: WebDeps) -> InspectorFrame:
    board = deps.board
    values = {}
    for topic in board.topics:
        envelope = board.latest(topic)
        if envelope is not None:
            text = envelope.msg.model_dump_json()
            if len(text) > VALUE_CHARS:
                text = text[: VALUE_CHARS - 1] + "…"
            values[topic.name] = TopicValue(seq=envelope.seq, text=text)
    estop = board.latest(ESTOP)
    return InspectorFrame(
        board=board.snapshot(),
        values=values,
        health=list(deps.health()) if deps.health is not None else [],
        estop=None if estop is None else estop.msg,
        map=map_frame(board, deps.poses, deps.sensors),
    )


class FrameCache:
    """One serialised inspector frame, shared by every stream and snapshot within
    ``max_age_s``: twenty open inspectors cost the event loop one frame, not twenty, so they
    cannot crowd out the control loop that shares it."""

    def __init__(self, deps: WebDeps, max_age_s: float) -> None:
        self.deps = deps
        self.max_age_s = max_age_s
        self._json: str | None = None
        self._at = 0.0

    def json(self) -> str:
        now = self.deps.board.clock.now()
        if self._json is None or now - self._at >= self.max_age_s:
            self._json = inspector_frame(self.deps).model_dump_json()
            self._at = now
        return self._json


async def open_event_stream(request: web.Request) -> web.StreamResponse:
    response = web.StreamResponse(
        headers={"Content-Type": "text/event-stream", "Cache-Control": "no-cache"}
    )
    await response.prepare(request)
    return response


async def send_event(response: web.StreamResponse, data: str | None) -> bool:
    """One event (or a comment heartbeat for None); False once the client has gone."""
    payload = f"data: {data}\n\n" if data is not None else ": heartbeat\n\n"
    try:
        await response.write(payload.encode())
    except (ConnectionResetError, RuntimeError):
        return False
    return True


async def sleep_unless_closed(changes: Changes, seconds: float) -> None:
    with contextlib.suppress(TimeoutError):
        await asyncio.wait_for(changes.closed.wait(), seconds)
