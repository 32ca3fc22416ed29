"""UWB reader: the DWM1001 tag's ``lec`` stream as position fixes on the board.

Only a ``POS`` the tag itself reported becomes a fix; lines without one, garbage and partial
lines are counted and skipped. A silent stream (tag reset, stationary mode) gets a fresh
handshake; a port that fails (USB unplug) is reopened with backoff, by the serial-device
base (:mod:`coffeebot.modules.serial_device`), which also logs each outage once.
"""

from __future__ import annotations

from dataclasses import dataclass

from coffeebot.config import SerialPortConfig
from coffeebot.hardware.dwm1001 import Dwm1001, parse_lec
from coffeebot.hardware.serial_port import SerialPort, open_port
from coffeebot.hardware.worker import DeviceWorker
from coffeebot.messages import HEALTH, UWB_FIX, HealthStatus
from coffeebot.modules.base import ModuleContext
from coffeebot.modules.serial_device import LinkCounters, Opener, SerialDeviceModule


@dataclass
class UwbCounters(LinkCounters):
    lines: int = 0
    fixes: int = 0
    no_position: int = 0
    garbage: int = 0
    overflows: int = 0
    silences: int = 0
    connects: int = 0


class UwbReader(SerialDeviceModule[UwbCounters]):
    name = "uwb"
    device = "UWB tag"
    outputs = (UWB_FIX, HEALTH)

    def __init__(
        self,
        uwb: SerialPortConfig,
        *,
        read_timeout_s: float = 0.2,
        silence_s: float = 2.0,
        backoff_s: tuple[float, float] = (0.25, 8.0),
        opener: Opener = open_port,
    ) -> None:
        super().__init__(
            uwb, UwbCounters(), read_timeout_s=read_timeout_s, backoff_s=backoff_s, opener=opener
        )
        self.silence_s = silence_s

    async def talk(self, ctx: ModuleContext, port: SerialPort, io: DeviceWorker) -> str:
        """Reset the tag into one ``lec`` stream, then publish fixes until it goes silent."""
        tag = Dwm1001(port)
        try:
            await io.call(tag.start)
            self.counters.connects += 1
            self.connected(ctx, "tag streaming again", f"streaming lec on {self.port}")
            await self._stream(ctx, io, tag)
        finally:
            self.counters.overflows += tag.lines.overflows
        return f"no line from the tag for {self.silence_s:g} s"

    async def _stream(self, ctx: ModuleContext, worker: DeviceWorker, tag: Dwm1001) -> None:
        """Publish fixes until the stream stays silent for ``silence_s``."""
        last_line = ctx.clock.now()
        while True:
            line = await worker.call(tag.readline)
            if line is None:
                if ctx.clock.now() - last_line > self.silence_s:
                    self.counters.silences += 1
                    self.health(ctx, HealthStatus.DEGRADED, "stream silent, re-handshaking")
                    return
                continue
            last_line = ctx.clock.now()
            self.counters.lines += 1
            try:
                report = parse_lec(line)
            except ValueError:
                self.counters.garbage += 1
                continue
            if report.fix is None:
                self.counters.no_position += 1
            else:
                self.counters.fixes += 1
                ctx.board.publish(UWB_FIX, report.fix)

    def health_detail(self, detail: str) -> str:
        return f"{detail} ({self.counters.summary()})"
