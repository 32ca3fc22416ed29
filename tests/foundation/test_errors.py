"""One error family: a caller catches coffeebot's own errors with ``except CoffeebotError``."""

from __future__ import annotations

from pathlib import Path

import pytest

from coffeebot.board import Board, BoardError
from coffeebot.board.recording import RecordingError, recording_info
from coffeebot.config import load_robot_config
from coffeebot.errors import CoffeebotError, ConfigError, HardwareError, OrderError
from coffeebot.floorplan import load_floorplan
from coffeebot.hardware.errors import DeviceError
from coffeebot.hardware.selfcheck import SelfCheckFailed
from coffeebot.messages import ALL_TOPICS
from coffeebot.modules.navigation import DeliveryAborted
from coffeebot.orders import OrderNotFound, OrdersUnavailable


def test_every_error_the_product_raises_is_a_coffeebot_error(tmp_path: Path) -> None:
    with pytest.raises(CoffeebotError):
        load_robot_config(tmp_path / "missing.toml")
    with pytest.raises(CoffeebotError):
        load_floorplan(tmp_path / "missing.toml")
    with pytest.raises(CoffeebotError):
        Board(ALL_TOPICS).topic("no/such/topic")
    (tmp_path / "junk.mcap").write_bytes(b"not a recording")
    with pytest.raises(CoffeebotError):
        recording_info(tmp_path / "junk.mcap")


def test_the_children_keep_the_standard_bases_callers_rely_on() -> None:
    assert issubclass(ConfigError, ValueError)  # a bad file is a bad value
    assert issubclass(DeviceError, OSError)  # a wrong answer is handled like no answer
    assert issubclass(DeviceError, HardwareError) and issubclass(SelfCheckFailed, HardwareError)
    assert issubclass(RecordingError, BoardError)
    assert issubclass(OrderNotFound, OrderError) and issubclass(OrdersUnavailable, OrderError)
    assert not issubclass(CoffeebotError, (ValueError, OSError))
    assert issubclass(DeliveryAborted, CoffeebotError)
