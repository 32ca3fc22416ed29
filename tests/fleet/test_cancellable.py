"""A cancellation that lands as the broker answers ends the task (Python 3.11's
``asyncio.wait_for``, which aiomqtt waits with, drops it)."""

from __future__ import annotations

import asyncio

import aiomqtt
import pytest

from coffeebot.fleet.cancellable import CancellableClient
from coffeebot.fleet.mosquitto import Mosquitto
from coffeebot.fleet.protocol import robot_topic


async def _answered_as_cancelled(client: aiomqtt.Client) -> BaseException | str:
    """What a task waiting for the broker's answer ends with when the answer and its
    cancellation come in the same turn of the event loop (not connected: only the wait)."""
    answer: asyncio.Future[str] = asyncio.get_running_loop().create_future()

    async def waiting() -> str:
        return await client._wait_for(answer, timeout=None)

    task = asyncio.create_task(waiting())
    await asyncio.sleep(0)
    answer.set_result("acknowledged")
    task.cancel()
    try:
        return await task
    except asyncio.CancelledError as exc:
        return exc


async def test_a_cancellation_that_comes_with_the_answer_ends_the_task() -> None:
    ended = await _answered_as_cancelled(CancellableClient("localhost", 1883))
    assert isinstance(ended, asyncio.CancelledError)


async def test_a_task_group_waiting_on_the_broker_ends_when_cancelled() -> None:
    """The hang it mends: the group's other task sees the cancellation, the one waiting on
    the broker must too, or the group waits for it for ever."""
    client = CancellableClient("localhost", 1883)
    answer: asyncio.Future[str] = asyncio.get_running_loop().create_future()
    waiting_on_broker = asyncio.Event()

    async def publishes_for_ever() -> None:
        while True:
            waiting_on_broker.set()
            await client._wait_for(answer, timeout=None)
            await asyncio.Event().wait()  # nothing more to publish

    async def bridge() -> None:
        async with asyncio.TaskGroup() as group:
            group.create_task(publishes_for_ever())
            await asyncio.Event().wait()

    task = asyncio.create_task(bridge())
    await waiting_on_broker.wait()
    answer.set_result("acknowledged")
    task.cancel()
    done, _ = await asyncio.wait({task}, timeout=5.0)
    assert task in done, "the group still waits for its task"
    with pytest.raises(asyncio.CancelledError):
        task.result()


async def test_a_timeout_is_an_mqtt_error_as_aiomqtt_says() -> None:
    client = CancellableClient("localhost", 1883)
    never: asyncio.Future[str] = asyncio.get_running_loop().create_future()
    with pytest.raises(aiomqtt.MqttError, match="timed out"):
        await client._wait_for(never, timeout=0.01)


async def test_aiomqtt_waits_for_the_broker_through_the_mended_wait(
    broker: Mosquitto, monkeypatch: pytest.MonkeyPatch
) -> None:
    """The mend replaces a private method of aiomqtt's: an aiomqtt that no longer waits
    through it (renamed in a release) fails here, not in a hang under load."""
    waits: list[float | None] = []
    mended = CancellableClient._wait_for

    async def counted(self: CancellableClient, fut: object, timeout: float | None) -> object:
        waits.append(timeout)
        return await mended(self, fut, timeout)  # type: ignore[arg-type]

    monkeypatch.setattr(CancellableClient, "_wait_for", counted)
    login = broker.credentials["robot-1"]
    client = CancellableClient(
        broker.address.host,
        broker.address.port,
        username=login.username,
        password=login.password,
        identifier="test-cancellable",
    )
    async with client:
        connected = len(waits)
        await client.publish(robot_topic("robot-1", "state"), b"{}", qos=1)
        published = len(waits)
    assert connected >= 1, "the connection waited through it"
    assert published == connected + 1, "the QoS 1 acknowledgement waited through it"
    assert len(waits) == published + 1, "the disconnection waited through it"
