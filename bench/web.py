"""Web load benchmark: the order API and the inspector stream, loaded from a second process
while the simulated robot drives.

The server under load is the whole daemon on the simulated robot (``build_sim`` with the web
server on: drivers on the simulated buses, collision, perception, state, navigation, motion,
orders, web), at ``--speed 1``, running a scenario (default ``scenarios/floor2-far.toml``)
whose order staff load so the robot drives down the hallway. The load phases start once the
order is on its way. Each phase runs ``python bench/web.py --client ...`` as a child process
on 127.0.0.1, bounded by a request count and a time limit, which reports latencies back as
JSON. Latency ratios are against ``GET /healthz`` measured in the same run.

Control-loop deadlines are measured on the real loop: every ``tof/scan`` envelope and every
``safety/collision`` verdict is noted as it is published (board clock stamps), and the verdict
is matched to its scan by ``scan_seq``. A scan whose verdict was published more than one scan
period after the scan's stamp, or that never got a verdict, is a missed deadline. The daemon
runs on the machine's clock (``SimSetup.wall_clock``), as on the robot, where time does not
wait for a busy loop: the stamps are wall-clock time.

Usage: ``.venv/bin/python bench/web.py [--requests 2000] [--seconds 10] [--streams 20]
[--scenario scenarios/floor2-far.toml]``
"""

from __future__ import annotations

import argparse
import asyncio
import dataclasses
import json
import math
import sys
import time
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any
from urllib.parse import urlsplit

import aiohttp

from coffeebot.board import Board
from coffeebot.config import load_robot_config
from coffeebot.messages import COLLISION, ORDER_UPDATE, RANGE_SCAN, OrderStatus
from coffeebot.modules.base import Module, ModuleContext
from coffeebot.runtime.assemble import Runtime
from coffeebot.runtime.service import serve
from coffeebot.runtime.sim import build_sim
from coffeebot.scenario.driver import ScenarioModule
from coffeebot.scenario.spec import Staff, load_scenario
from coffeebot.sim.simulation import Simulation
from coffeebot.web import WebModule

ROOT = Path(__file__).resolve().parents[1]
BOARD = ROOT / "boards" / "coffeebot-v1.toml"
SCENARIO = ROOT / "scenarios" / "floor2-far.toml"
ORDER = {"room": "210", "drink": "latte", "name": "Bench", "notes": "load test"}
SETTLE_S = 0.5
"""After a phase, how long to wait for the verdicts of its last scans."""


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
        print("go", flush=True)  # the server side starts its measurement window here
        cpu = time.process_time()
        began = time.perf_counter()
        await asyncio.gather(*(worker(session) for _ in range(concurrency)))
        elapsed = time.perf_counter() - began
        cpu = time.process_time() - cpu
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
        "cpu_pct": 100 * cpu / elapsed,
    }


# --- server side ---------------------------------------------------------------------------


class LoopTap:
    """Notes every scan and every collision verdict as the board publishes them.

    Wraps this board's ``publish`` so nothing depends on a subscriber being scheduled in
    time: the stamps are the board's own envelope stamps."""

    def __init__(self, board: Board) -> None:
        self.scans: dict[int, float] = {}
        """scan envelope seq -> stamp"""
        self.verdicts: dict[int, float] = {}
        """scan_seq -> stamp of the first verdict for that scan"""
        publish = board.publish

        def tapped(topic: Any, msg: Any) -> Any:
            envelope = publish(topic, msg)
            if envelope.topic == RANGE_SCAN.name:
                self.scans[envelope.seq] = envelope.stamp
            elif envelope.topic == COLLISION.name:
                self.verdicts.setdefault(envelope.msg.scan_seq, envelope.stamp)
            return envelope

        board.publish = tapped  # type: ignore[method-assign]

    def window(self, start: float, end: float, period_s: float) -> dict[str, float]:
        """Scans stamped in ``[start, end)``: count, rate, missed deadlines, latency p99."""
        stamps = [(seq, t) for seq, t in self.scans.items() if start <= t < end]
        latencies = []
        missed = 0
        for seq, t in stamps:
            verdict = self.verdicts.get(seq)
            if verdict is None or verdict - t > period_s:
                missed += 1
            if verdict is not None:
                latencies.append(verdict - t)
        return {
            "scans": len(stamps),
            "scan_hz": len(stamps) / (end - start),
            "missed": missed,
            "no_verdict": sum(1 for seq, _ in stamps if seq not in self.verdicts),
            "latency_p99_ms": percentile(latencies, 0.99) * 1e3,
            "latency_max_ms": max(latencies, default=math.nan) * 1e3,
        }


