"""The fleet at work: 1 to 4 simulated robots taking Poisson orders, against the targets.

    python bench/fleet.py                     # a table, for docs/fleet.md
    python bench/fleet.py --json              # one JSON object
    python bench/fleet.py --robots 1,3 --rates 90 --minutes 10 --workers 2
    python bench/fleet.py --robots 3 --rates 90 --greedy-rates "" --no-broker-kill \
        --minutes 60 --logs DIR --record DIR    # a jam to look into, log and MCAP

Each case is one fleet on a Mosquitto of its own (``coffeebot.runtime.fleet``): the
dispatcher and N whole robot daemons in one simulated CS building, every robot parked at its
spot in the tea room at the start. Orders arrive as a Poisson process at the case's rate, to
rooms drawn from every office of both floors; the simulated staff load the cup 3 s after the
robot is ready for it and the customer takes it 5 s after it arrived. The fleet dispatches
by joint assignment (``linear_sum_assignment``, the default); at the rates of
``--greedy-rates`` (the saturated one: there orders pile up) and fleet sizes of
``--greedy-robots``, each case runs a second time on the same arrivals with first-come
greedy dispatch (``[fleet.dispatch] strategy``), for the comparison. The two choose
differently only when several robots are free while several orders wait: each run counts
those assignments (``choices``) and how many the other strategy would have paired
differently (``choices_differing``).

What it measures, on the simulated clock:
- ``delivered_per_h``: cups handed over within the case's minutes (the joint run's; the greedy
  run's with ``--no-joint``);
- ``wait_p50_s``, ``wait_p95_s``: order to the robot at the door; an order still waiting at
  the end counts with its wait so far (a lower bound), so a swamped fleet shows as one;
- ``contacts``: any touch of a robot's body, in either strategy's run;
- ``elevator_wait_p95_s``: from a robot's asking for the elevator (at its door) until it is
  inside the car, the car's own travel included;
- per run (``--save``): each robot's estimate as the state module publishes it against where
  the robot truly was (p95, and the largest with when and where), and with ``--cameras``
  every ceiling-camera fix it received (p95, max, each over 300 mm or for the wrong floor);
- ``joint_p95_s``, ``greedy_p95_s``: the wait p95 of each strategy's run (null where
  it was not run);
- per run (``--save``, and in the table): ``round_trip_est_s``, the dispatcher's own estimate
  of a lone robot's way from the tea room to the door and back, averaged over the cups
  delivered. The orders are the same stream whatever the fleet, but one robot delivers its
  first ten or so, three their first twenty: in 30 minutes the two can draw rooms of
  different distances (seed 1: 190 s against 207), and the table's "same work" column
  weighs each cup by it;
- per run (``--save``, and in the table's notes): ``places_held_pct``, the share of the
  case's minutes each shared place was held by some robot (the dispatcher's lease book,
  sampled), what shows which place holds a fleet back.

``broker_kill``: three robots at 30 orders an hour for half the minutes, the broker killed
twice for 20 s while orders are on their way, then the orders drained: every order placed
must end delivered or failed with its reason (``lost`` counts those that never end), and
none may be served by two robots (``duplicated``: two robots reported it at its door).

Per robot, the broker's load (messages and bytes a second, by an observer subscribed to
everything) and the dispatcher's CPU (its daemon's modules and board, per simulated second)
are measured for docs/fleet.md's "How far one broker and one dispatcher go".

Targets: 0 contacts; 0 lost and 0 duplicated orders; at saturation three robots deliver at
least 2.4x what one does; joint assignment's p95 no worse than greedy's.
"""

from __future__ import annotations

import argparse
import asyncio
import contextlib
import functools
import json
import logging
import math
import random
import sys
import time
from collections import defaultdict
from collections.abc import Callable
from concurrent.futures import ProcessPoolExecutor
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import aiomqtt
import numpy as np

