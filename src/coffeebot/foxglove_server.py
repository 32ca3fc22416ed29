"""The board, live, in Foxglove: ``coffeebot run/sim --foxglove [PORT]``.

A Foxglove WebSocket server (``foxglove-sdk``) carries every board topic on a channel of the
same name, JSON with the JSON schema of its pydantic model: the channels an MCAP recording
(:mod:`coffeebot.board.recording`) has, so a layout made on a recording works live. Beside
them, what Foxglove's 3D panel draws (:mod:`coffeebot.foxglove_scene`):

* ``/tf``: the estimated pose, ``map`` to ``base_link``;
* ``/robot``: the body and each ToF sensor's field of view, as far as its reading reaches;
* ``/tof/points``: each reading that ranged something, as a point;
* ``/map/walls``: the walls of the robot's floor.

A message is serialised only while a client is subscribed to its channel; with nobody
watching, the server costs the control loop one task wake-up per board message.
"""

from __future__ import annotations

import asyncio
import contextlib
import logging
from typing import Any

import foxglove
from foxglove.channels import FrameTransformChannel, PointCloudChannel, SceneUpdateChannel
from foxglove.websocket import WebSocketServer

from coffeebot.board import Board, BoardOverflowError, Envelope, Subscription
from coffeebot.board.recording import (
    MESSAGE_ENCODING,
    SCHEMA_ENCODING,
    schema_name,
    topic_schema,
)
from coffeebot.config import RobotConfig
from coffeebot.floorplan import FloorPlan
from coffeebot.foxglove_scene import body_and_cones, floor_walls, pose_transform, scan_points
from coffeebot.messages import CURRENT_STATE, RANGE_SCAN, CurrentState, RangeScan

log = logging.getLogger(__name__)

WALLS_EVERY_S = 2.0
"""The walls are sent again this often (board time), so a client that joins late gets them."""


def _ns(seconds: float) -> int:
    return round(seconds * 1e9)


class FoxgloveServer:
    """Serves ``board`` on ``host``:``port`` while open (``async with``); port 0 picks a free
    one, then :attr:`port` says which."""

    def __init__(
        self, board: Board, config: RobotConfig, plan: FloorPlan, port: int, host: str
    ) -> None:
        self.board = board
        self.config = config
        self.plan = plan
        self.port = port
        self.host = host
        self._context = foxglove.Context()
        self._server: WebSocketServer | None = None
        self._channels: dict[str, foxglove.Channel] = {}
        self._tf = FrameTransformChannel("/tf", context=self._context)
        self._robot = SceneUpdateChannel("/robot", context=self._context)
        self._points = PointCloudChannel("/tof/points", context=self._context)
        self._walls = SceneUpdateChannel("/map/walls", context=self._context)
        self._walls_sent: tuple[int, float] | None = None
        """The floor and board time the walls were last sent for."""
        self._pumps: list[asyncio.Task[None]] = []

    async def __aenter__(self) -> FoxgloveServer:
        try:
            self._server = foxglove.start_server(
                name=f"coffeebot {self.config.name}",
                host=self.host,
                port=self.port,
                context=self._context,
            )
        except RuntimeError as exc:  # the SDK's error for a port in use or a bad address
            raise OSError(f"--foxglove: cannot serve on {self.host}:{self.port}: {exc}") from exc
        self.port = self._server.port
        for topic in self.board.topics:
            schema = foxglove.Schema(
                name=schema_name(topic.model), encoding=SCHEMA_ENCODING, data=topic_schema(topic)
            )
            self._channels[topic.name] = foxglove.Channel(
                topic.name,
                schema=schema,
                message_encoding=MESSAGE_ENCODING,
                context=self._context,
                metadata={"delivery": topic.delivery.value},
            )
            subscription = self.board.subscribe(topic, name="foxglove")
            self._pumps.append(
                asyncio.create_task(self._pump(subscription), name=f"foxglove:{topic.name}")
            )
        log.info(
            "foxglove: open ws://%s:%d in Foxglove (Open connection, Foxglove WebSocket)",
            self.host,
            self.port,
            extra={"port": self.port},
        )
        return self

    async def __aexit__(self, *exc: object) -> None:
        for pump in self._pumps:
            pump.cancel()
        with contextlib.suppress(asyncio.CancelledError):
            await asyncio.gather(*self._pumps)
        if self._server is not None:
            self._server.stop()

    async def _pump(self, subscription: Subscription[Any]) -> None:
        topic = subscription.topic
        channel = self._channels[topic.name]
        while True:
            try:
                envelope = await subscription.get()
            except StopAsyncIteration:
                return
            except BoardOverflowError:
                # A viewer, not a recorder: go on from the newest message.
                subscription.close()
                subscription = self.board.subscribe(topic, name="foxglove")
                continue
            if channel.has_sinks():
                channel.log(envelope.msg.model_dump_json().encode(), log_time=_ns(envelope.stamp))
            if topic.name == CURRENT_STATE.name:
                self._state(envelope)
            elif topic.name == RANGE_SCAN.name:
                self._scan(envelope)

    def _state(self, envelope: Envelope[CurrentState]) -> None:
        pose = envelope.msg.pose
        if not pose.initialised:
            return
        stamp = envelope.stamp
        if self._tf.has_sinks():
            self._tf.log(pose_transform(pose, stamp), log_time=_ns(stamp))
        sent = self._walls_sent
        if self._walls.has_sinks() and (
            sent is None or sent[0] != pose.floor or stamp - sent[1] >= WALLS_EVERY_S
        ):
            self._walls.log(floor_walls(self.plan.floor(pose.floor), stamp), log_time=_ns(stamp))
            self._walls_sent = (pose.floor, stamp)

    def _scan(self, envelope: Envelope[RangeScan]) -> None:
        readings = envelope.msg.readings
        tof = self.config.tof
        stamp = envelope.stamp
        if self._robot.has_sinks():
            scene = body_and_cones(
                readings, tof.sensors, self.config.geometry, tof.max_range_mm, stamp
            )
            self._robot.log(scene, log_time=_ns(stamp))
        if self._points.has_sinks():
            points = scan_points(readings, tof.sensors, tof.max_range_mm, stamp)
            self._points.log(points, log_time=_ns(stamp))
