"""A chaos run: random faults injected at random moments of simulated deliveries.

    python bench/faults.py                       # a table, for docs/benchmarks.md
    python bench/faults.py --json                # one JSON object
    python bench/faults.py --runs 50 --seed 1 --workers 2 --speed max --save chaos.json

Each run is one delivery through the whole daemon as ``coffeebot sim`` assembles it
(drivers on the simulated buses, perception, navigation, motion, the elevator, the orders
module on its SQLite store), to a room near the tea room (floor 3 for the elevator's
faults). A run draws one fault (a quarter of the runs two) from every kind the simulator
injects (``coffeebot.sim.faults``): the order store locked, read only or full; the motor
controller silent, babbling or unplugged; the UWB tag unplugged or babbling; a ToF sensor
NACKing or no longer ranging; the elevator not answering; a module crashing. Each starts at
a random moment of the delivery and lasts a random while (device faults, one time in five,
for good). Some runs carry no fault: the baseline, measured in the same run.

Each run is judged from its record: the scenario's report (orders as the board last showed
them, contacts), the order database as left on disk, and the robot's truth when the run
ended (a run that ends with an order not delivered goes on until the robot stands still).

- **ended safe**: every order delivered, or the robot standing still at the end;
- **lost**: an accepted order gone from the store, its stored status behind what the board
  announced, or not ended (and not visibly under way) when the run ended;
- **false status**: ``delivered`` or ``arrived`` without the robot at the door, the store
  ahead of what the customer was told, a cancel nobody asked for, a failure whose reason
  does not name the fault injected (or any failure in a run without one);
- **contacts**: the body touched something (ground truth).

Targets: every injected fault ends safe, 0 lost, 0 false statuses, 0 contacts.
"""

from __future__ import annotations

import argparse
import asyncio
import concurrent.futures
import functools
import json
import logging
import math
import multiprocessing
import random
import sqlite3
import sys
import tempfile
import time
from collections.abc import Callable, Sequence
from dataclasses import asdict, dataclass, field
from pathlib import Path
from typing import Any

from coffeebot.config import RobotConfig, load_robot_config
from coffeebot.floorplan import load_floorplan
from coffeebot.messages import MOTION_STATUS, OrderStatus
from coffeebot.modules.base import Module
from coffeebot.runtime.assemble import Runtime
from coffeebot.runtime.service import serve
from coffeebot.runtime.sim import build_sim
from coffeebot.scenario.driver import ScenarioModule
from coffeebot.scenario.report import ScenarioReport
from coffeebot.scenario.spec import Scenario
from coffeebot.sim.simulation import Simulation

ROOT = Path(__file__).resolve().parents[1]
BOARD = ROOT / "boards" / "coffeebot-v1.toml"
PLAN = ROOT / "floorplans" / "cs-building.toml"
START = {"floor": 2, "x_mm": 41500, "y_mm": 295, "heading_deg": 180}
"""By the tea room door, facing down the hallway (floor 2 rooms)."""
START_ELEVATOR = {**START, "heading_deg": 0}
"""Facing the elevator end (floor 3 rooms)."""

NEAR_ROOMS = ("213", "212", "211", "210")
"""Floor 2, 3 to 12 m from the tea room door: short runs."""
UPSTAIRS_ROOMS = ("313", "312")
"""Floor 3, beside the elevator: a ride in every run."""
UPSTAIRS_SHARE = 0.15
"""Runs of the other kinds that go upstairs too (the UWB's floor, a crash while riding)."""
ORDER_AT_S = 2.0

STORE_FAULTS = ("store_locked", "store_read_only", "store_full")
DEVICE_FAULTS = (
    "motor_silent",
    "motor_garbage",
    "motor_unplug",
    "uwb_unplug",
    "uwb_garbage",
    "sensor_nack",
    "sensor_stale",
    "elevator_silent",
)
KINDS = (*STORE_FAULTS, *DEVICE_FAULTS, "module_crash")
BASELINE = "none"
CRASHABLE = (
    "tof",
    "uwb",
    "motor",
    "collision",
    "angle",
    "door",
    "state",
    "navigation",
    "motion",
    "elevator",
    "orders",
)
PERMANENT_SHARE = 0.2
"""Device faults that never clear."""
TWO_FAULTS_SHARE = 0.25

