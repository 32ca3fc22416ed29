from __future__ import annotations

import asyncio

import pytest

from coffeebot.board import Board
from coffeebot.config import SupervisionConfig
from coffeebot.daemon import Daemon
from coffeebot.messages import ALL_TOPICS, ESTOP, HEALTH, EStop, HealthStatus
from coffeebot.modules.base import Module, ModuleContext


class Crasher(Module):
    name = "crasher"

    def __init__(self, crashes: int) -> None:
        self.crashes = crashes
        self.runs = 0

    async def run(self, ctx: ModuleContext) -> None:
        self.runs += 1
        if self.runs <= self.crashes:
            raise RuntimeError(f"boom {self.runs}")
        await asyncio.Event().wait()


class Recorder(Module):
    """Records the order in which shutdown hooks and cancellations happen."""

    def __init__(self, name: str, order: int, journal: list[str]) -> None:
        self.name = name  # type: ignore[misc]
        self.shutdown_order = order  # type: ignore[misc]
        self.journal = journal

    async def run(self, ctx: ModuleContext) -> None:
        try:
            await asyncio.Event().wait()
        except asyncio.CancelledError:
            self.journal.append(f"cancel {self.name}")
            raise

    async def shutdown(self) -> None:
        self.journal.append(f"shutdown {self.name}")


SUPERVISION = SupervisionConfig(
    restart_backoff_s=1.0, restart_backoff_max_s=4.0, max_restarts=3, failure_window_s=60
)


async def drain(sub) -> list:
    out = []
    while (env := sub.get_nowait()) is not None:
        out.append(env.msg)
    return out


async def test_crashing_module_is_restarted_with_backoff_and_reported(clock, caplog) -> None:
    board = Board(ALL_TOPICS, clock=clock)
    health = board.subscribe(HEALTH, name="test")
    module = Crasher(crashes=2)
    daemon = Daemon(board, [module], SUPERVISION)
    await daemon.start()
    reports = await drain(health)
    assert [r.status for r in reports] == [HealthStatus.RUNNING, HealthStatus.RESTARTING]
    assert "RuntimeError: boom 1" in reports[-1].detail
    assert "Traceback" in caplog.text and "boom 1" in caplog.text
    await clock.advance(0.9)
    assert module.runs == 1  # still backing off
    await clock.advance(0.2)
    assert module.runs == 2
    await clock.advance(1.8)  # second backoff doubled to 2 s (from t+1.0 to t+3.0)
    assert module.runs == 2
    await clock.advance(0.2)
    assert module.runs == 3
    reports = await drain(health)
    assert reports[-1].status is HealthStatus.RUNNING and reports[-1].restarts == 2
    await daemon.shutdown()


async def test_module_that_keeps_failing_is_marked_failed(clock) -> None:
    board = Board(ALL_TOPICS, clock=clock)
    health = board.subscribe(HEALTH, name="test")
    module = Crasher(crashes=100)
    daemon = Daemon(board, [module], SUPERVISION)
    await daemon.start()
    for _ in range(10):
        await clock.advance(5)
    assert module.runs == SUPERVISION.max_restarts + 1
    reports = await drain(health)
    assert reports[-1].status is HealthStatus.FAILED
    assert daemon.states["crasher"].status is HealthStatus.FAILED
    await daemon.shutdown()


async def test_failed_critical_module_engages_the_emergency_stop(clock) -> None:
    class CriticalCrasher(Crasher):
        name = "motor"
        critical = True

    board = Board(ALL_TOPICS, clock=clock)
    daemon = Daemon(board, [CriticalCrasher(crashes=100), Crasher(crashes=100)], SUPERVISION)
    await daemon.start()
    estops = board.subscribe(ESTOP, name="test")
    for _ in range(10):
        await clock.advance(5)
    assert all(s.status is HealthStatus.FAILED for s in daemon.states.values())
    engaged = [env.msg for env in iter(estops.get_nowait, None)]
    assert len(engaged) == 1  # only the critical one
    assert engaged[0].engaged and "critical module motor failed" in engaged[0].reason
    await daemon.shutdown()


async def test_shutdown_runs_safety_hooks_first_then_cancels_in_reverse(clock) -> None:
    journal: list[str] = []
    board = Board(ALL_TOPICS, clock=clock)
    modules = [
        Recorder("web", 50, journal),
        Recorder("motors", 0, journal),
        Recorder("nav", 20, journal),
    ]
    daemon = Daemon(board, modules, SUPERVISION)
    runner = asyncio.create_task(daemon.run())
    await asyncio.sleep(0.01)
    daemon.request_stop("test")
    await asyncio.wait_for(runner, 1)
    assert journal == [
        "shutdown motors",
        "shutdown nav",
        "shutdown web",
        "cancel nav",
        "cancel motors",
        "cancel web",
    ]
    assert all(s.status is HealthStatus.STOPPED for s in daemon.states.values())


class LosesOneCancel(Module):
    """Runs on after its first cancellation, as a module does whose cancel lands just as
    ``asyncio.wait_for`` completes (Python 3.11 drops it there)."""

    name = "deaf"

    def __init__(self) -> None:
        self.cancels = 0

    async def run(self, ctx: ModuleContext) -> None:
        while True:
            try:
                await asyncio.Event().wait()
            except asyncio.CancelledError:
                self.cancels += 1
                if self.cancels > 1:
                    raise


async def test_shutdown_ends_a_module_that_lost_its_cancellation(clock) -> None:
    module = LosesOneCancel()
    daemon = Daemon(Board(ALL_TOPICS, clock=clock), [module], SUPERVISION)
    await daemon.start()
    await asyncio.sleep(0)
    done, _ = await asyncio.wait({asyncio.create_task(daemon.shutdown())}, timeout=10)
    assert done, "the shutdown hangs"
    assert module.cancels == 2
    assert daemon.states["deaf"].status is HealthStatus.STOPPED


async def test_sigterm_stops_the_daemon_in_order(clock) -> None:
    import os
    import signal

    journal: list[str] = []
    board = Board(ALL_TOPICS, clock=clock)
    daemon = Daemon(board, [Recorder("motors", 0, journal)], SUPERVISION)
    daemon.install_signal_handlers()
    runner = asyncio.create_task(daemon.run())
    await asyncio.sleep(0.01)
    os.kill(os.getpid(), signal.SIGTERM)
    await asyncio.wait_for(runner, 1)
    asyncio.get_running_loop().remove_signal_handler(signal.SIGTERM)
    asyncio.get_running_loop().remove_signal_handler(signal.SIGINT)
    assert daemon.stop_reason == "signal SIGTERM"
    assert journal == ["shutdown motors", "cancel motors"]


class Sneaky(Module):
    name = "sneaky"
    outputs = (HEALTH,)

    async def run(self, ctx: ModuleContext) -> None:
        ctx.board.publish(ESTOP, EStop(engaged=False, source="sneaky"))


async def test_module_cannot_publish_undeclared_topic(clock) -> None:
    board = Board(ALL_TOPICS, clock=clock)
    daemon = Daemon(board, [Sneaky()], SUPERVISION)
    await daemon.start()
    await asyncio.sleep(0)
    assert "may not publish 'operator/estop'" in daemon.states["sneaky"].last_error
    assert board.latest(ESTOP) is None
    await daemon.shutdown()


def test_two_modules_with_one_name_are_refused(clock) -> None:
    board = Board(ALL_TOPICS, clock=clock)
    with pytest.raises(ValueError, match="crasher"):
        Daemon(board, [Crasher(0), Crasher(0)])
