"""CPU time per module: which board task costs what, on the machine that runs it.

Every asyncio task the daemon runs is created through :func:`metered_task_factory`
(installed by :func:`meter_tasks`), which
times each step of the task's coroutine with ``time.thread_time`` (CPU time of the event
loop's thread, not time spent waiting) and books it to the account in the task's context.
The supervisor sets a module's account in the module's task (:data:`ACCOUNT`), and every task
the module starts inherits its context, so a module's helper tasks are booked to it too.
Blocking calls a module hands to a device worker thread are timed in that thread and booked
to the account of the task that made the call (:func:`metered_call`). The board's own work
(publishing, handing messages to subscribers) is booked to the ledger's board account and
taken off the publishing module (:class:`board_time`); what the simulated hardware computes
inside a module's call (a chip's registers, the world behind them) is taken off too
(:func:`unbook`, through ``SimWorld.simulated``), and the task that steps the world
has an account of its own. What runs outside any module (the web server's handlers, the
recorder's pumps) is booked to nobody here; the process total says how much that is.

The shares (:meth:`CpuLedger.shares`) are per cent of one core over the machine's time, not
the board clock's: on the simulator, sped up, they say what the run costs this machine.
"""

from __future__ import annotations

import asyncio
import contextvars
import threading
import time
from collections.abc import Callable, Coroutine, Generator
from dataclasses import dataclass, field
from typing import Any, TypeVar

T = TypeVar("T")
Stepped = Coroutine[Any, Any, Any] | Generator[Any, None, Any]
"""What asyncio runs as a task: a coroutine, or a generator-based one."""


@dataclass(eq=False)
class CpuAccount:
    """CPU seconds booked to one name, from the event loop's and the workers' threads."""

    name: str
    seconds: float = 0.0
    _lock: threading.Lock = field(default_factory=threading.Lock, repr=False)

    def add(self, seconds: float) -> None:
        with self._lock:
            self.seconds += seconds


ACCOUNT: contextvars.ContextVar[CpuAccount | None] = contextvars.ContextVar(
    "coffeebot_cpu_account", default=None
)
"""The account the current task's CPU time is booked to (None: outside every module)."""

BOARD_NAME = "board"


class CpuLedger:
    """Every module's account and the board's, and the shares of one core since the last
    look."""

    def __init__(self) -> None:
        self.accounts: dict[str, CpuAccount] = {}
        self.board = self.account(BOARD_NAME)
        self._since = time.monotonic()
        self._process_since = time.process_time()
        self._booked_since: dict[str, float] = {}
        self.last: dict[str, float] = {}
        """Per cent of one core per account over the last window (:meth:`shares`)."""
        self.last_process_pct: float | None = None
        """The whole process over that window: every thread, inside modules or not."""

    def account(self, name: str) -> CpuAccount:
        if name not in self.accounts:
            self.accounts[name] = CpuAccount(name)
        return self.accounts[name]

    def shares(self) -> dict[str, float]:
        """Per cent of one core per account since the last call, and that of the process
        (kept in :attr:`last` and :attr:`last_process_pct`)."""
        now, process = time.monotonic(), time.process_time()
        elapsed = now - self._since
        if elapsed <= 0:
            return dict(self.last)
        shares = {}
        for name, account in self.accounts.items():
            booked = account.seconds
            shares[name] = 100.0 * (booked - self._booked_since.get(name, 0.0)) / elapsed
            self._booked_since[name] = booked
        self.last_process_pct = 100.0 * (process - self._process_since) / elapsed
        self._since, self._process_since = now, process
        self.last = shares
        return dict(shares)


class _Metered(Coroutine[Any, Any, Any]):
    """A coroutine whose every step is timed and booked to the account in its context."""

    __slots__ = ("_coro",)

    def __init__(self, coro: Stepped) -> None:
        self._coro = coro

    def send(self, value: Any) -> Any:
        start = time.thread_time()
        try:
            return self._coro.send(value)
        finally:
            _book(time.thread_time() - start)

    def throw(self, *args: Any) -> Any:
        start = time.thread_time()
        try:
            return self._coro.throw(*args)
        finally:
            _book(time.thread_time() - start)

    def close(self) -> None:
        self._coro.close()

    def __await__(self) -> Generator[Any, None, Any]:
        inner = self._coro
        return inner.__await__() if isinstance(inner, Coroutine) else inner


def _book(seconds: float) -> None:
    account = ACCOUNT.get()
    if account is not None:
        account.add(seconds)


def unbook(seconds: float) -> None:
    """Take ``seconds`` off the current account: work done inside a module's step or call on
    behalf of nobody on the robot (the simulated world answering a device)."""
    _book(-seconds)


def metered_task_factory(
    loop: asyncio.AbstractEventLoop, coro: Stepped, **kwargs: Any
) -> asyncio.Task[Any]:
    """The event loop's task factory: each task's steps are booked to its context's account
    (``loop.set_task_factory``)."""
    return asyncio.Task(_Metered(coro), loop=loop, **kwargs)


def meter_tasks() -> None:
    """Create every task of the running loop from now on through
    :func:`metered_task_factory`, unless the loop has a task factory already."""
    loop = asyncio.get_running_loop()
    if loop.get_task_factory() is None:
        loop.set_task_factory(metered_task_factory)


def metered_call(fn: Callable[[], T]) -> Callable[[], T]:
    """``fn`` to run in a worker thread, its CPU time booked to the caller's account."""
    account = ACCOUNT.get()
    if account is None:
        return fn

    # Not functools.wraps: copying fn's metadata (a partial's, mostly missing) cost more
    # than the rest of a device call's hand-over, and nobody reads it off the job.
    def timed() -> T:
        token = ACCOUNT.set(account)  # for :func:`unbook` in this thread
        start = time.thread_time()
        try:
            return fn()
        finally:
            account.add(time.thread_time() - start)
            ACCOUNT.reset(token)

    return timed


class board_time:
    """Books the enclosed work to the board, off the account of the module that caused it
    (a module's step already counts it: the board's share is moved, not counted twice). On
    the same clock as the step, ``thread_time``: a publication's elapsed time would include
    the moments the machine ran something else, and take more off the module than its step
    cost."""

    __slots__ = ("_board", "_start")

    def __init__(self, board: CpuAccount | None) -> None:
        self._board = board
        self._start = 0.0

    def __enter__(self) -> None:
        if self._board is not None:
            self._start = time.thread_time()

    def __exit__(self, *exc: object) -> None:
        if self._board is None:
            return
        spent = time.thread_time() - self._start
        self._board.add(spent)
        unbook(spent)
