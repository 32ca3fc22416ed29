"""Running under systemd: the sd_notify protocol, the watchdog, and the service lifecycle.

The notify protocol is one datagram of ``KEY=value`` lines to the AF_UNIX socket named in
``NOTIFY_SOCKET`` (sd_notify(3)); it is spoken here directly rather than through a library.
Outside systemd ``NOTIFY_SOCKET`` is unset and every call is a no-op, so ``coffeebot sim`` and
the tests run the same code path.

The watchdog pings only while the control loop is healthy. "Healthy" is a
:data:`HealthCheck` (the safety topics keep arriving, see :func:`control_loop_check`) plus the
event loop keeping time: the pinging task runs on the event loop, so a blocked loop sends
nothing, and a loop that wakes the task far too late withholds the ping as well.
"""

from __future__ import annotations

import asyncio
import contextlib
import logging
import os
import socket
from collections.abc import Awaitable, Callable, Iterable, Mapping
from typing import Any

from coffeebot.board import Board, Topic
from coffeebot.clock import Clock, MonotonicClock
from coffeebot.daemon import Daemon
from coffeebot.logs import Event, log_event

log = logging.getLogger(__name__)

HealthCheck = Callable[[], str | None]
"""Returns why the control loop is unhealthy, or None while it is healthy."""

SelfCheck = Callable[[], Awaitable[str]]
"""Checks the hardware before the robot may move: a one-line summary, or raises."""


def _socket_address(name: str) -> str:
    """``@name`` is Linux's abstract namespace, spelled with a leading NUL byte."""
    return "\0" + name[1:] if name.startswith("@") else name


class Notifier:
    """Sends service state to systemd. Never raises: losing systemd must not stop the robot."""

    def __init__(self, address: str | None, watchdog_usec: int | None = None) -> None:
        self.address = address
        self.watchdog_interval_s = watchdog_usec / 2e6 if watchdog_usec else None
        """systemd's recommendation: ping at half the WatchdogSec= timeout."""
        self._socket: socket.socket | None = None
        self._send_failed = False
        if address:
            self._socket = socket.socket(socket.AF_UNIX, socket.SOCK_DGRAM | socket.SOCK_CLOEXEC)
            self._socket.setblocking(False)

    @classmethod
    def from_env(cls, environ: Mapping[str, str] | None = None) -> Notifier:
        """The notifier systemd asked for through ``NOTIFY_SOCKET`` and ``WATCHDOG_USEC``."""
        env = os.environ if environ is None else environ
        usec = env.get("WATCHDOG_USEC")
        pid = env.get("WATCHDOG_PID")
        # WATCHDOG_PID names the process the watchdog is meant for; a child that inherited the
        # environment must not ping on its parent's behalf.
        for_us = not pid or int(pid) == os.getpid()
        return cls(env.get("NOTIFY_SOCKET") or None, int(usec) if usec and for_us else None)

    @property
    def enabled(self) -> bool:
        return self._socket is not None

    def send(self, *assignments: str) -> bool:
        """Send ``KEY=value`` lines as one datagram; False if not under systemd or it failed."""
        if self._socket is None or self.address is None:
            return False
        try:
            self._socket.sendto("\n".join(assignments).encode(), _socket_address(self.address))
        except OSError as exc:
            if not self._send_failed:
                log.warning("cannot notify systemd at %s: %s", self.address, exc)
            self._send_failed = True
            return False
        self._send_failed = False
        return True

    def ready(self, status: str) -> bool:
        return self.send("READY=1", _status(status))

    def status(self, status: str) -> bool:
        return self.send(_status(status))

    def watchdog(self) -> bool:
        return self.send("WATCHDOG=1")

    def stopping(self, status: str) -> bool:
        return self.send("STOPPING=1", _status(status))

    def close(self) -> None:
        if self._socket is not None:
            self._socket.close()
            self._socket = None


def _status(text: str) -> str:
    return "STATUS=" + " ".join(text.split())


