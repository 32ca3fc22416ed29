"""A simulated fleet's messages take no simulated time, however slow the wire: the clock
waits for them (coffeebot.fleet.in_step), so a fleet run does not depend on the machine.

The broker is reached through a proxy that holds every chunk of bytes for 30 ms of the
machine's time, and the simulated clock runs flat out: without the wait, hundreds of steps
would pass while one message travels.
"""

from __future__ import annotations

import asyncio
import contextlib
import math
from collections.abc import AsyncIterator

import aiomqtt
import pytest

from coffeebot.clock import SteppedClock
from coffeebot.fleet.client import mqtt_client
from coffeebot.fleet.in_step import messages_in_step
from coffeebot.fleet.mosquitto import DISPATCHER_USER, Mosquitto, free_port
from coffeebot.fleet.protocol import robot_topic
from coffeebot.sim.stepper import STEP_S, settle

WIRE_DELAY_S = 0.03
ROBOT = "robot-1"


async def _pump(reader: asyncio.StreamReader, writer: asyncio.StreamWriter, delay_s: float) -> None:
    try:
        while chunk := await reader.read(65536):
            await asyncio.sleep(delay_s)
            writer.write(chunk)
            await writer.drain()
    except ConnectionError:
        pass
    finally:
        writer.close()


@contextlib.asynccontextmanager
async def slow_wire(broker: Mosquitto, delay_s: float = WIRE_DELAY_S) -> AsyncIterator[str]:
    """A loopback proxy to the broker that delays every chunk by ``delay_s``, in order; its
    URL."""

    handlers: list[asyncio.Task[object]] = []

    async def connect(reader: asyncio.StreamReader, writer: asyncio.StreamWriter) -> None:
        handlers.append(asyncio.current_task())  # type: ignore[arg-type]
        up_reader, up_writer = await asyncio.open_connection(
            broker.address.host, broker.address.port
        )
        with contextlib.suppress(asyncio.CancelledError):  # the proxy closing
            await asyncio.gather(
                _pump(reader, up_writer, delay_s), _pump(up_reader, writer, delay_s)
            )

    port = free_port()
    server = await asyncio.start_server(connect, "127.0.0.1", port)
    try:
        yield f"mqtt://127.0.0.1:{port}"
    finally:
        server.close()
        for handler in handlers:
            handler.cancel()
        await asyncio.gather(*handlers, return_exceptions=True)


async def run_clock(clock: SteppedClock, until_s: float, pace_s: float = 0.0) -> None:
    """The simulator's stepping: each step once the process has settled, ``pace_s`` of the
    machine's time apart."""
    loop = asyncio.get_running_loop()
    clock.lockstep.engage(True)
    try:
        while clock.now() < until_s:
            await settle(loop, clock.lockstep)
            clock.advance(STEP_S)
            if pace_s:
                await asyncio.sleep(pace_s)
    finally:
        clock.lockstep.engage(False)


async def exchange(
    broker: Mosquitto, stepped: bool, until_s: float, pace_s: float = 0.0
) -> list[tuple[str, float, float]]:
    """The dispatcher sends the robot an assignment (QoS 1) and traffic (QoS 0) at 0.1 s
    intervals; the robot acknowledges each (QoS 1). Each message with the simulated time
    it was sent and received."""
    clock = SteppedClock(math.inf)
    in_step = messages_in_step(clock) if stepped else None
    sent: dict[str, float] = {}
    seen: list[tuple[str, float, float]] = []
    async with slow_wire(broker) as url:
        dispatcher = mqtt_client(
            url, broker.credentials[DISPATCHER_USER], "dispatcher", in_step=in_step
        )
        robot = mqtt_client(url, broker.credentials[ROBOT], ROBOT, in_step=in_step)
        async with dispatcher, robot:
            await dispatcher.subscribe(robot_topic(ROBOT, "ack"), qos=1)
            await robot.subscribe(robot_topic(ROBOT, "+"), qos=1)

            async def receive(client: aiomqtt.Client, answers: bool) -> None:
                """Note when each message came; the robot acknowledges each."""
                async for message in client.messages:
                    payload = message.payload
                    assert isinstance(payload, bytes)
                    name = payload.decode()
                    seen.append((name, sent[name], clock.now()))
                    if answers:
                        reply = f"ack {name}"
                        sent[reply] = clock.now()
                        await client.publish(robot_topic(ROBOT, "ack"), reply, qos=1)

            async def send() -> None:
                for i in range(3):
                    await clock.sleep(0.1)
                    for kind, qos in (("assignment", 1), ("traffic", 0)):
                        name = f"{kind} {i}"
                        sent[name] = clock.now()
                        await dispatcher.publish(robot_topic(ROBOT, kind), name, qos=qos)

            tasks = [
                asyncio.create_task(receive(robot, answers=True)),
                asyncio.create_task(receive(dispatcher, answers=False)),
                asyncio.create_task(send()),
            ]
            await run_clock(clock, until_s, pace_s)
            for task in tasks:
                task.cancel()
            await asyncio.gather(*tasks, return_exceptions=True)
    return seen