REASONS: dict[str, tuple[str, ...]] = {
    "motor_silent": ("motor",),
    "motor_garbage": ("motor",),
    "motor_unplug": ("motor",),
    "uwb_unplug": ("uwb", "where it is", "floor"),
    "uwb_garbage": ("uwb", "where it is", "floor"),
    "sensor_nack": ("tof", "sensor"),
    "sensor_stale": ("tof", "sensor"),
    "elevator_silent": ("elevator",),
    "store_locked": ("database", "store"),
    "store_read_only": ("database", "store"),
    "store_full": ("database", "store"),
    "module_crash": ("module", "motion", "crash"),
}
"""Words a failed order's reason must contain (one of) to name the fault injected."""

AT_DOOR_MM = 400.0
"""``arrived``/``delivered`` is true only with the robot this near the door's centre."""
STILL_MM_S = 5.0
STILL_FOR_S = 3.0
SETTLE_LIMIT_S = 150.0
"""After the orders ended undelivered, how long the robot may take to come to rest."""


# --- what a run is ----------------------------------------------------------------------------


@dataclass(frozen=True)
class RunPlan:
    index: int
    room: str
    seed: int
    kinds: tuple[str, ...]
    faults: tuple[dict[str, Any], ...]

    @property
    def upstairs(self) -> bool:
        return self.room.startswith("3")


@functools.cache
def expected_s(room: str) -> float:
    """Roughly when the robot stands at ``room``'s door (measured: 213 23 s, 313 83 s)."""
    door = load_floorplan(PLAN).find_room(room).door
    travel = (42000 - door.at_mm) / 1000 * 3.0
    return ORDER_AT_S + 9 + travel + (60 if room.startswith("3") else 0)


def draw_fault(kind: str, rng: random.Random, room: str) -> dict[str, Any]:
    """One fault of ``kind`` at a random moment of a delivery to ``room``."""
    start = round(rng.uniform(ORDER_AT_S + 1.0, expected_s(room)), 2)
    fault: dict[str, Any] = {"kind": kind, "from_s": start}
    permanent = kind in DEVICE_FAULTS and rng.random() < PERMANENT_SHARE
    if not permanent:
        fault["to_s"] = round(start + rng.uniform(0.5, 40.0), 2)
    if kind in ("sensor_nack", "sensor_stale"):
        fault["sensor"] = rng.randrange(8)
    elif kind in ("uwb_garbage", "motor_garbage"):
        fault["seed"] = rng.randrange(1_000_000)
        fault["bytes_per_burst"] = rng.choice((8, 40, 200))
    elif kind == "module_crash":
        fault["module"] = rng.choice(CRASHABLE)
        fault.pop("to_s", None)
    return fault


def plan_runs(runs: int, seed: int) -> list[RunPlan]:
    """``runs`` runs: the kinds and the baseline dealt in shuffled rounds, so every kind
    comes up about as often; rooms, moments and lengths drawn from ``seed``."""
    rng = random.Random(seed)
    deck: list[str] = []
    plans: list[RunPlan] = []
    for index in range(runs):
        if not deck:
            deck = [BASELINE, *KINDS]
            rng.shuffle(deck)
        kind = deck.pop()
        kinds: tuple[str, ...] = () if kind == BASELINE else (kind,)
        if kinds and rng.random() < TWO_FAULTS_SHARE:
            kinds += (rng.choice([k for k in KINDS if k != kind]),)
        upstairs = "elevator_silent" in kinds or rng.random() < UPSTAIRS_SHARE
        room = rng.choice(UPSTAIRS_ROOMS if upstairs else NEAR_ROOMS)
        faults = tuple(draw_fault(k, rng, room) for k in kinds)
        plans.append(RunPlan(index, room, rng.randrange(1_000_000), kinds, faults))
    return plans