from coffeebot.board.recording import Recorder
from coffeebot.clock import Clock
from coffeebot.config import RobotConfig, load_robot_config
from coffeebot.cpu import BOARD_NAME
from coffeebot.fleet.estimates import TravelTimes
from coffeebot.fleet.mosquitto import DISPATCHER_USER, Mosquitto, mosquitto
from coffeebot.floorplan import load_floorplan
from coffeebot.logs import LogfmtFormatter, RobotTag
from coffeebot.messages import (
    CAMERA_FIX,
    CURRENT_STATE,
    DELIVERY_STATUS,
    LEASE_NEED,
    OrderStatus,
)
from coffeebot.modules.base import Module, ModuleContext
from coffeebot.runtime.fleet import FleetSim, build_fleet_sim, robot_ids, serve_fleet
from coffeebot.scenario.spec import Staff
from coffeebot.scenario.staff import StaffModule
from coffeebot.sim.simulation import Simulation
from coffeebot.store import NewOrder, OrderRules
from coffeebot.web.eta import Pace

ROOT = Path(__file__).resolve().parents[1]
PLAN = load_floorplan(ROOT / "floorplans" / "cs-building.toml")
BOARD = load_robot_config(ROOT / "boards" / "coffeebot-v1.toml")
RULES = OrderRules(rooms=set(PLAN.rooms), drinks=set(BOARD.web.drinks))
TRAVEL = TravelTimes(PLAN, BOARD, Pace())
"""The dispatcher's estimates, for the work each delivered cup took."""
STAFF = Staff(load_after_s=3.0, pickup_after_s=5.0)
SAMPLE_S = 0.25
"""How often the bench looks at the world (elevator entries) and the leases, and places due
orders."""
SPEED = 4.0
"""The daemons are in lockstep with the world, the broker between them is not: at most
this fast, so a message's time on the wire stays small in simulated time."""
MODERATE_PER_H = 10
SATURATED_PER_H = 90
"""One robot delivers ~15 cups an hour, four ~50: 10 an hour keeps one robot busy most of the
time, 90 an hour swamps every fleet size."""
KILLS_AT = (0.3, 0.65)
"""When the broker is killed, as fractions of the broker-kill case's minutes."""
KILL_FOR_S = 20.0
KILL_PER_H = 30
"""The broker-kill case's rate: three robots busy, an order or two waiting most of the time."""
DRAIN_S = 1800.0
"""After the broker-kill case's orders stop: simulated seconds for every order to end."""
AT_THE_DOOR = (OrderStatus.ARRIVED, OrderStatus.DELIVERED)


@dataclass(frozen=True)
class Case:
    robots: int
    orders_per_h: float
    strategy: str
    minutes: float
    seed: int
    broker_kill: bool = False
    cameras: bool = False
    """The building's ceiling cameras on: the dispatcher's camera service for every robot."""

    @property
    def label(self) -> str:
        """What names the case's log and recordings."""
        kill = "-broker-kill" if self.broker_kill else ""
        return f"{self.robots}x{self.orders_per_h:g}-{self.strategy}{kill}"


@dataclass
class Probe(Module):
    """On a robot's board: when it asked for the elevator, which orders it got to the door,
    and how far its estimate and each camera fix it received were from where it truly was
    (``truth``: the simulated robot's floor and position, set once the fleet is built)."""

    name = "bench_probe"
    inputs = (DELIVERY_STATUS, LEASE_NEED, CAMERA_FIX, CURRENT_STATE)

    elevator_asked_s: list[float] = field(default_factory=list)
    at_door: set[str] = field(default_factory=set)
    truth: Callable[[], tuple[int, float, float]] | None = None
    fix_errors: list[tuple[float, str, float]] = field(default_factory=list)
    """(simulated second, camera, distance mm) of every fix received."""
    pose_errors: list[tuple[float, int, float, float, float]] = field(default_factory=list)
    """(simulated second, floor, true x, true y, distance mm) of every estimate published."""

    async def run(self, ctx: ModuleContext) -> None:
        async with asyncio.TaskGroup() as group:
            group.create_task(self._judge_fixes(ctx))
            group.create_task(self._judge_estimates(ctx))
            with (
                ctx.board.subscribe(DELIVERY_STATUS) as reports,
                ctx.board.subscribe(LEASE_NEED) as needs,
            ):
                while True:
                    while (report := reports.get_nowait()) is not None:
                        if report.msg.status in AT_THE_DOOR:
                            self.at_door.add(report.msg.order_id)
                    while (need := needs.get_nowait()) is not None:
                        if need.msg.place == "elevator" and need.msg.want:
                            self.elevator_asked_s.append(ctx.clock.now())
                    await ctx.clock.sleep(SAMPLE_S)

    async def _judge_estimates(self, ctx: ModuleContext) -> None:
        """The state module's estimate as it is published against the truth then (the
        robots' own sensors read each other as walls and people)."""
        with ctx.board.subscribe(CURRENT_STATE) as states:
            async for state in states:
                pose = state.msg.pose
                if self.truth is None or not pose.initialised:
                    continue
                floor, x, y = self.truth()
                if floor == pose.floor:
                    off = math.hypot(pose.x_mm - x, pose.y_mm - y)
                    self.pose_errors.append((ctx.clock.now(), floor, x, y, off))

    async def _judge_fixes(self, ctx: ModuleContext) -> None:
        """Each fix as it arrives (it is the pose at that moment) against the truth then."""
        with ctx.board.subscribe(CAMERA_FIX) as fixes:
            async for fix in fixes:
                if self.truth is None:
                    continue
                floor, x, y = self.truth()
                off = math.hypot(fix.msg.x_mm - x, fix.msg.y_mm - y)
                self.fix_errors.append(
                    (
                        ctx.clock.now(),
                        fix.msg.camera_id,
                        off if floor == fix.msg.floor else math.inf,
                    )
                )


