"""Board traffic like a short hallway pass, for the recording tests."""

from __future__ import annotations

import asyncio
from collections.abc import Callable
from pathlib import Path
from typing import Any

from pydantic import BaseModel

from coffeebot.board import Board, Envelope, Topic
from coffeebot.board.recording import Player, PlayStats, Recorder
from coffeebot.messages import (
    ALL_TOPICS,
    COLLISION,
    DELIVERY_STATUS,
    HEALTH,
    ODOMETRY,
    RANGE_SCAN,
    CollisionStatus,
    DeliveryUpdate,
    Health,
    HealthStatus,
    Odometry,
    OrderStatus,
    RangeReading,
    RangeScan,
    ReadingStatus,
    SafetyState,
)
from manual_clock import ManualClock, settle

Published = dict[str, list[Envelope[Any]]]


def scan(n: int, t: float) -> RangeScan:
    return RangeScan(
        cycle_start_s=t,
        cycle_time_s=0.02,
        readings=[
            RangeReading(sensor=i, status=ReadingStatus.VALID, distance_mm=600 + 10 * i + n % 50)
            for i in range(8)
        ],
    )


def odometry(n: int) -> Odometry:
    return Odometry(
        controller_time_ms=10 * n,
        left_ticks=3 * n,
        right_ticks=3 * n + n // 7,
        gyro_z_dps=0.5,
        left_mm_s=500.0,
        right_mm_s=505.0,
    )


async def periodic(
    board: Board,
    topic: Topic[Any],
    period_s: float,
    make: Callable[[int], BaseModel],
    out: Published,
    count: int,
) -> None:
    for n in range(count):
        out.setdefault(topic.name, []).append(board.publish(topic, make(n)))
        await board.clock.sleep(period_s)


async def drive_traffic(board: Board, clock: ManualClock) -> Published:
    """A short hallway pass: scans and verdicts at 50 Hz, odometry at 100 Hz, a few events."""
    out: Published = {}
    tasks = [
        periodic(board, RANGE_SCAN, 0.02, lambda n: scan(n, clock.now()), out, 100),
        periodic(
            board,
            COLLISION,
            0.02,
            lambda n: CollisionStatus(state=SafetyState.GO, scan_seq=n),
            out,
            100,
        ),
        periodic(board, ODOMETRY, 0.01, odometry, out, 200),
        periodic(
            board,
            DELIVERY_STATUS,
            0.5,
            lambda n: DeliveryUpdate(order_id="A1", status=list(OrderStatus)[n]),
            out,
            4,
        ),
    ]
    running = [asyncio.create_task(t) for t in tasks]
    out[HEALTH.name] = [board.publish(HEALTH, Health(module="tof", status=HealthStatus.RUNNING))]
    await clock.advance(2.5)
    await asyncio.gather(*running)
    return out


async def make_recording(path: Path) -> tuple[Published, Recorder]:
    """Record :func:`drive_traffic` on a board whose clock starts at 100 s."""
    clock = ManualClock(start=100.0)
    board = Board(ALL_TOPICS, clock=clock)
    async with Recorder(board, path, metadata={"robot": "coffeebot-v1"}) as recorder:
        published = await drive_traffic(board, clock)
        await settle()
    return published, recorder


async def play_through(player: Player, clock: ManualClock) -> PlayStats:
    """Run the player, moving the clock to each message's stamp in turn."""
    task = asyncio.create_task(player.run())
    while not task.done():
        deadline = clock.next_deadline()
        if deadline is None:
            await asyncio.sleep(0.001)  # the player is reading the file in a thread
        else:
            await clock.advance(deadline - clock.now())
    return task.result()