def chaos_config(config: RobotConfig) -> RobotConfig:
    """The board's config with the waits that end a hopeless delivery shortened, so a fault
    for good fails its order within a short run (the reason is what is judged, not when)."""
    nav = config.navigation
    elevator = nav.elevator.model_copy(
        update={"call_timeout_s": 20.0, "call_retries": 1, "operator_timeout_s": 20.0}
    )
    nav = nav.model_copy(update={"blocked_give_up_s": 45.0, "elevator": elevator})
    return config.model_copy(update={"navigation": nav})


def scenario_of(plan: RunPlan) -> Scenario:
    upstairs = plan.upstairs
    return Scenario.model_validate(
        {
            "name": f"run{plan.index}-{plan.room}-" + ("+".join(plan.kinds) or BASELINE),
            "floorplan": PLAN,
            "seed": plan.seed,
            "time_limit_s": 420 if upstairs else 300,
            "start": START_ELEVATOR if upstairs else START,
            "orders": [{"room": plan.room, "at_s": ORDER_AT_S}],
            "faults": list(plan.faults),
        }
    )


# --- running one ------------------------------------------------------------------------------


@dataclass
class EndState:
    """The robot's truth when the run ended."""

    t_s: float = 0.0
    speed_mm_s: float = math.inf
    floor: int | None = None
    motion: str = ""
    health: dict[str, str] = field(default_factory=dict)


class Events(logging.Handler):
    """The operator's log: every line with an ``event=``, as (t, module, event, cause)."""

    def __init__(self, sim: Callable[[], Simulation | None]) -> None:
        super().__init__(logging.INFO)
        self.sim = sim
        self.lines: list[dict[str, Any]] = []

    def emit(self, record: logging.LogRecord) -> None:
        event = getattr(record, "event", None)
        if event is None or event == "order" or len(self.lines) >= 60:
            return
        sim = self.sim()
        self.lines.append(
            {
                "t": None if sim is None else round(sim.t_s, 2),
                "logger": record.name.removeprefix("coffeebot."),
                "event": event,
                "cause": str(getattr(record, "cause", ""))[:160],
            }
        )


def _end_state(runtime: Runtime, sim: Simulation) -> EndState:
    with sim.lock:
        left, right = sim.robot.wheel_speeds_mm_s
        floor = sim.robot.floor_level
    motion = runtime.board.latest(MOTION_STATUS)
    return EndState(
        t_s=round(sim.t_s, 2),
        speed_mm_s=round(max(abs(left), abs(right)), 1),
        floor=floor,
        motion="" if motion is None else f"{motion.msg.state.value}: {motion.msg.detail}",
        health={h.module: h.status.value for h in runtime.daemon.health()},
    )


