"""An order's id identifies it; only its key (or the operator token) acts on it. Requests
naming another host, cross-site writes and malformed headers are refused with a JSON answer
that carries the security headers."""

from __future__ import annotations

import asyncio
import json
from typing import Any

from aiohttp.test_utils import TestClient

from coffeebot.board import Board
from coffeebot.messages import DELIVERY_STATUS, DeliveryUpdate, OrderStatus

from .conftest import TOKEN

ORDER = {"room": "210", "drink": "latte", "name": "Ada", "notes": ""}
OPERATOR = {"Authorization": f"Bearer {TOKEN}"}


async def place(client: TestClient, **fields: Any) -> dict[str, Any]:
    response = await client.post("/api/orders", json={**ORDER, **fields})
    assert response.status == 201
    return await response.json()


async def test_another_customers_order_is_untouchable_without_its_key(
    client: TestClient, board: Board
) -> None:
    mine = await place(client)
    theirs = await place(client, name="Grace")
    order = f"/api/orders/{theirs['id']}"
    for key in ("", f"?key={mine['key']}", "?key=guess"):
        assert (await client.get(order + key)).status == 403
        assert (await client.get(f"/orders/{theirs['id']}{key}")).status == 403
        assert (await client.get(f"{order}/events{key}")).status == 403
        assert (await client.delete(order + key)).status == 403
    board.publish(DELIVERY_STATUS, DeliveryUpdate(order_id=mine["id"], status=OrderStatus.ARRIVED))
    await asyncio.sleep(0.05)  # let the orders module store it
    # Someone who knows the id but not the key cannot confirm the pickup at 210.
    assert (await client.post(f"/api/orders/{mine['id']}/pickup")).status == 403
    assert (await client.get(f"{order}?key={theirs['key']}")).status == 200
    assert (await client.get(order, headers=OPERATOR)).status == 200
    cancelled = await client.delete(f"{order}?key={theirs['key']}")
    assert (await cancelled.json())["status"] == "cancelled"


async def test_anonymous_board_snapshot_has_no_names_or_keys(client: TestClient) -> None:
    placed = await place(client, name="Zebedee")
    snapshot = await (await client.get("/api/board")).text()
    assert "Zebedee" not in snapshot
    assert placed["key"] not in snapshot
    order = await (await client.get(f"/api/orders/{placed['id']}", headers=OPERATOR)).json()
    assert "key" not in order  # shown once, to the customer who placed it


async def test_another_hosts_name_is_refused(client: TestClient) -> None:
    refused = await client.get("/api/board", headers={"Host": "rebound.attacker.example"})
    assert refused.status == 421
    assert "rebound.attacker.example" in (await refused.json())["error"]
    assert refused.headers["X-Content-Type-Options"] == "nosniff"
    for host in ("localhost:8080", "127.0.0.1:8080", "[::1]:8080"):
        assert (await client.get("/api/board", headers={"Host": host})).status == 200


async def test_cross_site_writes_are_refused(client: TestClient) -> None:
    evil = {"Origin": "http://attacker.example"}
    assert (await client.post("/api/orders", json=ORDER, headers=evil)).status == 403
    cross = {"Sec-Fetch-Site": "cross-site"}
    assert (await client.post("/orders", data=ORDER, headers=cross)).status == 403
    same = {"Sec-Fetch-Site": "same-origin"}
    assert (await client.post("/api/orders", json=ORDER, headers=same)).status == 201


async def test_json_api_needs_a_json_body(client: TestClient) -> None:
    response = await client.post(
        "/api/orders", data=json.dumps(ORDER), headers={"Content-Type": "text/plain"}
    )
    assert response.status == 415
    assert "application/json" in (await response.json())["error"]


async def test_estop_takes_only_true_or_false(client: TestClient) -> None:
    for engaged in ("yes", 1, "true"):
        response = await client.post("/api/estop", json={"engaged": engaged}, headers=OPERATOR)
        assert response.status == 422, engaged


async def test_order_page_and_streams_carry_the_headers(client: TestClient) -> None:
    placed = await place(client)
    page = await client.get(f"/orders/{placed['id']}?key={placed['key']}")
    assert page.headers["Cache-Control"] == "no-store"
    async with client.get(f"/api/orders/{placed['id']}/events?key={placed['key']}") as stream:
        assert stream.headers["X-Content-Type-Options"] == "nosniff"
        assert "Content-Security-Policy" in stream.headers
    async with client.get("/api/board/stream") as stream:
        assert stream.headers["X-Content-Type-Options"] == "nosniff"


async def raw_request(client: TestClient, request: bytes) -> bytes:
    reader, writer = await asyncio.open_connection(client.server.host, client.server.port)
    writer.write(request)
    await writer.drain()
    answer = await reader.read(65536)
    writer.close()
    return answer


async def test_non_utf8_authorization_header_is_401(client: TestClient, caplog: Any) -> None:
    caplog.set_level("INFO")
    answer = await raw_request(
        client,
        b"POST /api/estop HTTP/1.1\r\nHost: localhost\r\nContent-Type: application/json\r\n"
        b"Authorization: Bearer \xff\xfe\xe9t\xe9\r\nContent-Length: 17\r\n"
        b"Connection: close\r\n\r\n"
        b'{"engaged": true}',
    )
    head, _, body = answer.partition(b"\r\n\r\n")
    assert head.startswith(b"HTTP/1.1 401"), head
    assert "error" in json.loads(body)
    assert b"X-Content-Type-Options: nosniff" in head
    assert not [r for r in caplog.records if r.levelname == "ERROR"]
