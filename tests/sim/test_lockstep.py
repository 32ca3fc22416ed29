"""The world steps only when the daemon has settled: a worker thread's call holds the step
until its result is handed over, results are handed over in the order the calls were made,
and a read on a simulated serial line waits in simulated time."""

from __future__ import annotations

import asyncio
import threading
from collections.abc import Awaitable, Callable

import pytest

from coffeebot.clock import SteppedClock
from coffeebot.hardware.worker import DeviceWorker
from coffeebot.lockstep import Lockstep
from coffeebot.sim.serial_line import MemoryLine

WAIT_S = 5.0
"""How long a test waits for a thread before calling it stuck."""


async def settle(lockstep: Lockstep) -> list[Callable[[], None]]:
    """``Lockstep.settle`` without blocking the test's loop (a wrong answer must not hang)."""
    return await asyncio.wait_for(asyncio.to_thread(lockstep.settle), WAIT_S)


def engaged_clock() -> SteppedClock:
    clock = SteppedClock()
    clock.lockstep.engage(True)
    return clock


async def test_a_running_call_holds_the_step_until_its_result_is_handed_over() -> None:
    clock = engaged_clock()
    worker = DeviceWorker("bus", clock)
    running, release = threading.Event(), threading.Event()

    def transfer() -> str:
        running.set()
        release.wait(WAIT_S)
        return "sample"

    call = asyncio.create_task(worker.call(transfer))
    await asyncio.sleep(0)
    assert running.wait(WAIT_S)
    waiting: list[list[Callable[[], None]]] = []
    settler = threading.Thread(target=lambda: waiting.append(clock.lockstep.settle()))
    settler.start()
    settler.join(0.2)
    assert settler.is_alive(), "settled while a call was still running"
    release.set()
    settler.join(WAIT_S)
    (deliver,) = waiting[0]
    await asyncio.sleep(0.05)
    assert not call.done(), "the result reached the loop before the world handed it over"
    deliver()
    assert await call == "sample"
    worker.close()


async def test_results_reach_the_loop_in_the_order_the_calls_were_made() -> None:
    clock = engaged_clock()
    first, second = DeviceWorker("i2c", clock), DeviceWorker("uart", clock)
    second_done = threading.Event()
    woke: list[str] = []

    def slow() -> str:
        second_done.wait(WAIT_S)  # finishes after the call made after it
        return "i2c"

    def quick() -> str:
        second_done.set()
        return "uart"

    async def record(call: Awaitable[str]) -> None:
        woke.append(await call)

    tasks = [
        asyncio.create_task(record(first.call(slow))),
        asyncio.create_task(record(second.call(quick))),
    ]
    await asyncio.sleep(0)
    results: list[Callable[[], None]] = []
    while len(results) < 2:
        results += await settle(clock.lockstep)
    for deliver in results:
        deliver()
    await asyncio.gather(*tasks)
    assert woke == ["i2c", "uart"]
    first.close()
    second.close()


async def test_a_read_waits_for_bytes_or_for_its_timeout_in_simulated_time() -> None:
    clock = engaged_clock()
    line = MemoryLine("tag", clock.lockstep)
    line.plug()
    port = line.open(line.port, 115200, 0.05)
    worker = DeviceWorker("tag", clock)
    read = asyncio.create_task(worker.call(port.read, 3))
    await asyncio.sleep(0)
    assert await settle(clock.lockstep) == []  # waiting for bytes is settled
    line.send(b"ab")  # not the three bytes it waits for
    assert await settle(clock.lockstep) == []
    clock.advance(0.04)
    assert await settle(clock.lockstep) == []
    assert not read.done()
    clock.advance(0.01)  # the simulated timeout: the read returns what it has
    (deliver,) = await settle(clock.lockstep)
    deliver()
    assert await read == b"ab"
    worker.close()


async def test_an_unplugged_line_fails_the_read_as_pyserial_does() -> None:
    clock = engaged_clock()
    line = MemoryLine("motor", clock.lockstep)
    line.plug()
    port = line.open(line.port, 115200, 1.0)
    worker = DeviceWorker("motor", clock)
    read = asyncio.create_task(worker.call(port.read, 1))
    await asyncio.sleep(0)
    assert await settle(clock.lockstep) == []
    line.unplug()
    (deliver,) = await settle(clock.lockstep)
    deliver()
    with pytest.raises(OSError, match="hung up"):
        await read
    with pytest.raises(OSError, match="could not open port sim://motor"):
        line.open(line.port, 115200, 1.0)
    worker.close()


def test_a_wait_ends_on_the_machines_clock_once_the_world_has_stopped() -> None:
    """After the world's last step (shutdown) simulated time stands still: a driver's poll
    still ends, after its length in the machine's time, so no thread outlives the run."""
    clock = engaged_clock()
    clock.advance(1.0)
    clock.lockstep.engage(False)
    sleeper = threading.Thread(target=clock.lockstep.sleep, args=(0.2,))
    sleeper.start()
    sleeper.join(WAIT_S)
    assert not sleeper.is_alive(), "a 0.2 s sleep never ended once the world had stopped"


def test_a_wait_under_way_when_the_world_stops_ends_too() -> None:
    clock = engaged_clock()
    sleeper = threading.Thread(target=clock.lockstep.sleep, args=(0.2,))
    sleeper.start()
    sleeper.join(0.1)
    assert sleeper.is_alive(), "an engaged sleep ended without simulated time passing"
    clock.lockstep.engage(False)
    sleeper.join(WAIT_S)
    assert not sleeper.is_alive(), "the sleep outlived the world"
