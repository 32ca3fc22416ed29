"""The JSON API: every status code, escaping, the rate limit and the operator token."""

from __future__ import annotations

import dataclasses
import json
from typing import Any

import pytest
from aiohttp.test_utils import TestClient

from coffeebot.board import Board
from coffeebot.errors import OrderError
from coffeebot.messages import (
    DELIVERY_STATUS,
    ESTOP,
    OPERATOR_EVENT,
    RANGE_SCAN,
    DeliveryUpdate,
    OrderStatus,
    RangeReading,
    RangeScan,
    ReadingStatus,
)
from coffeebot.modules.orders import OrdersModule
from coffeebot.orders import OrderNotFound, OrdersUnavailable
from coffeebot.store import NewOrder, Order, PlacedOrder
from coffeebot.web import create_app

from .conftest import TOKEN, web_deps

ORDER = {"room": "210", "drink": "latte", "name": "Ada", "notes": ""}
OPERATOR = {"Authorization": f"Bearer {TOKEN}"}
XSS = '<script>alert("x")</script><img src=x onerror=alert(1)>'


async def place(client: TestClient, **fields: Any) -> dict[str, Any]:
    response = await client.post("/api/orders", json={**ORDER, **fields})
    assert response.status == 201, await response.text()
    return await response.json()


def keyed(order: dict[str, Any], path: str = "/api/orders/{id}") -> str:
    """``path`` for ``order`` with its key, as its customer's status link has it."""
    return path.format(id=order["id"]) + f"?key={order['key']}"


async def test_create_and_get_order(client: TestClient) -> None:
    response = await client.post("/api/orders", json=ORDER)
    assert response.status == 201
    order = await response.json()
    assert response.headers["Location"] == keyed(order)
    assert order["status"] == "preparing"  # the robot was idle: dispatched at once
    second = await place(client, name="Grace")
    assert (second["status"], second["ahead"]) == ("queued", 1)
    fetched = await client.get(keyed(second))
    assert fetched.status == 200
    assert (await fetched.json())["name"] == "Grace"


@pytest.mark.parametrize(
    ("fields", "status", "named"),
    [
        ({"room": "999"}, 422, "room"),
        ({"drink": "whisky"}, 422, "drink"),
        ({"name": ""}, 422, "name"),
        ({"name": "   "}, 422, "name"),
        ({"name": "x" * 41}, 422, "name"),
        ({"notes": "n" * 201}, 422, "notes"),
        ({"room": None}, 422, "room"),
        ({"table": "3"}, 422, "table"),
    ],
)
async def test_bad_fields_are_named(
    client: TestClient, fields: dict[str, Any], status: int, named: str
) -> None:
    response = await client.post("/api/orders", json={**ORDER, **fields})
    assert response.status == status
    body = await response.json()
    assert named in body["fields"]
    assert named in body["error"]


async def test_missing_field_is_named(client: TestClient) -> None:
    response = await client.post("/api/orders", json={"room": "210", "drink": "tea"})
    assert response.status == 422
    assert "name" in (await response.json())["fields"]


async def test_bad_json_is_400(client: TestClient) -> None:
    response = await client.post(
        "/api/orders", data=b'{"room": "210",', headers={"Content-Type": "application/json"}
    )
    assert response.status == 400
    assert "JSON" in (await response.json())["error"]


async def test_oversized_body_is_413(client: TestClient) -> None:
    response = await client.post("/api/orders", json={**ORDER, "notes": "n" * 5000})
    assert response.status == 413
    assert "error" in await response.json()


async def test_unknown_order_is_404(client: TestClient) -> None:
    for method in ("GET", "DELETE"):
        response = await client.request(method, "/api/orders/nosuchorder")
        assert response.status == 404
        assert "nosuchorder" in (await response.json())["error"]


async def test_cancel_while_queued_else_409(client: TestClient) -> None:
    first = await place(client)
    second = await place(client, name="Grace")
    response = await client.delete(keyed(second))
    assert response.status == 200
    assert (await response.json())["status"] == "cancelled"
    again = await client.delete(keyed(second))
    assert again.status == 409
    out = await client.delete(keyed(first))
    assert out.status == 409
    assert "preparing" in (await out.json())["error"]


async def test_rate_limit_per_client(client: TestClient) -> None:
    for _ in range(5):
        await place(client)
    refused = await client.post("/api/orders", json=ORDER)
    assert refused.status == 429
    assert int(refused.headers["Retry-After"]) >= 1
    assert "too many" in (await refused.json())["error"]
    form = await client.post("/orders", data=ORDER)
    assert form.status == 429


