"""What every module that owns one serial device does when the device goes away."""

from __future__ import annotations

from typing import ClassVar, Protocol

from coffeebot.logs import Event, Transitions
from coffeebot.messages import HEALTH, Health, HealthStatus
from coffeebot.modules.backoff import Backoff
from coffeebot.modules.base import Module, ModuleContext

CONNECTED, DISCONNECTED = "connected", "disconnected"


class _Counters(Protocol):
    failures: int


class SerialDeviceModule(Module):
    """A module reading and writing one serial port: outages are counted, logged once,
    reported on the health topic and retried with backoff."""

    device: ClassVar[str]
    """What is on the port, for log lines ("UWB tag", "motor controller")."""
    port: str
    counters: _Counters

    def health_detail(self, detail: str) -> str:
        """The health topic's detail line; modules may append their counters."""
        return detail

    def _health(self, ctx: ModuleContext, status: HealthStatus, detail: str) -> None:
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

    async def _failed(
        self, ctx: ModuleContext, exc: OSError, backoff: Backoff, link: Transitions
    ) -> None:
        self.counters.failures += 1
        delay = backoff.next_delay()
        link.update(self.port, DISCONNECTED, Event.DISCONNECT, str(exc))
        ctx.log.debug("%s on %s: %s; retry in %.2f s", self.device, self.port, exc, delay)
        self._health(ctx, HealthStatus.DEGRADED, f"{exc}; retry in {delay:.2f} s")
        await ctx.clock.sleep(delay)