@dataclass
class Traffic:
    """What crossed the broker, per robot (an observer subscribed to everything)."""

    messages: dict[str, int] = field(default_factory=lambda: defaultdict(int))
    payload_bytes: dict[str, int] = field(default_factory=lambda: defaultdict(int))


async def observe(broker: Mosquitto, traffic: Traffic) -> None:
    login = broker.credentials[DISPATCHER_USER]
    host, port = broker.address.host, broker.address.port
    while True:
        with contextlib.suppress(aiomqtt.MqttError):
            async with aiomqtt.Client(
                host,
                port,
                username=login.username,
                password=login.password,
                identifier="bench-observer",
            ) as client:
                await client.subscribe("coffeebot/v1/robots/#", qos=0)
                async for message in client.messages:
                    robot = str(message.topic).split("/")[3]
                    traffic.messages[robot] += 1
                    payload = message.payload
                    traffic.payload_bytes[robot] += (
                        len(payload) if isinstance(payload, bytes) else 0
                    )
        await asyncio.sleep(0.5)


def arrivals(case: Case) -> list[tuple[float, str]]:
    """(simulated second, room) of every order: exponential gaps at the case's rate."""
    rng = random.Random(case.seed)
    rooms = sorted(PLAN.rooms)
    t, out = 0.0, list[tuple[float, str]]()
    while True:
        t += rng.expovariate(case.orders_per_h / 3600.0)
        if t >= case.minutes * 60:
            return out
        out.append((t, rng.choice(rooms)))


def percentile(values: list[float], q: float) -> float | None:
    return round(float(np.percentile(values, q)), 1) if values else None


