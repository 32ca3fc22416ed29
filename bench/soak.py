"""Soak: the whole daemon on the simulated robot for N minutes with orders arriving all along.

The simulated robot runs as `coffeebot sim` runs it (web server included), at real time by
default. Orders are placed through the orders module the way the web places them, every
--order-every simulated seconds, by the scenario driver; a customer's page polls the newest
order over HTTP. At the start (after --warmup) and at the end, and once a minute between,
it prints: resident memory, the process's CPU share and the simulated world's own share of
it (CPU time inside the world, counted by ``Simulation.cpu_s``), board overflows on reliable
topics, module restarts, and orders by status. Staff load each cup once the robot stands
ready in the tea room and customers confirm pickup, as in the scenarios; orders arrive faster
than one robot delivers them, so the queue grows, which is part of the load.

    .venv/bin/python bench/soak.py --minutes 10

Targets over 10 minutes: RSS growth <= 10 % and RSS <= 150 MB, zero restarts, zero drops on
reliable topics.
"""

from __future__ import annotations

import argparse
import asyncio
import contextlib
import itertools
import time
from collections import Counter
from dataclasses import dataclass
from pathlib import Path

import aiohttp

from coffeebot.board import Delivery
from coffeebot.config import load_robot_config
from coffeebot.floorplan import load_floorplan
from coffeebot.logs import setup_logging
from coffeebot.messages import OrderStatus
from coffeebot.modules.base import Module, ModuleContext
from coffeebot.runtime.assemble import Runtime
from coffeebot.runtime.service import serve
from coffeebot.runtime.sim import build_sim
from coffeebot.scenario.driver import ScenarioModule
from coffeebot.scenario.spec import OrderSpec, Scenario, StartPose
from coffeebot.sim.simulation import Simulation
from coffeebot.web import WebModule

ROOT = Path(__file__).resolve().parents[1]
BOARD = ROOT / "boards" / "coffeebot-v1.toml"
PLAN = ROOT / "floorplans" / "cs-building.toml"
STATUS_POLL_S = 2.0
"""How often an open order page asks for its order (simulated seconds)."""


def rss_mb() -> float:
    """Resident set size now, from /proc (what the Pi's memory actually holds)."""
    for line in Path("/proc/self/status").read_text().splitlines():
        if line.startswith("VmRSS:"):
            return int(line.split()[1]) / 1024
    raise RuntimeError("no VmRSS in /proc/self/status")


@dataclass
class Sample:
    wall_s: float
    cpu_s: float
    world_cpu_s: float
    rss_mb: float
    sim_s: float


class Probe(Module):
    """Samples the process every minute of simulated time and ends the run after ``minutes``."""

    name = "soak"

    def __init__(self, runtime: Runtime, sim: Simulation, minutes: float, warmup_s: float) -> None:
        self.runtime = runtime
        self.sim = sim
        self.duration_s = minutes * 60
        self.warmup_s = warmup_s
        self.first: Sample | None = None
        self.last: Sample | None = None

    def sample(self) -> Sample:
        sim = self.sim
        with sim.lock:
            world_cpu_s, sim_s = sim.shared.cpu_s, sim.t_s
        return Sample(time.monotonic(), time.process_time(), world_cpu_s, rss_mb(), sim_s)

    async def run(self, ctx: ModuleContext) -> None:
        await ctx.clock.sleep(self.warmup_s)
        started = ctx.clock.now()
        self.first = previous = self.sample()
        await self.row("start", previous, previous)
        for minute in itertools.count(1):
            elapsed = min(minute * 60.0, self.duration_s)
            await ctx.clock.sleep(started + elapsed - ctx.clock.now())
            now = self.sample()
            done = elapsed >= self.duration_s
            await self.row("end" if done else f"{minute} min", previous, now)
            previous = self.last = now
            if done:
                self.runtime.request_stop(f"soak of {self.duration_s / 60:g} min done")
                return

    async def row(self, label: str, before: Sample, now: Sample) -> None:
        """One table row: ``now``'s state, CPU shares over ``before`` .. ``now``."""
        runtime = self.runtime
        wall = now.wall_s - before.wall_s
        cpu = f"{100 * (now.cpu_s - before.cpu_s) / wall:.1f}" if wall > 0 else "-"
        world = f"{100 * (now.world_cpu_s - before.world_cpu_s) / wall:.1f}" if wall > 0 else "-"
        snapshot = runtime.board.snapshot()
        drops = sum(t.overflowed for t in snapshot.topics if t.delivery is Delivery.RELIABLE)
        restarts = sum(s.restarts for s in runtime.daemon.states.values())
        stored = await runtime.own_orders().store.with_status(list(OrderStatus))
        orders = Counter(o.status for o in stored)
        print(
            f"| {label} | {now.sim_s:.0f} | {now.rss_mb:.1f} | {cpu} | {world} | {drops} | "
            f"{restarts} | {sum(orders.values())} | {orders[OrderStatus.DELIVERED]} | "
            f"{orders[OrderStatus.FAILED]} | {orders[OrderStatus.PREPARING]} | "
            f"{orders[OrderStatus.QUEUED]} |",
            flush=True,
        )


