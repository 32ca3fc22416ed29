"""A watchdog for a test run that stops moving: it names what is stuck, prints every thread's
and every asyncio task's stack, and ends the process, so a hang fails the run with its cause
instead of waiting for CI's limit with nothing to show."""

from __future__ import annotations

import asyncio
import faulthandler
import gc
import inspect
import os
import threading
from typing import TextIO

BACKSTOP_S = 30.0
"""How long after the watchdog the interpreter-level dump follows: it fires even if a thread
holds the GIL and the watchdog thread cannot run."""


class StuckGuard:
    """Armed with what is running and how long it may take; disarmed when it is done."""

    def __init__(self, out: TextIO) -> None:
        """``out``: the run's real standard error, not a capture buffer nobody reads."""
        self._out = out
        self._timer: threading.Timer | None = None

    def arm(self, what: str, seconds: float) -> None:
        self.disarm()
        self._timer = threading.Timer(seconds, self._fire, args=(what, seconds))
        self._timer.daemon = True
        self._timer.start()
        faulthandler.dump_traceback_later(seconds + BACKSTOP_S, exit=True, file=self._out)

    def disarm(self) -> None:
        if self._timer is not None:
            self._timer.cancel()
            self._timer = None
        faulthandler.cancel_dump_traceback_later()

    def _fire(self, what: str, seconds: float) -> None:
        out = self._out
        out.write(f"\n\nSTUCK: {what} has run for {seconds:.0f} s. Its asyncio tasks:\n")
        for task in _every_task():
            out.write(f"\n--- {task.get_name()}\n")
            _write_awaits(task.get_coro(), out)
        out.write("\nAsync generators waiting (a fixture's teardown is one):\n")
        for agen in _waiting_async_generators():
            out.write("\n---\n")
            _write_awaits(agen, out)
        out.write("\nIts threads:\n")
        out.flush()
        faulthandler.dump_traceback(file=out, all_threads=True)
        out.flush()
        os._exit(1)


def _write_awaits(awaitable: object, out: TextIO) -> None:
    """The chain of what ``awaitable`` awaits, one line per coroutine or generator, down to
    what it is stuck on: a task's own stack stops at its first frame."""
    while awaitable is not None:
        frame = getattr(awaitable, "cr_frame", None) or getattr(awaitable, "ag_frame", None)
        frame = frame or getattr(awaitable, "gi_frame", None)
        if frame is None:
            out.write(f"    awaiting {awaitable!r}\n")
            return
        code = frame.f_code
        out.write(f"    {code.co_filename}:{frame.f_lineno} in {code.co_name}\n")
        awaitable = (
            getattr(awaitable, "cr_await", None)
            or getattr(awaitable, "ag_await", None)
            or getattr(awaitable, "gi_yieldfrom", None)
        )


def _waiting_async_generators() -> list[object]:
    return [obj for obj in gc.get_objects() if inspect.isasyncgen(obj) and obj.ag_await is not None]


def _every_task() -> list[asyncio.Task[object]]:
    """Every task of every event loop alive (the stuck loop is another thread's, or this
    process's main thread's, and not running here to be asked)."""
    return [obj for obj in gc.get_objects() if isinstance(obj, asyncio.Task) and not obj.done()]
