"""CPU time per module: a module that burns CPU shows up as such, in its helper tasks and its
worker thread too, the board's publishing is booked apart, and so is the simulated hardware."""

from __future__ import annotations

import asyncio
import time
from pathlib import Path

import pytest

import coffeebot.daemon as daemon_module
from coffeebot.board import Board
from coffeebot.clock import MonotonicClock
from coffeebot.config import load_robot_config
from coffeebot.cpu import unbook
from coffeebot.daemon import Daemon
from coffeebot.floorplan import load_floorplan
from coffeebot.hardware.worker import DeviceWorker
from coffeebot.messages import ALL_TOPICS, MOTOR_COMMAND, MotorCommand
from coffeebot.modules.base import Module, ModuleContext
from coffeebot.sim.i2c import SimI2CBus
from coffeebot.sim.stepper import SimWorld
from coffeebot.sim.world import Pose, RobotSpec, World

BURN_S = 0.05
"""CPU seconds a busy module burns per step: far above anything an idle module costs."""


def burn(seconds: float) -> None:
    """Spend ``seconds`` of this thread's CPU time (not waiting: computing)."""
    end = time.thread_time() + seconds
    while time.thread_time() < end:
        pass


class Busy(Module):
    """Burns CPU in its own task, in a helper task it starts, and in a worker thread."""

    name = "busy"

    def __init__(self) -> None:
        self.worker = DeviceWorker("busy-bus")
        self.steps = 0

    async def run(self, ctx: ModuleContext) -> None:
        helper = asyncio.create_task(self._helper())
        try:
            while True:
                burn(BURN_S)
                await self.worker.call(burn, BURN_S)
                self.steps += 1
                await asyncio.sleep(0)
        finally:
            helper.cancel()

    async def _helper(self) -> None:
        while True:
            burn(BURN_S)
            await asyncio.sleep(0)


class Idle(Module):
    name = "idle"

    async def run(self, ctx: ModuleContext) -> None:
        await asyncio.Event().wait()


class Publisher(Module):
    """Publishes many messages and does nothing else."""

    name = "publisher"
    outputs = (MOTOR_COMMAND,)

    async def run(self, ctx: ModuleContext) -> None:
        command = MotorCommand(left_mm_s=0, right_mm_s=0)
        while True:
            for _ in range(100):
                ctx.board.publish(MOTOR_COMMAND, command)
            await asyncio.sleep(0)


async def test_a_module_that_burns_cpu_shows_up_with_its_helpers_and_worker_thread(
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    # One window, the test's own: on a loaded machine the four steps outlast the daemon's
    # 5 s window, and a renewal just after the burning left the shares asked below empty.
    monkeypatch.setattr(daemon_module, "CPU_WINDOW_S", 3600.0)
    board = Board(ALL_TOPICS)
    busy = Busy()
    daemon = Daemon(board, [busy, Idle()])
    await daemon.start()
    while busy.steps < 4:
        await asyncio.sleep(0.01)
    await daemon.shutdown()
    busy.worker.close()
    booked = {name: account.seconds for name, account in daemon.cpu.accounts.items()}
    # Each step: one burn in the module's task, one in its worker, about one in its helper.
    assert booked["busy"] >= 3 * 4 * BURN_S * 0.9
    assert booked["idle"] < BURN_S
    shares = daemon.cpu.shares()
    assert shares["busy"] > shares["idle"]
    snapshot = {h.module: h.cpu_pct for h in daemon.health()}
    assert snapshot["busy"] is not None and snapshot["busy"] > 0


async def test_publishing_is_booked_to_the_board_not_the_publisher() -> None:
    """With a hundred subscribers, handing each message over is nearly all the work."""
    board = Board(ALL_TOPICS)
    readers = [board.subscribe(MOTOR_COMMAND, name=f"reader {i}") for i in range(100)]
    daemon = Daemon(board, [Publisher()])
    await daemon.start()
    for _ in range(20):
        await asyncio.sleep(0)
    await daemon.shutdown()
    for reader in readers:
        reader.close()
    assert daemon.cpu.board.seconds > 3 * daemon.cpu.accounts["publisher"].seconds > 0


class Simulated(Module):
    """Its worker call is all simulated hardware: the world's answer, unbooked."""

    name = "simulated"

    def __init__(self) -> None:
        self.worker = DeviceWorker("simulated-bus")
        self.calls = 0

    async def run(self, ctx: ModuleContext) -> None:
        while True:
            await self.worker.call(self._answer)
            self.calls += 1

    @staticmethod
    def _answer() -> None:
        start = time.thread_time()
        burn(BURN_S)
        unbook(time.thread_time() - start)


async def after_calls(module: Simulated | ChipReader, calls: int = 4) -> Daemon:
    """The daemon of ``module`` alone, shut down once the module made ``calls`` worker calls."""
    daemon = Daemon(Board(ALL_TOPICS), [module])
    await daemon.start()
    while module.calls < calls:
        await asyncio.sleep(0.01)
    await daemon.shutdown()
    module.worker.close()
    return daemon


async def test_what_the_simulated_world_computes_in_a_call_is_not_the_modules() -> None:
    module = Simulated()
    daemon = await after_calls(module)
    assert abs(daemon.cpu.accounts["simulated"].seconds) < BURN_S


class BurningChip:
    """A simulated chip whose registers cost CPU, and whose answer asks the world too."""

    address = 0x29

    def __init__(self, shared: SimWorld) -> None:
        self.shared = shared

    def write(self, data: bytes) -> None:
        burn(BURN_S)
        with self.shared.world_time():
            burn(BURN_S)

    def read(self, length: int) -> bytes:
        return bytes(length)


class ChipReader(Module):
    """Writes to a simulated chip in its worker thread, as the ToF poller does."""

    name = "reader"

    def __init__(self, bus: SimI2CBus) -> None:
        self.worker = DeviceWorker("reader-bus")
        self.bus = bus
        self.calls = 0

    async def run(self, ctx: ModuleContext) -> None:
        while True:
            await self.worker.call(self.bus.write_byte, BurningChip.address, 1)
            self.calls += 1


async def test_a_simulated_chips_work_is_the_worlds_and_counted_once() -> None:
    root = Path(__file__).resolve().parents[2]
    config = load_robot_config(root / "boards" / "coffeebot-v1.toml")
    plan = load_floorplan(root / "floorplans" / "cs-building.toml")
    shared = SimWorld(
        World(plan, RobotSpec.from_config(config), floor=2, pose=Pose(2000, 0, 0)), MonotonicClock()
    )
    bus = SimI2CBus(shared.simulated)
    bus.attach(BurningChip(shared))
    module = ChipReader(bus)
    daemon = await after_calls(module)
    assert abs(daemon.cpu.accounts["reader"].seconds) < BURN_S
    # Each call burned twice BURN_S in the chip, once of it inside the world: not counted twice.
    assert 2 * BURN_S * module.calls <= shared.cpu_s < 2 * BURN_S * (module.calls + 1) + BURN_S
