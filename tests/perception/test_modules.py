"""The board modules: thin wrappers, wired to the right topics, deciding in one loop turn."""

from __future__ import annotations

import asyncio
import math

import pytest
from perception_helpers import BOARD_FILE, robot, scan

from coffeebot.board import Board
from coffeebot.daemon import Daemon
from coffeebot.floorplan import load_floorplan
from coffeebot.messages import (
    ALL_TOPICS,
    COLLISION,
    CURRENT_STATE,
    ODOMETRY,
    RANGE_SCAN,
    TRAFFIC,
    UWB_FIX,
    Odometry,
    OtherRobot,
    SafetyState,
    Traffic,
    UwbFix,
)
from coffeebot.modules.angle import AngleModule
from coffeebot.modules.collision import CollisionModule
from coffeebot.modules.door import DoorModule
from coffeebot.modules.state import StateModule

PLAN = load_floorplan(BOARD_FILE.parents[1] / "floorplans" / "cs-building.toml")


async def test_collision_verdict_in_the_same_loop_turn_as_the_scan(caplog) -> None:
    caplog.set_level("INFO")
    board = Board(ALL_TOPICS)
    daemon = Daemon(board, [CollisionModule(robot(), PLAN)])
    await daemon.start()
    seqs = []
    # Scans far enough apart that the obstacle memory has let go of the 150 mm return.
    for k, distance in enumerate((2000, 150, 2000)):
        envelope = board.publish(RANGE_SCAN, scan({0: 300, 1: 300}, default=distance, t=2.0 * k))
        verdict = await board.next(COLLISION, timeout=1.0)
        seqs.append((envelope.seq, verdict.msg.scan_seq, verdict.msg.state))
    await daemon.shutdown()
    assert seqs == [
        (1, 1, SafetyState.GO),
        (2, 2, SafetyState.STOP),
        (3, 3, SafetyState.GO),
    ]
    # Each change is logged once with its cause; the initial "stop" is no event.
    events = [(r.event, r.cause) for r in caplog.records if hasattr(r, "event")]
    assert [e for e, _ in events] == ["safety_clear", "safety_stop", "safety_clear"]
    assert "obstacle at 150 mm" in events[1][1]
    # The states read as docs/operations.md shows them: stop and go.
    changes = [(r.state, r.previous) for r in caplog.records if hasattr(r, "event")]
    assert changes == [("go", "stop"), ("stop", "go"), ("go", "stop")]


@pytest.mark.parametrize("fusion", ["ekf", "particles"])
async def test_state_module_fuses_odometry_and_uwb(fusion: str) -> None:
    board = Board(ALL_TOPICS)
    config = robot()
    config = config.model_copy(update={"state": config.state.model_copy(update={"fusion": fusion})})
    modules = [StateModule(config, PLAN), AngleModule(config, PLAN), DoorModule(config, PLAN)]
    daemon = Daemon(board, modules)
    await daemon.start()
    board.publish(UWB_FIX, UwbFix(x_mm=5000, y_mm=-300, z_mm=900, quality=90))
    state = await board.next(CURRENT_STATE, timeout=1.0)
    first = state.msg.pose
    # The first fix places the Kalman filter on it, and seeds the particles around it.
    assert first.initialised
    assert math.hypot(first.x_mm - 5000, first.y_mm + 300) <= (0.0 if fusion == "ekf" else 50.0)
    ticks_per_mm = config.motor.ticks_per_rev / (3.141592653589793 * config.motor.wheel_diameter_mm)
    for k in range(3):
        board.publish(
            ODOMETRY,
            Odometry(
                controller_time_ms=100 * k,
                left_ticks=round(100 * k * ticks_per_mm),
                right_ticks=round(100 * k * ticks_per_mm),
                gyro_z_dps=0.0,
                left_mm_s=1000,
                right_mm_s=1000,
            ),
        )
    await asyncio.sleep(0.01)
    await daemon.shutdown()
    latest = board.latest(CURRENT_STATE)
    assert latest is not None
    moved = math.hypot(latest.msg.pose.x_mm - first.x_mm, latest.msg.pose.y_mm - first.y_mm)
    assert moved > 100  # along its (unknown) heading
    assert latest.msg.pose.speed_mm_s > 900
    assert set(latest.msg.sources) == {"uwb", "odometry"}


async def test_state_module_follows_the_fleets_traffic_without_publishing_for_it() -> None:
    board = Board(ALL_TOPICS)
    module = StateModule(robot(), PLAN)
    daemon = Daemon(board, [module])
    await daemon.start()
    parked = OtherRobot(
        robot="robot-2",
        floor=2,
        x_mm=43100.0,
        y_mm=-3300.0,
        heading_deg=90.0,
        moving=False,
        reported_at_s=0.0,
        age_s=0.1,
    )
    sent = board.publish(TRAFFIC, Traffic(robots=[parked]))
    await asyncio.sleep(0.01)
    await daemon.shutdown()
    # The next scans leave out what that robot explains; nothing new to publish until then.
    assert len(module.estimator.other_robots(sent.stamp)) == 1
    assert board.latest(CURRENT_STATE) is None
