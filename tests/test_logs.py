"""The log line format and the log-once-per-transition convention."""

from __future__ import annotations

import asyncio
import io
import logging
import os
import tempfile

import pytest

from coffeebot.logs import (
    ROBOT,
    Event,
    LogfmtFormatter,
    RobotTag,
    Transitions,
    attached_to_journal,
    log_event,
)


@pytest.fixture
def captured() -> tuple[logging.Logger, io.StringIO]:
    stream = io.StringIO()
    handler = logging.StreamHandler(stream)
    handler.setFormatter(LogfmtFormatter())
    logger = logging.getLogger("test.logs")
    logger.handlers[:] = [handler]
    logger.setLevel(logging.DEBUG)
    logger.propagate = False
    return logger, stream


def lines(stream: io.StringIO) -> list[str]:
    return stream.getvalue().splitlines()


def test_event_line_carries_kind_cause_and_fields(captured: tuple[logging.Logger, io.StringIO]):
    logger, stream = captured
    log_event(logger, Event.RECONNECT, "port reopened after unplug", port="/dev/serial0")
    (line,) = lines(stream)
    assert "level=INFO" in line
    assert 'msg="reconnect: port reopened after unplug"' in line
    assert "event=reconnect" in line
    assert 'cause="port reopened after unplug"' in line
    assert "port=/dev/serial0" in line


def test_fault_is_an_error_and_safety_stop_a_warning(captured: tuple[logging.Logger, io.StringIO]):
    logger, stream = captured
    log_event(logger, Event.FAULT, "sensor 3 bus error")
    log_event(logger, Event.SAFETY_STOP, "obstacle")
    assert [line.split()[1] for line in lines(stream)] == ["level=ERROR", "level=WARNING"]


def test_a_condition_seen_every_cycle_is_logged_once_per_change(
    captured: tuple[logging.Logger, io.StringIO],
):
    logger, stream = captured
    safety = Transitions(logger)
    for state in ["stop", "stop", "go", "go", "go", "stop", "stop"]:
        event = Event.SAFETY_STOP if state == "stop" else Event.SAFETY_CLEAR
        safety.update("collision", state, event, f"verdict {state}", sensor=3)
    logged = lines(stream)
    assert len(logged) == 3
    assert "state=stop previous=None" in logged[0]
    assert "state=go previous=stop" in logged[1]
    assert "event=safety_stop" in logged[2] and "sensor=3" in logged[2]


def test_subjects_are_tracked_separately(captured: tuple[logging.Logger, io.StringIO]):
    logger, stream = captured
    orders = Transitions(logger)
    assert orders.update("order A", "queued", Event.ORDER, "placed on the web")
    assert orders.update("order B", "queued", Event.ORDER, "placed on the web")
    assert not orders.update("order A", "queued", Event.ORDER, "placed on the web")
    assert len(lines(stream)) == 2


def test_reaching_the_initial_state_is_no_event(captured: tuple[logging.Logger, io.StringIO]):
    logger, stream = captured
    link = Transitions(logger, initial={"uwb": "connected"})
    assert not link.update("uwb", "connected", Event.RECONNECT, "port opened")
    assert link.update("uwb", "disconnected", Event.DISCONNECT, "unplugged")
    assert link.update("uwb", "connected", Event.RECONNECT, "port reopened")
    assert ["event=disconnect" in line for line in lines(stream)] == [True, False]
    assert "previous=disconnected" in lines(stream)[1]


def test_tracebacks_stay_on_one_line(captured: tuple[logging.Logger, io.StringIO]):
    logger, stream = captured
    try:
        raise ValueError("bad\nvalue")
    except ValueError:
        logger.exception("boom")
    (line,) = lines(stream)
    assert "exc=" in line and "ValueError" in line


def test_journald_priority_prefix():
    record = logging.LogRecord("x", logging.WARNING, __file__, 1, "hello", None, None)
    assert LogfmtFormatter(syslog_prefix=True).format(record).startswith("<4>ts=")
    assert LogfmtFormatter().format(record).startswith("ts=")


def test_journal_stream_is_recognised_by_device_and_inode():
    with tempfile.TemporaryFile("w") as stream:
        stat = os.fstat(stream.fileno())
        assert attached_to_journal(stream, {"JOURNAL_STREAM": f"{stat.st_dev}:{stat.st_ino}"})
        assert not attached_to_journal(stream, {"JOURNAL_STREAM": f"{stat.st_dev}:1"})
        assert not attached_to_journal(stream, {})


async def test_a_robots_tasks_name_it_in_their_lines(captured: tuple[logging.Logger, io.StringIO]):
    """Two daemons in one process: a task inherits the robot of the task that started it."""
    logger, stream = captured
    logger.handlers[0].addFilter(RobotTag())

    async def daemon(robot: str) -> None:
        ROBOT.set(robot)

        async def module() -> None:
            await asyncio.sleep(0)
            logger.info("motion idle -> moving")

        await asyncio.gather(module(), module())

    await asyncio.gather(daemon("robot-1"), daemon("robot-2"))
    logger.info("dispatcher line")
    robots = [line.rsplit(" ", 1)[-1] for line in lines(stream)]
    assert sorted(robots[:4]) == ["robot=robot-1"] * 2 + ["robot=robot-2"] * 2
    assert "robot=" not in lines(stream)[4]
