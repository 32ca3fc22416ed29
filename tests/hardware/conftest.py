"""Simulated UART devices on pseudo-terminals, and ports opened on them like real ones."""

from __future__ import annotations

import logging
from collections.abc import Callable, Iterator

import pytest

from coffeebot.board import Board
from coffeebot.clock import Clock
from coffeebot.hardware.serial_port import SerialPort, open_port
from coffeebot.modules.base import Module, ModuleBoard, ModuleContext
from coffeebot.sim.clock import SteppedClock
from coffeebot.sim.dwm1001 import SimDwm1001
from coffeebot.sim.motor_controller import SimMotorController

PORT_TIMEOUT_S = 0.05


@pytest.fixture
def sim_dwm() -> Iterator[SimDwm1001]:
    with SimDwm1001(lambda: (1500.0, 850.0, 0.0), rate_hz=50, noise_mm=0.0) as sim:
        yield sim


@pytest.fixture
def sim_motor() -> Iterator[SimMotorController]:
    with SimMotorController() as sim:
        yield sim


@pytest.fixture
def open_sim_port() -> Iterator[Callable[[str], SerialPort]]:
    """Opens ports like the daemon does (``serial_for_url``) and closes them after the test."""
    ports: list[SerialPort] = []

    def _open(path: str) -> SerialPort:
        ports.append(open_port(path, 115200, PORT_TIMEOUT_S))
        return ports[-1]

    yield _open
    for port in ports:
        port.close()


@pytest.fixture
def stepped_clock() -> SteppedClock:
    return SteppedClock()


@pytest.fixture
def context_for() -> Callable[[Board, Module, Clock], ModuleContext]:
    """What the daemon hands a module, without the daemon."""

    def _make(board: Board, module: Module, clock: Clock) -> ModuleContext:
        return ModuleContext(ModuleBoard(board, module), clock, logging.getLogger(module.name))

    return _make
