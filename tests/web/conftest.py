"""Fixtures for the order store, the orders module and the web app."""

from __future__ import annotations

from collections.abc import AsyncIterator, Iterator
from pathlib import Path

import pytest

from coffeebot.board import Board, Subscription
from coffeebot.daemon import Daemon
from coffeebot.messages import ALL_TOPICS, ORDER_UPDATE, OrderUpdate
from coffeebot.modules.orders import OrdersModule
from coffeebot.store import NewOrder, OrderRules, OrderStore

RULES = OrderRules(rooms={"201", "210", "302"}, drinks={"latte", "tea"})


def new_order(name: str = "Ada", room: str = "210", **fields: str) -> NewOrder:
    return NewOrder.model_validate(
        {"room": room, "drink": "latte", "name": name, **fields}, context=RULES
    )


@pytest.fixture
def db_path(tmp_path: Path) -> Path:
    return tmp_path / "state" / "orders.sqlite3"


@pytest.fixture
def store(db_path: Path) -> Iterator[OrderStore]:
    store = OrderStore(db_path)
    yield store
    store.close()


@pytest.fixture
def board() -> Board:
    return Board(ALL_TOPICS)


@pytest.fixture
def updates(board: Board) -> Iterator[Subscription[OrderUpdate]]:
    with board.subscribe(ORDER_UPDATE, name="test") as sub:
        yield sub


@pytest.fixture
async def orders(board: Board, store: OrderStore) -> AsyncIterator[OrdersModule]:
    """The orders module running under a daemon on ``board``."""
    module = OrdersModule(store)
    daemon = Daemon(board, [module])
    await daemon.start()
    yield module
    await daemon.shutdown()
