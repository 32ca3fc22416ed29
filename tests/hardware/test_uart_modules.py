"""UWB reader and motor driver modules against simulated devices on ptys (real time, short
timeouts; assertions wait for outcomes, never for durations)."""

from __future__ import annotations

import asyncio
import contextlib
import logging
from collections.abc import AsyncIterator, Callable
from typing import Any

import pytest
from pydantic import ValidationError

from coffeebot.board import Board
from coffeebot.clock import Clock, MonotonicClock
from coffeebot.config import MotorConfig, SerialPortConfig
from coffeebot.messages import (
    ALL_TOPICS,
    HEALTH,
    MOTOR_COMMAND,
    ODOMETRY,
    UWB_FIX,
    HealthStatus,
    MotorCommand,
)
from coffeebot.modules.base import Module, ModuleContext
from coffeebot.modules.motor_driver import COMMANDS, MotorDriver
from coffeebot.modules.uwb_reader import UwbReader
from coffeebot.sim.dwm1001 import SimDwm1001
from coffeebot.sim.motor_controller import SimMotorController
from logged import causes, events

ContextFor = Callable[[Board, Module, Clock], ModuleContext]
FAST_BACKOFF = (0.02, 0.1)


@contextlib.asynccontextmanager
async def running(module: Module, context_for: ContextFor) -> AsyncIterator[Board]:
    board = Board(ALL_TOPICS, clock=MonotonicClock())
    task = asyncio.create_task(module.run(context_for(board, module, board.clock)))
    try:
        yield board
    finally:
        await module.shutdown()
        task.cancel()
        with contextlib.suppress(asyncio.CancelledError):
            await task


async def until(predicate: Callable[[], Any], timeout_s: float = 5.0) -> None:
    """Wait for a condition the module must reach; the timeout only bounds a failing test."""
    async with asyncio.timeout(timeout_s):
        while not predicate():
            await asyncio.sleep(0.005)


def uwb_reader(sim: SimDwm1001) -> UwbReader:
    return UwbReader(
        SerialPortConfig(port=sim.port),
        read_timeout_s=0.02,
        silence_s=0.2,
        backoff_s=FAST_BACKOFF,
    )


async def test_uwb_publishes_fixes(sim_dwm: SimDwm1001, context_for: ContextFor) -> None:
    reader = uwb_reader(sim_dwm)
    async with running(reader, context_for) as board:
        fix = (await board.next(UWB_FIX, timeout=5.0)).msg
    assert (fix.x_mm, fix.y_mm, fix.quality) == (1500.0, 850.0, 80)
    assert len(fix.anchors) == 4


async def test_uwb_garbage_and_missing_pos_are_counted_never_published(
    sim_dwm: SimDwm1001, context_for: ContextFor
) -> None:
    reader = uwb_reader(sim_dwm)
    async with running(reader, context_for) as board:
        await board.next(UWB_FIX, timeout=5.0)
        sim_dwm.inject(b"\r\n\x00garbage\xff\r\nDIST,4,AN0,02")
        await until(lambda: reader.counters.garbage >= 2)
        sim_dwm.drop_pos = True
        await until(lambda: reader.counters.no_position >= 1)
        last = board.latest(UWB_FIX)
        await until(lambda: reader.counters.no_position >= 5)
        assert board.latest(UWB_FIX) is last  # no position invented for POS-less lines


async def test_uwb_recovers_from_tag_reset(
    sim_dwm: SimDwm1001, context_for: ContextFor, caplog: pytest.LogCaptureFixture
) -> None:
    caplog.set_level(logging.INFO)
    reader = uwb_reader(sim_dwm)
    async with running(reader, context_for) as board:
        await board.next(UWB_FIX, timeout=5.0)
        sim_dwm.reset()
        await until(lambda: reader.counters.silences == 1 and reader.counters.connects == 2)
        await board.next(UWB_FIX, timeout=5.0)
    assert sim_dwm.resets >= 3  # ours at each connect, plus the injected one
    assert causes(caplog, "disconnect") == ["no line from the tag for 0.2 s"]
    assert causes(caplog, "reconnect") == ["tag streaming again"]


