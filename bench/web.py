"""Web load benchmark: the order API and the inspector stream, loaded from a second process.

The daemon (orders + web modules on a real board, SQLite store in a temporary directory) runs
in this process on 127.0.0.1; each load phase runs ``python bench/web.py --client ...`` as a
child process, bounded by a request count and a time limit, and reports latencies back as
JSON. Latency ratios are against ``GET /healthz`` measured in the same run.

Control-loop deadlines: until the simulated robot is merged, a stand-in board load runs next
to the server: a 50 Hz publisher on ``tof/scan`` and a subscriber that makes a trivial
decision per scan. A scan whose decision comes later than one scan period after its
scheduled time is a missed deadline, as the collision loop would count it.

Usage: ``.venv/bin/python bench/web.py [--requests 2000] [--seconds 10] [--streams 20]``
"""

from __future__ import annotations

import argparse
import asyncio
import contextlib
import json
import sys
import tempfile
import time
from dataclasses import dataclass, field
from pathlib import Path
from urllib.parse import urlsplit

import aiohttp

from coffeebot.board import Board
from coffeebot.config import WebConfig
from coffeebot.daemon import Daemon
from coffeebot.messages import ALL_TOPICS, RANGE_SCAN, RangeReading, RangeScan, ReadingStatus
from coffeebot.modules.orders import OrdersModule
from coffeebot.modules.web import WebModule
from coffeebot.store import NewOrder, OrderRules, OrderStore
from coffeebot.web import RoomChoice, WebDeps

SCAN_HZ = 50.0
ORDER = {"room": "210", "drink": "latte", "name": "Bench", "notes": "load test"}


# --- client side (the child process) -------------------------------------------------------


def percentile(values: list[float], q: float) -> float:
    ordered = sorted(values)
    return ordered[min(len(ordered) - 1, int(q * len(ordered)))] if ordered else float("nan")


async def load(
    url: str, method: str, concurrency: int, requests: int, seconds: float, streams: int
) -> dict[str, float]:
    """``requests`` calls with ``concurrency`` workers (stopping at ``seconds``), while
    ``streams`` inspector streams are held open and read."""
    if urlsplit(url).hostname not in ("127.0.0.1", "localhost"):
        raise SystemExit("the benchmark only loads loopback addresses")
    base = f"{urlsplit(url).scheme}://{urlsplit(url).netloc}"
    latencies: list[float] = []
    failures = 0
    frames = 0
    remaining = requests
    deadline = time.perf_counter() + seconds
    body = json.dumps(ORDER).encode()
    headers = {"Content-Type": "application/json"}

    async def worker(session: aiohttp.ClientSession) -> None:
        nonlocal remaining, failures
        while remaining > 0 and time.perf_counter() < deadline:
            remaining -= 1
            start = time.perf_counter()
            data = body if method == "POST" else None
            async with session.request(method, url, data=data, headers=headers) as response:
                await response.read()
                if response.status >= 400:
                    failures += 1
            latencies.append(time.perf_counter() - start)

    async def reader(session: aiohttp.ClientSession) -> None:
        nonlocal frames
        async with session.get(base + "/api/board/stream") as response:
            async for line in response.content:
                if line.startswith(b"data: "):
                    frames += 1

    connector = aiohttp.TCPConnector(limit=concurrency + streams)
    async with aiohttp.ClientSession(connector=connector) as session:
        readers = [asyncio.create_task(reader(session)) for _ in range(streams)]
        began = time.perf_counter()
        await asyncio.gather(*(worker(session) for _ in range(concurrency)))
        elapsed = time.perf_counter() - began
        for task in readers:
            task.cancel()
        await asyncio.gather(*readers, return_exceptions=True)
    return {
        "requests": len(latencies),
        "failures": failures,
        "rps": len(latencies) / elapsed,
        "p50_ms": percentile(latencies, 0.50) * 1e3,
        "p99_ms": percentile(latencies, 0.99) * 1e3,
        "frames_per_s": frames / elapsed,
    }


# --- server side ---------------------------------------------------------------------------


@dataclass
class ScanLoad:
    """The control-loop stand-in: 50 Hz scans and a subscriber that checks its deadline."""

    board: Board
    period_s: float = 1.0 / SCAN_HZ
    scans: int = 0
    missed: int = 0
    lateness_ms: list[float] = field(default_factory=list)
    stop: bool = False
    last_seq: int = 0

    def reset(self) -> None:
        self.scans = self.missed = 0
        self.lateness_ms.clear()

    async def publish(self) -> None:
        readings = [
            RangeReading(sensor=i, status=ReadingStatus.VALID, distance_mm=900) for i in range(8)
        ]
        due = time.perf_counter()
        while True:
            due += self.period_s
            await asyncio.sleep(max(0.0, due - time.perf_counter()))
            scan = RangeScan(cycle_start_s=due, cycle_time_s=0.02, readings=readings)
            self.board.publish(RANGE_SCAN, scan)

    async def decide(self) -> None:
        with self.board.subscribe(RANGE_SCAN, name="deadline-probe") as scans:
            async for envelope in scans:
                self.stop = min(r.distance_mm or 0 for r in envelope.msg.readings) < 200
                late = time.perf_counter() - envelope.msg.cycle_start_s
                self.scans += 1
                self.lateness_ms.append(late * 1e3)
                # LATEST delivery drops scans a slow reader never saw: those are missed too.
                skipped = envelope.seq - self.last_seq - 1 if self.last_seq else 0
                self.last_seq = envelope.seq
                self.missed += int(late > self.period_s) + skipped