def control_loop_check(
    board: Board, topics: Iterable[Topic[Any] | str], max_age_s: float
) -> HealthCheck:
    """Healthy while every one of ``topics`` has a message younger than ``max_age_s``.

    The safety topic is the natural choice: the collision module publishes a verdict on every
    range scan, so its age covers the I2C poller, the collision module and the board at once.
    Ages are in the board clock's seconds. Unknown topics fail here, not in the watchdog.
    """
    names = [board.topic(t if isinstance(t, str) else t.name).name for t in topics]

    def check() -> str | None:
        for name in names:
            age = board.age(name)
            if age is None:
                return f"no message on {name} yet"
            if age > max_age_s:
                return f"{name} silent for {age:.2f} s (limit {max_age_s:g} s)"
        return None

    return check


class Watchdog:
    """Pings systemd's watchdog every ``interval_s`` while ``check`` passes and the loop keeps time.

    ``clock`` must tick in real seconds (systemd's watchdog does), which is why it is separate
    from the board clock that the simulator may speed up.
    """

    def __init__(
        self,
        notifier: Notifier,
        interval_s: float,
        check: HealthCheck,
        max_loop_lag_s: float,
        clock: Clock | None = None,
    ) -> None:
        self.notifier = notifier
        self.interval_s = interval_s
        self.check = check
        self.max_loop_lag_s = max_loop_lag_s
        self.clock: Clock = clock or MonotonicClock()
        self.pings = 0
        self.withheld = 0
        self._healthy = True

    def verdict(self, lag_s: float) -> str | None:
        """Why this tick must not ping, or None."""
        if lag_s > self.max_loop_lag_s:
            return f"event loop stalled: watchdog woke {lag_s:.2f} s late"
        return self.check()

    async def run(self) -> None:
        while True:
            due = self.clock.now() + self.interval_s
            await self.clock.sleep(self.interval_s)
            reason = self.verdict(self.clock.now() - due)
            if reason is None:
                if not self._healthy:
                    log_event(log, Event.RECOVERED, "control loop healthy, watchdog pings resume")
                    self.notifier.status("running")
                self.notifier.watchdog()
                self.pings += 1
            else:
                if self._healthy:
                    log_event(log, Event.FAULT, reason, watchdog="pings withheld")
                    self.notifier.status(f"unhealthy, watchdog pings withheld: {reason}")
                self.withheld += 1
            self._healthy = reason is None


async def run_as_service(
    daemon: Daemon,
    notifier: Notifier,
    check: HealthCheck,
    *,
    self_check: SelfCheck | None = None,
    max_loop_lag_s: float = 1.0,
    watchdog_clock: Clock | None = None,
) -> None:
    """Run ``daemon`` as a ``Type=notify`` service until a stop is requested.

    Order: STATUS (self-check), the self-check, the modules start, READY=1, watchdog pings
    while healthy, then STOPPING=1 before the ordered shutdown. A failing self-check raises
    before READY, so systemd sees a failed start and ``Restart=on-failure`` retries it.
    """
    notifier.status("hardware self-check")
    try:
        summary = await self_check() if self_check is not None else "no hardware self-check"
    except Exception as exc:
        notifier.status(f"hardware self-check failed: {exc}")
        raise
    await daemon.start()
    notifier.ready(f"running {len(daemon.modules)} modules; {summary}")
    watchdog_task: asyncio.Task[None] | None = None
    if notifier.watchdog_interval_s is not None:
        watchdog = Watchdog(
            notifier, notifier.watchdog_interval_s, check, max_loop_lag_s, watchdog_clock
        )
        watchdog_task = asyncio.create_task(watchdog.run(), name="systemd-watchdog")
    try:
        await daemon.wait_stop_requested()
    finally:
        notifier.stopping(f"stopping: {daemon.stop_reason or 'cancelled'}")
        if watchdog_task is not None:
            watchdog_task.cancel()
            with contextlib.suppress(asyncio.CancelledError):
                await watchdog_task
        await daemon.shutdown()
