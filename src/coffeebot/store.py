"""Durable order storage: one SQLite file in WAL mode, created on first run.

Every order change is one committed transaction before anyone is told about it, so a daemon
that is killed at any moment restarts with exactly the orders people were shown. Status
changes are conditional updates (``UPDATE ... WHERE status IN (...)``), which makes "cancel
while queued" and "dispatch the head of the queue" atomic without an application lock.

sqlite3 blocks, so all database work runs on one private thread; the event loop only awaits.
"""

from __future__ import annotations

import asyncio
import secrets
import sqlite3
import time
from collections.abc import Callable, Collection, Sequence
from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass
from pathlib import Path
from typing import Any, TypeVar

from pydantic import BaseModel, ConfigDict, Field, ValidationInfo, field_validator

from coffeebot.messages import OrderStatus

T = TypeVar("T")

ACTIVE = tuple(s for s in OrderStatus if not s.final)
IN_FLIGHT = tuple(s for s in ACTIVE if s is not OrderStatus.QUEUED)

_SCHEMA = """
CREATE TABLE IF NOT EXISTS orders (
    seq        INTEGER PRIMARY KEY AUTOINCREMENT,
    id         TEXT NOT NULL UNIQUE,
    room       TEXT NOT NULL,
    drink      TEXT NOT NULL,
    name       TEXT NOT NULL,
    notes      TEXT NOT NULL,
    client     TEXT NOT NULL,
    status     TEXT NOT NULL,
    detail     TEXT NOT NULL,
    created_at REAL NOT NULL,
    updated_at REAL NOT NULL
);
CREATE INDEX IF NOT EXISTS orders_status ON orders (status, seq);
"""

_COLUMNS = "seq, id, room, drink, name, notes, status, detail, created_at, updated_at"


@dataclass(frozen=True)
class OrderRules:
    """What a new order may ask for: the rooms of the floor plan and the drinks on offer."""

    rooms: Collection[str]
    drinks: Collection[str]


class NewOrder(BaseModel):
    """An order as a customer submits it (JSON API and HTML form share this model).

    Validate with ``NewOrder.model_validate(data, context=rules)`` so room and drink are checked
    against the building and the menu; errors then name the offending field.
    """

    model_config = ConfigDict(extra="forbid", str_strip_whitespace=True, frozen=True)

    room: str = Field(min_length=1, max_length=16)
    drink: str = Field(min_length=1, max_length=40)
    name: str = Field(min_length=1, max_length=40)
    notes: str = Field("", max_length=200)

    @field_validator("room", "drink")
    @classmethod
    def _offered(cls, value: str, info: ValidationInfo) -> str:
        rules = info.context
        if not isinstance(rules, OrderRules):
            raise ValueError("no order rules given to check against")
        allowed = rules.rooms if info.field_name == "room" else rules.drinks
        if value not in allowed:
            raise ValueError(f"unknown {info.field_name} {value!r}")
        return value


class Order(BaseModel):
    """A stored order as the API and the pages show it."""

    model_config = ConfigDict(frozen=True)

    id: str
    seq: int
    room: str
    drink: str
    name: str
    notes: str
    status: OrderStatus
    detail: str
    created_at: float
    updated_at: float
    ahead: int | None = Field(
        None, description="active orders before this one (None once it has ended)"
    )


def _order(row: sqlite3.Row) -> Order:
    """A row as an ``Order``; the row's ``ahead`` column, if selected, only counts while active."""
    data = dict(row)
    ahead = data.pop("ahead", None)
    return Order(**data, ahead=None if OrderStatus(data["status"]).final else ahead)


def _marks(values: Sequence[Any]) -> str:
    return ", ".join("?" for _ in values)


