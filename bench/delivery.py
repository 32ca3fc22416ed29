"""Whole deliveries on the simulated robot: random rooms, obstacles and seeds, against the targets.

    python bench/delivery.py                 # a table, for docs/benchmarks.md
    python bench/delivery.py --json          # one JSON object
    python bench/delivery.py --runs 10 --seed 7 --speed 4

Each run is a scenario (``coffeebot.scenario``) run through the whole daemon: drivers on
the simulated buses, perception, state, navigation, motion, the simulated elevator. The room
is drawn from every office of the floor plan; with probability one half a static obstacle
from the seed's set stands in the lane somewhere on the way (a cardboard box or a mail cart,
the ones the sensors can see at 250 mm; the chairs cannot be seen and a person stepping in
cannot be braked for, see the perception benchmark), and with probability one quarter a
person walks along the other side of the hallway. Targets: every order delivered or failed
with a true reason, zero collisions with the robot moving, stop error p95 <= 50 mm. The
simulated walker avoids nothing, so a contact with the robot standing (under 20 mm/s, as
``docs/safety.md`` counts it) is the walker's, counted apart.
"""

from __future__ import annotations

import argparse
import asyncio
import json
import random
import sys
import time
from pathlib import Path
from typing import Any

import numpy as np

from coffeebot.config import load_robot_config
from coffeebot.floorplan import FloorPlan, load_floorplan
from coffeebot.scenario.run import run_scenario
from coffeebot.scenario.spec import OrderSpec, Scenario, StartPose
from coffeebot.sim.world import ObstacleSpec
from coffeebot.sim.world.contact import MOVING_MM_S
from coffeebot.sim.world.obstacles import ObstacleKind

ROOT = Path(__file__).resolve().parents[1]
PLAN_PATH = ROOT / "floorplans" / "cs-building.toml"
START = StartPose(floor=2, x_mm=41500, y_mm=295, heading_deg=180)
"""By the tea room door, facing down the hallway (floor 2 rooms)."""
START_ELEVATOR = START.model_copy(update={"heading_deg": 0.0})
"""Facing the elevator end (floor 3 rooms): no turn on the spot beside the wall."""
LANE_OBSTACLES: tuple[ObstacleKind, ...] = ("cardboard_box", "mail_cart")


def random_scenario(plan: FloorPlan, rng: random.Random, index: int) -> Scenario:
    room = rng.choice(plan.rooms)
    loc = plan.find_room(room)
    floor = loc.floor
    obstacles: list[ObstacleSpec] = []
    # Between the start (or the elevator) and the door, away from both ends of the stretch.
    far = max(loc.door.at_mm + 3000, 8000)
    if rng.random() < 0.5 and far < 37000:
        kind = rng.choice(LANE_OBSTACLES)
        s = rng.uniform(far, 37000)
        x, y = floor.from_hallway(s, 600 if kind == "cardboard_box" else 580)
        obstacles.append(ObstacleSpec(id=kind, kind=kind, floor=floor.level, x_mm=x, y_mm=y))
    if rng.random() < 0.25:
        a, b = floor.from_hallway(8000, -450), floor.from_hallway(36000, -450)
        obstacles.append(
            ObstacleSpec(
                id="person",
                kind="person",
                floor=floor.level,
                x_mm=a[0],
                y_mm=a[1],
                path=[b],
                speed_mm_s=700,
                path_mode="back_and_forth",
            )
        )
    return Scenario(
        name=f"run{index}-{room}" + "".join(f"-{o.kind}" for o in obstacles),
        floorplan=PLAN_PATH,
        seed=rng.randrange(1_000_000),
        time_limit_s=300 if floor.level != START.floor else 200,
        start=START if floor.level == START.floor else START_ELEVATOR,
        orders=[OrderSpec(room=room, at_s=2.0)],
        obstacles=obstacles,
    )