class OrderPage(Module):
    """A customer's open order page: polls the newest order's status over HTTP."""

    name = "order-page"

    def __init__(self, runtime: Runtime) -> None:
        self.runtime = runtime
        self.requests = 0

    async def run(self, ctx: ModuleContext) -> None:
        web = self.runtime.module("web")
        assert isinstance(web, WebModule)
        await web.started.wait()
        async with aiohttp.ClientSession(base_url=web.url) as http:
            while True:
                newest = await self.runtime.own_orders().store.with_status(list(OrderStatus))
                if newest:
                    async with http.get(f"/api/orders/{newest[-1].id}") as response:
                        response.raise_for_status()
                        await response.read()
                    self.requests += 1
                await ctx.clock.sleep(STATUS_POLL_S)


def soak_scenario(minutes: float, warmup_s: float, order_every_s: float) -> Scenario:
    """Orders for the offices of floor 2 and 3 in turn, one every ``order_every_s``."""
    plan = load_floorplan(PLAN)
    offices = [d.room for f in plan.floors for d in f.doors if d.kind == "office"]
    run_s = warmup_s + minutes * 60
    times = itertools.takewhile(lambda t: t < run_s, itertools.count(1.0, order_every_s))
    return Scenario(
        name="soak",
        floorplan=PLAN,
        time_limit_s=run_s + 60,  # the probe ends the run; this is a backstop
        start=StartPose(floor=2, x_mm=41500, y_mm=295, heading_deg=180),
        orders=[
            OrderSpec(room=room, at_s=t, name=f"soak {n}")
            for n, (t, room) in enumerate(zip(times, itertools.cycle(offices), strict=False))
        ],
    )


async def soak(minutes: float, speed: float, warmup_s: float, order_every_s: float) -> None:
    config = load_robot_config(BOARD)
    config = config.model_copy(update={"web": config.web.model_copy(update={"port": 0})})
    plan = load_floorplan(PLAN)
    scenario = soak_scenario(minutes, warmup_s, order_every_s)
    probe: list[Probe] = []
    page: list[OrderPage] = []

    def add(runtime: Runtime, sim: Simulation) -> list[Module]:
        driver = ScenarioModule(
            scenario, plan, runtime.config, sim, runtime.own_orders(), runtime.request_stop
        )
        probe.append(Probe(runtime, sim, minutes, warmup_s))
        page.append(OrderPage(runtime))
        return [driver, probe[0], page[0]]

    print(
        f"soak: {minutes:g} min at --speed {speed:g} after {warmup_s:g} s warm-up, an order "
        f"every {order_every_s:g} s, web server on, an order page polling every "
        f"{STATUS_POLL_S:g} s"
    )
    print()
    print(
        "| at | sim s | RSS MB | CPU % | world CPU % | reliable drops | restarts | orders | "
        "delivered | failed | preparing | queued |"
    )
    print("|---|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|")
    async with build_sim(config, plan, scenario.setup(speed), add, web=True) as (runtime, _):
        await serve(runtime)
    first, last = probe[0].first, probe[0].last
    if first is None or last is None:
        raise SystemExit("the run ended before the soak did")
    growth = 100 * (last.rss_mb - first.rss_mb) / first.rss_mb
    cpu = 100 * (last.cpu_s - first.cpu_s) / (last.wall_s - first.wall_s)
    world = 100 * (last.world_cpu_s - first.world_cpu_s) / (last.wall_s - first.wall_s)
    print()
    print(
        f"RSS {first.rss_mb:.1f} -> {last.rss_mb:.1f} MB ({growth:+.1f} %); CPU {cpu:.1f} % "
        f"of one core, of which the simulated world {world:.1f} % and the robot "
        f"{cpu - world:.1f} %; {page[0].requests} order page requests"
    )


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--minutes", type=float, default=10.0, help="measured, after warm-up")
    parser.add_argument("--speed", type=float, default=1.0, help="simulated time speed-up")
    parser.add_argument("--warmup", type=float, default=30.0, help="simulated s before 'start'")
    parser.add_argument("--order-every", type=float, default=20.0, help="simulated s")
    parser.add_argument("--log-level", default="WARNING")
    args = parser.parse_args()
    setup_logging(args.log_level)
    with contextlib.suppress(KeyboardInterrupt):
        asyncio.run(soak(args.minutes, args.speed, args.warmup, args.order_every))


if __name__ == "__main__":
    main()
