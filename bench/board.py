"""Message board benchmark: publish -> receive latency and throughput against asyncio.Queue.

The baseline is the simplest correct fan-out: one unbounded ``asyncio.Queue`` per subscriber,
``put_nowait`` into each. It is measured in the same run with the same message objects, so
the ratios hold on a noisy machine. Cases: 1, 8 and 32 subscribers, paced at 1 kHz and a flood
(the publisher yields once per message so readers run, as a sensor loop would).

    python bench/board.py [--messages 2000] [--json]
"""

from __future__ import annotations

import argparse
import asyncio
import json
import time
from collections.abc import Awaitable, Callable
from typing import Any

import numpy as np

from coffeebot.board import Board, Delivery, Topic
from coffeebot.messages import Message


class Sample(Message):
    sent_ns: int


TOPIC = Topic("bench/sample", Sample, Delivery.RELIABLE, queue_size=1_000_000)

Publish = Callable[[Sample], None]
Receive = Callable[[int], Awaitable[Sample]]


def board_fanout(subscribers: int) -> tuple[Publish, Receive]:
    board = Board([TOPIC])
    subs = [board.subscribe(TOPIC, name=f"s{i}") for i in range(subscribers)]

    async def receive(i: int) -> Sample:
        return (await subs[i].get()).msg

    def publish(msg: Sample) -> None:
        board.publish(TOPIC, msg)

    return publish, receive


def queue_fanout(subscribers: int) -> tuple[Publish, Receive]:
    queues: list[asyncio.Queue[Sample]] = [asyncio.Queue() for _ in range(subscribers)]

    def publish(msg: Sample) -> None:
        for q in queues:
            q.put_nowait(msg)

    async def receive(i: int) -> Sample:
        return await queues[i].get()

    return publish, receive


async def run_case(
    fanout: Callable[[int], tuple[Publish, Receive]],
    subscribers: int,
    messages: int,
    rate_hz: float | None,
) -> dict[str, float]:
    publish, receive = fanout(subscribers)
    latencies = np.zeros((subscribers, messages), dtype=np.int64)

    async def reader(i: int) -> None:
        for n in range(messages):
            msg = await receive(i)
            latencies[i, n] = time.perf_counter_ns() - msg.sent_ns

    readers = [asyncio.create_task(reader(i)) for i in range(subscribers)]
    await asyncio.sleep(0)
    start = time.perf_counter()
    period = None if rate_hz is None else 1.0 / rate_hz
    for n in range(messages):
        if period is not None:
            delay = start + n * period - time.perf_counter()
            if delay > 0:
                await asyncio.sleep(delay)
        publish(Sample(sent_ns=time.perf_counter_ns()))
        if period is None:
            await asyncio.sleep(0)
    await asyncio.gather(*readers)
    elapsed = time.perf_counter() - start
    return {
        "p50_us": float(np.percentile(latencies, 50) / 1000),
        "p99_us": float(np.percentile(latencies, 99) / 1000),
        "msgs_per_s": messages * subscribers / elapsed,
    }


async def run_all(messages: int) -> list[dict[str, Any]]:
    cases = []
    for rate_hz in (1000.0, None):
        for subscribers in (1, 8, 32):
            n = messages if rate_hz else messages * 5
            # Interleave and repeat so drift in machine load hits both sides alike.
            board_runs, queue_runs = [], []
            for _ in range(3):
                queue_runs.append(await run_case(queue_fanout, subscribers, n, rate_hz))
                board_runs.append(await run_case(board_fanout, subscribers, n, rate_hz))

            def med(runs: list[dict[str, float]], key: str) -> float:
                return float(np.median([r[key] for r in runs]))

            cases.append(
                {
                    "subscribers": subscribers,
                    "rate_hz": rate_hz,
                    "board_p50_us": med(board_runs, "p50_us"),
                    "board_p99_us": med(board_runs, "p99_us"),
                    "queue_p50_us": med(queue_runs, "p50_us"),
                    "queue_p99_us": med(queue_runs, "p99_us"),
                    "board_msgs_per_s": med(board_runs, "msgs_per_s"),
                    "queue_msgs_per_s": med(queue_runs, "msgs_per_s"),
                }
            )
    return cases


def print_table(cases: list[dict[str, Any]]) -> None:
    head = (
        f"{'subs':>4} {'rate':>6} | {'board p50':>9} {'p99':>8} | {'queue p50':>9} {'p99':>8} | "
        f"{'p99 ratio':>9} | {'board msg/s':>11} {'queue msg/s':>11} {'ratio':>6}"
    )
    print(head)
    print("-" * len(head))
    for c in cases:
        rate = "flood" if c["rate_hz"] is None else f"{c['rate_hz']:.0f}Hz"
        print(
            f"{c['subscribers']:>4} {rate:>6}"
            f" | {c['board_p50_us']:>7.1f}us {c['board_p99_us']:>6.1f}us"
            f" | {c['queue_p50_us']:>7.1f}us {c['queue_p99_us']:>6.1f}us"
            f" | {c['board_p99_us'] / c['queue_p99_us']:>8.2f}x"
            f" | {c['board_msgs_per_s']:>11.0f} {c['queue_msgs_per_s']:>11.0f}"
            f" {c['board_msgs_per_s'] / c['queue_msgs_per_s']:>5.2f}x"
        )
    paced8 = next(c for c in cases if c["subscribers"] == 8 and c["rate_hz"] == 1000.0)
    floods = [c for c in cases if c["rate_hz"] is None]
    p99_ok = paced8["board_p99_us"] <= 2 * paced8["queue_p99_us"]
    flood_ok = all(c["board_msgs_per_s"] >= 0.5 * c["queue_msgs_per_s"] for c in floods)
    verdict = {True: "met", False: "MISSED"}
    print()
    print(f"target 1 kHz, 8 subscribers: board p99 <= 2 x queue p99: {verdict[p99_ok]}")
    print(f"target flood: board throughput >= 0.5 x queue:          {verdict[flood_ok]}")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--messages", type=int, default=2000, help="per paced case")
    parser.add_argument("--json", action="store_true", help="print one JSON object")
    args = parser.parse_args()
    cases = asyncio.run(run_all(args.messages))
    if args.json:
        print(json.dumps({"cases": cases}))
    else:
        print_table(cases)


if __name__ == "__main__":
    main()