async def run_one(plan: RunPlan, speed: float) -> dict[str, Any]:
    """Run ``plan`` through the whole daemon; its record, judged."""
    floorplan = load_floorplan(PLAN)
    scenario = scenario_of(plan)
    config = scenario.configure(chaos_config(load_robot_config(BOARD)))
    driver: list[ScenarioModule] = []
    end = EndState()
    holder: list[Simulation] = []
    events = Events(lambda: holder[0] if holder else None)
    logging.getLogger("coffeebot").addHandler(events)
    started = time.monotonic()
    try:
        with tempfile.TemporaryDirectory(prefix="coffeebot-chaos-") as state:
            state_dir = Path(state)
            settling: list[asyncio.Task[None]] = []

            def add_driver(runtime: Runtime, sim: Simulation) -> list[Module]:
                holder.append(sim)

                def finish(why: str) -> None:
                    """Delivered, or the time limit: stop now; else once the robot rests."""
                    track = driver[0].log
                    delivered = all(o.status == OrderStatus.DELIVERED for o in track.orders)
                    if delivered or track.ended == "time limit":
                        _stop(runtime, sim, why)
                    else:
                        settling.append(asyncio.create_task(_settle(runtime, sim, why)))

                driver.append(
                    ScenarioModule(
                        scenario, floorplan, runtime.config, sim, runtime.own_orders(), finish
                    )
                )
                return [*driver]

            def _stop(runtime: Runtime, sim: Simulation, why: str) -> None:
                nonlocal end
                end = _end_state(runtime, sim)
                runtime.request_stop(why)

            async def _settle(runtime: Runtime, sim: Simulation, why: str) -> None:
                clock = runtime.board.clock
                since = clock.now()
                still_from: float | None = None
                while clock.now() - since < SETTLE_LIMIT_S:
                    state = _end_state(runtime, sim)
                    if state.speed_mm_s < STILL_MM_S:
                        still_from = clock.now() if still_from is None else still_from
                        if clock.now() - still_from >= STILL_FOR_S:
                            break
                    else:
                        still_from = None
                    await clock.sleep(0.25)
                _stop(runtime, sim, f"{why}; the robot came to rest")

            async with build_sim(
                config,
                floorplan,
                scenario.setup(speed),
                add_driver,
                web=False,
                state_dir=state_dir,
            ) as (runtime, _):
                await serve(runtime)
            report = driver[0].report()
            stored = read_store(state_dir / "orders.sqlite3")
    finally:
        logging.getLogger("coffeebot").removeHandler(events)
    row = judge(plan.kinds, report, stored, end)
    row.update(
        {
            "run": plan.index,
            "scenario": scenario.name,
            "room": plan.room,
            "faults": list(plan.faults),
            "end": asdict(end),
            "events": events.lines,
            "wall_s": round(time.monotonic() - started, 1),
        }
    )
    return row


def read_store(path: Path) -> dict[str, dict[str, str]]:
    """Every order in the database file as it was left: id -> status, detail."""
    db = sqlite3.connect(f"file:{path}?mode=ro", uri=True)
    try:
        rows = db.execute("SELECT id, status, detail FROM orders").fetchall()
    finally:
        db.close()
    return {row[0]: {"status": row[1], "detail": row[2]} for row in rows}


# --- judging one ------------------------------------------------------------------------------


def judge(
    kinds: Sequence[str],
    report: ScenarioReport,
    stored: dict[str, dict[str, str]],
    end: EndState,
) -> dict[str, Any]:
    """The verdict on one run from its record (see the module's docstring)."""
    orders: list[dict[str, Any]] = []
    for o in report.orders:
        verdict: dict[str, Any] = {
            "id": o.id,
            "status": o.status,
            "detail": o.detail,
            "lost": "",
            "false": "",
        }
        orders.append(verdict)
        if o.id is None:
            continue  # refused when placed: the customer was told, nothing was accepted
        row = stored.get(o.id)
        status = OrderStatus(o.status)
        at_door = o.stop_error_mm is not None and o.stop_error_mm <= AT_DOOR_MM
        if row is None:
            verdict["lost"] = "accepted but not in the database"
            continue
        if row["status"] != o.status:
            ahead = _rank(row["status"]) > _rank(o.status)
            if ahead:
                verdict["false"] = f"the database says {row['status']}, the customer saw {o.status}"
            else:
                verdict["lost"] = f"announced {o.status}, the database says {row['status']}"
            continue
        if status in (OrderStatus.DELIVERED, OrderStatus.ARRIVED) and not at_door:
            verdict["false"] = f"{o.status} with the robot {o.stop_error_mm} mm from the door"
        elif status is OrderStatus.CANCELLED:
            verdict["false"] = "cancelled, and nobody cancelled it"
        elif status is OrderStatus.FAILED:
            words = [w for k in kinds for w in REASONS[k]]
            if not kinds:
                verdict["false"] = "failed in a run without a fault"
            elif not any(w in o.detail.lower() for w in words):
                verdict["false"] = f"failed, and the reason names none of {', '.join(kinds)}"
        elif not status.final:
            moving = end.speed_mm_s >= STILL_MM_S
            if not (
                moving and status in (OrderStatus.ON_THE_WAY, OrderStatus.WAITING_FOR_ELEVATOR)
            ):
                doing = "moving" if moving else "at rest"
                verdict["lost"] = f"still {o.status} with the robot {doing} at the end"
    delivered = bool(report.orders) and all(
        o.status == OrderStatus.DELIVERED for o in report.orders
    )
    return {
        "kinds": list(kinds),
        "ended_safe": delivered or end.speed_mm_s < STILL_MM_S,
        "orders": orders,
        "contacts": [c.model_dump() for c in report.collisions],
        "sim_time_s": report.sim_time_s,
    }


