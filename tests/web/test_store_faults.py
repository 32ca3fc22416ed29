"""The order database failing under a delivery (locked by another process, read only, the disk
full): nothing navigation reported is lost, the queue moves on once it recovers, and the
operator sees it on the health topic. A database that cannot be used at start is one line."""

from __future__ import annotations

import asyncio
import logging
import sqlite3
from collections.abc import AsyncIterator, Callable
from pathlib import Path
from typing import Any

import pytest
from aiohttp.test_utils import TestClient

from coffeebot.board import Board, Subscription
from coffeebot.cli import main
from coffeebot.config import StoreConfig
from coffeebot.daemon import Daemon
from coffeebot.errors import StoreError
from coffeebot.messages import (
    ALL_TOPICS,
    DELIVERY_STATUS,
    HEALTH,
    ORDER_UPDATE,
    DeliveryUpdate,
    Health,
    HealthStatus,
    OrderStatus,
)
from coffeebot.modules.orders import OrdersModule
from coffeebot.orders import OrdersUnavailable
from coffeebot.sim.store import SimStore
from coffeebot.store import OrderStore
from coffeebot.web import create_app
from logged import causes

from .conftest import new_order, web_deps

ROOT = Path(__file__).resolve().parents[2]
BOARD = ROOT / "boards" / "coffeebot-v1.toml"
PLAN = ROOT / "floorplans" / "cs-building.toml"
CONFIG = StoreConfig(busy_timeout_s=0.05, retry_max_s=0.1, failed_after_s=0.3)
BOUND_S = 10.0
"""Only bounds a failing test: every wait below is for an outcome."""


class Rig:
    def __init__(self, path: Path) -> None:
        self.store = SimStore(path, busy_timeout_s=CONFIG.busy_timeout_s)
        self.board = Board(ALL_TOPICS)
        self.orders = OrdersModule(self.store, CONFIG)
        self.daemon = Daemon(self.board, [self.orders])

    def report(self, order_id: str, status: OrderStatus) -> None:
        self.board.publish(DELIVERY_STATUS, DeliveryUpdate(order_id=order_id, status=status))


@pytest.fixture
async def rig(tmp_path: Path) -> AsyncIterator[Rig]:
    rig = Rig(tmp_path / "orders.sqlite3")
    await rig.daemon.start()
    yield rig
    await rig.daemon.shutdown()
    rig.store.close()


FAULTS: dict[str, tuple[Callable[[SimStore], Any], Callable[[SimStore], Any]]] = {
    "locked": (lambda s: s.lock(), lambda s: s.unlock()),
    "read_only": (lambda s: s.set_read_only(True), lambda s: s.set_read_only(False)),
    "full": (lambda s: setattr(s, "full", True), lambda s: setattr(s, "full", False)),
}


async def health_until(health: Subscription[Health], status: HealthStatus) -> Health:
    async for envelope in health:
        if envelope.msg.module == "orders" and envelope.msg.status is status:
            return envelope.msg
    raise AssertionError("health topic closed")


@pytest.mark.parametrize("fault", sorted(FAULTS))
async def test_no_report_lost_and_the_queue_moves_on(
    rig: Rig, fault: str, caplog: pytest.LogCaptureFixture
) -> None:
    caplog.set_level(logging.INFO)
    begin, end = FAULTS[fault]
    first = await rig.orders.place(new_order(name="A"), client="c")
    second = await rig.orders.place(new_order(name="B"), client="c")
    assert (first.status, second.status) == (OrderStatus.PREPARING, OrderStatus.QUEUED)
    with rig.board.subscribe(HEALTH) as health, rig.board.subscribe(ORDER_UPDATE) as updates:
        async with asyncio.timeout(BOUND_S):
            assert begin(rig.store) is not False
            for status in (OrderStatus.ON_THE_WAY, OrderStatus.ARRIVED, OrderStatus.DELIVERED):
                rig.report(first.id, status)
            degraded = await health_until(health, HealthStatus.DEGRADED)
            assert "3 delivery report(s) waiting" in degraded.detail
            await health_until(health, HealthStatus.FAILED)  # past failed_after_s
            # A customer is told the orders are unavailable, and nothing is half-stored.
            with pytest.raises(OrdersUnavailable):
                await rig.orders.place(new_order(name="C"), client="c")
            assert updates.get_nowait() is None  # nothing announced that was not stored
            end(rig.store)
            await health_until(health, HealthStatus.RUNNING)
        announced = [(e.msg.order_id, e.msg.status) for e in iter(updates.get_nowait, None)]
    assert announced == [
        (first.id, OrderStatus.ON_THE_WAY),
        (first.id, OrderStatus.ARRIVED),
        (first.id, OrderStatus.DELIVERED),
        (second.id, OrderStatus.PREPARING),
    ]
    assert (await rig.orders.get(first.id)).status is OrderStatus.DELIVERED
    assert rig.orders.current == second.id
    [began] = causes(caplog, "fault")
    assert str(rig.store.path) in began and "every change is kept" in began
    [recovered] = causes(caplog, "recovered")
    assert recovered.startswith("order database written again after ")


