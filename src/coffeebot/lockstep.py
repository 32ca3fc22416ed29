"""Worker threads in step with simulated time, so a simulated run depends on its seed alone.

The simulator's clock (:class:`coffeebot.clock.SteppedClock`) moves only when the simulated
world steps it. That alone does not make a run repeatable: if the world stepped on while the
daemon was still reacting to the last step, how far the robot got before it braked would
depend on how fast the machine computed the reaction. So the world steps only once the
daemon has *settled*: the event loop has nothing left to run, and every blocking call the
drivers and the order store made in their worker threads has finished or waits for something
only a later step can bring (bytes on a serial line, a moment of simulated time).
:class:`Lockstep` is the ledger of those calls. The daemon's computing then takes no
simulated time at all, however busy the machine is, and results of finished calls reach the
event loop in the order the calls were made, not in the order threads happened to finish.

The ledger is *engaged* while the world steps the clock. Before that and after (shutdown),
results are handed over as they come and waits are in the machine's time, as on the robot,
which has no lockstep at all.
"""

from __future__ import annotations

import asyncio
import itertools
import logging
import threading
import time
from collections.abc import Callable
from dataclasses import dataclass
from typing import Protocol

log = logging.getLogger(__name__)

SLOW_SETTLE_S = 10.0
"""A worker still busy after this many seconds of the machine's time is logged (a blocking
call that waits for something no step brings would stop the run)."""


class OutsideTraffic(Protocol):
    """What the daemons send each other outside the process (a broker's messages,
    :mod:`coffeebot.fleet.in_step`), held in step with the world."""

    async def drain(self) -> bool:
        """Wait until nothing is on its way and hand over what arrived; True if anything
        was (the daemons may have something new to do)."""
        ...

    def let_through(self) -> bool:
        """Hand over whatever is held back (the ledger is no longer engaged); True if
        anything was."""
        ...


@dataclass(eq=False)
class Waiter:
    """A thread inside :meth:`Lockstep.block`: what it waits for, and until when."""

    until: Callable[[], bool]
    deadline: float
    wakeup: threading.Condition

    def due(self, now: float) -> bool:
        return now >= self.deadline or self.until()


@dataclass(eq=False)
class WorkerSlot:
    """One worker thread as the ledger sees it."""

    name: str
    outstanding: int = 0
    """Calls submitted and not finished (queued or running)."""
    waiter: Waiter | None = None
    """Set while the thread waits in :meth:`Lockstep.block`."""


class _ThreadState(threading.local):
    def __init__(self) -> None:
        self.slot: WorkerSlot | None = None


_current = _ThreadState()


