"""Durable order storage: one SQLite file in WAL mode, created on first run.

Every order change is one committed transaction before anyone is told about it, so a daemon
that is killed at any moment restarts with exactly the orders people were shown. Status
changes are conditional updates (``UPDATE ... WHERE status IN (...)``), which makes "cancel
while queued" and "dispatch the head of the queue" atomic without an application lock; the
changed row is read back in the same transaction, so a change is either stored and returned
or not made at all.

What identifies an order (its ``id``: on the board, in the logs, on the operator's pages) is
kept apart from what authorizes acting on it: a per-order key, handed to the customer once
in their status link and stored only as a hash.

Every SQLite failure (the file locked by another process, read only, the disk full, not a
database at all) is a :class:`~coffeebot.errors.StoreError` naming the file; the orders
module retries what it must not lose.

sqlite3 blocks, so all database work runs on one private thread; the event loop only awaits.
"""

from __future__ import annotations

import contextlib
import hashlib
import hmac
import secrets
import sqlite3
import time
from collections.abc import Callable, Collection, Iterator, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any, TypeVar

from pydantic import BaseModel, ConfigDict, Field, ValidationInfo, field_validator

from coffeebot.clock import Clock
from coffeebot.config import DRINK_NAME_CHARS
from coffeebot.errors import StoreError
from coffeebot.hardware.worker import DeviceWorker
from coffeebot.messages import OrderStatus

T = TypeVar("T")

ACTIVE = tuple(s for s in OrderStatus if not s.final)
IN_FLIGHT = tuple(s for s in ACTIVE if s is not OrderStatus.QUEUED)

