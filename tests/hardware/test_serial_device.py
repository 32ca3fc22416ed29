"""The serial-device base: a subclass that only talks gets opening, backoff, health and the
once-per-outage log lines from it."""

from __future__ import annotations

import asyncio
import logging
from dataclasses import dataclass

import pytest

from coffeebot.board import Board
from coffeebot.config import SerialPortConfig
from coffeebot.hardware.serial_port import SerialPort
from coffeebot.hardware.worker import DeviceWorker
from coffeebot.messages import ALL_TOPICS, HEALTH, HealthStatus
from coffeebot.modules.base import ModuleBoard, ModuleContext
from coffeebot.modules.serial_device import LinkCounters, SerialDeviceModule
from logged import causes


class NoPort:
    """Stands in for an open port; the device under test never reads it."""

    in_waiting = 0

    def read(self, size: int = 1) -> bytes:
        return b""

    def write(self, data: bytes, /) -> int | None:
        return len(data)

    def reset_input_buffer(self) -> None: ...

    def close(self) -> None: ...


@dataclass
class TalkCounters(LinkCounters):
    sessions: int = 0


class Talker(SerialDeviceModule[TalkCounters]):
    """The port fails to open ``unplugged`` times; then the first session goes quiet at
    once and the second lasts."""

    name = "talker"
    device = "test device"
    outputs = (HEALTH,)

    def __init__(self, unplugged: int) -> None:
        super().__init__(
            SerialPortConfig(port="test://talker"),
            TalkCounters(),
            read_timeout_s=0.01,
            backoff_s=(0.001, 0.004),
            opener=self._open,
        )
        self.unplugged = unplugged

    def _open(self, url: str, baudrate: int, timeout_s: float) -> SerialPort:
        if self.unplugged:
            self.unplugged -= 1
            raise FileNotFoundError(f"no such port {url}")
        return NoPort()

    async def talk(self, ctx: ModuleContext, port: SerialPort, io: DeviceWorker) -> str:
        self.counters.sessions += 1
        self.connected(ctx, "talking again", "talking")
        if self.counters.sessions > 1:
            await asyncio.Event().wait()  # the second session lasts until the test ends
        return "went quiet"


async def test_outages_are_retried_reported_and_logged_once(
    caplog: pytest.LogCaptureFixture,
) -> None:
    caplog.set_level(logging.INFO)
    board = Board(ALL_TOPICS)
    device = Talker(unplugged=3)
    ctx = ModuleContext(ModuleBoard(board, device), board.clock, logging.getLogger("talker"))
    with board.subscribe(HEALTH) as health:
        task = asyncio.create_task(device.run(ctx))
        try:
            async with asyncio.timeout(5):
                while device.counters.sessions < 2:
                    await asyncio.sleep(0.001)
        finally:
            task.cancel()
            await asyncio.gather(task, return_exceptions=True)
        reports = [m.msg for m in iter(health.get_nowait, None)]
    assert device.counters.failures == 3
    # Three failed opens are one outage; the first session's end is another.
    assert causes(caplog, "disconnect") == ["no such port test://talker", "went quiet"]
    assert causes(caplog, "reconnect") == ["talking again", "talking again"]
    statuses = [r.status for r in reports]
    assert statuses == [HealthStatus.DEGRADED] * 3 + [HealthStatus.RUNNING] * 2
    assert reports[-1].component == "test://talker" and reports[-1].restarts == 3
