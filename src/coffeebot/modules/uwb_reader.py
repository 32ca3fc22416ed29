"""UWB reader: the DWM1001 tag's ``lec`` stream as position fixes on the board.

Only a ``POS`` the tag itself reported becomes a fix; lines without one, garbage and partial
lines are counted and skipped. A silent stream (tag reset, stationary mode) gets a fresh
handshake; a port that fails (USB unplug) is reopened with backoff. Each outage is logged
once as ``event=disconnect`` with its cause and once as ``event=reconnect`` when the tag
streams again, however many retries it took.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import asdict, dataclass

from coffeebot.config import SerialPortConfig
from coffeebot.hardware.dwm1001 import Dwm1001, parse_lec
from coffeebot.hardware.serial_port import SerialPort, open_port
from coffeebot.hardware.worker import DeviceWorker
from coffeebot.logs import Event, Transitions
from coffeebot.messages import HEALTH, UWB_FIX, HealthStatus
from coffeebot.modules.backoff import Backoff
from coffeebot.modules.base import ModuleContext
from coffeebot.modules.serial_device import CONNECTED, DISCONNECTED, SerialDeviceModule


@dataclass
class UwbCounters:
    lines: int = 0
    fixes: int = 0
    no_position: int = 0
    garbage: int = 0
    overflows: int = 0
    silences: int = 0
    connects: int = 0
    failures: int = 0

    def summary(self) -> str:
        return " ".join(f"{k}={v}" for k, v in asdict(self).items())


class UwbReader(SerialDeviceModule):
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
        opener: Callable[[str, int, float], SerialPort] = open_port,
    ) -> None:
        self.uwb = uwb
        self.port = uwb.port
        self.read_timeout_s = read_timeout_s
        self.silence_s = silence_s
        self.backoff_s = backoff_s
        self.opener = opener
        self.counters = UwbCounters()

    async def run(self, ctx: ModuleContext) -> None:
        worker = DeviceWorker("uwb")
        backoff = Backoff(*self.backoff_s)
        link = Transitions(ctx.log, initial={self.uwb.port: CONNECTED})
        try:
            while True:
                try:
                    port = await worker.call(
                        self.opener, self.uwb.port, self.uwb.baudrate, self.read_timeout_s
                    )
                except OSError as exc:
                    await self._failed(ctx, exc, backoff, link)
                    continue
                tag = Dwm1001(port)
                try:
                    await worker.call(tag.start)
                    self.counters.connects += 1
                    backoff.reset()
                    link.update(self.uwb.port, CONNECTED, Event.RECONNECT, "tag streaming again")
                    self._health(ctx, HealthStatus.RUNNING, f"streaming lec on {self.uwb.port}")
                    await self._stream(ctx, worker, tag)
                    link.update(
                        self.uwb.port,
                        DISCONNECTED,
                        Event.DISCONNECT,
                        f"no line from the tag for {self.silence_s:g} s",
                    )
                except OSError as exc:
                    await self._failed(ctx, exc, backoff, link)
                finally:
                    self.counters.overflows += tag.lines.overflows
                    await worker.call(port.close)
        finally:
            worker.close()

    async def _stream(self, ctx: ModuleContext, worker: DeviceWorker, tag: Dwm1001) -> None:
        """Publish fixes until the stream stays silent for ``silence_s``."""
        last_line = ctx.clock.now()
        while True:
            line = await worker.call(tag.readline)
            if line is None:
                if ctx.clock.now() - last_line > self.silence_s:
                    self.counters.silences += 1
                    self._health(ctx, HealthStatus.DEGRADED, "stream silent, re-handshaking")
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
