"""One MQTT connection to the fleet's broker, as robots and the dispatcher both open it:
logged in, with a retained last will saying the connection broke (VDA 5050's pattern), so
whoever listens learns of a vanished peer from the broker itself."""

from __future__ import annotations

import time
from urllib.parse import urlparse

import aiomqtt

from coffeebot.fleet.mosquitto import Credentials
from coffeebot.fleet.protocol import Connection, ConnectionState, encode

KEEPALIVE_S = 5
"""MQTT keep-alive: the broker publishes the last will this long (x1.5) after a peer falls
silent."""


def broker_address(url: str) -> tuple[str, int]:
    """``mqtt://host[:port]`` as host and port (1883 by default)."""
    parsed = urlparse(url)
    return parsed.hostname or "localhost", parsed.port or 1883


def fleet_client(
    url: str, credentials: Credentials, identifier: str, connection_topic: str
) -> aiomqtt.Client:
    """A client for ``url`` whose last will marks ``connection_topic`` broken."""
    host, port = broker_address(url)
    broken = encode(Connection(state=ConnectionState.CONNECTION_BROKEN, at_s=time.time()))
    return aiomqtt.Client(
        host,
        port,
        username=credentials.username,
        password=credentials.password,
        identifier=identifier,
        keepalive=KEEPALIVE_S,
        will=aiomqtt.Will(connection_topic, broken, qos=1, retain=True),
    )
