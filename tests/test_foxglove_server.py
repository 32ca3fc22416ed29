"""``--foxglove``: a WebSocket client speaking Foxglove's protocol connects, sees every board
topic advertised as the MCAP recording has it, subscribes, and reads the robot's state and
its pose as a transform."""

from __future__ import annotations

import asyncio
import base64
import json
import math
import socket
import struct
from collections.abc import AsyncIterator
from pathlib import Path
from typing import Any

import aiohttp
import pytest

from coffeebot.board import Board
from coffeebot.board.recording import schema_name
from coffeebot.cli import build_parser
from coffeebot.config import load_robot_config
from coffeebot.floorplan import load_floorplan
from coffeebot.foxglove_server import FoxgloveServer
from coffeebot.messages import (
    ALL_TOPICS,
    CURRENT_STATE,
    RANGE_SCAN,
    CurrentState,
    PoseEstimate,
    RangeScan,
)
from coffeebot.runtime.service import serve
from coffeebot.runtime.sim import build_sim
from coffeebot.sim.simulation import demo_setup
from foxglove_decode import decode
from manual_clock import ManualClock

REPO = Path(__file__).resolve().parents[1]
SUBPROTOCOL = "foxglove.sdk.v1"
MESSAGE_DATA = 0x01
"""Opcode of a binary message frame: subscription id (u32), log time (u64 ns), payload."""


def state(x_mm: float) -> CurrentState:
    return CurrentState(
        pose=PoseEstimate(
            x_mm=x_mm, y_mm=-400, heading_deg=180, floor=2,
            sigma_x_mm=40, sigma_y_mm=40, sigma_heading_deg=2,
        )
    )  # fmt: skip


@pytest.fixture
async def served() -> AsyncIterator[tuple[Board, FoxgloveServer]]:
    board = Board(ALL_TOPICS, clock=ManualClock(start=42.0))
    config = load_robot_config(REPO / "boards" / "coffeebot-v1.toml")
    plan = load_floorplan(REPO / "floorplans" / "cs-building.toml")
    async with FoxgloveServer(board, config, plan, port=0, host="127.0.0.1") as server:
        yield board, server


async def advertised(ws: aiohttp.ClientWebSocketResponse) -> dict[str, dict[str, Any]]:
    while (message := await ws.receive_json())["op"] != "advertise":
        pass
    return {channel["topic"]: channel for channel in message["channels"]}


async def test_every_board_topic_is_advertised_as_the_recording_has_it(
    served: tuple[Board, FoxgloveServer],
) -> None:
    _, server = served
    async with (
        aiohttp.ClientSession() as session,
        session.ws_connect(f"ws://127.0.0.1:{server.port}", protocols=(SUBPROTOCOL,)) as ws,
    ):
        channels = await advertised(ws)
    for topic in ALL_TOPICS:
        channel = channels[topic.name]
        assert (channel["encoding"], channel["schemaEncoding"]) == ("json", "jsonschema")
        assert channel["schemaName"] == schema_name(topic.model)
        assert json.loads(channel["schema"]) == topic.model.model_json_schema()
    scene = {name: channels[name]["schemaName"] for name in channels if name.startswith("/")}
    assert scene == {
        "/tf": "foxglove.FrameTransform",
        "/robot": "foxglove.SceneUpdate",
        "/tof/points": "foxglove.PointCloud",
        "/map/walls": "foxglove.SceneUpdate",
    }


async def test_a_subscriber_reads_the_state_and_the_pose_as_a_transform(
    served: tuple[Board, FoxgloveServer],
) -> None:
    board, server = served
    async with (
        aiohttp.ClientSession() as session,
        session.ws_connect(f"ws://127.0.0.1:{server.port}", protocols=(SUBPROTOCOL,)) as ws,
    ):
        channels = await advertised(ws)
        wanted = {1: CURRENT_STATE.name, 2: "/tf"}
        await ws.send_json(
            {
                "op": "subscribe",
                "subscriptions": [
                    {"id": sid, "channelId": channels[name]["id"]} for sid, name in wanted.items()
                ],
            }
        )

        async def publish_until_read() -> None:
            # The server takes the subscription on its own thread: until it has, a message
            # goes to nobody, so keep publishing the same state.
            while True:
                board.publish(CURRENT_STATE, state(x_mm=7_250))
                await asyncio.sleep(0.01)

        publisher = asyncio.create_task(publish_until_read())
        received: dict[int, tuple[int, bytes]] = {}
        try:
            async with asyncio.timeout(10):
                while set(received) != set(wanted):
                    frame = await ws.receive_bytes()
                    assert frame[0] == MESSAGE_DATA
                    sid, log_time = struct.unpack_from("<IQ", frame, 1)
                    received[sid] = (log_time, frame[13:])
        finally:
            publisher.cancel()

    log_time, payload = received[1]
    assert CurrentState.model_validate_json(payload) == state(x_mm=7_250)
    assert log_time == 42_000_000_000  # the board's stamp, as in a recording
    tf_channel = channels["/tf"]
    tf = decode(tf_channel["schemaName"], base64.b64decode(tf_channel["schema"]), received[2][1])
    assert (tf["parentFrameId"], tf["childFrameId"]) == ("map", "base_link")
    assert tf["translation"] == {"x": 7.25, "y": -0.4, "z": 0.0}
    assert tf["rotation"]["z"] == pytest.approx(1.0)


