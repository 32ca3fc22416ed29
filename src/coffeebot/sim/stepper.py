"""The simulated world as time moves it: one world, its clock, and the robots' simulations.

:meth:`SimWorld.run` is the clock's only advancer, for as long as the daemons run (from
before their self-checks to after their shutdown). On the simulator's
:class:`~coffeebot.clock.SteppedClock` it steps the world only once every daemon in the
process has settled: the event loop has nothing else to run and every worker thread has
finished or waits for a later step (:mod:`coffeebot.lockstep`); results of the threads'
calls are handed over in the order the calls were made. So a daemon's reaction to a step
takes no simulated time, and a run is the same on a busy machine as on an idle one, only
slower. The steps are paced to the clock's speed in the machine's time as long as the
machine keeps up (a late step is not made up for by a burst). On the machine's clock (a
benchmark of the daemon's own timing) the world just steps as time goes.
"""

from __future__ import annotations

import asyncio
import contextlib
import threading
import time
from collections.abc import Iterator, Sized
from typing import TYPE_CHECKING

from coffeebot.clock import Clock, SteppedClock
from coffeebot.cpu import ACCOUNT, CpuAccount, meter_tasks, unbook
from coffeebot.lockstep import Lockstep
from coffeebot.sim.world import World

if TYPE_CHECKING:
    from coffeebot.sim.simulation import Simulation

STEP_S = 0.005
"""Simulated seconds per step: a sensor sample is 20 ms, a motor telemetry line 20 ms."""


class _Simulated(contextlib.AbstractContextManager[None]):
    """A block of :meth:`SimWorld.simulated`. A plain class, not a generator-based context
    manager: it is entered for every transaction of every simulated device (some 60 a scan
    cycle), and what it costs outside the timed part stays on the module that made the
    call, as if the robot had spent it."""

    __slots__ = ("_depth", "_start", "_world")

    def __init__(self, world: SimWorld) -> None:
        self._world = world
        self._depth = 0
        self._start = 0.0

    def __enter__(self) -> None:
        local = self._world._local
        depth = self._depth = getattr(local, "depth", 0)
        local.depth = depth + 1
        if depth == 0:
            self._start = time.thread_time()

    def __exit__(self, *exc: object) -> None:
        world = self._world
        world._local.depth = depth = self._depth
        if depth == 0:
            spent = time.thread_time() - self._start
            with world.lock:
                world.cpu_s += spent
            unbook(spent)


class SimWorld:
    def __init__(self, world: World, clock: Clock) -> None:
        self.world = world
        self.clock = clock
        self._task: asyncio.Task[None] | None = None
        self.lock = threading.RLock()
        """Held for every access to the world: the I2C worker threads ask it too."""
        if isinstance(clock, SteppedClock):
            self.lockstep = clock.lockstep
        else:  # the machine's clock (a benchmark of the daemon's own timing): never engaged
            self.lockstep = Lockstep(clock.now)
        self.cpu_s = 0.0
        """CPU seconds spent in the world and the simulated devices, on whichever thread
        asked (see :meth:`simulated`)."""
        self._local = threading.local()
        self.stepping = CpuAccount("simulator stepping")
        """CPU time of the stepping task itself, the world's own time taken off: waiting for
        the daemons to settle, handing results over, pacing. The robot has none of it."""
        self.robots: list[Simulation] = []
        """Each robot's simulation, in the order they were made (each adds itself)."""
        self._origin = clock.now()
        """The world's t = 0 on the clock: the robots are switched on (self-checks included)."""

    def simulated(self) -> contextlib.AbstractContextManager[None]:
        """The calling thread's CPU time in the block added to ``cpu_s`` and taken off the
        module whose call it is: a simulated device answering (its registers, the world
        behind them) is not the robot's cost. Nested blocks count once."""
        return _Simulated(self)

    @contextlib.contextmanager
    def world_time(self) -> Iterator[World]:
        """The world under the lock, its CPU time booked as :meth:`simulated` (``thread_time``
        counts no time spent waiting for the lock)."""
        with self.simulated(), self.lock:
            yield self.world

    def world_t(self, clock_t: float) -> float:
        """The world's time at clock time ``clock_t``."""
        return clock_t - self._origin

    def advance(self) -> None:
        """Step the world to the clock's present; then each robot's devices and faults."""
        now = self.clock.now()
        with self.world_time() as world:
            world.step(now - self._origin - world.t_s)
        for robot in self.robots:
            robot.advance(now)

    def start(self) -> asyncio.Task[None]:
        """Step the world in a task, in lockstep from this moment: a device call made before
        the task first ran would otherwise take a share of simulated time that depends on
        how soon the machine got to it."""
        if isinstance(self.clock, SteppedClock):
            self.lockstep.engage(True)
        meter_tasks()
        self._task = asyncio.create_task(self.run(), name="simulated world")
        return self._task

    async def stop(self) -> None:
        """Stop stepping (after the daemons' shutdown) and close every robot's devices."""
        if self._task is not None:
            self._task.cancel()
            with contextlib.suppress(asyncio.CancelledError):
                await self._task
        self.close()

    async def run(self, step_s: float = STEP_S) -> None:
        ACCOUNT.set(self.stepping)  # this task's steps (the world's own time is taken off)
        clock = self.clock
        if not isinstance(clock, SteppedClock):
            while True:
                self.advance()
                await clock.sleep(step_s)
        loop = asyncio.get_running_loop()
        wall_step = step_s / clock.speed
        self.lockstep.engage(True)
        try:
            due = time.monotonic()
            while True:
                await settle(loop, self.lockstep)
                # One step is one event for the worker threads: a read that times out at
                # this step sees the bytes the step brings, whichever thread wakes first.
                with self.lockstep.lock:
                    clock.advance(step_s)
                    self.advance()
                if wall_step > 0:
                    due = max(due + wall_step, time.monotonic() - wall_step)
                    if due > time.monotonic():
                        await asyncio.sleep(due - time.monotonic())
        finally:
            self.lockstep.engage(False)

    def close(self) -> None:
        for robot in self.robots:
            robot.close()


async def settle(loop: asyncio.AbstractEventLoop, lockstep: Lockstep) -> None:
    """Return once nothing in the daemons can happen before simulated time moves on: no task
    or callback is ready to run (``loop._ready``, CPython's run queue, is the only place
    that says so), no worker thread is busy and nothing they sent outside the process is
    still on its way (:attr:`Lockstep.outside`); finished calls' results are handed over
    meanwhile, in the order the calls were made."""
    ready: Sized | None = getattr(loop, "_ready", None)
    if ready is None:
        raise RuntimeError("the simulator steps time on asyncio's own event loop only")
    while True:
        await _settle_inside(ready, lockstep)
        arrived = [await traffic.drain() for traffic in lockstep.outside]
        if not any(arrived):
            return


async def _settle_inside(ready: Sized, lockstep: Lockstep) -> None:
    while True:
        await asyncio.sleep(0)
        if ready:
            continue
        results = lockstep.settle()
        if not results and not ready:
            return
        for deliver in results:
            deliver()