@pytest.mark.parametrize("path", ["/api/orders", "/orders"])
async def test_refused_orders_do_not_use_up_the_rate_limit(client: TestClient, path: str) -> None:
    for _ in range(8):
        if path == "/orders":
            refused = await client.post(path, data={**ORDER, "name": ""})
        else:
            refused = await client.post(path, json={**ORDER, "name": ""})
        assert refused.status == 422
    accepted = await client.post("/api/orders", json=ORDER)
    assert accepted.status == 201, await accepted.text()


@pytest.mark.parametrize(
    ("method", "path", "body"),
    [
        ("POST", "/api/estop", {"engaged": True}),
        ("GET", "/api/orders", None),
        ("POST", "/api/orders/{id}/cup-loaded", None),
        ("POST", "/api/orders/{id}/elevator-confirm", None),
    ],
)
@pytest.mark.parametrize(
    "auth", [None, "Bearer wrong-token", f"Basic {TOKEN}", "Bearer ", f"Bearer {TOKEN}x"]
)
async def test_operator_actions_need_the_token(
    client: TestClient, board: Board, method: str, path: str, body: Any, auth: str | None
) -> None:
    order = await place(client)
    headers = {} if auth is None else {"Authorization": auth}
    response = await client.request(method, path.format(id=order["id"]), json=body, headers=headers)
    assert response.status == 401
    assert response.headers["WWW-Authenticate"].startswith("Bearer")
    assert board.latest(ESTOP) is None
    assert board.latest(OPERATOR_EVENT) is None


async def test_no_configured_token_refuses_everyone(
    aiohttp_client: Any, board: Board, orders: OrdersModule
) -> None:
    deps = dataclasses.replace(web_deps(board, orders), operator_token=None)
    client = await aiohttp_client(create_app(deps, board))
    response = await client.post("/api/estop", json={"engaged": True}, headers=OPERATOR)
    # Not "token required" as for a wrong token: no token would do, and it says how to set one.
    assert response.status == 403
    error = (await response.json())["error"]
    assert error.startswith("operator actions are off: no operator token is set")
    assert "COFFEEBOT_OPERATOR_TOKEN" in error
    assert board.latest(ESTOP) is None


async def test_estop_with_token(client: TestClient, board: Board) -> None:
    response = await client.post(
        "/api/estop", json={"engaged": True, "reason": "spill"}, headers=OPERATOR
    )
    assert response.status == 200
    published = board.latest(ESTOP)
    assert published is not None
    assert (published.msg.engaged, published.msg.reason) == (True, "spill")
    bad = await client.post("/api/estop", json={"engaged": "maybe"}, headers=OPERATOR)
    assert bad.status == 422
    assert "engaged" in (await bad.json())["fields"]
    await client.post("/api/estop", json={"engaged": False}, headers=OPERATOR)
    assert board.latest(ESTOP).msg.engaged is False


async def test_cup_loaded_and_pickup_follow_the_lifecycle(client: TestClient, board: Board) -> None:
    order = await place(client)
    too_early = await client.post(keyed(order, "/api/orders/{id}/pickup"))
    assert too_early.status == 409
    loaded = await client.post(f"/api/orders/{order['id']}/cup-loaded", headers=OPERATOR)
    assert loaded.status == 202
    assert board.latest(OPERATOR_EVENT).msg.kind == "cup_loaded"
    board.publish(DELIVERY_STATUS, DeliveryUpdate(order_id=order["id"], status=OrderStatus.ARRIVED))
    async with client.get(keyed(order, "/api/orders/{id}/events")) as stream:
        await wait_for_status(stream, "arrived")
    picked = await client.post(keyed(order, "/api/orders/{id}/pickup"))
    assert picked.status == 202
    event = board.latest(OPERATOR_EVENT).msg
    assert (event.kind, event.order_id) == ("pickup_confirmed", order["id"])
    late = await client.post(f"/api/orders/{order['id']}/cup-loaded", headers=OPERATOR)
    assert late.status == 409