async def test_uwb_reconnects_after_unplug(
    sim_dwm: SimDwm1001, context_for: ContextFor, caplog: pytest.LogCaptureFixture
) -> None:
    caplog.set_level(logging.INFO)
    reader = uwb_reader(sim_dwm)
    async with running(reader, context_for) as board:
        await board.next(UWB_FIX, timeout=5.0)
        assert events(caplog, "reconnect") == []  # the first connection is no reconnect
        with board.subscribe(HEALTH) as health:
            sim_dwm.unplug()
            degraded = await health.get()
            assert degraded.msg.status is HealthStatus.DEGRADED
            await until(lambda: reader.counters.failures >= 2)  # still unplugged: backing off
            sim_dwm.replug()
            await until(lambda: reader.counters.connects == 2)
        await board.next(UWB_FIX, timeout=5.0)
    # Every failed retry while unplugged is one outage: logged when it began and when it ended.
    [lost] = events(caplog, "disconnect")
    assert lost.subject == sim_dwm.port and lost.cause
    assert causes(caplog, "reconnect") == ["tag streaming again"]


@pytest.fixture
def motor_driver(sim_motor: SimMotorController) -> MotorDriver:
    return MotorDriver(
        MotorConfig(port=sim_motor.port), read_timeout_s=0.02, backoff_s=FAST_BACKOFF
    )


async def test_motor_commands_reach_controller_and_odometry_comes_back(
    sim_motor: SimMotorController, motor_driver: MotorDriver, context_for: ContextFor
) -> None:
    async with running(motor_driver, context_for) as board:
        await board.next(ODOMETRY, timeout=5.0)
        for _ in range(100):
            board.publish(MOTOR_COMMAND, MotorCommand(left_mm_s=150, right_mm_s=150))
            odo = (await board.next(ODOMETRY, timeout=5.0)).msg
            if odo.left_mm_s == 150:
                break
        assert odo.right_mm_s == 150 and not odo.watchdog_tripped
    assert sim_motor.commands[-1].kind == "S"  # shutdown sent a stop
    assert sim_motor.setpoint == (0, 0)


async def test_a_braking_command_is_the_controllers_stop_line(
    sim_motor: SimMotorController, motor_driver: MotorDriver, context_for: ContextFor
) -> None:
    async with running(motor_driver, context_for) as board:
        await board.next(ODOMETRY, timeout=5.0)
        board.publish(MOTOR_COMMAND, MotorCommand(left_mm_s=200, right_mm_s=200))
        await until(lambda: sim_motor.setpoint == (200, 200))
        board.publish(MOTOR_COMMAND, MotorCommand(left_mm_s=0, right_mm_s=0))
        await until(lambda: sim_motor.commands[-1].kind == "V" and sim_motor.setpoint == (0, 0))
        board.publish(MOTOR_COMMAND, MotorCommand(left_mm_s=0, right_mm_s=0, brake=True))
        await until(lambda: sim_motor.commands[-1].kind == "S")
        assert motor_driver.counters.stale_stops == 0


def test_only_a_standing_command_may_brake() -> None:
    with pytest.raises(ValidationError, match="both wheel speeds to 0"):
        MotorCommand(left_mm_s=0, right_mm_s=100, brake=True)


async def test_stale_command_becomes_stop(
    sim_motor: SimMotorController,
    motor_driver: MotorDriver,
    context_for: ContextFor,
    caplog: pytest.LogCaptureFixture,
) -> None:
    caplog.set_level(logging.INFO)
    async with running(motor_driver, context_for) as board:
        reports = board.subscribe(HEALTH)
        await board.next(ODOMETRY, timeout=5.0)
        board.publish(MOTOR_COMMAND, MotorCommand(left_mm_s=200, right_mm_s=200))
        await until(lambda: sim_motor.setpoint == (200, 200))
        # Nobody publishes any more: the module stops the motors itself, keeps the
        # controller fed (no watchdog trip) and counts the stops.
        await until(lambda: sim_motor.setpoint == (0, 0) and motor_driver.counters.stale_stops)
        assert sim_motor.watchdog_trips == 0
        await until(lambda: motor_driver.counters.stale_stops >= 3)
        assert causes(caplog, "safety_stop") == ["no motor command for 0.25 s: motors stopped"]
        board.publish(MOTOR_COMMAND, MotorCommand(left_mm_s=100, right_mm_s=100))
        await until(lambda: sim_motor.setpoint == (100, 100))
        board.publish(MOTOR_COMMAND, MotorCommand(left_mm_s=0, right_mm_s=0))
        stale = motor_driver.counters.stale_stops
        await until(lambda: motor_driver.counters.stale_stops >= stale + 3)
        said = []
        while (report := reports.get_nowait()) is not None:
            if report.msg.component == COMMANDS:
                said.append((report.msg.status, report.msg.detail))
    # A stop that is not renewed leaves the robot standing: no second safety stop, only the
    # shutdown's own, which says that it got out.
    assert causes(caplog, "safety_stop") == [
        "no motor command for 0.25 s: motors stopped",
        "shutdown: motors stopped",
    ]
    # The stop is on the health topic too, where run reports and the operator's alerts see it.
    assert said == [
        (HealthStatus.DEGRADED, "no motor command for 0.25 s: motors stopped"),
        (HealthStatus.RUNNING, "motor commands resumed"),
    ]
    assert causes(caplog, "safety_clear") == ["motor commands resumed"]