_ORDER = [
    OrderStatus.QUEUED,
    OrderStatus.PREPARING,
    OrderStatus.ON_THE_WAY,
    OrderStatus.WAITING_FOR_ELEVATOR,
    OrderStatus.ARRIVED,
]


def _rank(status: str) -> int:
    """How far along the lifecycle (final statuses last)."""
    s = OrderStatus(status)
    return len(_ORDER) if s.final else _ORDER.index(s)


# --- many runs --------------------------------------------------------------------------------


def run_in_process(plan: RunPlan, speed: float) -> dict[str, Any]:
    logging.basicConfig(level=logging.CRITICAL)
    logging.getLogger("coffeebot").setLevel(logging.INFO)
    logging.getLogger("coffeebot").propagate = False
    try:
        return asyncio.run(run_one(plan, speed))
    except Exception as exc:  # a run the bench could not finish is reported, not hidden
        return {
            "run": plan.index,
            "scenario": scenario_of(plan).name,
            "kinds": list(plan.kinds),
            "faults": list(plan.faults),
            "error": f"{type(exc).__name__}: {exc}",
            "ended_safe": False,
            "orders": [],
            "contacts": [],
        }


def bench(runs: int, seed: int, workers: int, speed: float, progress: bool) -> dict[str, Any]:
    plans = plan_runs(runs, seed)
    rows: list[dict[str, Any]] = []
    context = multiprocessing.get_context("spawn")
    with concurrent.futures.ProcessPoolExecutor(workers, mp_context=context) as pool:
        futures = [pool.submit(run_in_process, plan, speed) for plan in plans]
        for future in concurrent.futures.as_completed(futures):
            row = future.result()
            rows.append(row)
            if progress:
                print(_progress(row, len(rows), runs), file=sys.stderr, flush=True)
    rows.sort(key=lambda r: int(r["run"]))
    return summarize(rows)


def _progress(row: dict[str, Any], done: int, runs: int) -> str:
    bad = [o["lost"] or o["false"] for o in row["orders"] if o["lost"] or o["false"]]
    status = ", ".join(f"{o['status']}" for o in row["orders"])
    return (
        f"[{done}/{runs}] {row['scenario']}: {status} safe={row['ended_safe']} "
        f"contacts={len(row['contacts'])} {row.get('error', '')} {'; '.join(bad)} "
        f"({row.get('wall_s', '?')} s)"
    )


def _tally(rows: Sequence[dict[str, Any]]) -> dict[str, int]:
    orders = [o for r in rows for o in r["orders"] if o["id"] is not None]
    return {
        "runs": len(rows),
        "faults_injected": sum(len(r["kinds"]) for r in rows),
        "ended_safe": sum(len(r["kinds"]) for r in rows if r["ended_safe"]),
        "runs_ended_safe": sum(bool(r["ended_safe"]) for r in rows),
        "orders": len(orders),
        "delivered": sum(o["status"] == "delivered" for o in orders),
        "failed": sum(o["status"] == "failed" for o in orders),
        "orders_lost": sum(bool(o["lost"]) for o in orders),
        "orders_with_false_status": sum(bool(o["false"]) for o in orders),
        "contacts": sum(len(r["contacts"]) for r in rows),
        "errors": sum("error" in r for r in rows),
    }


