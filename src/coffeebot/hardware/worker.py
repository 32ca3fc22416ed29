"""One worker thread per bus or port, so blocking I/O never runs on the event loop."""

from __future__ import annotations

import asyncio
import functools
from collections.abc import Callable
from concurrent.futures import ThreadPoolExecutor
from typing import ParamSpec, TypeVar

from coffeebot.clock import Clock, SteppedClock
from coffeebot.cpu import metered_call
from coffeebot.lockstep import Lockstep, WorkerSlot

P = ParamSpec("P")
T = TypeVar("T")


class DeviceWorker:
    """A single thread that runs every blocking call for one bus or port, in order.

    One thread (not a pool) matters for I2C: a mux selection and the sensor transfers behind
    it must not interleave with another sensor's, and a single queue guarantees that without
    a lock as long as each sensor's work is submitted as one call.

    On the simulator's clock every call is entered in the clock's lockstep ledger, so the
    simulated world does not step on while a call runs, and its result reaches the event
    loop in the order the calls were made (:mod:`coffeebot.lockstep`).
    """

    def __init__(self, name: str, clock: Clock | None = None) -> None:
        self.name = name
        self._lockstep: Lockstep | None = None
        self._slot: WorkerSlot | None = None
        initializer: Callable[[], None] | None = None
        if isinstance(clock, SteppedClock):
            self._lockstep = clock.lockstep
            slot = self._slot = clock.lockstep.worker(name)
            initializer = functools.partial(Lockstep.bind, slot)
        self._executor = ThreadPoolExecutor(
            max_workers=1, thread_name_prefix=name, initializer=initializer
        )

    async def call(self, fn: Callable[P, T], *args: P.args, **kwargs: P.kwargs) -> T:
        loop = asyncio.get_running_loop()
        job = metered_call(functools.partial(fn, *args, **kwargs))
        lockstep, slot = self._lockstep, self._slot
        if lockstep is None or slot is None:
            return await loop.run_in_executor(self._executor, job)
        future: asyncio.Future[T] = loop.create_future()
        number = lockstep.submit(slot)

        def run() -> None:
            try:
                result = job()
            except BaseException as exc:  # handed to the awaiting task, as run_in_executor does
                error = exc
                lockstep.finish(slot, number, lambda: _fail(future, error), loop)
            else:
                lockstep.finish(slot, number, lambda: _succeed(future, result), loop)

        try:
            self._executor.submit(run)
        except RuntimeError:  # closed: the call never runs
            lockstep.finish(slot, number, lambda: None, loop)
            raise
        return await future

    def post(self, fn: Callable[[], object]) -> None:
        """Queue ``fn`` behind the calls already queued, without waiting for it (a fault the
        simulator injects into a device's thread)."""
        if self._lockstep is None or self._slot is None:
            self._executor.submit(fn)
            return
        lockstep, slot = self._lockstep, self._slot
        number = lockstep.submit(slot)
        loop = asyncio.get_running_loop()

        def run() -> None:
            try:
                fn()
            finally:
                lockstep.finish(slot, number, lambda: None, loop)

        self._executor.submit(run)

    def run_now(self, fn: Callable[[], T]) -> T:
        """Run ``fn`` on the thread and block until it is done (opening and closing, outside
        the event loop's work)."""
        return self._executor.submit(fn).result()

    def close(self) -> None:
        """Stop accepting work; a call already running finishes in its thread."""
        if self._lockstep is not None and self._slot is not None:
            self._lockstep.retire(self._slot)
        self._executor.shutdown(wait=False, cancel_futures=True)

    def join(self) -> None:
        """Close and wait for the call still running (the store's last write)."""
        self.close()
        self._executor.shutdown(wait=True)


def _succeed(future: asyncio.Future[T], result: T) -> None:
    if not future.done():
        future.set_result(result)


def _fail(future: asyncio.Future[T], error: BaseException) -> None:
    if not future.done():
        future.set_exception(error)