async def test_shutdown_without_a_controller_says_what_stops_the_motors(
    sim_motor: SimMotorController,
    motor_driver: MotorDriver,
    context_for: ContextFor,
    caplog: pytest.LogCaptureFixture,
) -> None:
    caplog.set_level(logging.INFO)
    async with running(motor_driver, context_for) as board:
        await board.next(ODOMETRY, timeout=5.0)
        sim_motor.unplug()
        await until(lambda: motor_driver.counters.failures >= 1)
    assert causes(caplog, "safety_stop") == []
    assert any(
        r.getMessage() == "shutdown: no motor controller connected to stop; "
        "the controller's 200 ms watchdog stops the motors"
        for r in caplog.records
    )


async def test_silent_controller_is_reported_failed_and_its_recovery_logged(
    sim_motor: SimMotorController,
    context_for: ContextFor,
    caplog: pytest.LogCaptureFixture,
) -> None:
    caplog.set_level(logging.INFO)
    driver = MotorDriver(
        MotorConfig(port=sim_motor.port, telemetry_timeout_s=0.1),
        read_timeout_s=0.02,
        backoff_s=FAST_BACKOFF,
    )
    async with running(driver, context_for) as board:
        await board.next(ODOMETRY, timeout=5.0)
        # The timeout only bounds a failing test.
        async with asyncio.timeout(5.0):
            with board.subscribe(HEALTH) as health:
                sim_motor.silent = True  # hung firmware: the port stays open, nothing comes
                failed = (await health.get()).msg
                assert failed.status is HealthStatus.FAILED
                assert failed.detail.startswith("no telemetry from the motor controller for 0.1 s")
                sim_motor.silent = False
                assert (await health.get()).msg.status is HealthStatus.RUNNING
    assert driver.counters.silences == 1
    [silent] = events(caplog, "fault")
    assert silent.subject == sim_motor.port
    assert silent.cause == "no telemetry from the motor controller for 0.1 s"
    [back] = causes(caplog, "reconnect")
    assert back.startswith("telemetry resumed after ") and back.endswith(" s of silence")


async def test_motor_survives_garbage_reset_and_unplug(
    sim_motor: SimMotorController,
    motor_driver: MotorDriver,
    context_for: ContextFor,
    caplog: pytest.LogCaptureFixture,
) -> None:
    caplog.set_level(logging.INFO)
    async with running(motor_driver, context_for) as board:
        await board.next(ODOMETRY, timeout=5.0)
        sim_motor.inject(b"T,1,2,3*00\n\xff\xfe\x00\n")
        await until(lambda: motor_driver.counters.garbage >= 2)
        sim_motor.reset()
        await until(lambda: motor_driver.counters.controller_boots >= 1)
        telemetry = motor_driver.counters.telemetry
        await until(lambda: motor_driver.counters.telemetry > telemetry + 3)
        [reset] = events(caplog, "fault")
        assert reset.subject == sim_motor.port and "reset while running" in reset.cause
        sim_motor.unplug()
        await until(lambda: motor_driver.counters.failures >= 2)  # retries back off
        sim_motor.replug()
        telemetry = motor_driver.counters.telemetry
        await until(lambda: motor_driver.counters.telemetry > telemetry + 3)
        [lost] = events(caplog, "disconnect")
        assert lost.subject == sim_motor.port and lost.cause
        # Back after the reset, then after the unplug: once each.
        assert causes(caplog, "reconnect") == ["telemetry resumed", "telemetry resumed"]
        board.publish(MOTOR_COMMAND, MotorCommand(left_mm_s=50, right_mm_s=60))
        await until(lambda: sim_motor.setpoint == (50, 60))