async def test_an_order_placed_while_the_dispatch_fails_goes_out_once_it_recovers(
    rig: Rig,
) -> None:
    first = await rig.orders.place(new_order(name="A"), client="c")
    rig.report(first.id, OrderStatus.FAILED)
    with rig.board.subscribe(ORDER_UPDATE) as updates:
        async with asyncio.timeout(BOUND_S):
            while (await updates.get()).msg.status is not OrderStatus.FAILED:
                pass
            rig.store.lock()
            # Stored before the lock? Then placed; the dispatch waits for the store.
            rig.store.unlock()
            second = await rig.orders.place(new_order(name="B"), client="c")
            while rig.orders.current != second.id:
                await asyncio.sleep(0.01)
    assert (await rig.orders.get(second.id)).status is OrderStatus.PREPARING


def test_a_file_that_is_not_a_database_is_one_line(tmp_path: Path) -> None:
    path = tmp_path / "orders.sqlite3"
    path.write_bytes(b"these are not the orders you are looking for" * 100)
    with pytest.raises(StoreError) as error:
        OrderStore(path)
    assert str(error.value).startswith(f"{path}: not a usable SQLite database")
    assert "move the file aside" in str(error.value) and "\n" not in str(error.value)


def test_a_place_the_service_cannot_write_is_one_line(tmp_path: Path) -> None:
    # /proc/self is a directory nobody may create files in, root included.
    path = Path("/proc/self/orders.sqlite3")
    with pytest.raises(StoreError) as error:
        OrderStore(path)
    assert str(error.value).startswith(f"{path}: cannot open or create the order database")
    assert "[store] path" in str(error.value) and "\n" not in str(error.value)
    under_a_file = tmp_path / "file"
    under_a_file.write_text("")
    with pytest.raises(StoreError, match="cannot create the directory"):
        OrderStore(under_a_file / "orders.sqlite3")


def test_the_daemon_refuses_a_broken_database_with_one_line(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    db = tmp_path / "orders.sqlite3"
    db.write_bytes(b"\x00garbage" * 512)
    board = tmp_path / "robot.toml"
    board.write_text(BOARD.read_text().replace("/var/lib/coffeebot/orders.sqlite3", str(db)))
    assert main(["run", "--board", str(board), "--floorplan", str(PLAN)]) == 1
    err = capsys.readouterr().err
    assert "Traceback" not in err
    [line] = [line for line in err.splitlines() if line.startswith("coffeebot: ")]
    assert line.startswith(f"coffeebot: {db}: not a usable SQLite database")


class Broken:
    """Orders whose store fails in a way nobody foresaw."""

    async def get(self, order_id: str) -> Any:
        raise sqlite3.InterfaceError("bad parameter")

    async def authorize(self, order_id: str, key: str) -> Any:
        return await self.get(order_id)


async def test_an_unexpected_error_is_a_json_500_with_the_headers(
    aiohttp_client: Callable[..., Any], board: Board, caplog: pytest.LogCaptureFixture
) -> None:
    client: TestClient = await aiohttp_client(create_app(web_deps(board, Broken()), board))  # type: ignore[arg-type]
    response = await client.get("/api/orders/abc?key=x")
    assert response.status == 500
    assert (await response.json())["error"].startswith("internal error")
    assert response.headers["X-Content-Type-Options"] == "nosniff"
    assert response.headers["Cache-Control"] == "no-store"
    [logged] = [r for r in caplog.records if r.levelname == "ERROR"]
    assert "bad parameter" in logged.cause