@pytest.mark.asyncio
async def test_a_message_and_its_answer_take_no_simulated_time(broker: Mosquitto) -> None:
    seen = await exchange(broker, stepped=True, until_s=0.6)
    names = sorted(name for name, _, _ in seen)
    expected = sorted(
        f"{ack}{kind} {i}"
        for i in range(3)
        for kind in ("assignment", "traffic")
        for ack in ("", "ack ")
    )
    assert names == expected
    late = [(name, sent, got) for name, sent, got in seen if got != sent]
    assert late == []


@pytest.mark.asyncio
async def test_without_the_wait_the_slow_wire_shows(broker: Mosquitto) -> None:
    """The control: plain connections on the same wire see the clock run on meanwhile (here
    paced at a step a millisecond, as the simulator at 5x real time)."""
    seen = await exchange(broker, stepped=False, until_s=5.0, pace_s=0.001)
    assert seen, "the plain connections exchanged nothing"
    assert all(got > sent for _, sent, got in seen)


async def arrival_order(broker: Mosquitto, delays_s: dict[str, float]) -> list[str]:
    """Two robots each acknowledge three messages in the same step (QoS 1), each on a wire
    of its own delay; the order they reach the dispatcher in."""
    clock = SteppedClock(math.inf)
    in_step = messages_in_step(clock)
    got: list[str] = []
    async with contextlib.AsyncExitStack() as stack:
        dispatcher = await stack.enter_async_context(
            mqtt_client(
                broker.address.url,
                broker.credentials[DISPATCHER_USER],
                "dispatcher",
                in_step=in_step,
            )
        )
        await dispatcher.subscribe(robot_topic("+", "ack"), qos=1)
        robots = {}
        for robot, delay_s in delays_s.items():
            url = await stack.enter_async_context(slow_wire(broker, delay_s))
            robots[robot] = await stack.enter_async_context(
                mqtt_client(url, broker.credentials[robot], robot, in_step=in_step)
            )

        async def receive() -> None:
            async for message in dispatcher.messages:
                assert isinstance(message.payload, bytes)
                got.append(message.payload.decode())

        async def send(robot: str) -> None:
            await clock.sleep(0.1)
            for i in range(3):
                await robots[robot].publish(robot_topic(robot, "ack"), f"{robot} {i}", qos=1)

        tasks = [asyncio.create_task(receive())]
        tasks += [asyncio.create_task(send(robot)) for robot in delays_s]
        await run_clock(clock, 0.3)
        for task in tasks:
            task.cancel()
        await asyncio.gather(*tasks, return_exceptions=True)
    return got


@pytest.mark.asyncio
async def test_what_arrives_in_one_step_comes_in_one_order_whatever_the_wire(
    broker: Mosquitto,
) -> None:
    """Whichever robot's wire is the slow one, the dispatcher reads their messages of one
    step in the same order: each publisher's together, in the order it sent them."""
    first = await arrival_order(broker, {"robot-1": WIRE_DELAY_S, "robot-2": 0.0})
    second = await arrival_order(broker, {"robot-1": 0.0, "robot-2": WIRE_DELAY_S})
    assert first == [f"robot-{r} {i}" for r in (1, 2) for i in range(3)]
    assert second == first


@pytest.mark.asyncio
async def test_the_clock_goes_on_when_the_broker_is_gone(broker: Mosquitto) -> None:
    """A stepped connection whose broker was killed holds simulated time for no longer than
    the drain's patience: the robots go on without it."""
    clock = SteppedClock(math.inf)
    in_step = messages_in_step(clock)
    client = mqtt_client(broker.address.url, broker.credentials[ROBOT], ROBOT, in_step=in_step)
    with pytest.raises(aiomqtt.MqttError):
        async with client:
            broker.stop()
            await asyncio.sleep(0.2)  # the socket's close reaches the loop
            await client.publish(robot_topic(ROBOT, "ack"), "after the broker", qos=1)
    await asyncio.wait_for(run_clock(clock, 0.1), 5.0)
