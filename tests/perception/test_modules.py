"""The board modules: thin wrappers, wired to the right topics, deciding in one loop turn."""

from __future__ import annotations

import asyncio

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
    UWB_FIX,
    Odometry,
    SafetyState,
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


async def test_state_module_fuses_odometry_and_uwb() -> None:
    board = Board(ALL_TOPICS)
    config = robot()
    modules = [StateModule(config, PLAN), AngleModule(config, PLAN), DoorModule(config, PLAN)]
    daemon = Daemon(board, modules)
    await daemon.start()
    board.publish(UWB_FIX, UwbFix(x_mm=5000, y_mm=-300, z_mm=900, quality=90))
    state = await board.next(CURRENT_STATE, timeout=1.0)
    assert state.msg.pose.initialised and state.msg.pose.x_mm == 5000
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
    assert abs(latest.msg.pose.x_mm - 5000) > 100  # moved along its (unknown) heading
    assert latest.msg.pose.speed_mm_s > 900
    assert set(latest.msg.sources) == {"uwb", "odometry"}
