"""A simulated fleet's broker traffic in step with the simulated clock, so a fleet run depends
on its seed alone, as a single robot's does.

The daemons of a simulated fleet share one process, one event loop and one
:class:`~coffeebot.clock.SteppedClock`, and the world steps only once they have settled
(:mod:`coffeebot.lockstep`). Their messages go through a real Mosquitto, and a message on the
wire leaves the event loop with nothing to run: without more, the world would step on while
it travels, and where a robot stood when its order or its lease came would depend on how
busy the machine was. So every connection of a simulated fleet is a :class:`SteppedClient`,
and before the world steps, :meth:`MessagesInStep.drain` waits until nothing is on the wire:

- every call waiting for the broker's answer (connecting, subscribing, a QoS 1 message's
  acknowledgement) has it;
- every message published since the last step has reached every connection subscribed to
  it. Each connection that published sends a *step marker* after its messages, and the
  broker passes one client's messages to each subscriber in the order it received them; a
  connection that has every marker has everything sent before them.

That a message arrives within its step is not enough: *when* within the step, before or
after the daemons' other work of that step, and in which order messages of different senders
reach one connection, would still follow the machine's timing (a seed-2 run of the fleet
benchmark and its repeat parted at 136 s, a lease request logged one step apart). So while
the world steps, a stepped connection holds what it receives, and the drain hands it over
only once everything is in: connection by connection in a fixed order, each connection's
messages grouped by their publisher (:func:`~coffeebot.fleet.protocol.publisher`) in the
order that publisher sent them.

The daemons' reactions to what arrived are settled before the clock moves, and may send
more, drained in turn. A robot on its own Pi has none of this: its clock is the machine's.
"""

from __future__ import annotations

import asyncio
import itertools
import logging
import time
import weakref
from collections.abc import Callable
from types import TracebackType
from typing import Any, Self

import paho.mqtt.client as paho

from coffeebot.clock import Clock, SteppedClock
from coffeebot.fleet.cancellable import CancellableClient
from coffeebot.fleet.protocol import ROOT, publisher

log = logging.getLogger(__name__)

STEP_TOPIC = f"{ROOT}/step"
"""Markers go out on ``step/<user>``; every stepped connection reads ``step/#``."""
PATIENCE_S = 10.0
"""Machine seconds a drain waits for the broker before the world steps on anyway (logged):
a broker that was killed answers nothing, and the robots must go on without it."""


class MessagesInStep:
    """The stepped connections of one simulated process, and the drain the world awaits
    (:class:`~coffeebot.lockstep.OutsideTraffic`)."""

    def __init__(self, engaged: Callable[[], bool]) -> None:
        self.engaged = engaged
        """While true, what a connection receives is held for the drain."""
        self._clients: list[SteppedClient] = []
        self._changed = asyncio.Event()
        self._markers = itertools.count(1)

    def join(self, client: SteppedClient) -> None:
        self._clients.append(client)
        self.changed()

    def leave(self, client: SteppedClient) -> None:
        if client in self._clients:
            self._clients.remove(client)
        client.hand_over()
        self.changed()

    def changed(self) -> None:
        self._changed.set()

    async def drain(self) -> bool:
        """Wait until nothing is on the wire, then hand over what arrived; True if anything
        was sent or arrived (the daemons may have something new to do)."""
        if any(client.awaiting for client in self._clients):
            await self._until(lambda: not any(c.awaiting for c in self._clients), "answers")
            return True
        senders = [client for client in self._clients if client.sent and client.linked]
        if senders:
            expected = {
                client.identifier: client.send_marker(next(self._markers)) for client in senders
            }
            await self._until(
                lambda: all(c.has_markers(expected) for c in self._clients if c.linked),
                "markers",
            )
        return self.let_through() or bool(senders)

    def let_through(self) -> bool:
        """Hand every connection what it holds, in a fixed order; True if any held some."""
        handed = False
        for client in sorted(self._clients, key=lambda c: (c.user, c.identifier)):
            handed = client.hand_over() or handed
        return handed

    async def _until(self, done: Callable[[], bool], what: str) -> None:
        deadline = time.monotonic() + PATIENCE_S
        while not done():
            self._changed.clear()
            left = deadline - time.monotonic()
            if left <= 0:
                log.warning(
                    "simulated time goes on without the broker's %s (%.0f s of machine time)",
                    what,
                    PATIENCE_S,
                )
                for client in self._clients:
                    client.sent = False
                return
            try:
                async with asyncio.timeout(left):
                    await self._changed.wait()
            except TimeoutError:
                continue


