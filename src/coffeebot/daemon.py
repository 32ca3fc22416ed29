"""The daemon: one board, the modules as supervised tasks, and an ordered shutdown.

Supervision follows the usual shape (Erlang's one-for-one, systemd's Restart=): a module
whose ``run`` raises is logged with its traceback, reported on the health topic and restarted
after an exponential backoff; a module that fails more than ``max_restarts`` times within
``failure_window_s`` is marked failed and left down. Safety never depends on a module being
up: motion treats a failed or silent collision module as "stop", and a *critical* module that
is marked failed also engages the emergency stop, which only an operator releases.
"""

from __future__ import annotations

import asyncio
import contextlib
import logging
import signal
from collections import deque
from collections.abc import Iterable

from coffeebot.board import Board
from coffeebot.clock import Clock
from coffeebot.config import SupervisionConfig
from coffeebot.cpu import ACCOUNT, CpuLedger, meter_tasks
from coffeebot.logs import Event
from coffeebot.messages import ESTOP, HEALTH, EStop, Health, HealthStatus
from coffeebot.modules.base import Module, ModuleBoard, ModuleContext

log = logging.getLogger(__name__)

SHUTDOWN_HOOK_TIMEOUT_S = 2.0
CPU_WINDOW_S = 5.0
"""The machine's seconds over which each module's share of a core is taken."""
CANCEL_REPEAT_S = 1.0
"""How long a cancelled module has to end before it is cancelled again. A cancellation can
be lost: Python 3.11's ``asyncio.wait_for`` drops one that lands as the awaited future
completes, and the module then runs on. (The fleet's MQTT client no longer waits with it,
``fleet/cancellable.py``: a task of a module's ``TaskGroup`` is cancelled only once.)"""


class ModuleState:
    """What the supervisor knows about one module."""

    def __init__(self, module: Module) -> None:
        self.module = module
        self.status = HealthStatus.STARTING
        self.restarts = 0
        self.failure_times: deque[float] = deque()
        self.last_error = ""
        self.task: asyncio.Task[None] | None = None