class OrderStore:
    """The order table. Open once per process; ``close`` when the daemon has stopped."""

    def __init__(self, path: str | Path, wall_clock: Callable[[], float] = time.time) -> None:
        self.path = Path(path)
        self._now = wall_clock
        self._executor = ThreadPoolExecutor(max_workers=1, thread_name_prefix="order-store")
        self._db = self._executor.submit(self._open).result()

    def _open(self) -> sqlite3.Connection:
        self.path.parent.mkdir(parents=True, exist_ok=True)
        db = sqlite3.connect(self.path, isolation_level=None, check_same_thread=False)
        db.row_factory = sqlite3.Row
        db.execute("PRAGMA journal_mode=WAL")
        # FULL: a committed order survives a power cut, not only a process crash; the robot
        # runs on a battery and orders arrive a few per minute, so the fsync is cheap.
        db.execute("PRAGMA synchronous=FULL")
        db.execute("PRAGMA busy_timeout=5000")
        db.executescript(_SCHEMA)
        return db

    async def _call(self, fn: Callable[[], T]) -> T:
        return await asyncio.get_running_loop().run_in_executor(self._executor, fn)

    def close(self) -> None:
        self._executor.submit(self._db.close).result()
        self._executor.shutdown()

    async def journal_mode(self) -> str:
        return await self._call(lambda: self._db.execute("PRAGMA journal_mode").fetchone()[0])

    async def add(self, new: NewOrder, client: str) -> Order:
        """Store a new queued order under a fresh unguessable id (the id is the customer's key)."""
        order_id = secrets.token_urlsafe(9)
        now = self._now()

        def insert() -> None:
            self._db.execute(
                "INSERT INTO orders (id, room, drink, name, notes, client, status, detail,"
                " created_at, updated_at) VALUES (?, ?, ?, ?, ?, ?, ?, '', ?, ?)",
                (
                    order_id,
                    new.room,
                    new.drink,
                    new.name,
                    new.notes,
                    client,
                    OrderStatus.QUEUED.value,
                    now,
                    now,
                ),
            )

        await self._call(insert)
        order = await self.get(order_id)
        assert order is not None
        return order

    async def get(self, order_id: str) -> Order | None:
        def select() -> Order | None:
            row = self._db.execute(
                f"SELECT {_COLUMNS}, (SELECT COUNT(*) FROM orders a WHERE a.seq < o.seq"
                f" AND a.status IN ({_marks(ACTIVE)})) AS ahead FROM orders o WHERE id = ?",
                (*ACTIVE, order_id),
            ).fetchone()
            return None if row is None else _order(row)

        return await self._call(select)

    async def with_status(self, statuses: Sequence[OrderStatus], limit: int = -1) -> list[Order]:
        """Orders in any of ``statuses``, in order of arrival, at most ``limit`` (-1: all)."""

        def select() -> list[Order]:
            rows = self._db.execute(
                f"SELECT {_COLUMNS} FROM orders WHERE status IN ({_marks(statuses)})"
                " ORDER BY seq LIMIT ?",
                (*statuses, limit),
            ).fetchall()
            return [_order(row) for row in rows]

        return await self._call(select)

    async def active(self) -> list[Order]:
        """Every order that has not ended, in order of arrival, with its place in the queue."""
        orders = await self.with_status(ACTIVE)
        return [o.model_copy(update={"ahead": i}) for i, o in enumerate(orders)]

    async def transition(
        self,
        order_id: str,
        status: OrderStatus,
        detail: str,
        allowed_from: Collection[OrderStatus],
    ) -> Order | None:
        """Set ``status`` if the order is currently in ``allowed_from``; None if it was not."""
        sources = tuple(allowed_from)

        def update() -> int:
            cursor = self._db.execute(
                f"UPDATE orders SET status = ?, detail = ?, updated_at = ?"
                f" WHERE id = ? AND status IN ({_marks(sources)})",
                (status.value, detail, self._now(), order_id, *sources),
            )
            return cursor.rowcount

        if not sources or await self._call(update) == 0:
            return None
        return await self.get(order_id)