async def bench(runs: int, seed: int, speed: float) -> dict[str, Any]:
    config = load_robot_config(ROOT / "boards" / "coffeebot-v1.toml")
    plan = load_floorplan(PLAN_PATH)
    rng = random.Random(seed)
    rows: list[dict[str, Any]] = []
    for i in range(runs):
        scenario = random_scenario(plan, rng, i)
        report = await run_scenario(config, scenario, plan, speed=speed)
        order = report.orders[0]
        delivery_s = None
        if (
            order.delivered_at_s is not None
            and order.arrived_at_s is not None
            and order.placed_at_s is not None
        ):
            delivery_s = order.arrived_at_s - order.placed_at_s
        rows.append(
            {
                "scenario": scenario.name,
                "status": order.status,
                "detail": order.detail,
                "stop_error_mm": order.stop_error_mm,
                "collisions": len(report.collisions),
                "contacts": [c.model_dump() for c in report.collisions],
                "delivery_s": delivery_s,
                "speed_mm_s": report.mean_speed_mm_s,
            }
        )
    errors = [float(r["stop_error_mm"]) for r in rows if r["stop_error_mm"] is not None]
    times = [float(r["delivery_s"]) for r in rows if r["delivery_s"] is not None]
    speeds = [float(r["speed_mm_s"]) for r in rows if r["speed_mm_s"] is not None]
    return {
        "runs": runs,
        "delivered": sum(r["status"] == "delivered" for r in rows),
        "failed": [
            {"scenario": r["scenario"], "reason": f"{r['status']}: {r['detail']}"}
            for r in rows
            if r["status"] != "delivered"
        ],
        "collisions": sum(r["collisions"] for r in rows),
        "collisions_robot_moving": sum(
            abs(c["speed_mm_s"]) >= MOVING_MM_S for r in rows for c in r["contacts"]
        ),
        "contacts": [
            {"scenario": r["scenario"], **contact} for r in rows for contact in r["contacts"]
        ],
        "stop_error_mm_p95": round(float(np.percentile(errors, 95)), 1) if errors else None,
        "mean_delivery_s": round(float(np.mean(times)), 1) if times else None,
        "mean_speed_mm_s": round(float(np.mean(speeds)), 1) if speeds else None,
        "rows": rows,
    }


def print_table(result: dict[str, Any], elapsed: float) -> None:
    print("| run | status | stop error mm | collisions | order to door s | mean speed mm/s |")
    print("|---|---|---|---|---|---|")
    for r in result["rows"]:
        speed = "" if r["speed_mm_s"] is None else f"{r['speed_mm_s']:.0f}"
        delivery = "" if r["delivery_s"] is None else f"{r['delivery_s']:.1f}"
        print(
            f"| {r['scenario']} | {r['status']} | {r['stop_error_mm']} | {r['collisions']} "
            f"| {delivery} | {speed} |"
        )
    print()
    print("| figure | value | target |")
    print("|---|---|---|")
    print(
        f"| delivered | {result['delivered']} of {result['runs']} | all, or failed with a reason |"
    )
    print(f"| collisions with the robot moving | {result['collisions_robot_moving']} | 0 |")
    print(f"| collisions, all (a walker into a standing robot too) | {result['collisions']} | |")
    print(f"| stop error p95 | {result['stop_error_mm_p95']} mm | <= 50 mm |")
    print(f"| mean order-to-door time | {result['mean_delivery_s']} s | |")
    print(f"| mean speed while moving | {result['mean_speed_mm_s']} mm/s | |")
    for failed in result["failed"]:
        print(f"- not delivered: {failed['scenario']}: {failed['reason']}")
    for c in result["contacts"]:
        print(
            f"- collision: {c['scenario']}: t={c['t']} s with {c['with']} at "
            f"{c['speed_mm_s']} mm/s, floor {c['floor']} ({c['x_mm']}, {c['y_mm']})"
        )
    print(f"\n(elapsed {elapsed:.1f} s)")


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--runs", type=int, default=8)
    parser.add_argument("--seed", type=int, default=1)
    parser.add_argument("--speed", type=float, default=4.0, help="simulated time per wall time")
    parser.add_argument("--json", action="store_true")
    args = parser.parse_args(argv)
    started = time.monotonic()
    result = asyncio.run(bench(args.runs, args.seed, args.speed))
    if args.json:
        print(json.dumps({k: v for k, v in result.items() if k != "rows"}))
    else:
        print_table(result, time.monotonic() - started)
    return 0


if __name__ == "__main__":
    sys.exit(main())