@dataclass
class Phase:
    label: str
    path: str
    method: str = "GET"
    concurrency: int = 8
    streams: int = 0


@dataclass
class Row:
    phase: Phase
    load: dict[str, float]
    loop: dict[str, float]
    cpu_pct: float
    """this process (daemon and simulated world) over the phase's wall time"""
    world_pct: float
    client_pct: float
    driven_m: float


async def run_phase(
    url: str, phase: Phase, requests: int, seconds: float, started: Callable[[], None]
) -> dict[str, float]:
    """One load phase in a child process; ``started`` is called when its load begins."""
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
    assert child.stdout is not None
    if await child.stdout.readline() == b"go\n":
        started()
    out, _ = await child.communicate()
    if child.returncode != 0:
        raise RuntimeError(f"load phase {phase.label!r} failed")
    return json.loads(out)


@dataclass
class LoadBench(Module):
    """Waits until the order is on its way, then runs the load phases and ends the run."""

    runtime: Runtime
    sim: Simulation
    tap: LoopTap
    requests: int
    seconds: float
    streams: int
    period_s: float
    rows: list[Row] = field(default_factory=list)
    error: str = ""
    name = "web-bench"
    inputs = (ORDER_UPDATE,)

    async def run(self, ctx: ModuleContext) -> None:
        try:
            await self._run(ctx)
        except Exception as exc:  # a failed phase ends the run with its reason, not a restart
            self.error = f"{type(exc).__name__}: {exc}"
        self.runtime.request_stop("web benchmark done")

    async def _run(self, ctx: ModuleContext) -> None:
        runtime = self.runtime
        web = runtime.module("web")
        assert isinstance(web, WebModule)
        await web.started.wait()
        assert web.url is not None
        with ctx.board.subscribe(ORDER_UPDATE) as updates:
            async for update in updates:
                if update.msg.status is OrderStatus.ON_THE_WAY:
                    break
        first = (await runtime.own_orders().store.with_status(list(OrderStatus)))[0]
        phases = [
            Phase("GET /healthz (baseline)", "/healthz"),
            Phase("POST /api/orders, 1 client", "/api/orders", "POST", concurrency=1),
            Phase("POST /api/orders, 8 clients", "/api/orders", "POST"),
            Phase("GET /api/orders/{id}", f"/api/orders/{first.id}"),
            Phase("GET /api/board (snapshot)", "/api/board"),
            Phase(
                f"POST /api/orders + {self.streams} inspector streams",
                "/api/orders",
                "POST",
                streams=self.streams,
            ),
        ]
        for phase in phases:
            self.rows.append(await self.measure(ctx, web.url, phase))

    async def measure(self, ctx: ModuleContext, url: str, phase: Phase) -> Row:
        sim = self.sim
        clock = ctx.clock

        def sample() -> tuple[float, float, float, float, tuple[float, float]]:
            with sim.lock:
                world, pose = sim.shared.cpu_s, (sim.robot.pose.x_mm, sim.robot.pose.y_mm)
            return clock.now(), time.monotonic(), time.process_time(), world, pose

        samples = []
        load = await run_phase(
            url, phase, self.requests, self.seconds, lambda: samples.append(sample())
        )
        after = sample()
        if not samples:
            raise RuntimeError(f"load phase {phase.label!r} never started")
        before = samples[0]
        await clock.sleep(SETTLE_S)
        wall = after[1] - before[1]
        return Row(
            phase,
            load,
            self.tap.window(before[0], after[0], self.period_s),
            cpu_pct=100 * (after[2] - before[2]) / wall,
            world_pct=100 * (after[3] - before[3]) / wall,
            client_pct=load["cpu_pct"],
            driven_m=math.dist(before[4], after[4]) / 1000,
        )


