"""The durable order store: WAL, creation on first run, conditional transitions, arrival order."""

from __future__ import annotations

from pathlib import Path

import pytest
from pydantic import ValidationError

from coffeebot.messages import OrderStatus
from coffeebot.store import NewOrder, Order, OrderStore

from .conftest import RULES, new_order


async def test_created_on_first_run_in_wal_mode(db_path: Path) -> None:
    assert not db_path.parent.exists()
    store = OrderStore(db_path)
    try:
        assert db_path.exists()
        assert await store.journal_mode() == "wal"
    finally:
        store.close()


async def test_orders_survive_reopening(db_path: Path) -> None:
    first = OrderStore(db_path)
    order = await first.add(new_order(notes="no sugar"), client="10.0.0.5")
    first.close()
    second = OrderStore(db_path)
    try:
        again = await second.get(order.id)
    finally:
        second.close()
    assert again == Order(**order.model_dump(exclude={"key"}))
    assert again.notes == "no sugar"
    assert again.status is OrderStatus.QUEUED


async def test_ids_are_unguessable_and_distinct(store: OrderStore) -> None:
    a = await store.add(new_order(), client="c")
    b = await store.add(new_order(), client="c")
    assert a.id != b.id
    assert len(a.id) >= 12
    assert b.seq > a.seq


async def test_active_orders_in_arrival_order_with_place(store: OrderStore) -> None:
    ids = [(await store.add(new_order(name=n), client="c")).id for n in ("A", "B", "C")]
    await store.transition(ids[1], OrderStatus.CANCELLED, "", (OrderStatus.QUEUED,))
    active = await store.active()
    assert [o.id for o in active] == [ids[0], ids[2]]
    assert [o.ahead for o in active] == [0, 1]
    assert (await store.get(ids[2])).ahead == 1
    assert (await store.get(ids[1])).ahead is None


async def test_transition_only_from_allowed_states(store: OrderStore) -> None:
    order = await store.add(new_order(), client="c")
    assert (
        await store.transition(order.id, OrderStatus.ARRIVED, "", (OrderStatus.ON_THE_WAY,)) is None
    )
    moved = await store.transition(order.id, OrderStatus.PREPARING, "go", (OrderStatus.QUEUED,))
    assert moved is not None
    assert (moved.status, moved.detail) == (OrderStatus.PREPARING, "go")
    assert await store.transition("missing", OrderStatus.FAILED, "", (OrderStatus.QUEUED,)) is None


@pytest.mark.parametrize(
    ("field", "value"),
    [
        ("room", "999"),
        ("drink", "whisky"),
        ("name", "   "),
        ("notes", "x" * 201),
        ("name", "n" * 41),
    ],
)
def test_new_order_errors_name_the_field(field: str, value: str) -> None:
    data = {"room": "210", "drink": "latte", "name": "Ada", "notes": "", field: value}
    with pytest.raises(ValidationError) as info:
        NewOrder.model_validate(data, context=RULES)
    assert [e["loc"] for e in info.value.errors()] == [(field,)]


def test_new_order_refuses_unknown_fields() -> None:
    with pytest.raises(ValidationError) as info:
        NewOrder.model_validate(
            {"room": "210", "drink": "latte", "name": "A", "status": "delivered"}, context=RULES
        )
    assert info.value.errors()[0]["loc"] == ("status",)
