"""Does recording slow the control loop? Scan -> collision -> motion latency, with and without.

The board carries the robot's usual traffic (ToF scans and collision verdicts at --scan-hz,
odometry at twice that, UWB fixes at 10 Hz, motor commands per verdict, health at 1 Hz).
Latency is measured from a scan's board stamp to the moment the motion stand-in holds the
collision verdict for it; loop lag is how late a 5 ms ticker wakes. Rounds alternate between
"off" and "on" so that machine noise falls on both alike; the ratio on/off is the answer.

    .venv/bin/python bench/record.py --seconds 10 --rounds 3
"""

from __future__ import annotations

import argparse
import asyncio
import statistics
import tempfile
from collections.abc import Callable, Coroutine
from pathlib import Path
from typing import Any

from coffeebot.board import Board
from coffeebot.board.recording import Recorder
from coffeebot.messages import (
    ALL_TOPICS,
    COLLISION,
    HEALTH,
    MOTOR_COMMAND,
    ODOMETRY,
    RANGE_SCAN,
    UWB_FIX,
    CollisionStatus,
    Health,
    HealthStatus,
    MotorCommand,
    Odometry,
    RangeReading,
    RangeScan,
    ReadingStatus,
    SafetyState,
    UwbFix,
)


class Samples:
    def __init__(self) -> None:
        self.latency_ms: list[float] = []
        self.lag_ms: list[float] = []
        self.scan_stamps: dict[int, float] = {}


async def every(period_s: float, body: Callable[[int], None]) -> None:
    n = 0
    while True:
        body(n)
        n += 1
        await asyncio.sleep(period_s)


async def collision(board: Board) -> None:
    with board.subscribe(RANGE_SCAN, name="collision") as scans:
        async for envelope in scans:
            nearest = min(r.distance_mm or 4000 for r in envelope.msg.readings)
            state = SafetyState.STOP if nearest < 200 else SafetyState.GO
            board.publish(COLLISION, CollisionStatus(state=state, scan_seq=envelope.seq))


async def motion(board: Board, samples: Samples) -> None:
    with board.subscribe(COLLISION, name="motion") as verdicts:
        async for envelope in verdicts:
            stamp = samples.scan_stamps.pop(envelope.msg.scan_seq, None)
            if stamp is not None:
                samples.latency_ms.append((board.clock.now() - stamp) * 1e3)
            speed = 500.0 if envelope.msg.state is SafetyState.GO else 0.0
            board.publish(MOTOR_COMMAND, MotorCommand(left_mm_s=speed, right_mm_s=speed))


async def ticker(board: Board, samples: Samples) -> None:
    period = 0.005
    while True:
        due = board.clock.now() + period
        await asyncio.sleep(period)
        samples.lag_ms.append(max(0.0, board.clock.now() - due) * 1e3)


def traffic(board: Board, samples: Samples, scan_hz: float) -> list[Coroutine[Any, Any, None]]:
    def scan(n: int) -> None:
        readings = [
            RangeReading(sensor=i, status=ReadingStatus.VALID, distance_mm=800 + (n * 7 + i) % 300)
            for i in range(8)
        ]
        now = board.clock.now()
        envelope = board.publish(
            RANGE_SCAN, RangeScan(cycle_start_s=now, cycle_time_s=1 / scan_hz, readings=readings)
        )
        samples.scan_stamps[envelope.seq] = envelope.stamp

    def odometry(n: int) -> None:
        board.publish(
            ODOMETRY,
            Odometry(
                controller_time_ms=n * 10,
                left_ticks=n * 3,
                right_ticks=n * 3,
                gyro_z_dps=0.1,
                left_mm_s=500.0,
                right_mm_s=500.0,
            ),
        )

    def fix(n: int) -> None:
        board.publish(UWB_FIX, UwbFix(x_mm=1000.0 + n, y_mm=850.0, z_mm=0.0, quality=80))

    def health(n: int) -> None:
        board.publish(HEALTH, Health(module="tof", status=HealthStatus.RUNNING))

    return [
        every(1 / scan_hz, scan),
        every(1 / (2 * scan_hz), odometry),
        every(0.1, fix),
        every(1.0, health),
        collision(board),
        motion(board, samples),
        ticker(board, samples),
    ]


async def one_round(seconds: float, scan_hz: float, record_to: Path | None) -> tuple[Samples, str]:
    board = Board(ALL_TOPICS)
    samples = Samples()
    recorder = Recorder(board, record_to) if record_to is not None else None
    if recorder is not None:
        await recorder.start()
    tasks = [asyncio.create_task(coro) for coro in traffic(board, samples, scan_hz)]
    await asyncio.sleep(seconds)
    for task in tasks:
        task.cancel()
    await asyncio.gather(*tasks, return_exceptions=True)
    note = ""
    if recorder is not None and record_to is not None:
        await recorder.stop()
        size = record_to.stat().st_size
        note = (
            f"written {recorder.written}, lost {recorder.lost}, missed {recorder.missed}, "
            f"{size / 1e6:.2f} MB ({size / seconds / 1e3:.0f} kB/s)"
        )
    return samples, note


def pct(values: list[float], q: float) -> float:
    ordered = sorted(values)
    return ordered[min(len(ordered) - 1, int(q * len(ordered)))]


async def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--seconds", type=float, default=10.0, help="per round")
    parser.add_argument("--rounds", type=int, default=3, help="of each: off, on")
    parser.add_argument("--scan-hz", type=float, default=50.0, help="ToF scan rate")
    args = parser.parse_args()
    results: dict[str, Samples] = {"off": Samples(), "on": Samples()}
    notes = []
    with tempfile.TemporaryDirectory() as tmp:
        for n in range(args.rounds):
            for mode in ("off", "on"):
                path = Path(tmp) / f"round{n}.mcap" if mode == "on" else None
                samples, note = await one_round(args.seconds, args.scan_hz, path)
                results[mode].latency_ms += samples.latency_ms
                results[mode].lag_ms += samples.lag_ms
                if note:
                    notes.append(note)
    print(
        f"scan rate {args.scan_hz:g} Hz, {args.rounds} x {args.seconds:g} s per mode, "
        "latency = scan stamp -> verdict at motion"
    )
    print()
    print("| recording | scans | latency p50 ms | p99 ms | max ms | loop lag p50 ms | p99 ms |")
    print("|---|---|---|---|---|---|---|")
    for mode, s in results.items():
        print(
            f"| {mode} | {len(s.latency_ms)} | {statistics.median(s.latency_ms):.3f} | "
            f"{pct(s.latency_ms, 0.99):.3f} | {max(s.latency_ms):.3f} | "
            f"{statistics.median(s.lag_ms):.3f} | {pct(s.lag_ms, 0.99):.3f} |"
        )
    off, on = results["off"].latency_ms, results["on"].latency_ms
    print()
    print(
        f"ratio on/off: p50 {statistics.median(on) / statistics.median(off):.2f}, "
        f"p99 {pct(on, 0.99) / pct(off, 0.99):.2f}; "
        f"added p50 {(statistics.median(on) - statistics.median(off)) * 1e3:.0f} us "
        f"per {1e3 / args.scan_hz:g} ms cycle"
    )
    for note in notes:
        print(f"recorder: {note}")


if __name__ == "__main__":
    asyncio.run(main())
