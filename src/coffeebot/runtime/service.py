"""Running an assembled daemon as a service until it is asked to stop (a signal, the end of a
scenario, ``--duration``), recording the board and serving it to Foxglove if asked."""

from __future__ import annotations

import contextlib
import faulthandler
from pathlib import Path

from coffeebot.board import Board
from coffeebot.board.recording import Recorder
from coffeebot.config import RobotConfig
from coffeebot.floorplan import FloorPlan
from coffeebot.modules.base import Module, ModuleContext
from coffeebot.runtime.assemble import Runtime
from coffeebot.systemd import Notifier, control_loop_check, run_as_service


def recorder(
    board: Board, path: Path | None, config: RobotConfig
) -> contextlib.AbstractAsyncContextManager[object]:
    """``--record``: started before the modules, closed after their shutdown is on the board."""
    if path is None:
        return contextlib.nullcontext()
    return Recorder(board, path, metadata={"robot": config.name})


def foxglove(
    board: Board, config: RobotConfig, plan: FloorPlan, port: int | None
) -> contextlib.AbstractAsyncContextManager[object]:
    """``--foxglove``: on the web UI's address, so it reaches whom the web UI reaches."""
    if port is None:
        return contextlib.nullcontext()
    # Imported only when asked for: the SDK is a native library the robot need not load.
    from coffeebot.foxglove_server import FoxgloveServer

    return FoxgloveServer(board, config, plan, port, config.web.host)


async def serve(
    runtime: Runtime, record: Path | None = None, foxglove_port: int | None = None
) -> None:
    """Run the daemon as a service until asked to stop."""
    # systemd's watchdog kills a stalled daemon with SIGABRT: leave its stacks in the journal.
    faulthandler.enable()
    config = runtime.config
    daemon = runtime.daemon
    daemon.install_signal_handlers()
    watchdog = config.watchdog
    try:
        async with (
            recorder(runtime.board, record, config),
            foxglove(runtime.board, config, runtime.plan, foxglove_port),
        ):
            await run_as_service(
                daemon,
                Notifier.from_env(),
                control_loop_check(runtime.board, watchdog.topics, watchdog.max_age_s),
                self_check=runtime.self_check,
                max_loop_lag_s=watchdog.max_loop_lag_s,
            )
    finally:
        if runtime.store is not None:
            runtime.store.close()


class StopAfter(Module):
    """Ends the run after ``seconds`` of the board's clock (``--duration``)."""

    name = "duration"

    def __init__(self, runtime: Runtime, seconds: float) -> None:
        self.runtime = runtime
        self.seconds = seconds

    async def run(self, ctx: ModuleContext) -> None:
        await ctx.clock.sleep(self.seconds)
        self.runtime.request_stop(f"--duration {self.seconds:g} s reached")