async def test_operator_confirms_the_elevator_only_while_the_robot_waits_for_it(
    client: TestClient, board: Board
) -> None:
    order = await place(client)
    path = f"/api/orders/{order['id']}/elevator-confirm"
    assert (await client.post(path, headers=OPERATOR)).status == 409
    update = DeliveryUpdate(order_id=order["id"], status=OrderStatus.WAITING_FOR_ELEVATOR)
    board.publish(DELIVERY_STATUS, update)
    async with client.get(keyed(order, "/api/orders/{id}/events")) as stream:
        await wait_for_status(stream, "waiting_for_elevator")
    assert (await client.post(path, headers=OPERATOR)).status == 202
    event = board.latest(OPERATOR_EVENT).msg
    assert (event.kind, event.order_id) == ("elevator_confirm", order["id"])


async def test_operator_cancels_any_order(client: TestClient, board: Board) -> None:
    out = await place(client)
    queued = await place(client, name="Grace")
    listed = await client.get("/api/orders", headers=OPERATOR)
    assert [o["id"] for o in await listed.json()] == [out["id"], queued["id"]]
    response = await client.delete(f"/api/orders/{out['id']}", headers=OPERATOR)
    assert response.status == 202  # navigation ends the delivery and reports it
    event = board.latest(OPERATOR_EVENT).msg
    assert (event.kind, event.order_id) == ("cancel", out["id"])
    response = await client.delete(f"/api/orders/{queued['id']}", headers=OPERATOR)
    assert (await response.json())["status"] == "cancelled"


async def wait_for_status(stream: Any, status: str) -> dict[str, Any]:
    """Read server-sent events until the order reaches ``status``."""
    async for line in stream.content:
        if line.startswith(b"data: "):
            order = json.loads(line[6:])
            if order["status"] == status:
                return order
    raise AssertionError(f"stream ended before {status}")


async def test_order_events_follow_the_lifecycle(client: TestClient, board: Board) -> None:
    order = await place(client)
    async with client.get(keyed(order, "/api/orders/{id}/events")) as stream:
        assert stream.headers["Content-Type"] == "text/event-stream"
        await wait_for_status(stream, "preparing")
        for status in (OrderStatus.ON_THE_WAY, OrderStatus.ARRIVED, OrderStatus.DELIVERED):
            board.publish(DELIVERY_STATUS, DeliveryUpdate(order_id=order["id"], status=status))
            await wait_for_status(stream, status.value)
        # It ends with the order: the last word is the timeline of the delivered order.
        rest = (await stream.content.read()).decode().strip().splitlines()
        assert rest[0] == "event: timeline" and len(rest) == 2
        assert json.loads(rest[1].removeprefix("data: "))["final"] is True


async def test_the_status_stream_sends_the_timeline_in_plain_words(
    client: TestClient, board: Board
) -> None:
    order = await place(client)
    async with client.get(keyed(order, "/api/orders/{id}/events")) as stream:
        timeline = await next_timeline(stream)
        assert timeline["headline"] == "Being prepared in the tea room"
        steps = {s["key"]: s["state"] for s in timeline["steps"]}
        assert steps == {
            "queued": "done",
            "preparing": "current",
            "on_the_way": "todo",
            "arrived": "todo",
            "delivered": "todo",
        }
        update = DeliveryUpdate(
            order_id=order["id"], status=OrderStatus.ARRIVED, detail="at the door of 210 (-7 mm)"
        )
        board.publish(DELIVERY_STATUS, update)
        while (timeline := await next_timeline(stream))["status"] != "arrived":
            pass
    assert timeline["detail"] == "Please take your latte from the robot, then press the button."
    assert "mm" not in json.dumps(timeline)
    assert 170 < timeline["pickup_left_s"] <= 180
    snapshot = await client.get(keyed(order, "/api/orders/{id}/timeline"))
    assert (await snapshot.json())["headline"] == "At your door"
    # Without the key the timeline is nobody's business.
    assert (await client.get(f"/api/orders/{order['id']}/timeline")).status == 403


async def next_timeline(stream: Any) -> dict[str, Any]:
    named = False
    async for line in stream.content:
        if line.startswith(b"event: timeline"):
            named = True
        elif named and line.startswith(b"data: "):
            return dict(json.loads(line[6:]))
    raise AssertionError("stream ended without a timeline")


async def test_xss_in_name_and_notes_is_escaped(client: TestClient) -> None:
    order = await place(client, name=XSS[:40], notes=XSS)
    page = await client.get(keyed(order, "/orders/{id}"))
    html = await page.text()
    assert "<script>alert" not in html
    assert "<img src=x" not in html
    assert "&lt;script&gt;alert" in html
    assert "script-src 'self'" in page.headers["Content-Security-Policy"]
    api = await client.get(keyed(order))
    assert api.content_type == "application/json"
    assert (await api.json())["notes"] == XSS  # stored as given, escaped where shown


