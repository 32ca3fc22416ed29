"""The fleet's camera messages: what they carry and refuse, who may send and read them on a
real Mosquitto with the generated access rules, and a robot's bridge and the camera service
at either end of them (the service watching one bare-floor camera, the robot a stand-in
driving straight). Identification with whole simulated robots is test_fleet_cameras.py's.
"""

from __future__ import annotations

import asyncio
import math
import time
from collections.abc import AsyncIterator, Callable
from pathlib import Path

import aiomqtt
import numpy as np
import pytest

from camera_fakes import BareFloor
from coffeebot.board import Board
from coffeebot.clock import MonotonicClock
from coffeebot.config import FleetConfig, RobotConfig, load_robot_config
from coffeebot.daemon import Daemon
from coffeebot.fleet.camera_link import CameraLink
from coffeebot.fleet.camera_service import CameraServiceModule
from coffeebot.fleet.mosquitto import Mosquitto
from coffeebot.fleet.protocol import (
    CAMERA_LAYER_TOPIC,
    BadMessage,
    CameraFixReport,
    CameraLayerReport,
    OdometryBatch,
    OdometrySample,
    PositionSample,
    decode,
    encode,
    robot_topic,
)
from coffeebot.floorplan import load_floorplan
from coffeebot.messages import (
    ALL_TOPICS,
    CAMERA_FIX,
    CAMERA_LAYER,
    CURRENT_STATE,
    ODOMETRY,
    CameraFix,
    CameraLayer,
    CameraObject,
    CurrentState,
    Odometry,
    PoseEstimate,
)
from coffeebot.modules.base import Module, ModuleContext
from coffeebot.modules.fleet_bridge import FleetBridge

ROOT = Path(__file__).resolve().parents[2]
PLAN = load_floorplan(ROOT / "floorplans" / "cs-building.toml")
BASE = load_robot_config(ROOT / "boards" / "coffeebot-v1.toml")
CONFIG = BASE.model_copy(update={"cameras": BASE.cameras.model_copy(update={"enabled": True})})
LOBBY = next(camera for floor in PLAN.floors for camera in floor.cameras if camera.id == "lobby-2")
WAIT_S = 20.0
SPEED_MM_S = 500.0
FIX = CameraFix(
    camera_id="lobby-2",
    floor=2,
    x_mm=41000.0,
    y_mm=0.0,
    heading_deg=180.0,
    sigma_mm=20.0,
    sigma_heading_deg=1.0,
    fit_error_mm=3.0,
    points=21,
    track_id="lobby-2-1",
)


def batch(*times: float) -> OdometryBatch:
    return OdometryBatch(
        samples=[OdometrySample(t_s=t, x_mm=50.0 * t, y_mm=0.0, heading_deg=0.0) for t in times],
        estimate=PositionSample(
            t_s=times[-1], floor=2, x_mm=41000.0, y_mm=0.0, sigma_x_mm=30.0, sigma_y_mm=20.0
        ),
    )


# --- the messages -----------------------------------------------------------------------------


def test_an_odometry_batch_and_a_fix_cross_the_wire_unchanged() -> None:
    sent = batch(1.0, 1.1, 1.2)
    assert decode(OdometryBatch, "t", encode(sent)) == sent
    report = CameraFixReport(odometry_at_s=1.2, fix=FIX)
    assert decode(CameraFixReport, "t", encode(report)) == report


@pytest.mark.parametrize(
    ("payload", "reason"),
    [
        (
            b'{"samples": [{"t_s": 2, "x_mm": 0, "y_mm": 0, "heading_deg": 0},'
            b' {"t_s": 1, "x_mm": 0, "y_mm": 0, "heading_deg": 0}]}',
            "samples: Value error, sample times must increase",
        ),
        (b'{"samples": []}', "samples: List should have at least 1 item"),
        (
            b'{"samples": [{"t_s": 1, "x_mm": "far", "y_mm": 0, "heading_deg": 0}]}',
            "samples.0.x_mm: Input should be a valid number",
        ),
        (
            b'{"samples": [{"t_s": 1, "x_mm": 0, "y_mm": 0, "heading_deg": 0}], "speed": 1}',
            "speed: Extra inputs are not permitted",
        ),
        (
            b'{"samples": [{"t_s": 1, "x_mm": 0, "y_mm": 0, "heading_deg": 0}], "estimate":'
            b' {"t_s": 1, "floor": 2, "x_mm": 0, "y_mm": 0, "sigma_x_mm": 10,'
            b' "sigma_y_mm": 10, "cov_xy_mm2": 500}}',
            "estimate: Value error, cov_xy_mm2 is larger than sigma_x_mm * sigma_y_mm allows",
        ),
        (
            b'{"samples": [{"t_s": 1, "x_mm": 0, "y_mm": 0, "heading_deg": 0}], "estimate":'
            b' {"t_s": 1, "floor": 2, "x_mm": 0, "y_mm": 0, "sigma_x_mm": -1, "sigma_y_mm": 1}}',
            "estimate.sigma_x_mm: Input should be greater than or equal to 0",
        ),
    ],
)
def test_a_malformed_odometry_batch_is_refused_saying_what_is_wrong(
    payload: bytes, reason: str
) -> None:
    with pytest.raises(BadMessage) as refused:
        decode(OdometryBatch, "coffeebot/v1/robots/robot-1/odometry", payload)
    assert str(refused.value).startswith(f"coffeebot/v1/robots/robot-1/odometry: {reason}")