async def serve_and_measure(
    requests: int, seconds: float, streams: int, scenario_path: Path
) -> None:
    scenario, plan = load_scenario(scenario_path)
    # Nobody takes the cup (the run must not end at the door) and the bench ends the run.
    scenario = scenario.model_copy(
        update={
            "time_limit_s": 3600.0,
            "staff": Staff(load_after_s=scenario.staff.load_after_s, pickup_after_s=None),
        }
    )
    config = scenario.configure(load_robot_config(BOARD))
    web = config.web.model_copy(
        update={"host": "127.0.0.1", "port": 0, "order_burst": 10**9, "stream_period_s": 0.1}
    )
    config = config.model_copy(update={"web": web})
    tof = config.tof
    period_s = 1.0 / tof.scan_rate_hz if tof.scan_rate_hz else tof.timing_budget_ms / 1000.0
    bench: list[LoadBench] = []

    def add(runtime: Runtime, sim: Simulation) -> list[Module]:
        driver = ScenarioModule(
            scenario, plan, runtime.config, sim, runtime.own_orders(), runtime.request_stop
        )
        tap = LoopTap(runtime.board)
        bench.append(LoadBench(runtime, sim, tap, requests, seconds, streams, period_s))
        return [driver, bench[0]]

    setup = dataclasses.replace(scenario.setup(1.0), wall_clock=True)
    async with build_sim(config, plan, setup, add, web=True) as (runtime, _):
        await serve(runtime)
    if bench[0].error or not bench[0].rows:
        raise SystemExit(f"benchmark failed: {bench[0].error or 'the run ended first'}")
    print_table(
        bench[0].rows,
        requests,
        seconds,
        scenario.name,
        period_s,
    )


def print_table(
    rows: list[Row], requests: int, seconds: float, scenario: str, period_s: float
) -> None:
    base = rows[0].load
    print(
        f"# bench/web.py: loopback, load from a second process, <= {requests} requests or "
        f"{seconds:.0f} s per phase; SQLite synchronous=FULL"
    )
    print(
        f"# server: whole daemon on the simulated robot, scenario {scenario!r}, --speed 1 "
        f"(board clock held at real time); deadline = one scan period ({period_s * 1e3:.0f} ms), "
        "scan stamp -> collision verdict stamp"
    )
    print()
    print(
        "| phase | requests | failed | req/s | p50 ms | p99 ms | p50 x baseline | "
        "stream frames/s | scans | scan Hz | missed deadlines | scan->verdict p99 ms | max ms | "
        "driven m | daemon CPU % | world CPU % | load CPU % |"
    )
    print("|---|" + "---:|" * 16)
    for row in rows:
        r, loop = row.load, row.loop
        missed = f"{loop['missed']:.0f}"
        if loop["no_verdict"]:
            missed += f" ({loop['no_verdict']:.0f} without verdict)"
        print(
            f"| {row.phase.label} | {r['requests']:.0f} | {r['failures']:.0f} | {r['rps']:.0f} | "
            f"{r['p50_ms']:.2f} | {r['p99_ms']:.2f} | {r['p50_ms'] / base['p50_ms']:.1f} | "
            f"{r['frames_per_s']:.1f} | {loop['scans']:.0f} | {loop['scan_hz']:.1f} | {missed} | "
            f"{loop['latency_p99_ms']:.2f} | {loop['latency_max_ms']:.1f} | {row.driven_m:.1f} | "
            f"{row.cpu_pct:.0f} | {row.world_pct:.0f} | {row.client_pct:.0f} |"
        )
    print()
    print(
        "daemon CPU % is this process (robot modules, web server and the simulated world) over"
        " the phase's wall time, 100 % = one core; world CPU % is the part inside the"
        " simulated world (Simulation.cpu_s), which the robot does not pay; load CPU % is the"
        " load generator (the child process)."
    )


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--requests", type=int, default=2000)
    parser.add_argument("--seconds", type=float, default=10.0)
    parser.add_argument("--streams", type=int, default=20)
    parser.add_argument("--scenario", type=Path, default=SCENARIO)
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
        asyncio.run(serve_and_measure(args.requests, args.seconds, args.streams, args.scenario))


if __name__ == "__main__":
    main()