async def drive(
    fleet: FleetSim, case: Case, staff: StaffModule, probes: dict[str, Probe], broker: Mosquitto
) -> dict[str, Any]:
    clock = fleet.dispatcher.board.clock
    orders = fleet.dispatcher.module
    (lift,) = fleet.world.world.elevators  # a fleet shares one car
    due = arrivals(case)
    placed: dict[str, float] = {}
    entered: dict[str, list[float]] = {name: [] for name in probes}
    end_s = case.minutes * 60
    kills = [f * end_s for f in KILLS_AT] if case.broker_kill else []
    restart_at: float | None = None
    held_s: dict[str, float] = defaultdict(float)
    """Per shared place, how long some robot held it (sampled every ``SAMPLE_S``)."""

    async def place(room: str) -> None:
        new = NewOrder.model_validate(
            {"room": room, "drink": BOARD.web.drinks[0], "name": "Ada"}, context=RULES
        )
        while True:
            with contextlib.suppress(Exception):
                order = await orders.place(new, "bench")
                placed[order.id] = clock.now()
                return
            await clock.sleep(0.05)  # the dispatcher is still starting

    while True:
        now = clock.now()
        while due and due[0][0] <= now:
            await place(due.pop(0)[1])
        if kills and now >= kills[0]:
            kills.pop(0)
            broker.stop()
            restart_at = now + KILL_FOR_S
        if restart_at is not None and now >= restart_at:
            broker.start()
            restart_at = None
        if (dispatcher := orders.dispatcher) is not None and now < end_s:
            for shared, state in dispatcher.leases.places.items():
                # Read, not asked: ``holder()`` would let an expired lease go early.
                if state.lease is not None and now < state.lease.expires_at_s:
                    held_s[shared] += SAMPLE_S
        with fleet.world.lock:
            for sim in fleet.sims:
                asked, inside = probes[sim.robot.name].elevator_asked_s, entered[sim.robot.name]
                pose = sim.robot.pose
                if len(inside) < len(asked) and lift.inside(
                    sim.robot.floor_level, pose.x_mm, pose.y_mm
                ):
                    inside.append(now)
        if now >= end_s and restart_at is None:
            ended = all((t := staff.orders.get(o)) is not None and t.status.final for o in placed)
            if not case.broker_kill or ended or now >= end_s + DRAIN_S:
                break
        await clock.sleep(SAMPLE_S)

    unfinished = sum((t := staff.orders.get(o)) is None or not t.status.final for o in placed)
    waits, delivered, failed = [], 0, []
    round_trips: list[float] = []
    for order_id, placed_s in placed.items():
        times = staff.orders.get(order_id)
        if times is not None and times.arrived_s is not None and times.arrived_s <= end_s:
            waits.append(times.arrived_s - placed_s)
        elif times is None or not times.status.final:
            waits.append(end_s - placed_s)
        if times is not None and times.status is OrderStatus.DELIVERED:
            if times.ended_s is not None and times.ended_s <= end_s:
                delivered += 1
                room = (await orders.get(order_id)).room
                round_trips.append(2 * TRAVEL.base_to(room))
        elif times is not None and times.status.final:
            order = await orders.get(order_id)
            failed.append(f"{order.room}: {order.status}, {order.detail}")
    elevator = [
        entered_s - asked_s
        for name, probe in probes.items()
        for asked_s, entered_s in zip(probe.elevator_asked_s, entered[name], strict=False)
    ]
    servers: dict[str, int] = defaultdict(int)
    for probe in probes.values():
        for order_id in probe.at_door:
            servers[order_id] += 1
    contacts = [
        f"{sim.robot.name} at {c.t_s:.1f} s: {c.element} at {c.speed_mm_s:.0f} mm/s"
        for sim in fleet.sims
        for c in sim.robot.collisions
    ]
    dispatcher = orders.dispatcher
    accounts = fleet.dispatcher.daemon.cpu.accounts
    dispatcher_cpu_s = sum(a.seconds for a in accounts.values())
    return {
        "robots": case.robots,
        "orders_per_h": case.orders_per_h,
        "strategy": case.strategy,
        "simulated_s": round(clock.now(), 1),
        "orders": len(placed),
        "delivered": delivered,
        "delivered_per_h": round(delivered / (end_s / 3600), 1),
        "round_trip_est_s": round(float(np.mean(round_trips)), 1) if round_trips else None,
        "failed": failed,
        "waiting_at_end": unfinished,
        "wait_p50_s": percentile(waits, 50),
        "wait_p95_s": percentile(waits, 95),
        "elevator_rides": len(elevator),
        "places_held_pct": {p: round(100 * held_s[p] / end_s, 1) for p in sorted(held_s)},
        "choices": 0 if dispatcher is None else dispatcher.counters.choices,
        "choices_differing": 0 if dispatcher is None else dispatcher.counters.choices_differing,
        "elevator_wait_p95_s": percentile(elevator, 95),
        "contacts": contacts,
        "pose_error_mm_p95": percentile(
            [e for p in probes.values() for *_, e in p.pose_errors], 95
        ),
        "pose_error_worst": max(
            (
                (round(e), f"{name} at {t:.1f} s on floor {floor} at ({x:.0f}, {y:.0f})")
                for name, probe in probes.items()
                for t, floor, x, y, e in probe.pose_errors
            ),
            default=None,
        ),
        "camera_fixes": len(fix_errors := [e for p in probes.values() for e in p.fix_errors]),
        "camera_fix_error_mm_p95": percentile(
            [e for _, _, e in fix_errors if math.isfinite(e)], 95
        ),
        "camera_fix_error_mm_max": max(
            (round(e, 1) for _, _, e in fix_errors if math.isfinite(e)), default=None
        ),
        "camera_fixes_over_300mm": [
            f"{name} at {t:.1f} s: {camera} "
            + (f"{e:.0f} mm" if math.isfinite(e) else "wrong floor")
            for name, probe in probes.items()
            for t, camera, e in probe.fix_errors
            if e > 300.0
        ],
        "lost": unfinished,  # after the broker-kill case's drain: orders that never ended
        "duplicated": sum(n > 1 for n in servers.values()),
        "dispatcher_cpu_pct_per_robot": round(
            100 * dispatcher_cpu_s / clock.now() / case.robots, 3
        ),
        "dispatcher_board_pct": round(100 * accounts[BOARD_NAME].seconds / clock.now(), 3),
    }


