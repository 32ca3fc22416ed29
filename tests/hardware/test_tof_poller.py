"""The ToF poller module on the simulated bus: scans, rate, per-sensor faults and recovery."""

from __future__ import annotations

import asyncio
import errno
import itertools
import logging
from collections.abc import AsyncIterator, Callable

import pytest

from coffeebot.board import Board, Envelope
from coffeebot.clock import Clock
from coffeebot.config import I2CConfig, TofConfig, TofSensorConfig
from coffeebot.messages import (
    ALL_TOPICS,
    HEALTH,
    RANGE_SCAN,
    HealthStatus,
    RangeScan,
    ReadingStatus,
)
from coffeebot.modules.base import Module, ModuleContext
from coffeebot.modules.tof_poller import TofPoller
from coffeebot.sim.clock import SteppedClock
from coffeebot.sim.i2c import SimTofHardware, make_tof_hardware, targets_at
from logged import events

ContextFor = Callable[[Board, Module, Clock], ModuleContext]


def tof_config(rate_hz: float | None = 25.0) -> TofConfig:
    return TofConfig(
        scan_rate_hz=rate_hz,
        sensors=[
            TofSensorConfig(id=i, channel=7 - i, face="front", x_mm=0, y_mm=0, yaw_deg=0)
            for i in range(8)
        ],
    )


@pytest.fixture
def hw(stepped_clock: SteppedClock) -> SimTofHardware:
    return make_tof_hardware(targets_at(lambda ch: 1000.0 + ch), clock=stepped_clock.now)


@pytest.fixture
async def board(
    hw: SimTofHardware, stepped_clock: SteppedClock, context_for: ContextFor
) -> AsyncIterator[Board]:
    board = Board(ALL_TOPICS, clock=stepped_clock)
    poller = TofPoller(
        I2CConfig(), tof_config(), lambda: hw.bus, blocking_sleep=stepped_clock.advance
    )
    task = asyncio.create_task(poller.run(context_for(board, poller, stepped_clock)))
    yield board
    task.cancel()
    with pytest.raises(asyncio.CancelledError):
        await task


async def scans(board: Board, n: int) -> list[RangeScan]:
    out = []
    with board.subscribe(RANGE_SCAN) as sub:
        async for env in sub:
            out.append(env.msg)
            if len(out) == n:
                return out
    raise AssertionError("subscription ended")


def by_sensor(scan: RangeScan) -> dict[int, tuple[ReadingStatus, int | None]]:
    return {r.sensor: (r.status, r.distance_mm) for r in scan.readings}


async def test_scans_carry_every_sensor(board: Board) -> None:
    *_, scan = await scans(board, 3)
    # sensor i sits on channel 7 - i, and the world puts channel c at 1000 + c mm
    assert by_sensor(scan) == {i: (ReadingStatus.VALID, 1007 - i) for i in range(8)}


async def test_rate_holds_while_one_sensor_nacks(board: Board, hw: SimTofHardware) -> None:
    await scans(board, 2)
    hw.sensors[7 - 3].nack = True
    got = await scans(board, 20)
    starts = [s.cycle_start_s for s in got]
    periods = [b - a for a, b in itertools.pairwise(starts)]
    assert min(periods) >= 0.04 - 1e-9
    assert sum(periods) / len(periods) <= 0.04 * 1.05  # 25 Hz, in simulated time
    for scan in got[1:]:
        readings = by_sensor(scan)
        assert readings.pop(3) == (ReadingStatus.BUS_ERROR, None)
        assert all(status is ReadingStatus.VALID for status, _ in readings.values())
    assert not got[-1].readings[3].healthy


async def test_failed_sensor_is_reported_and_recovers(
    board: Board, hw: SimTofHardware, caplog: pytest.LogCaptureFixture
) -> None:
    caplog.set_level(logging.INFO)
    await scans(board, 2)
    assert events(caplog, "fault") == events(caplog, "recovered") == []  # a normal start
    with board.subscribe(HEALTH) as health:
        hw.sensors[7 - 5].nack = True
        degraded: Envelope = await health.get()
        assert degraded.msg.component == "tof5"
        assert degraded.msg.status is HealthStatus.DEGRADED
        assert f"[Errno {errno.EREMOTEIO}]" in degraded.msg.detail
        await scans(board, 30)  # retries fail and back off meanwhile
        hw.sensors[7 - 5].nack = False
        while (env := await health.get()).msg.status is not HealthStatus.RUNNING:
            pass
        assert env.msg.component == "tof5" and env.msg.restarts >= 2
    *_, scan = await scans(board, 3)
    assert by_sensor(scan)[5] == (ReadingStatus.VALID, 1002)
    # However many retries failed, one line when it failed and one when it came back.
    [fault] = events(caplog, "fault")
    assert fault.subject == "tof5" and f"[Errno {errno.EREMOTEIO}]" in fault.cause
    [recovered] = events(caplog, "recovered")
    assert recovered.subject == "tof5" and recovered.cause == "re-initialised"


async def test_status_errors_and_bus_timeout(board: Board, hw: SimTofHardware) -> None:
    await scans(board, 2)
    hw.sensors[7 - 1].forced_status = 6  # sigma fail
    *_, scan = await scans(board, 2)
    assert scan.readings[1].status is ReadingStatus.SIGMA_FAIL
    assert scan.readings[1].distance_mm is None and scan.readings[1].healthy
    hw.bus.timeout = True
    scan, *_ = await scans(board, 2)
    assert {r.status for r in scan.readings} == {ReadingStatus.BUS_ERROR}
    hw.bus.timeout = False
    for _ in range(200):
        (scan,) = await scans(board, 1)
        if all(r.healthy for r in scan.readings):
            break
    assert all(r.healthy for r in scan.readings)


async def test_sensor_not_ready_in_time(board: Board, hw: SimTofHardware) -> None:
    await scans(board, 2)
    hw.sensors[7 - 6].halt()
    *_, scan = await scans(board, 2)
    assert scan.readings[6].status is ReadingStatus.NOT_READY


async def test_a_sensor_that_stopped_ranging_is_reinitialised(
    board: Board, hw: SimTofHardware, caplog: pytest.LogCaptureFixture
) -> None:
    """A sensor that answers but never has a new sample (it stopped ranging, as after a
    brown-out) is a fault the operator hears of, and it is re-initialised: nothing else
    starts it again."""
    caplog.set_level(logging.INFO)
    await scans(board, 2)
    hw.sensors[7 - 6].halt()
    got = await scans(board, 40)  # 1.6 s at 25 Hz
    assert any(s.readings[6].status is ReadingStatus.BUS_ERROR for s in got)
    assert by_sensor(got[-1])[6] == (ReadingStatus.VALID, 1001)
    # Its re-initialisation never held the bus: no cycle longer than one waiting out a late
    # sample (two sample periods). A stall makes every collision verdict late, and motion
    # then holds the robot for that instead of for the sensor.
    starts = [s.cycle_start_s for s in got]
    assert max(b - a for a, b in itertools.pairwise(starts)) <= 2 * 0.04 + 1e-9
    [fault] = events(caplog, "fault")
    assert fault.subject == "tof6" and "stopped ranging" in fault.cause
    [recovered] = events(caplog, "recovered")
    assert recovered.subject == "tof6"
