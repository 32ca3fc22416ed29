"""aiomqtt's client without Python 3.11's lost cancellations.

aiomqtt waits for every answer of the broker (the connection, a QoS 1 message's
acknowledgement, a subscription, the disconnection) with ``asyncio.wait_for``. In Python 3.11
that returns the answer and drops a cancellation that lands in the same turn of the event
loop. A task of an ``asyncio.TaskGroup`` that lost its cancellation runs on, and the group
waits for it for ever: a cancelled group cancels its tasks only once, and takes every later
cancellation of its own task (a shutdown repeating it) as already in hand. A robot's fleet
bridge then never ends on shutdown (seen under load, in a fleet test's teardown: the bridge
had just published a delivery report). ``asyncio.timeout`` loses nothing, as Python 3.12's
``wait_for`` (rebuilt on it) does not.
"""

from __future__ import annotations

import asyncio
import math
from collections.abc import Awaitable
from typing import TypeVar

import aiomqtt

T = TypeVar("T")


class CancellableClient(aiomqtt.Client):
    """An :class:`aiomqtt.Client` that waits for the broker with ``asyncio.timeout``."""

    async def _wait_for(self, fut: Awaitable[T], timeout: float | None) -> T:
        seconds = self.timeout if timeout is None else timeout
        try:
            async with asyncio.timeout(None if seconds == math.inf else seconds):
                return await fut
        except TimeoutError:
            raise aiomqtt.MqttError("Operation timed out") from None