def summarize(rows: list[dict[str, Any]]) -> dict[str, Any]:
    by_fault = {}
    for kind in (BASELINE, *KINDS):
        mine = [r for r in rows if (kind in r["kinds"]) or (kind == BASELINE and not r["kinds"])]
        tally = _tally(mine)
        if kind != BASELINE:  # a run with two faults counts once under each
            tally["faults_injected"] = sum(r["kinds"].count(kind) for r in mine)
            tally["ended_safe"] = sum(r["kinds"].count(kind) for r in mine if r["ended_safe"])
        by_fault[kind] = tally
    total = _tally(rows)
    return {**total, "by_fault": by_fault, "rows": rows}


def table(result: dict[str, Any]) -> str:
    lines = [
        "| fault | runs | injected | ended safe | orders | delivered | failed | lost "
        "| false status | contacts |",
        "|---|---|---|---|---|---|---|---|---|---|",
    ]
    for kind, t in result["by_fault"].items():
        label = "none (baseline)" if kind == BASELINE else kind
        safe = t["runs_ended_safe"] if kind == BASELINE else t["ended_safe"]
        lines.append(
            f"| {label} | {t['runs']} | {t['faults_injected']} | {safe} | {t['orders']} "
            f"| {t['delivered']} | {t['failed']} | {t['orders_lost']} "
            f"| {t['orders_with_false_status']} | {t['contacts']} |"
        )
    r = result
    lines.append(
        f"| **all** | {r['runs']} | {r['faults_injected']} | {r['ended_safe']} "
        f"| {r['orders']} | {r['delivered']} | {r['failed']} | {r['orders_lost']} "
        f"| {r['orders_with_false_status']} | {r['contacts']} |"
    )
    notes = []
    for row in result["rows"]:
        for o in row["orders"]:
            if o["lost"] or o["false"]:
                notes.append(f"- {row['scenario']}: {o['lost'] or o['false']} ({o['detail']})")
        if not row["ended_safe"]:
            notes.append(f"- {row['scenario']}: not safe at the end: {row.get('end')}")
        for c in row["contacts"]:
            notes.append(f"- {row['scenario']}: contact with {c['with']} at {c['speed_mm_s']} mm/s")
        if "error" in row:
            notes.append(f"- {row['scenario']}: the bench failed: {row['error']}")
    return "\n".join(lines + (["", *notes] if notes else []))


def speed_arg(text: str) -> float:
    return math.inf if text == "max" else float(text)


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=(__doc__ or "").splitlines()[0])
    parser.add_argument("--runs", type=int, default=26)
    parser.add_argument("--seed", type=int, default=1)
    parser.add_argument("--workers", type=int, default=1)
    parser.add_argument(
        "--speed", type=speed_arg, default=math.inf, help="times real time, or max (default)"
    )
    parser.add_argument("--json", action="store_true", help="print the figures as one JSON object")
    parser.add_argument("--save", type=Path, help="write every run's record here (JSON)")
    parser.add_argument("--table", type=Path, help="write the table here (Markdown)")
    parser.add_argument("--quiet", action="store_true", help="no line per run on stderr")
    args = parser.parse_args(argv)
    started = time.monotonic()
    result = bench(args.runs, args.seed, args.workers, args.speed, not args.quiet)
    elapsed = time.monotonic() - started
    text = table(result)
    if args.save:
        args.save.write_text(json.dumps(result, indent=1) + "\n")
    if args.table:
        args.table.write_text(text + "\n")
    if args.json:
        print(json.dumps({k: v for k, v in result.items() if k != "rows"}))
    else:
        print(text)
        print(f"\n(elapsed {elapsed:.0f} s)")
    return 0


if __name__ == "__main__":
    sys.exit(main())