async def run_case(case: Case, record_dir: Path | None = None) -> dict[str, Any]:
    fleet_config = BOARD.fleet.model_copy(
        update={"dispatch": BOARD.fleet.dispatch.model_copy(update={"strategy": case.strategy})}
    )
    cameras = BOARD.cameras.model_copy(update={"enabled": case.cameras})
    config: RobotConfig = BOARD.model_copy(update={"fleet": fleet_config, "cameras": cameras})
    names = robot_ids(case.robots)
    staff = StaffModule(STAFF)
    probes = {name: Probe() for name in names}
    traffic = Traffic()
    started = time.monotonic()
    with mosquitto(names) as broker:
        async with build_fleet_sim(
            config,
            PLAN,
            case.robots,
            broker.address,
            broker.credentials,
            speed=SPEED,
            seed=case.seed,
            web=False,
            dispatcher_extra=[staff],
            robot_extra=lambda name: [probes[name]],
        ) as fleet:
            for sim in fleet.sims:
                probes[sim.robot.name].truth = functools.partial(_truth, fleet, sim)
            simulated_time = SimulatedTime(fleet.dispatcher.board.clock)
            for handler in logging.getLogger().handlers:
                handler.addFilter(simulated_time)
            async with contextlib.AsyncExitStack() as recordings:
                if record_dir is not None:
                    for runtime in fleet.robots:
                        name = runtime.config.fleet.robot_id
                        path = record_dir / f"{case.label}-{name}.mcap"
                        await recordings.enter_async_context(
                            Recorder(runtime.board, path, metadata={"robot": name})
                        )
                serving = asyncio.create_task(serve_fleet(fleet))
                observer = asyncio.create_task(observe(broker, traffic))
                try:
                    result = await drive(fleet, case, staff, probes, broker)
                finally:
                    observer.cancel()
                    fleet.request_stop("bench case over")
                    await asyncio.wait_for(serving, 120)
    simulated_s = result["simulated_s"]
    result["broker_msgs_per_s_per_robot"] = round(
        sum(traffic.messages.values()) / simulated_s / case.robots, 2
    )
    result["broker_bytes_per_s_per_robot"] = round(
        sum(traffic.payload_bytes.values()) / simulated_s / case.robots
    )
    result["wall_s"] = round(time.monotonic() - started, 1)
    return result


def _truth(fleet: FleetSim, sim: Simulation) -> tuple[int, float, float]:
    with fleet.world.lock:
        pose = sim.robot.pose
        return sim.robot.floor_level, pose.x_mm, pose.y_mm


class SimulatedTime(logging.Filter):
    """Puts ``sim_s=`` (the case's simulated clock) on every line of ``--logs``: how long a
    place was held or a robot waited is read back from the lines, and their machine time
    runs at whatever pace the machine steps the fleet."""

    def __init__(self, clock: Clock) -> None:
        super().__init__()
        self.clock = clock

    def filter(self, record: logging.LogRecord) -> bool:
        record.sim_s = round(self.clock.now(), 2)
        return True


