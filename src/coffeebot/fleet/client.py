"""One MQTT connection to the fleet's broker, as robots and the dispatcher both open it:
logged in, announced online on a retained connection topic, with a retained last will saying
the connection broke and a retained "offline" when it is closed on purpose (VDA 5050's
pattern), so whoever listens learns from the broker itself whether a peer is there, left, or
vanished."""

from __future__ import annotations

import asyncio
import contextlib
import time
from collections.abc import AsyncIterator
from typing import Any
from urllib.parse import urlparse

import aiomqtt

from coffeebot.fleet.cancellable import CancellableClient
from coffeebot.fleet.in_step import MessagesInStep, SteppedClient
from coffeebot.fleet.mosquitto import Credentials
from coffeebot.fleet.protocol import Connection, ConnectionState, encode

KEEPALIVE_S = 5
"""MQTT keep-alive: the broker publishes the last will this long (x1.5) after a peer falls
silent."""


def broker_address(url: str) -> tuple[str, int]:
    """``mqtt://host[:port]`` as host and port (1883 by default)."""
    parsed = urlparse(url)
    return parsed.hostname or "localhost", parsed.port or 1883


GOODBYE_S = 1.0
"""How long a closing connection tries to say "offline" before it goes anyway."""


@contextlib.asynccontextmanager
async def fleet_session(
    url: str,
    credentials: Credentials,
    identifier: str,
    connection_topic: str,
    in_step: MessagesInStep | None = None,
) -> AsyncIterator[aiomqtt.Client]:
    """Connected and announced online; a shutdown (the task cancelled) announces offline
    before it disconnects, so peers do not take a robot that left for one still there."""
    broken = encode(Connection(state=ConnectionState.CONNECTION_BROKEN, at_s=time.time()))
    will = aiomqtt.Will(connection_topic, broken, qos=1, retain=True)
    async with mqtt_client(url, credentials, identifier, will, in_step) as client:
        await _announce(client, connection_topic, ConnectionState.ONLINE)
        try:
            yield client
        except asyncio.CancelledError:
            with contextlib.suppress(aiomqtt.MqttError, TimeoutError):
                async with asyncio.timeout(GOODBYE_S):
                    await _announce(client, connection_topic, ConnectionState.OFFLINE)
            raise


async def _announce(client: aiomqtt.Client, topic: str, state: ConnectionState) -> None:
    await client.publish(
        topic, encode(Connection(state=state, at_s=time.time())), qos=1, retain=True
    )


def mqtt_client(
    url: str,
    credentials: Credentials,
    identifier: str,
    will: aiomqtt.Will | None = None,
    in_step: MessagesInStep | None = None,
) -> aiomqtt.Client:
    """A client for ``url``; in a simulated fleet (``in_step``) one whose traffic the
    simulated clock waits for."""
    host, port = broker_address(url)
    options: dict[str, Any] = {
        "username": credentials.username,
        "password": credentials.password,
        "identifier": identifier,
        "keepalive": KEEPALIVE_S,
        "will": will,
    }
    if in_step is not None:
        return SteppedClient(in_step, host, port, **options)
    return CancellableClient(host, port, **options)
