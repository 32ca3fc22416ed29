"""The order store with the faults a robot's storage has: locked by another process, read
only, full. Scenarios and the chaos bench inject them (``sim/faults.py``) so the orders
module meets them through the real SQLite code path.

Locked and read only are SQLite's own: a second connection holds the write lock (as a
backup tool or an ``sqlite3`` shell left open does), and ``PRAGMA query_only`` makes every
write fail as on a read-only file system. A full disk has no such switch, so every commit
fails the way SQLite reports one ("database or disk is full") and is rolled back.
"""

from __future__ import annotations

import contextlib
import sqlite3
from collections.abc import Iterator

from coffeebot.store import OrderStore


class SimStore(OrderStore):
    """An :class:`OrderStore` whose storage can be locked, made read only or full."""

    full = False

    _locker: sqlite3.Connection | None = None

    def lock(self) -> bool:
        """Take the database's write lock from another connection; False if the store was
        writing just then (try again on the next step). Never blocks."""
        if self._locker is not None:
            return True
        locker = sqlite3.connect(self.path, timeout=0, isolation_level=None)
        try:
            locker.execute("BEGIN EXCLUSIVE")
        except sqlite3.OperationalError:
            locker.close()
            return False
        self._locker = locker
        return True

    def unlock(self) -> None:
        if self._locker is not None:
            self._locker.close()  # rolls the empty transaction back
            self._locker = None

    def set_read_only(self, read_only: bool) -> None:
        """Every write fails with SQLite's "attempt to write a readonly database" (queued on
        the store's thread, after whatever it is doing)."""
        self._worker.post(lambda: self._db.execute(f"PRAGMA query_only={int(read_only)}"))

    @contextlib.contextmanager
    def _transaction(self) -> Iterator[sqlite3.Connection]:
        with super()._transaction() as db:
            yield db
            if self.full:
                raise sqlite3.OperationalError("database or disk is full")

    def close(self) -> None:
        self.unlock()
        super().close()