def test_a_layer_older_than_navigation_takes_for_fresh_is_dropped() -> None:
    """A retained layer a stopped service left on the broker is no camera information."""
    link = CameraLink(CONFIG)
    stale_s = CONFIG.navigation.camera_stale_s
    cart = CameraObject(
        id="lobby-2-7",
        camera_id="lobby-2",
        floor=2,
        x_mm=40000,
        y_mm=0,
        length_mm=500,
        width_mm=900,
        axis_deg=90,
        standing_since_s=980.0,
        seen_s=999.0,
    )
    report = CameraLayerReport(at_s=999.0, layer=CameraLayer(objects=[cart], expiry_s=60.0))
    # The fleet's time base is 900 s ahead of the board's clock.
    fresh = link.layer(report, offset_s=900.0, now=100.0)
    assert fresh is not None
    assert (fresh.objects[0].standing_since_s, fresh.objects[0].seen_s) == (80.0, 99.0)
    assert link.layer(report, offset_s=900.0, now=99.0 + stale_s + 0.1) is None


# --- who may send and read what -----------------------------------------------------------------


def client(broker: Mosquitto, user: str, name: str) -> aiomqtt.Client:
    login = broker.credentials[user]
    return aiomqtt.Client(
        broker.address.host,
        broker.address.port,
        username=login.username,
        password=login.password,
        identifier=name,
    )


async def first_messages(subscriber: aiomqtt.Client, until: Callable[[str], bool]) -> list[str]:
    """The topics ``subscriber`` gets, up to and with the first that ``until`` accepts."""
    topics: list[str] = []
    async with asyncio.timeout(WAIT_S):
        async for message in subscriber.messages:
            topics.append(str(message.topic))
            if until(topics[-1]):
                return topics
    return topics


async def test_a_robot_can_send_only_its_own_odometry(broker: Mosquitto) -> None:
    async with (
        client(broker, "dispatcher", "test-service") as service,
        client(broker, "robot-1", "test-robot-1") as robot,
    ):
        await service.subscribe("coffeebot/v1/robots/+/odometry")
        await service.subscribe(CAMERA_LAYER_TOPIC)
        forged = encode(batch(1.0))
        await robot.publish(robot_topic("robot-2", "odometry"), forged, qos=1)
        await robot.publish(CAMERA_LAYER_TOPIC, b"{}", qos=1)
        await robot.publish(robot_topic("robot-1", "odometry"), encode(batch(2.0)), qos=1)
        own = robot_topic("robot-1", "odometry")
        topics = await first_messages(service, lambda topic: topic == own)
    assert topics == [own], "the broker let robot-1 pose as robot-2 or as the camera service"


async def test_a_robot_reads_only_its_own_fixes_and_the_layer(broker: Mosquitto) -> None:
    async with (
        client(broker, "dispatcher", "test-service") as service,
        client(broker, "robot-1", "test-robot-1") as robot,
    ):
        for topic in ("robot-2", "robot-1"):
            await robot.subscribe(robot_topic(topic, "camera_fix"))
        await robot.subscribe(CAMERA_LAYER_TOPIC)
        fix = encode(CameraFixReport(odometry_at_s=1.0, fix=FIX))
        await service.publish(robot_topic("robot-2", "camera_fix"), fix, qos=1)
        await service.publish(robot_topic("robot-1", "camera_fix"), fix, qos=1)
        layer = CameraLayerReport(at_s=1.0, layer=CameraLayer(expiry_s=60.0))
        await service.publish(CAMERA_LAYER_TOPIC, encode(layer), qos=1)
        topics = await first_messages(robot, lambda topic: topic == CAMERA_LAYER_TOPIC)
    assert topics == [robot_topic("robot-1", "camera_fix"), CAMERA_LAYER_TOPIC]


# --- a robot's bridge and the camera service --------------------------------------------------


class StraightDrive(Module):
    """Stands in for the motor controller and the state module: telemetry at 50 Hz of a
    robot driving straight at ``SPEED_MM_S``, its estimate in the lobby."""

    name = "drive"
    outputs = (ODOMETRY, CURRENT_STATE)

    async def run(self, ctx: ModuleContext) -> None:
        ticks_per_mm = CONFIG.motor.ticks_per_rev / (math.pi * CONFIG.motor.wheel_diameter_mm)
        pose = PoseEstimate(
            x_mm=41000,
            y_mm=0,
            heading_deg=180,
            floor=2,
            sigma_x_mm=30,
            sigma_y_mm=30,
            sigma_heading_deg=1,
        )
        ctx.board.publish(CURRENT_STATE, CurrentState(pose=pose))
        start = ctx.clock.now()
        while True:
            t = ctx.clock.now() - start
            ticks = round(SPEED_MM_S * t * ticks_per_mm)
            ctx.board.publish(
                ODOMETRY,
                Odometry(
                    controller_time_ms=round(t * 1000),
                    left_ticks=ticks,
                    right_ticks=ticks,
                    gyro_z_dps=0.0,
                    left_mm_s=SPEED_MM_S,
                    right_mm_s=SPEED_MM_S,
                ),
            )
            await ctx.clock.sleep(0.02)