@dataclass
class Phase:
    label: str
    path: str
    method: str = "GET"
    concurrency: int = 8
    streams: int = 0


Row = tuple[Phase, dict[str, float], int, int, float]


async def run_phase(url: str, phase: Phase, requests: int, seconds: float) -> dict[str, float]:
    child = await asyncio.create_subprocess_exec(
        sys.executable,
        __file__,
        "--client",
        url + phase.path,
        "--method",
        phase.method,
        "--concurrency",
        str(phase.concurrency),
        "--requests",
        str(requests),
        "--seconds",
        str(seconds),
        "--streams",
        str(phase.streams),
        stdout=asyncio.subprocess.PIPE,
    )
    out, _ = await child.communicate()
    if child.returncode != 0:
        raise SystemExit(f"load phase {phase.label!r} failed")
    return json.loads(out)


async def serve_and_measure(requests: int, seconds: float, streams: int) -> None:
    board = Board(ALL_TOPICS)
    with tempfile.TemporaryDirectory() as tmp:
        store = OrderStore(Path(tmp) / "orders.sqlite3")
        orders = OrdersModule(store)
        config = WebConfig(port=0, drinks=["latte"], order_burst=10**9, stream_period_s=0.1)
        web = WebModule(
            WebDeps(
                board=board,
                bus=board,
                orders=orders,
                rooms=[RoomChoice(id="210", floor=2)],
                config=config,
                modules=[orders],
            )
        )
        daemon = Daemon(board, [orders, web])
        await daemon.start()
        await web.started.wait()
        assert web.url is not None
        scan_load = ScanLoad(board)
        tasks = [asyncio.create_task(scan_load.publish()), asyncio.create_task(scan_load.decide())]
        rules = OrderRules(rooms={"210"}, drinks={"latte"})
        first = await orders.place(NewOrder.model_validate(ORDER, context=rules), client="bench")
        phases = [
            Phase("GET /healthz (baseline)", "/healthz"),
            Phase("POST /api/orders, 1 client", "/api/orders", "POST", concurrency=1),
            Phase("POST /api/orders, 8 clients", "/api/orders", "POST"),
            Phase("GET /api/orders/{id}", f"/api/orders/{first.id}"),
            Phase("GET /api/board (snapshot)", "/api/board"),
            Phase(
                f"POST /api/orders + {streams} inspector streams",
                "/api/orders",
                "POST",
                streams=streams,
            ),
        ]
        rows: list[Row] = []
        try:
            for phase in phases:
                scan_load.reset()
                result = await run_phase(web.url, phase, requests, seconds)
                rows.append(
                    (
                        phase,
                        result,
                        scan_load.scans,
                        scan_load.missed,
                        percentile(scan_load.lateness_ms, 0.99),
                    )
                )
        finally:
            for task in tasks:
                task.cancel()
            with contextlib.suppress(asyncio.CancelledError):
                await asyncio.gather(*tasks)
            await daemon.shutdown()
            store.close()
    print_table(rows, requests, seconds, streams)


def print_table(rows: list[Row], requests: int, seconds: float, streams: int) -> None:
    base = rows[0][1]
    print(
        f"# bench/web.py: loopback, load from a second process, <= {requests} requests or "
        f"{seconds:.0f} s per phase; SQLite synchronous=FULL"
    )
    print(
        "# control loop: STAND-IN (50 Hz tof/scan publisher + deadline-probe subscriber on the"
        " board) until the simulated robot is merged"
    )
    print()
    print(
        "| phase | requests | failed | req/s | p50 ms | p99 ms | p50 x baseline | "
        "stream frames/s | scans | missed deadlines | scan lateness p99 ms |"
    )
    print("|---|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|")
    for phase, r, scans, missed, late99 in rows:
        print(
            f"| {phase.label} | {r['requests']:.0f} | {r['failures']:.0f} | {r['rps']:.0f} | "
            f"{r['p50_ms']:.2f} | {r['p99_ms']:.2f} | {r['p50_ms'] / base['p50_ms']:.1f} | "
            f"{r['frames_per_s']:.1f} | {scans} | {missed} | {late99:.2f} |"
        )


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--requests", type=int, default=2000)
    parser.add_argument("--seconds", type=float, default=10.0)
    parser.add_argument("--streams", type=int, default=20)
    parser.add_argument("--client", help=argparse.SUPPRESS)
    parser.add_argument("--method", default="GET", help=argparse.SUPPRESS)
    parser.add_argument("--concurrency", type=int, default=8, help=argparse.SUPPRESS)
    args = parser.parse_args()
    if args.client:
        result = asyncio.run(
            load(
                args.client,
                args.method,
                args.concurrency,
                args.requests,
                args.seconds,
                args.streams,
            )
        )
        print(json.dumps(result))
    else:
        asyncio.run(serve_and_measure(args.requests, args.seconds, args.streams))


if __name__ == "__main__":
    main()
