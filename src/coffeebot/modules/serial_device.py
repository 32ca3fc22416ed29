"""One serial device behind a board task: the connection loop every such module shares.

In the manner of python-can's ``BusABC.recv`` over ``_recv_internal``: :meth:`run` owns the
connection (open the port by URL in the port's worker thread, close it, back off after a
failure, the health topic and the log lines) and subclasses implement only the talking,
:meth:`SerialDeviceModule.talk`, which handshakes and exchanges lines until the device goes
quiet (it returns why) or fails (an ``OSError``). A subclass calls :meth:`connected` once
the device really talks, which is when the backoff starts afresh and the outage, if any, is
logged as over. Each outage is logged once as ``event=disconnect`` with its cause and once as
``event=reconnect``, however many retries it took.
"""

from __future__ import annotations

import dataclasses
from abc import abstractmethod
from collections.abc import Callable
from dataclasses import dataclass
from typing import ClassVar, Generic, TypeVar

from coffeebot.config import SerialPortConfig
from coffeebot.hardware.serial_port import SerialPort, open_port
from coffeebot.hardware.worker import DeviceWorker
from coffeebot.logs import Event, Transitions
from coffeebot.messages import HEALTH, Health, HealthStatus
from coffeebot.modules.backoff import Backoff
from coffeebot.modules.base import Module, ModuleContext

CONNECTED, DISCONNECTED = "connected", "disconnected"

Opener = Callable[[str, int, float], SerialPort]
"""Opens a port by URL, baud rate and read timeout (``open_port``; tests pass their own)."""


@dataclass
class LinkCounters:
    """What every serial device counts; each device's counters add their own fields."""

    failures: int = 0
    """Ports that could not be opened or failed while talking."""

    def summary(self) -> str:
        return " ".join(f"{k}={v}" for k, v in dataclasses.asdict(self).items())


C = TypeVar("C", bound=LinkCounters)


class SerialDeviceModule(Module, Generic[C]):
    """A module owning one serial port: outages are counted, logged once, reported on the
    health topic and retried with backoff."""

    device: ClassVar[str]
    """What is on the port, for log lines ("UWB tag", "motor controller")."""

    def __init__(
        self,
        port: SerialPortConfig,
        counters: C,
        *,
        read_timeout_s: float,
        backoff_s: tuple[float, float],
        opener: Opener = open_port,
    ) -> None:
        self.port = port.port
        self.baudrate = port.baudrate
        self.counters = counters
        self.read_timeout_s = read_timeout_s
        self.backoff_s = backoff_s
        self.opener = opener
        self._backoff = Backoff(*backoff_s)
        self._link: Transitions | None = None

    @abstractmethod
    async def talk(self, ctx: ModuleContext, port: SerialPort, io: DeviceWorker) -> str:
        """Handshake and exchange with the device on the open ``port`` (blocking calls go
        through ``io``, the port's worker thread). Return why the device went quiet, or raise
        ``OSError`` when it fails; call :meth:`connected` once it really talks."""

    def health_detail(self, detail: str) -> str:
        """The health topic's detail line; a device may append its counters."""
        return detail

    async def run(self, ctx: ModuleContext) -> None:
        io = DeviceWorker(self.name, ctx.clock)
        self._backoff = Backoff(*self.backoff_s)
        self._link = Transitions(ctx.log, initial={self.port: CONNECTED})
        try:
            while True:
                try:
                    port = await io.call(self.opener, self.port, self.baudrate, self.read_timeout_s)
                except OSError as exc:
                    await self._failed(ctx, exc)
                    continue
                try:
                    quiet = await self.talk(ctx, port, io)
                    self._link.update(self.port, DISCONNECTED, Event.DISCONNECT, quiet)
                except OSError as exc:
                    await self._failed(ctx, exc)
                finally:
                    await io.call(port.close)
        finally:
            io.close()

    def connected(self, ctx: ModuleContext, cause: str, detail: str) -> None:
        """The device talks: the backoff starts afresh, an outage is logged as over with
        ``cause``, and the health topic says ``running`` with ``detail``."""
        self._backoff.reset()
        self.link(CONNECTED, Event.RECONNECT, cause)
        self.health(ctx, HealthStatus.RUNNING, detail)

    def link(self, state: str, event: Event, cause: str) -> None:
        """Log the link's ``state`` once, when it changes (a controller reset, for one)."""
        assert self._link is not None, "only called from run()"
        self._link.update(self.port, state, event, cause)

    def health(self, ctx: ModuleContext, status: HealthStatus, detail: str) -> None:
        ctx.board.publish(
            HEALTH,
            Health(
                module=self.name,
                component=self.port,
                status=status,
                restarts=self.counters.failures,
                detail=self.health_detail(detail),
            ),
        )

    async def _failed(self, ctx: ModuleContext, exc: OSError) -> None:
        self.counters.failures += 1
        delay = self._backoff.next_delay()
        self.link(DISCONNECTED, Event.DISCONNECT, str(exc))
        ctx.log.debug("%s on %s: %s; retry in %.2f s", self.device, self.port, exc, delay)
        self.health(ctx, HealthStatus.DEGRADED, f"{exc}; retry in {delay:.2f} s")
        await ctx.clock.sleep(delay)