def robot_config(broker: Mosquitto) -> RobotConfig:
    fleet = FleetConfig(broker=broker.address.url, robot_id="robot-1")
    return CONFIG.model_copy(update={"fleet": fleet})


@pytest.fixture
async def ends(broker: Mosquitto) -> AsyncIterator[tuple[Daemon, CameraServiceModule]]:
    """Robot-1 (its bridge and a straight drive) and the camera service, on the broker."""
    clock = MonotonicClock()
    service = CameraServiceModule(
        CONFIG,
        PLAN,
        {"lobby-2": BareFloor(LOBBY)},
        broker.address.url,
        broker.credentials["dispatcher"],
    )
    daemons = [
        Daemon(Board(ALL_TOPICS, clock=clock), [service]),
        Daemon(
            Board(ALL_TOPICS, clock=clock),
            [FleetBridge(robot_config(broker), broker.credentials["robot-1"]), StraightDrive()],
        ),
    ]
    for daemon in daemons:
        await daemon.start()
    yield daemons[1], service
    for daemon in daemons:
        await daemon.shutdown()


async def until(check: Callable[[], bool], what: str) -> None:
    deadline = time.monotonic() + WAIT_S
    while not check():
        if time.monotonic() > deadline:
            raise AssertionError(f"not within {WAIT_S} s: {what}")
        await asyncio.sleep(0.05)


async def test_the_service_gets_the_robots_path_and_estimate_and_the_robot_the_layer(
    ends: tuple[Daemon, CameraServiceModule],
) -> None:
    robot, service = ends
    await until(lambda: "robot-1" in service.robots, "the service hears robot-1's odometry")
    known = service.robots["robot-1"]
    assert known.estimate is not None
    assert known.estimate.place == (2, 41000, 0)
    assert known.estimate.covariance_mm2 == ((900.0, 0.0), (0.0, 900.0))
    # Its moment, carried over the fleet's time base onto the service's clock (here the same).
    published = robot.board.latest(CURRENT_STATE)
    assert published is not None
    assert known.estimate.t_s == pytest.approx(published.stamp, abs=0.01)
    await until(lambda: robot.board.latest(CAMERA_LAYER) is not None, "the layer on the board")
    layer = robot.board.latest(CAMERA_LAYER)
    assert layer is not None
    assert [view.camera_id for view in layer.msg.cameras] == ["lobby-2"]
    # Straight at SPEED_MM_S in the odometry's frame, as the robot measured it.
    latest = known.path.latest
    assert latest is not None
    await until(lambda: known.path.covers(latest[0], latest[0] + 1.0, 0.0), "a second more of it")
    t, pose = latest
    moved = known.path.at(np.array([t + 1.0]))[0] - pose
    assert moved == pytest.approx(np.array([SPEED_MM_S, 0.0, 0.0]), abs=15)


async def test_a_fix_reaches_the_robots_board_carried_on_to_now_and_a_bad_batch_is_refused(
    ends: tuple[Daemon, CameraServiceModule], broker: Mosquitto
) -> None:
    robot, service = ends
    fixes = robot.board.subscribe(CAMERA_FIX)

    def driven_s(seconds: float) -> bool:
        known = service.robots.get("robot-1")
        latest = None if known is None else known.path.latest
        return (
            latest is not None
            and known is not None
            and known.path.covers(latest[0] - seconds, latest[0], 0.0)
        )

    await until(lambda: driven_s(1.5), "robot-1 connected and driving for a while")
    async with (
        client(broker, "dispatcher", "test-service") as sender,
        client(broker, "robot-1", "test-robot-1") as garbage,
    ):
        # Too old for the robot's path to carry on: dropped.
        old = CameraFixReport(odometry_at_s=time.time() - 60.0, fix=FIX)
        await sender.publish(robot_topic("robot-1", "camera_fix"), encode(old))
        # For a moment 1 s ago: the robot has driven on 500 mm since, along the fix's heading.
        recent = CameraFixReport(odometry_at_s=time.time() - 1.0, fix=FIX)
        await sender.publish(robot_topic("robot-1", "camera_fix"), encode(recent))
        async with asyncio.timeout(WAIT_S):
            fix = (await fixes.get()).msg
        await garbage.publish(robot_topic("robot-1", "odometry"), b'{"samples": "x"}')
    fixes.close()
    assert fix.x_mm == pytest.approx(FIX.x_mm - SPEED_MM_S, abs=50)
    assert fix.y_mm == pytest.approx(0.0, abs=1.0)
    assert abs(math.remainder(fix.heading_deg - 180.0, 360.0)) < 0.1
    await until(lambda: service.refused == 1, "the service refuses and counts the bad batch")