def run_case_in_process(
    case: Case, log_dir: Path | None, record_dir: Path | None = None
) -> dict[str, Any]:
    if log_dir is not None:
        handler = logging.FileHandler(log_dir / f"{case.label}.log")
        handler.setFormatter(LogfmtFormatter())
        handler.addFilter(RobotTag())  # whose daemon logged each line
        # A worker process runs several cases: each its own file.
        logging.basicConfig(handlers=[handler], level=logging.INFO, force=True)
    return asyncio.run(run_case(case, record_dir))


def summarize(runs: list[dict[str, Any]], cases: list[Case]) -> dict[str, Any]:
    by_key = {(r["robots"], r["orders_per_h"], r["strategy"]): r for r in runs}
    rows = []
    for robots, rate in sorted({(c.robots, c.orders_per_h) for c in cases if not c.broker_kill}):
        joint, greedy = by_key.get((robots, rate, "joint")), by_key.get((robots, rate, "greedy"))
        shown = joint if joint is not None else greedy  # the joint run's figures, if it ran
        assert shown is not None
        rows.append(
            {
                "robots": robots,
                "orders_per_h": rate,
                "delivered_per_h": shown["delivered_per_h"],
                "wait_p50_s": shown["wait_p50_s"],
                "wait_p95_s": shown["wait_p95_s"],
                "contacts": sum(len(r["contacts"]) for r in (joint, greedy) if r is not None),
                "elevator_wait_p95_s": shown["elevator_wait_p95_s"],
                "joint_p95_s": joint["wait_p95_s"] if joint else None,
                "greedy_p95_s": greedy["wait_p95_s"] if greedy else None,
            }
        )
    result: dict[str, Any] = {"cases": rows}
    kill = [r for c, r in zip(cases, runs, strict=True) if c.broker_kill]
    if kill:
        k = kill[0]
        result["broker_kill"] = {
            "orders": k["orders"],
            "lost": k["lost"],
            "duplicated": k["duplicated"],
            "failed": k["failed"],
        }
    return result


def print_table(result: dict[str, Any], runs: list[dict[str, Any]], elapsed: float) -> None:
    rows = result["cases"]
    one = {r["orders_per_h"]: r["delivered_per_h"] for r in rows if r["robots"] == 1}
    trips = {}  # the shown run's (the joint one's, if it ran), as summarize() shows it
    for r in sorted(runs, key=lambda run: run["strategy"] == "joint"):
        trips[r["robots"], r["orders_per_h"]] = r["round_trip_est_s"]
    print(
        "| robots | orders/h | delivered/h | vs 1 robot | round trip s a cup | vs 1 robot, "
        "same work | wait p50 s | wait p95 s | contacts | elevator wait p95 s | joint p95 s "
        "| greedy p95 s |"
    )
    print("|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|")
    for r in rows:
        rate = r["orders_per_h"]
        base, trip, base_trip = one.get(rate), trips.get((r["robots"], rate)), trips.get((1, rate))
        ratio = f"{r['delivered_per_h'] / base:.2f}x" if base else "-"
        same_work = (
            f"{r['delivered_per_h'] * trip / (base * base_trip):.2f}x"
            if base and trip and base_trip
            else "-"
        )
        print(
            f"| {r['robots']} | {rate:g} | {r['delivered_per_h']:.1f} | {ratio} | {trip} "
            f"| {same_work} | {r['wait_p50_s']} | {r['wait_p95_s']} | {r['contacts']} "
            f"| {r['elevator_wait_p95_s']} | {r['joint_p95_s']} | {r['greedy_p95_s']} |"
        )
    if "broker_kill" in result:
        k = result["broker_kill"]
        print(
            f"\nbroker killed twice for {KILL_FOR_S:.0f} s: {k['orders']} orders, "
            f"{k['lost']} lost, {k['duplicated']} duplicated"
        )
    print(
        "\n| run | simulated s | wall s | failed | msgs/s/robot | B/s/robot | dispatcher %/robot |"
    )
    print("|---|---:|---:|---|---:|---:|---:|")
    for r in runs:
        print(
            f"| {_label(r)} | {r['simulated_s']:.0f} | {r['wall_s']:.0f} | {len(r['failed'])} "
            f"| {r['broker_msgs_per_s_per_robot']} | {r['broker_bytes_per_s_per_robot']} "
            f"| {r['dispatcher_cpu_pct_per_robot']} |"
        )
    for r in runs:
        print(
            f"\n{_label(r)}: estimate's error p95 {r['pose_error_mm_p95']} mm, "
            f"largest {r['pose_error_worst']}"
        )
        held = ", ".join(f"{p} {pct} %" for p, pct in r["places_held_pct"].items())
        print(f"{_label(r)}: shared places held (share of the run): {held or 'none'}")
        print(
            f"{_label(r)}: assignments with several robots free and several orders waiting: "
            f"{r['choices']}, of which the other strategy would have paired differently: "
            f"{r['choices_differing']}"
        )
        if r["camera_fixes"]:
            print(
                f"{_label(r)}: {r['camera_fixes']} camera fixes, error p95 "
                f"{r['camera_fix_error_mm_p95']} mm, max {r['camera_fix_error_mm_max']} mm; "
                f"over 300 mm: {', '.join(r['camera_fixes_over_300mm']) or 'none'}"
            )
        for contact in r["contacts"]:
            print(f"{_label(r)}: contact: {contact}")
    print(f"\n{elapsed / 60:.1f} min")