SCHEMA_VERSION = 3
"""1: the first table; 2: each order's key hash; 3: the robot an order went to (a fleet)."""

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
    updated_at REAL NOT NULL,
    key_hash   TEXT NOT NULL DEFAULT '',
    robot      TEXT
);
CREATE INDEX IF NOT EXISTS orders_status ON orders (status, seq);
"""

_COLUMNS = "seq, id, room, drink, name, notes, status, detail, created_at, updated_at, robot"


class Keep:
    """An optional column left as it is (``None`` there means "no robot")."""


KEEP = Keep()


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
    drink: str = Field(min_length=1, max_length=DRINK_NAME_CHARS)
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
    """A stored order as the API and the pages show it (never with its key)."""

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
    robot: str | None = None
    """The robot it went to, in a fleet (None: not out yet, or a single robot's)."""
    ahead: int | None = Field(
        None, description="active orders before this one (None once it has ended)"
    )


class PlacedOrder(Order):
    """A new order as its customer is answered, the one time its key is shown."""

    key: str = Field(description="authorizes following, cancelling and confirming the order")


def key_hash(key: str) -> str:
    """What is stored of an order's key: a 128-bit random key needs no slow hash."""
    return hashlib.sha256(key.encode("utf-8", "surrogateescape")).hexdigest()


def _order(row: sqlite3.Row) -> Order:
    """A row as an ``Order``; the row's ``ahead`` column, if selected, only counts while active."""
    data = dict(row)
    ahead = data.pop("ahead", None)
    return Order(**data, ahead=None if OrderStatus(data["status"]).final else ahead)


def _marks(values: Sequence[Any]) -> str:
    return ", ".join("?" for _ in values)


def _refusal(path: Path, exc: sqlite3.Error) -> StoreError:
    """Why the file cannot be used at start, and what the operator can do about it."""
    text = str(exc)
    if isinstance(exc, sqlite3.DatabaseError) and ("not a database" in text or "malformed" in text):
        return StoreError(
            f"{path}: not a usable SQLite database ({text}); move the file aside to start "
            "with an empty queue, or set [store] path to another file"
        )
    return StoreError(
        f"{path}: cannot open or create the order database ({text}); [store] path must name "
        "a file in a directory the service may write (SQLite keeps -wal and -shm files beside "
        "it)"
    )


class OrderStore:
    """The order table. Open once per process; ``close`` when the daemon has stopped.

    Opening refuses a file that is not a database, is damaged or cannot be created with one
    :class:`StoreError` line; later failures raise :class:`StoreError` too.
    """

    def __init__(
        self,
        path: str | Path,
        wall_clock: Callable[[], float] = time.time,
        *,
        busy_timeout_s: float = 1.0,
        clock: Clock | None = None,
    ) -> None:
        """``wall_clock`` stamps orders; ``clock`` is the daemon's (the simulator's keeps
        the store's thread in step with simulated time)."""
        self.path = Path(path)
        self._now = wall_clock
        self._busy_timeout_ms = round(busy_timeout_s * 1000)
        self._worker = DeviceWorker("order-store", clock)
        self._closed = False
        try:
            self._db = self._worker.run_now(self._open)
        except BaseException:
            self._worker.join()
            raise

    def _open(self) -> sqlite3.Connection:
        try:
            self.path.parent.mkdir(parents=True, exist_ok=True)
        except OSError as exc:
            raise StoreError(
                f"{self.path}: cannot create the directory {self.path.parent}: "
                f"{exc.strerror or exc}; check [store] path"
            ) from None
        if self.path.is_dir():
            raise StoreError(f"{self.path}: is a directory; [store] path must name a file")
        db: sqlite3.Connection | None = None
        try:
            db = sqlite3.connect(self.path, isolation_level=None, check_same_thread=False)
            db.row_factory = sqlite3.Row
            db.execute(f"PRAGMA busy_timeout={self._busy_timeout_ms}")
            db.execute("PRAGMA journal_mode=WAL")
            # FULL: a committed order survives a power cut, not only a process crash; the robot
            # runs on a battery and orders arrive a few per minute, so the fsync is cheap.
            db.execute("PRAGMA synchronous=FULL")
            damage = db.execute("PRAGMA quick_check").fetchone()[0]
            if damage != "ok":
                raise sqlite3.DatabaseError(f"database disk image is malformed: {damage}")
            self._migrate(db)
        except sqlite3.Error as exc:
            if db is not None:
                db.close()
            raise _refusal(self.path, exc) from None
        return db

    @staticmethod
    def _migrate(db: sqlite3.Connection) -> None:
        """Bring a file of an older version up to this one (a robot keeps its orders)."""
        version = db.execute("PRAGMA user_version").fetchone()[0]
        if version >= SCHEMA_VERSION:
            return
        exists = db.execute("SELECT 1 FROM sqlite_master WHERE name = 'orders'").fetchone()
        columns = {row[1] for row in db.execute("PRAGMA table_info(orders)")}
        if exists and "key_hash" not in columns:
            db.execute("ALTER TABLE orders ADD COLUMN key_hash TEXT NOT NULL DEFAULT ''")
        if exists and "robot" not in columns:
            db.execute("ALTER TABLE orders ADD COLUMN robot TEXT")
        db.executescript(_SCHEMA)
        db.execute(f"PRAGMA user_version={SCHEMA_VERSION}")

    async def _call(self, fn: Callable[[], T]) -> T:
        """Run ``fn`` on the store's thread; an SQLite failure becomes a :class:`StoreError`."""

        def guarded() -> T:
            try:
                return fn()
            except sqlite3.Error as exc:
                raise StoreError(f"order database {self.path}: {exc}") from exc

        return await self._worker.call(guarded)

    @contextlib.contextmanager
    def _transaction(self) -> Iterator[sqlite3.Connection]:
        """One write transaction: committed, or rolled back if anything in it fails."""
        self._db.execute("BEGIN IMMEDIATE")
        try:
            yield self._db
            self._db.execute("COMMIT")
        except BaseException:
            with contextlib.suppress(sqlite3.Error):
                self._db.execute("ROLLBACK")
            raise

    def close(self) -> None:
        """Close the database (again: nothing happens)."""
        if self._closed:
            return
        self._closed = True
        self._worker.run_now(self._db.close)
        self._worker.join()

    def now(self) -> float:
        """The clock orders are stamped with (``created_at``, ``updated_at``)."""
        return self._now()

    async def journal_mode(self) -> str:
        return await self._call(lambda: self._db.execute("PRAGMA journal_mode").fetchone()[0])

    def _select(self, order_id: str) -> Order | None:
        row = self._db.execute(
            f"SELECT {_COLUMNS}, (SELECT COUNT(*) FROM orders a WHERE a.seq < o.seq"
            f" AND a.status IN ({_marks(ACTIVE)})) AS ahead FROM orders o WHERE id = ?",
            (*ACTIVE, order_id),
        ).fetchone()
        return None if row is None else _order(row)

    async def add(self, new: NewOrder, client: str) -> PlacedOrder:
        """Store a new queued order under a fresh id and key; the key is only returned here."""
        order_id = secrets.token_urlsafe(9)
        key = secrets.token_urlsafe(16)
        now = self._now()

        def insert() -> Order | None:
            with self._transaction() as db:
                db.execute(
                    "INSERT INTO orders (id, room, drink, name, notes, client, status, detail,"
                    " created_at, updated_at, key_hash) VALUES (?, ?, ?, ?, ?, ?, ?, '', ?, ?, ?)",
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
                        key_hash(key),
                    ),
                )
                return self._select(order_id)

        order = await self._call(insert)
        assert order is not None
        return PlacedOrder(**order.model_dump(), key=key)

    async def get(self, order_id: str) -> Order | None:
        return await self._call(lambda: self._select(order_id))

    async def key_matches(self, order_id: str, key: str) -> bool:
        """Whether ``key`` is the order's key (compared in constant time)."""

        def stored() -> str | None:
            row = self._db.execute("SELECT key_hash FROM orders WHERE id = ?", (order_id,))
            found = row.fetchone()
            return None if found is None else str(found[0])

        expected = await self._call(stored)
        return expected is not None and hmac.compare_digest(expected, key_hash(key))

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
        robot: str | Keep | None = KEEP,
    ) -> Order | None:
        """Set ``status`` (and the ``robot`` it is with, if given) if the order is currently
        in ``allowed_from``; None if it was not."""
        sources = tuple(allowed_from)
        if not sources:
            return None
        assign = "" if isinstance(robot, Keep) else ", robot = ?"
        values = () if isinstance(robot, Keep) else (robot,)

        def update() -> Order | None:
            with self._transaction() as db:
                cursor = db.execute(
                    f"UPDATE orders SET status = ?, detail = ?, updated_at = ?{assign}"
                    f" WHERE id = ? AND status IN ({_marks(sources)})",
                    (status.value, detail, self._now(), *values, order_id, *sources),
                )
                return self._select(order_id) if cursor.rowcount else None

        return await self._call(update)
