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
from coffeebot.clock import Clock
from coffeebot.cpu import BOARD_NAME, CpuLedger
from coffeebot.messages import ESTOP, HEALTH, ORDER_UPDATE, EStop, Health
from coffeebot.web.alerts import (
    Alert,
    AlertList,
    Seen,
    health_alerts,
    order_alerts,
    robot_alerts,
    stale_alerts,
)
from coffeebot.web.deps import BoardIO, WebDeps
from coffeebot.web.livemap import MapFrame, map_frame

VALUE_CHARS = 600
"""Last values longer than this are cut in the inspector: it shows values, it is no recorder."""

HEARTBEAT_S = 15.0


class Changes:
    """A version number that moves whenever an order changes, the app's closing flag, and
    what the alerts need from the board's reliable topics (component health, failures)."""

    def __init__(self) -> None:
        self.version = 0
        self.closed = asyncio.Event()
        self.seen = Seen(components={}, failed=[])
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

    async def pump(self, bus: BoardIO, clock: Clock) -> None:
        """Follow order updates until cancelled."""
        with bus.subscribe(ORDER_UPDATE) as sub:
            async for envelope in sub:
                self.seen.note_order(envelope.msg, clock.now())
                self.bump()

    async def pump_health(self, bus: BoardIO, clock: Clock) -> None:
        """Follow every health report until cancelled (components report only changes)."""
        with bus.subscribe(HEALTH) as sub:
            async for envelope in sub:
                self.seen.note_health(envelope.msg, clock.now())


class TopicValue(BaseModel):
    seq: int
    text: str


class CpuFrame(BaseModel):
    """Beside the modules' own shares: the board's, and the whole process's (the web
    server, the recorder, and on the simulator the simulated world, are in it too)."""

    board_pct: float | None
    process_pct: float | None


class InspectorFrame(BaseModel):
    """Everything the inspector shows at one moment (also the body of ``GET /api/board``)."""

    board: BoardSnapshot
    values: dict[str, TopicValue]
    health: list[Health]
    cpu: CpuFrame | None
    """Per cent of one core over the last few seconds (None before the first window)."""
    estop: EStop | None
    map: MapFrame
    alerts: list[Alert]
    stale_after_s: dict[str, float]
    orders_version: int
    """Moves whenever an order changes: an operator's page refreshes its orders table."""
    operator_actions: bool
    """Whether an operator token is configured at all."""


def inspector_frame(deps: WebDeps, changes: Changes, alert_list: AlertList) -> InspectorFrame:
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
    health = list(deps.health()) if deps.health is not None else []
    alerts = [
        *robot_alerts(board),
        *health_alerts(board, health, changes.seen),
        *order_alerts(board, changes.seen),
        *stale_alerts(board, deps.config.stale_after_s),
    ]
    return InspectorFrame(
        board=board.snapshot(),
        values=values,
        health=health,
        cpu=cpu_frame(deps.cpu() if deps.cpu is not None else None),
        estop=None if estop is None else estop.msg,
        map=map_frame(board, deps.poses, deps.sensors, deps.max_range_mm, deps.plan),
        alerts=alert_list.update(alerts, board.clock.now()),
        stale_after_s=deps.config.stale_after_s,
        orders_version=changes.version,
        operator_actions=bool(deps.operator_token),
    )


def cpu_frame(ledger: CpuLedger | None) -> CpuFrame | None:
    if ledger is None or ledger.last_process_pct is None:
        return None
    board = ledger.last.get(BOARD_NAME)
    return CpuFrame(
        board_pct=None if board is None else round(board, 2),
        process_pct=round(ledger.last_process_pct, 2),
    )


class FrameCache:
    """One serialised inspector frame, shared by every stream and snapshot within
    ``max_age_s``: twenty open inspectors cost the event loop one frame, not twenty, so they
    cannot crowd out the control loop that shares it."""

    def __init__(self, deps: WebDeps, changes: Changes, max_age_s: float) -> None:
        self.deps = deps
        self.changes = changes
        self.max_age_s = max_age_s
        self.alerts = AlertList()
        self._json: str | None = None
        self._at = 0.0
        self._version = -1

    def json(self) -> str:
        now = self.deps.board.clock.now()
        stale = now - self._at >= self.max_age_s or self._version != self.changes.version
        if self._json is None or stale:
            frame = inspector_frame(self.deps, self.changes, self.alerts)
            self._json = frame.model_dump_json()
            self._at, self._version = now, frame.orders_version
        return self._json


async def open_event_stream(request: web.Request) -> web.StreamResponse:
    response = web.StreamResponse(
        headers={"Content-Type": "text/event-stream", "Cache-Control": "no-cache"}
    )
    await response.prepare(request)
    return response


async def send_event(
    response: web.StreamResponse, data: str | None, event: str | None = None
) -> bool:
    """One event, named ``event`` if given (or a comment heartbeat for None); False once the
    client has gone."""
    if data is None:
        payload = ": heartbeat\n\n"
    else:
        payload = (f"event: {event}\n" if event else "") + f"data: {data}\n\n"
    try:
        await response.write(payload.encode())
    except (ConnectionResetError, RuntimeError):
        return False
    return True


async def sleep_unless_closed(changes: Changes, seconds: float) -> None:
    """``asyncio.timeout``, not 3.11's ``wait_for``, which may drop the server's cancel
    (``coffeebot/fleet/cancellable.py``)."""
    with contextlib.suppress(TimeoutError):
        async with asyncio.timeout(seconds):
            await changes.closed.wait()
