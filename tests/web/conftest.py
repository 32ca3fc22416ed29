"""Fixtures for the order store, the orders module and the web app."""

from __future__ import annotations

from collections.abc import AsyncIterator, Awaitable, Callable, Iterator
from pathlib import Path
from typing import Any

import pytest
from aiohttp import web
from aiohttp.test_utils import TestClient

from coffeebot.board import Board, Subscription
from coffeebot.config import WebConfig
from coffeebot.daemon import Daemon
from coffeebot.messages import ALL_TOPICS, ORDER_UPDATE, OrderUpdate
from coffeebot.modules.orders import OrdersModule
from coffeebot.store import NewOrder, OrderRules, OrderStore
from coffeebot.web import RoomChoice, WebDeps, create_app

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


TOKEN = "operator-secret"
ROOMS = [
    RoomChoice(id="201", floor=2),
    RoomChoice(id="210", floor=2),
    RoomChoice(id="302", floor=3),
]


def web_deps(board: Board, orders: OrdersModule, **fields: Any) -> WebDeps:
    config = WebConfig(drinks=sorted(RULES.drinks), max_body_bytes=2048)
    return WebDeps(
        board=board,
        orders=orders,
        rooms=ROOMS,
        config=config,
        operator_token=TOKEN,
        **fields,
    )


@pytest.fixture
async def client(
    aiohttp_client: Callable[[web.Application], Awaitable[TestClient]],
    board: Board,
    orders: OrdersModule,
) -> TestClient:
    return await aiohttp_client(
        create_app(web_deps(board, orders, modules=lambda: [orders]), board)
    )