class Daemon:
    """Runs modules on one board until asked to stop, then stops them in a defined order."""

    def __init__(
        self,
        board: Board,
        modules: Iterable[Module],
        supervision: SupervisionConfig | None = None,
    ) -> None:
        self.board = board
        self.clock: Clock = board.clock
        self.supervision = supervision or SupervisionConfig()
        self.states: dict[str, ModuleState] = {}
        for module in modules:
            if module.name in self.states:
                raise ValueError(f"two modules are named {module.name!r}")
            self.states[module.name] = ModuleState(module)
        self._stop = asyncio.Event()
        self.stop_reason = ""
        self.cpu = CpuLedger()
        """CPU time per module and the board's (:mod:`coffeebot.cpu`)."""
        board.cpu_account = self.cpu.board
        self._meter: asyncio.Task[None] | None = None

    @property
    def modules(self) -> list[Module]:
        return [state.module for state in self.states.values()]

    def request_stop(self, reason: str) -> None:
        if not self._stop.is_set():
            log.info("shutdown requested: %s", reason)
            self.stop_reason = reason
            self._stop.set()

    def install_signal_handlers(self) -> None:
        loop = asyncio.get_running_loop()
        for sig in (signal.SIGINT, signal.SIGTERM):
            loop.add_signal_handler(sig, self.request_stop, f"signal {sig.name}")

    def health(self) -> list[Health]:
        """Every module's status as the supervisor sees it now, for the inspector.

        The health topic carries changes; a page opened later needs the current state.
        """
        return [
            Health(
                module=s.module.name,
                status=s.status,
                restarts=s.restarts,
                detail=s.last_error,
                publishes=_published(s.module),
                cpu_pct=_rounded(self.cpu.last.get(s.module.name)),
            )
            for s in self.states.values()
        ]

    def _report(self, state: ModuleState, detail: str = "") -> None:
        self.board.publish(
            HEALTH,
            Health(
                module=state.module.name,
                status=state.status,
                restarts=state.restarts,
                detail=detail,
                publishes=_published(state.module),
            ),
        )

    async def _supervise(self, state: ModuleState) -> None:
        module = state.module
        cfg = self.supervision
        ctx = ModuleContext(
            board=ModuleBoard(self.board, module),
            clock=self.clock,
            log=logging.getLogger(f"coffeebot.module.{module.name}"),
        )
        backoff = cfg.restart_backoff_s
        # This task's context, and so every task the module starts, books its CPU time here.
        ACCOUNT.set(self.cpu.account(module.name))
        while True:
            state.status = HealthStatus.RUNNING
            self._report(state)
            try:
                await module.run(ctx)
            except asyncio.CancelledError:
                raise
            except Exception as exc:
                now = self.clock.now()
                state.last_error = f"{type(exc).__name__}: {exc}"
                state.failure_times.append(now)
                while state.failure_times[0] < now - cfg.failure_window_s:
                    state.failure_times.popleft()
                if len(state.failure_times) > cfg.max_restarts:
                    state.status = HealthStatus.FAILED
                    log.error(
                        "module %s failed %d times within %.0f s, giving up: %s",
                        module.name,
                        len(state.failure_times),
                        cfg.failure_window_s,
                        state.last_error,
                        exc_info=True,
                        extra={"event": Event.FAULT.value, "cause": state.last_error},
                    )
                    self._report(state, state.last_error)
                    if module.critical:
                        self.board.publish(
                            ESTOP,
                            EStop(
                                engaged=True,
                                source="supervisor",
                                reason=f"critical module {module.name} failed: {state.last_error}",
                            ),
                        )
                    return
                state.status = HealthStatus.RESTARTING
                state.restarts += 1
                log.error(
                    "module %s crashed, restart %d in %.2f s: %s",
                    module.name,
                    state.restarts,
                    backoff,
                    state.last_error,
                    exc_info=True,
                    extra={"event": Event.FAULT.value, "cause": state.last_error},
                )
                self._report(state, state.last_error)
                await self.clock.sleep(backoff)
                backoff = min(backoff * 2, cfg.restart_backoff_max_s)
            else:
                state.status = HealthStatus.STOPPED
                self._report(state, "run() returned")
                log.info("module %s finished", module.name)
                return

    async def start(self) -> None:
        meter_tasks()
        self._meter = asyncio.create_task(self._measure(), name="daemon:cpu")
        for state in self.states.values():
            state.task = asyncio.create_task(
                self._supervise(state), name=f"module:{state.module.name}"
            )
        await asyncio.sleep(0)

    async def _measure(self) -> None:
        """Each module's share of a core, renewed every ``CPU_WINDOW_S`` of the machine's
        time (not the board clock's: the cost on this machine is the question)."""
        while True:
            await asyncio.sleep(CPU_WINDOW_S)
            self.cpu.shares()

    async def wait_stop_requested(self) -> None:
        """Return once :meth:`request_stop` has been called (a signal, an operator, a test)."""
        await self._stop.wait()

    async def run(self) -> None:
        """Start every module, wait for a stop request, then shut down in order."""
        await self.start()
        try:
            await self.wait_stop_requested()
        finally:
            await self.shutdown()

    async def shutdown(self) -> None:
        """Safety hooks first (motors stop), then cancel tasks in reverse start order."""
        for state in sorted(self.states.values(), key=lambda s: s.module.shutdown_order):
            try:
                await asyncio.wait_for(state.module.shutdown(), SHUTDOWN_HOOK_TIMEOUT_S)
            except Exception:
                log.exception("shutdown hook of module %s failed", state.module.name)
        for state in reversed(self.states.values()):
            if state.task is not None:
                await _cancel(state.task, state.module.name)
            state.status = HealthStatus.STOPPED
            self._report(state, "daemon stopped")
        if self._meter is not None:
            await _cancel(self._meter, "cpu meter")


async def _cancel(task: asyncio.Task[None], name: str) -> None:
    """Cancel ``task`` until it ends: a shutdown never hangs on a lost cancellation."""
    while not task.done():
        task.cancel()
        await asyncio.wait({task}, timeout=CANCEL_REPEAT_S)
        if not task.done():
            log.warning("module %s runs on %.1f s after its cancel: again", name, CANCEL_REPEAT_S)
    with contextlib.suppress(asyncio.CancelledError):
        await task


def _rounded(pct: float | None) -> float | None:
    return None if pct is None else round(pct, 2)


def _published(module: Module) -> tuple[str, ...]:
    return tuple(topic.name for topic in module.outputs)
