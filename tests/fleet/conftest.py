"""The broker the fleet's tests talk through: a Mosquitto of their own, on a free port."""

from __future__ import annotations

from collections.abc import Iterator

import pytest

from coffeebot.fleet.mosquitto import Mosquitto

ROBOTS = ["robot-1", "robot-2"]


@pytest.fixture
def broker() -> Iterator[Mosquitto]:
    broker = Mosquitto(ROBOTS)
    broker.start()
    yield broker
    broker.close()