_IN_STEP: weakref.WeakKeyDictionary[SteppedClock, MessagesInStep] = weakref.WeakKeyDictionary()


def messages_in_step(clock: Clock) -> MessagesInStep | None:
    """The stepped traffic of the simulated process ``clock`` belongs to; None on the
    machine's clock (a real robot, a real dispatcher)."""
    if not isinstance(clock, SteppedClock):
        return None
    stepped = _IN_STEP.get(clock)
    if stepped is None:
        lockstep = clock.lockstep
        stepped = _IN_STEP[clock] = MessagesInStep(lambda: lockstep.engaged)
        lockstep.outside.append(stepped)
    return stepped


class SteppedClient(CancellableClient):
    """An MQTT connection whose traffic :class:`MessagesInStep` can wait for."""

    def __init__(self, in_step: MessagesInStep, *args: Any, **kwargs: Any) -> None:
        super().__init__(*args, **kwargs)
        self._in_step = in_step
        self.user = str(kwargs.get("username"))
        self.awaiting = 0
        """Calls waiting for the broker's answer."""
        self.sent = False
        """Published since its last marker."""
        self.linked = False
        """Connected, and reading the markers."""
        self._seen: dict[str, int] = {}
        """The last marker received from each connection (by client id)."""
        self._held: list[paho.MQTTMessage] = []
        """Received while the world steps, not yet handed over."""

    async def __aenter__(self) -> Self:
        self.awaiting += 1
        try:
            await super().__aenter__()
            self._client.message_callback_add(f"{STEP_TOPIC}/#", self._on_marker)
            await super().subscribe(f"{STEP_TOPIC}/#", qos=1)
            self.linked = True
            self._in_step.join(self)
        finally:
            self._answered()
        return self

    async def __aexit__(
        self,
        exc_type: type[BaseException] | None,
        exc: BaseException | None,
        tb: TracebackType | None,
    ) -> None:
        self.linked = False
        self._in_step.leave(self)
        await super().__aexit__(exc_type, exc, tb)

    async def publish(self, *args: Any, **kwargs: Any) -> None:
        self.awaiting += 1
        self.sent = True
        try:
            await super().publish(*args, **kwargs)
        finally:
            self._answered()

    async def subscribe(self, *args: Any, **kwargs: Any) -> Any:
        self.awaiting += 1
        try:
            return await super().subscribe(*args, **kwargs)
        finally:
            self._answered()

    def _answered(self) -> None:
        self.awaiting -= 1
        self._in_step.changed()

    def send_marker(self, number: int) -> int:
        """Publish marker ``number`` behind everything this connection sent; returns it."""
        self.sent = False
        self._client.publish(f"{STEP_TOPIC}/{self.user}", f"{self.identifier} {number}", qos=1)
        return number

    def has_markers(self, expected: dict[str, int]) -> bool:
        if not self._client.is_connected():
            return True  # a connection the broker dropped waits for nothing
        return all(self._seen.get(sender, 0) >= number for sender, number in expected.items())

    def _on_message(self, client: paho.Client, userdata: Any, message: paho.MQTTMessage) -> None:
        if self._in_step.engaged():
            self._held.append(message)
            self._in_step.changed()
        else:
            super()._on_message(client, userdata, message)

    def hand_over(self) -> bool:
        """Queue what this connection holds for its readers, each publisher's messages
        together, in the order it sent them; True if it held any."""
        held, self._held = self._held, []
        for message in sorted(held, key=lambda m: publisher(m.topic)):
            super()._on_message(self._client, None, message)
        return bool(held)

    def _on_marker(self, _client: paho.Client, _userdata: Any, message: paho.MQTTMessage) -> None:
        sender, _, number = message.payload.decode(errors="replace").partition(" ")
        if number.isdigit():
            self._seen[sender] = int(number)
        self._in_step.changed()