async def test_form_errors_escape_what_was_typed(client: TestClient) -> None:
    response = await client.post("/orders", data={**ORDER, "room": XSS[:16], "notes": XSS})
    assert response.status == 422
    html = await response.text()
    assert "<script>" not in html
    assert "&lt;script&gt;" in html  # the notes as typed, escaped
    assert "Please pick your office." in html


async def test_form_submission_redirects_to_the_status_page(client: TestClient) -> None:
    response = await client.post("/orders", data=ORDER, allow_redirects=False)
    assert response.status == 303
    page = await client.get(response.headers["Location"])
    assert page.status == 200
    assert "Ada" in await page.text()


async def test_pages_render(client: TestClient) -> None:
    form = await client.get("/")
    html = await form.text()
    assert form.status == 200
    assert 'label="Floor 3"' in html
    assert "302" in html
    missing = await client.get("/orders/doesnotexist")
    assert missing.status == 404
    assert "text/html" in missing.content_type
    assert (await client.get("/inspect")).status == 200
    graph = await client.get("/inspect/graph.svg")
    assert "orders/dispatch" in await graph.text()
    assert (await client.get("/api/map/2.svg")).status == 404
    assert (await client.get("/static/inspect.js")).status == 200


async def test_board_snapshot_and_stream(client: TestClient, board: Board) -> None:
    board.publish(
        RANGE_SCAN,
        RangeScan(
            cycle_start_s=0.0,
            cycle_time_s=0.02,
            readings=[RangeReading(sensor=3, status=ReadingStatus.VALID, distance_mm=812)],
        ),
    )
    response = await client.get("/api/board")
    frame = await response.json()
    scan = next(t for t in frame["board"]["topics"] if t["name"] == "tof/scan")
    assert scan["published"] == 1
    assert "812" in frame["values"]["tof/scan"]["text"]
    async with client.get("/api/board/stream") as stream:
        async for line in stream.content:
            if line.startswith(b"data: "):
                assert b"tof/scan" in line
                break


class QueueDown:
    """Orders kept somewhere that cannot be reached now (a fleet's dispatcher, restarting):
    the web needs nothing but the orders protocol."""

    async def place(self, new: NewOrder, client: str) -> PlacedOrder:
        raise OrdersUnavailable("the dispatcher is restarting")

    async def get(self, order_id: str) -> Order:
        raise OrderNotFound(f"no order {order_id!r}")

    async def authorize(self, order_id: str, key: str) -> Order:
        return await self.get(order_id)

    async def cancel(self, order_id: str, detail: str = "") -> Order:
        raise OrderError(f"order {order_id!r} is out")

    async def active(self) -> list[Order]:
        return []


async def test_order_errors_become_http_answers_in_one_place(
    aiohttp_client: Any, board: Board, orders: OrdersModule
) -> None:
    deps = dataclasses.replace(web_deps(board, orders), orders=QueueDown())
    client = await aiohttp_client(create_app(deps, board))
    placed = await client.post("/api/orders", json={"room": "210", "drink": "tea", "name": "A"})
    assert placed.status == 503
    assert (await placed.json())["error"] == "the dispatcher is restarting"
    assert (await client.get("/api/orders/abc")).status == 404
    assert (await client.get("/orders/abc")).status == 404  # the page, not JSON
    listed = await client.get("/api/orders", headers=OPERATOR)
    assert listed.status == 200 and await listed.json() == []


async def test_the_form_says_what_to_fix_in_plain_words(client: TestClient) -> None:
    response = await client.post("/orders", data={"drink": "latte", "name": " ", "notes": ""})
    assert response.status == 422
    page = await response.text()
    assert "Please tell us your name" in page and "Please pick your office." in page
    assert "String should" not in page and "Field required" not in page
    too_long = await client.post("/orders", data={**ORDER, "name": "x" * 41})
    assert "Please keep your name to 40 characters." in await too_long.text()


async def test_the_form_preselects_no_office_and_lets_the_browser_check_it(
    client: TestClient,
) -> None:
    page = await (await client.get("/")).text()
    assert "novalidate" not in page
    room = page[page.index('<select name="room" required>') :]
    room = room[: room.index("</select>")]
    assert '<option value="" selected disabled>Choose your office' in room
    assert room.count("selected") == 1