class Lockstep:
    """Which worker threads are busy, and the results waiting for the event loop.

    ``now`` is the simulated clock; ``free_speed`` converts simulated into the machine's
    seconds for waits while the ledger is not engaged. One lock (:attr:`lock`) guards the
    ledger and the simulated serial lines' buffers, so a thread's "is there anything for me"
    and the world's "is everyone settled" see the same state. Each waiting thread has a
    condition of its own on that lock and is woken only when what it waits for may have
    come (:meth:`wake`), not at every step.
    """

    def __init__(self, now: Callable[[], float], free_speed: float = 1.0) -> None:
        self._now = now
        self.free_speed = free_speed
        self.lock = threading.RLock()
        self._settled = threading.Condition(self.lock)
        self._workers: list[WorkerSlot] = []
        self._waiters: list[Waiter] = []
        self._finished: list[tuple[int, Callable[[], None]]] = []
        self._jobs = itertools.count()
        self.engaged = False
        self.outside: list[OutsideTraffic] = []
        """What the daemons send outside the process: the world steps once none of it is
        on its way or newly arrived."""

    def now(self) -> float:
        """The simulated clock's time."""
        return self._now()

    # --- worker threads -------------------------------------------------------------------

    def worker(self, name: str) -> WorkerSlot:
        """A new worker thread's slot (``name`` is for log lines)."""
        slot = WorkerSlot(name)
        with self.lock:
            self._workers.append(slot)
        return slot

    @staticmethod
    def bind(slot: WorkerSlot) -> None:
        """Called in the worker's thread: :meth:`block` there is that worker waiting."""
        _current.slot = slot

    def retire(self, slot: WorkerSlot) -> None:
        """The worker stops taking calls; whatever it still runs is no longer waited for."""
        with self.lock:
            if slot in self._workers:
                self._workers.remove(slot)
            self._settled.notify()

    def submit(self, slot: WorkerSlot) -> int:
        """A call is queued on ``slot``'s thread; its number orders the results."""
        with self.lock:
            slot.outstanding += 1
            return next(self._jobs)

    def finish(
        self,
        slot: WorkerSlot,
        job: int,
        deliver: Callable[[], None],
        loop: asyncio.AbstractEventLoop,
    ) -> None:
        """Called in the worker's thread when call ``job`` is done: ``deliver`` (which sets
        the awaiting future) runs on ``loop``, by the world when engaged, at once if not."""
        with self.lock:
            slot.outstanding -= 1
            if self.engaged and slot in self._workers:
                self._finished.append((job, deliver))
                self._settled.notify()
                return
        loop.call_soon_threadsafe(deliver)

    def block(self, until: Callable[[], bool], deadline: float) -> None:
        """Wait in this thread until ``until()`` holds or simulated time reaches
        ``deadline``; ``until`` is evaluated with :attr:`lock` held, and whoever makes it
        true calls :meth:`wake`. While a worker waits here it counts as settled."""
        waiter = Waiter(until, deadline, threading.Condition(self.lock))
        slot = _current.slot
        with self.lock:
            self._waiters.append(waiter)
            if slot is not None:
                slot.waiter = waiter
                self._settled.notify()  # the world may be waiting for this worker
            free_deadline: float | None = None
            try:
                while not until():
                    now = self._now()
                    if now >= deadline:
                        return
                    if self.engaged:
                        free_deadline = None
                        waiter.wakeup.wait()
                        continue
                    # Not engaged, simulated time stands still: the rest of the wait passes
                    # on the machine's clock, or a worker would wait forever at shutdown.
                    if free_deadline is None:
                        free_deadline = time.monotonic() + (deadline - now) / self.free_speed
                    left = free_deadline - time.monotonic()
                    if left <= 0:
                        return
                    waiter.wakeup.wait(left)
            finally:
                self._waiters.remove(waiter)
                if slot is not None:
                    slot.waiter = None

    def sleep(self, seconds: float) -> None:
        """A blocking sleep in simulated time, for a driver's polls in its worker thread."""
        self.block(lambda: False, self._now() + seconds)

    def wake(self) -> None:
        """Time moved on or bytes arrived: wake the threads whose wait is over."""
        with self.lock:
            now = self._now()
            for waiter in self._waiters:
                if waiter.due(now):
                    waiter.wakeup.notify()

    # --- the world ------------------------------------------------------------------------

    def engage(self, engaged: bool) -> None:
        """From now on (not) in step with the world; results held back are released."""
        with self.lock:
            self.engaged = engaged
            held, self._finished = self._finished, []
            for waiter in self._waiters:
                waiter.wakeup.notify()
        for _, deliver in sorted(held, key=lambda job: job[0]):
            deliver()
        if not engaged:
            for traffic in self.outside:
                traffic.let_through()

    def settle(self) -> list[Callable[[], None]]:
        """Wait (blocking) until every worker is settled; the results that came in, in the
        order their calls were made. Call on the event loop's thread, when the loop has
        nothing else to run."""
        started = time.monotonic()
        warned = False
        with self.lock:
            while (busy := self._busy()) is not None:
                self._settled.wait(1.0)
                if not warned and time.monotonic() - started > SLOW_SETTLE_S:
                    warned = True
                    log.warning(
                        "simulated time waits for worker %s (busy for %.0f s of machine time)",
                        busy.name,
                        SLOW_SETTLE_S,
                    )
            done, self._finished = self._finished, []
        return [deliver for _, deliver in sorted(done, key=lambda job: job[0])]

    def _busy(self) -> WorkerSlot | None:
        now = self._now()
        for slot in self._workers:
            if slot.outstanding == 0:
                continue
            if slot.waiter is None or slot.waiter.due(now):
                return slot
        return None
