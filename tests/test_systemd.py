"""The sd_notify protocol and the watchdog, against a NOTIFY_SOCKET the test creates."""

from __future__ import annotations

import asyncio
import os
import socket
from collections.abc import Iterator
from pathlib import Path
from typing import ClassVar

import pytest

from coffeebot.board import Board, BoardError
from coffeebot.daemon import Daemon
from coffeebot.messages import ALL_TOPICS, COLLISION, CollisionStatus, SafetyState
from coffeebot.modules.base import Module, ModuleContext
from coffeebot.systemd import Notifier, Watchdog, control_loop_check, run_as_service
from manual_clock import ManualClock, settle


@pytest.fixture
def notify_socket(tmp_path: Path) -> Iterator[tuple[socket.socket, str]]:
    """A datagram socket standing in for systemd's notification socket."""
    sock = socket.socket(socket.AF_UNIX, socket.SOCK_DGRAM)
    path = str(tmp_path / "notify")
    sock.bind(path)
    sock.setblocking(False)
    yield sock, path
    sock.close()


def received(sock: socket.socket) -> list[str]:
    """Every datagram waiting on ``sock``, in arrival order."""
    out = []
    while True:
        try:
            out.append(sock.recv(4096).decode())
        except BlockingIOError:
            return out


def verdict(scan_seq: int) -> CollisionStatus:
    return CollisionStatus(state=SafetyState.GO, scan_seq=scan_seq)


def test_state_lines_arrive_in_order(notify_socket: tuple[socket.socket, str]):
    sock, path = notify_socket
    notifier = Notifier.from_env({"NOTIFY_SOCKET": path})
    assert notifier.enabled
    notifier.status("hardware self-check")
    notifier.ready("running 7 modules")
    notifier.watchdog()
    notifier.stopping("stopping: signal\nSIGTERM")
    notifier.close()
    assert received(sock) == [
        "STATUS=hardware self-check",
        "READY=1\nSTATUS=running 7 modules",
        "WATCHDOG=1",
        "STOPPING=1\nSTATUS=stopping: signal SIGTERM",
    ]


def test_abstract_socket_address():
    name = f"coffeebot-test-{os.getpid()}"
    with socket.socket(socket.AF_UNIX, socket.SOCK_DGRAM) as sock:
        sock.bind("\0" + name)
        sock.setblocking(False)
        assert Notifier.from_env({"NOTIFY_SOCKET": "@" + name}).ready("up")
        assert received(sock) == ["READY=1\nSTATUS=up"]


def test_outside_systemd_every_call_is_a_no_op():
    notifier = Notifier.from_env({})
    assert not notifier.enabled
    assert notifier.watchdog_interval_s is None
    assert not notifier.ready("up")


def test_a_vanished_socket_is_reported_not_raised(tmp_path: Path):
    notifier = Notifier.from_env({"NOTIFY_SOCKET": str(tmp_path / "gone")})
    assert not notifier.watchdog()
    assert not notifier.watchdog()


def test_watchdog_interval_is_half_the_timeout_and_only_for_this_process():
    env = {"NOTIFY_SOCKET": "@x", "WATCHDOG_USEC": "5000000"}
    assert Notifier.from_env(env).watchdog_interval_s == 2.5
    assert Notifier.from_env({**env, "WATCHDOG_PID": str(os.getpid())}).watchdog_interval_s == 2.5
    assert Notifier.from_env({**env, "WATCHDOG_PID": "1"}).watchdog_interval_s is None


async def test_control_loop_check_names_the_silent_topic():
    clock = ManualClock()
    board = Board(ALL_TOPICS, clock=clock)
    check = control_loop_check(board, [COLLISION], max_age_s=0.5)
    assert check() == "no message on safety/collision yet"
    board.publish(COLLISION, verdict(1))
    assert check() is None
    await clock.advance(0.75)
    assert check() == "safety/collision silent for 0.75 s (limit 0.5 s)"


def test_control_loop_check_rejects_unknown_topics():
    with pytest.raises(BoardError):
        control_loop_check(Board(ALL_TOPICS), ["no/such/topic"], 1.0)


async def control_loop(board: Board, period_s: float) -> None:
    """Stands in for the collision module: one verdict per scan period."""
    seq = 0
    while True:
        seq += 1
        board.publish(COLLISION, verdict(seq))
        await board.clock.sleep(period_s)