def _label(run: dict[str, Any]) -> str:
    return f"{run['robots']} x {run['orders_per_h']:g}/h {run['strategy']}"


def int_list(text: str) -> list[int]:
    return [int(part) for part in text.split(",") if part]


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--robots", type=int_list, default=[1, 2, 3, 4])
    parser.add_argument("--rates", type=int_list, default=[MODERATE_PER_H, SATURATED_PER_H])
    parser.add_argument("--greedy-rates", type=int_list, default=[SATURATED_PER_H])
    parser.add_argument("--greedy-robots", type=int_list, default=[1, 2, 3, 4])
    parser.add_argument(
        "--no-joint", action="store_true", help="the greedy cases only (a run is repeatable)"
    )
    parser.add_argument("--minutes", type=float, default=30.0, help="simulated, per case")
    parser.add_argument("--seed", type=int, default=1)
    parser.add_argument("--workers", type=int, default=1, help="cases at once, a process each")
    parser.add_argument("--no-broker-kill", action="store_true")
    parser.add_argument(
        "--cameras", action="store_true", help="the ceiling cameras on, for every case"
    )
    parser.add_argument("--json", action="store_true")
    parser.add_argument("--save", type=Path, help="every run's figures, as JSON")
    parser.add_argument("--logs", type=Path, metavar="DIR", help="each case's log, INFO and up")
    parser.add_argument(
        "--record",
        type=Path,
        metavar="DIR",
        help="each robot's board, every case, as MCAP (on the simulated clock: open a jam in "
        "Foxglove at the second its log names)",
    )
    args = parser.parse_args(argv)
    cases = [
        Case(robots, rate, strategy, args.minutes, args.seed, cameras=args.cameras)
        for robots in args.robots
        for rate in args.rates
        for strategy in ("joint", "greedy")
        if (strategy == "joint" and not args.no_joint)
        or (strategy == "greedy" and rate in args.greedy_rates and robots in args.greedy_robots)
    ]
    if not args.no_broker_kill:
        cases.append(Case(3, KILL_PER_H, "joint", args.minutes / 2, args.seed, True, args.cameras))
    # The longest first, so two workers end together.
    order = sorted(range(len(cases)), key=lambda i: -cases[i].robots * cases[i].minutes)
    for directory in (args.logs, args.record):
        if directory is not None:
            directory.mkdir(parents=True, exist_ok=True)
    started = time.monotonic()
    with ProcessPoolExecutor(args.workers) as pool:
        done = dict(
            zip(
                order,
                pool.map(
                    functools.partial(
                        run_case_in_process, log_dir=args.logs, record_dir=args.record
                    ),
                    [cases[i] for i in order],
                ),
                strict=True,
            )
        )
    runs = [done[i] for i in range(len(cases))]
    result = summarize(runs, cases)
    if args.save:
        args.save.write_text(json.dumps({"result": result, "runs": runs}, indent=1))
    if args.json:
        print(json.dumps(result))
    else:
        print_table(result, runs, time.monotonic() - started)
    return 0


if __name__ == "__main__":
    sys.exit(main())