async def test_a_port_in_use_is_a_one_line_error_naming_it(
    served: tuple[Board, FoxgloveServer],
) -> None:
    board, server = served
    other = FoxgloveServer(board, server.config, server.plan, port=server.port, host="127.0.0.1")
    with pytest.raises(OSError, match=rf"--foxglove: cannot serve on 127\.0\.0\.1:{server.port}"):
        await other.__aenter__()


def test_foxglove_takes_an_optional_port_on_run_and_sim(capsys: pytest.CaptureFixture[str]) -> None:
    parser = build_parser()
    assert parser.parse_args(["run"]).foxglove is None
    assert parser.parse_args(["run", "--foxglove"]).foxglove == 8765
    assert parser.parse_args(["sim", "--foxglove", "9000"]).foxglove == 9000
    with pytest.raises(SystemExit):
        parser.parse_args(["sim", "--foxglove", "70000"])
    assert "a port is 0..65535, got 70000" in capsys.readouterr().err


def free_port() -> int:
    with socket.socket() as probe:
        probe.bind(("127.0.0.1", 0))
        return int(probe.getsockname()[1])


def points(channels: dict[str, dict[str, Any]], payload: bytes) -> list[tuple[float, ...]]:
    """The (x, y, z, distance) points of a ``/tof/points`` message."""
    channel = channels["/tof/points"]
    cloud = decode(channel["schemaName"], base64.b64decode(channel["schema"]), payload)
    return list(struct.iter_unpack("<ffff", base64.b64decode(cloud["data"])))


async def test_the_simulated_robot_live_its_scans_cones_points_and_walls() -> None:
    config = load_robot_config(REPO / "boards" / "coffeebot-v1.toml")
    config = config.model_copy(update={"web": config.web.model_copy(update={"host": "127.0.0.1"})})
    plan = load_floorplan(REPO / "floorplans" / "cs-building.toml")
    port = free_port()
    wanted = {1: RANGE_SCAN.name, 2: "/robot", 3: "/tof/points", 4: "/map/walls"}
    received: dict[int, bytes] = {}
    async with build_sim(config, plan, demo_setup(plan), web=False) as (runtime, _):
        serving = asyncio.create_task(serve(runtime, foxglove_port=port))
        try:
            async with asyncio.timeout(60), aiohttp.ClientSession() as session:
                while True:  # until the daemon has opened the server
                    try:
                        ws = await session.ws_connect(
                            f"ws://127.0.0.1:{port}", protocols=(SUBPROTOCOL,)
                        )
                        break
                    except aiohttp.ClientConnectionError:
                        await asyncio.sleep(0.05)
                async with ws:
                    channels = await advertised(ws)
                    subscriptions = [
                        {"id": sid, "channelId": channels[name]["id"]}
                        for sid, name in wanted.items()
                    ]
                    await ws.send_json({"op": "subscribe", "subscriptions": subscriptions})
                    # The sensors' first cycles are warm-up readings: wait for one that
                    # ranged something to come through as a point.
                    while set(received) != set(wanted) or not points(channels, received[3]):
                        frame = await ws.receive_bytes()
                        received[struct.unpack_from("<I", frame, 1)[0]] = frame[13:]
        finally:
            runtime.request_stop("test over")
            await asyncio.wait_for(serving, 30)

    scan = RangeScan.model_validate_json(received[1])
    assert sorted(r.sensor for r in scan.readings) == list(range(8))

    def scene(sid: int) -> dict[str, Any]:
        channel = channels[wanted[sid]]
        return decode(channel["schemaName"], base64.b64decode(channel["schema"]), received[sid])

    (robot,) = scene(2)["entities"]
    assert len(robot["lines"]) == 8 and len(robot["cubes"]) == 1
    # Each point lies on one sensor's axis, as far from its lens as it ranged, at its height.
    hits = points(channels, received[3])
    assert hits
    for x, y, z, distance in hits:
        assert 0 < distance < config.tof.max_range_mm / 1000
        assert any(
            (x, y, z)
            == pytest.approx(
                (
                    (s.x_mm + distance * 1000 * math.cos(math.radians(s.yaw_deg))) / 1000,
                    (s.y_mm + distance * 1000 * math.sin(math.radians(s.yaw_deg))) / 1000,
                    s.height_mm / 1000,
                ),
                abs=1e-4,
            )
            for s in config.tof.sensors
        )
    (walls,) = scene(4)["entities"]
    assert len(walls["lines"][0]["points"]) == 2 * len(plan.floor(2).segments)