async def test_pings_stop_while_the_control_loop_is_stalled_and_resume_after(
    notify_socket: tuple[socket.socket, str],
):
    sock, path = notify_socket
    clock = ManualClock()
    board = Board(ALL_TOPICS, clock=clock)
    notifier = Notifier(path, watchdog_usec=1_000_000)
    check = control_loop_check(board, [COLLISION], max_age_s=0.3)
    watchdog = Watchdog(notifier, 0.5, check, max_loop_lag_s=0.2, clock=clock)
    task = asyncio.create_task(watchdog.run())
    loop_task = asyncio.create_task(control_loop(board, 0.1))
    try:
        await clock.advance(1.0)
        assert received(sock) == ["WATCHDOG=1", "WATCHDOG=1"]

        loop_task.cancel()  # the control loop stops publishing
        await clock.advance(2.0)
        assert received(sock) == [
            "STATUS=unhealthy, watchdog pings withheld: safety/collision silent for 0.50 s "
            "(limit 0.3 s)"
        ]
        assert watchdog.withheld == 4

        loop_task = asyncio.create_task(control_loop(board, 0.1))
        await clock.advance(1.0)
        assert received(sock) == ["STATUS=running", "WATCHDOG=1", "WATCHDOG=1"]
    finally:
        task.cancel()
        loop_task.cancel()
        await settle()


async def test_pings_stop_when_the_event_loop_is_stalled(notify_socket: tuple[socket.socket, str]):
    sock, path = notify_socket
    clock = ManualClock()
    watchdog = Watchdog(Notifier(path), 0.5, lambda: None, max_loop_lag_s=0.2, clock=clock)
    task = asyncio.create_task(watchdog.run())
    try:
        await clock.advance(0.5)
        await clock.stall(3.0)  # the loop was blocked: the watchdog wakes 3 s late
        await clock.advance(0.5)
        assert received(sock) == [
            "WATCHDOG=1",
            "STATUS=unhealthy, watchdog pings withheld: event loop stalled: watchdog woke "
            "2.50 s late",
            "STATUS=running",
            "WATCHDOG=1",
        ]
    finally:
        task.cancel()
        await settle()


class FakeCollision(Module):
    name = "collision"
    outputs: ClassVar = (COLLISION,)

    async def run(self, ctx: ModuleContext) -> None:
        seq = 0
        while True:
            seq += 1
            ctx.board.publish(COLLISION, verdict(seq))
            await ctx.clock.sleep(0.1)


async def test_service_lifecycle_order(notify_socket: tuple[socket.socket, str]):
    sock, path = notify_socket
    clock = ManualClock()
    board = Board(ALL_TOPICS, clock=clock)
    daemon = Daemon(board, [FakeCollision()])
    notifier = Notifier.from_env({"NOTIFY_SOCKET": path, "WATCHDOG_USEC": "1000000"})
    checked: list[str] = []

    async def self_check() -> str:
        checked.append(sock.recv(4096).decode())  # STATUS was sent before the check ran
        return "8/8 sensors answer"

    service = asyncio.create_task(
        run_as_service(
            daemon,
            notifier,
            control_loop_check(board, [COLLISION], 0.5),
            self_check=self_check,
            watchdog_clock=clock,
        )
    )
    await clock.advance(1.0)
    daemon.request_stop("test finished")
    await service
    assert checked == ["STATUS=hardware self-check"]
    assert received(sock) == [
        "READY=1\nSTATUS=running 1 modules; 8/8 sensors answer",
        "WATCHDOG=1",
        "WATCHDOG=1",
        "STOPPING=1\nSTATUS=stopping: test finished",
    ]


async def test_failed_self_check_never_reports_ready(notify_socket: tuple[socket.socket, str]):
    sock, path = notify_socket
    daemon = Daemon(Board(ALL_TOPICS, clock=ManualClock()), [FakeCollision()])

    async def self_check() -> str:
        raise RuntimeError("sensor 3 does not answer on mux channel 3")

    with pytest.raises(RuntimeError):
        await run_as_service(daemon, Notifier(path), lambda: None, self_check=self_check)
    assert received(sock) == [
        "STATUS=hardware self-check",
        "STATUS=hardware self-check failed: sensor 3 does not answer on mux channel 3",
    ]
    assert all(state.task is None for state in daemon.states.values())
