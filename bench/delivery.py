"""Whole deliveries on the simulated robot: random rooms, obstacles and seeds, against the targets.

    python bench/delivery.py                 # a table, for docs/benchmarks.md
    python bench/delivery.py --json          # one JSON object
    python bench/delivery.py --runs 10 --seed 7 --speed 4
    python bench/delivery.py --floorplan floorplans/linden-hall.toml

Each run is a scenario (``coffeebot.scenario``) run through the whole daemon: drivers on
the simulated buses, perception, state, navigation, motion, the simulated elevator. The room
is drawn from every office of the floor plan (the CS building's unless ``--floorplan``); the
robot starts by the first tea room's door; with probability one half a static obstacle from
the seed's set stands in the lane somewhere on the room's hallway on the way (a cardboard
box or a mail cart, the ones the sensors can see at 250 mm; the chairs cannot be seen and a
person stepping in cannot be braked for, see the perception benchmark), and with probability
one quarter a person walks along the other side of that hallway. Targets: every order
delivered or failed with a true reason, zero collisions with the robot moving, stop error
p95 <= 50 mm. The simulated walker avoids nothing, so a contact with the robot standing
(under 20 mm/s, as ``docs/safety.md`` counts it) is the walker's, counted apart.
"""

from __future__ import annotations

import argparse
import asyncio
import json
import math
import random
import sys
import time
from pathlib import Path
from typing import Any

import numpy as np

from coffeebot.config import RobotConfig, load_robot_config
from coffeebot.floorplan import FloorPlan, load_floorplan
from coffeebot.navigation.hallway_graph import hops
from coffeebot.navigation.route import Move, RoutePlanner
from coffeebot.scenario.run import run_scenario
from coffeebot.scenario.spec import OrderSpec, Scenario, StartPose
from coffeebot.sim.world import ObstacleSpec
from coffeebot.sim.world.contact import MOVING_MM_S
from coffeebot.sim.world.obstacles import ObstacleKind

ROOT = Path(__file__).resolve().parents[1]
PLAN_PATH = ROOT / "floorplans" / "cs-building.toml"
LANE_OBSTACLES: tuple[ObstacleKind, ...] = ("cardboard_box", "mail_cart")
WALL_GAP_MM = {"cardboard_box": 250.0, "mail_cart": 270.0}
"""How far an obstacle's centre stands from the hallway's wall line: against the wall on the
robot's side, in its keep-right lane."""
START_BEFORE_DOOR_MM = 500.0
"""The robot starts this far short of the tea room's door (less ``s``)."""


class Building:
    """What a run needs of a floor plan: its routes, and where the robot starts: in the
    hallway by the first tea room's door, in the lane across from it."""

    def __init__(self, plan: FloorPlan, path: Path, config: RobotConfig) -> None:
        self.plan = plan
        self.path = path
        self.planner = RoutePlanner.for_robot(plan, config)
        self.give_up_s = config.navigation.blocked_give_up_s
        whole, door = plan.tea_room
        self.start_floor = whole.view_of(door)
        self.start_s = door.at_mm - START_BEFORE_DOOR_MM
        self.lane = -self.planner.side_lane_mm(self.start_floor, door)

    def start(self, room: str) -> StartPose:
        """Facing the way the route to ``room`` sets off: no turn on the spot beside a wall."""
        floor = self.start_floor
        route = self.planner.route(
            floor.level, self.start_s, self.planner.door_place(room), hallway=floor.hallway.id
        )
        first = next(
            s.instruction
            for s in route.steps
            if isinstance(s, Move) and s.instruction.target_s_mm is not None
        )
        assert first.target_s_mm is not None
        direction = 1.0 if first.target_s_mm >= self.start_s else -1.0
        x, y = floor.from_hallway(self.start_s, self.lane)
        return StartPose(
            floor=floor.level,
            x_mm=x,
            y_mm=y,
            heading_deg=floor.travel_deg(direction),
        )

    def entry_s(self, room: str) -> float:
        """Where along the room's hallway the robot comes into it: the tea room's door, the
        elevator's, or where it turns in from another hallway."""
        loc = self.plan.find_room(room)
        floor = loc.floor.view_of(loc.door)
        tea = self.plan.tea_room
        if loc.floor.level == tea.floor.level:
            came_from, s = self.start_floor.hallway.id, tea.door.at_mm
        else:
            assert loc.floor.elevator is not None
            came_from = loc.floor.hallway_of(loc.floor.elevator).id
            s = loc.floor.elevator.at_mm
        way = hops(loc.floor, came_from, s, floor.hallway.id, loc.door.at_mm)
        return way[-1].next_s_mm if way else s


def random_scenario(building: Building, rng: random.Random, index: int) -> Scenario:
    plan = building.plan
    room = rng.choice(plan.rooms)
    loc = plan.find_room(room)
    floor = loc.floor.view_of(loc.door)
    half = floor.hallway.width_mm / 2
    length = floor.hallway.length_mm
    obstacles: list[ObstacleSpec] = []
    # Between where the robot comes into the room's hallway and the door, away from both,
    # and as far from the hallway's end beyond the door as the walker turns.
    walk = min(8000.0, length / 4)
    entry = building.entry_s(room)
    towards = 1.0 if entry >= loc.door.at_mm else -1.0
    lane = building.planner.lane_mm(floor, -towards)  # the robot's, keeping right to the door
    beyond = walk if towards > 0 else length - walk
    near = towards * max(towards * (loc.door.at_mm + towards * 3000), towards * beyond)
    far = entry - towards * 5000
    if rng.random() < 0.5 and (far - near) * towards > 0:
        kind = rng.choice(LANE_OBSTACLES)
        s = rng.uniform(min(near, far), max(near, far))
        x, y = floor.from_hallway(s, math.copysign(half - WALL_GAP_MM[kind], lane))
        obstacles.append(
            ObstacleSpec(
                id=kind,
                kind=kind,
                floor=floor.level,
                x_mm=x,
                y_mm=y,
                heading_deg=floor.hallway.heading_deg,  # its long side along the hallway
            )
        )
    if rng.random() < 0.25:
        # On the other side of the hallway from the robot's lane.
        side = -math.copysign(half - 400, lane)
        a, b = floor.from_hallway(walk, side), floor.from_hallway(length - walk, side)
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
    same_hallway = floor.level == building.start_floor.level and (
        floor.hallway.id == building.start_floor.hallway.id
    )
    return Scenario(
        name=f"run{index}-{room}" + "".join(f"-{o.kind}" for o in obstacles),
        floorplan=building.path,
        seed=rng.randrange(1_000_000),
        # Long enough for a robot blocked for good to give up and say why.
        time_limit_s=(200 if same_hallway else 300) + building.give_up_s,
        start=building.start(room),
        orders=[OrderSpec(room=room, at_s=2.0)],
        obstacles=obstacles,
    )


async def bench(runs: int, seed: int, speed: float, plan_path: Path) -> dict[str, Any]:
    config = load_robot_config(ROOT / "boards" / "coffeebot-v1.toml")
    plan = load_floorplan(plan_path)
    building = Building(plan, plan_path, config)
    rng = random.Random(seed)
    rows: list[dict[str, Any]] = []
    for i in range(runs):
        scenario = random_scenario(building, rng, i)
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
            c["towards_mm_s"] >= MOVING_MM_S for r in rows for c in r["contacts"]
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
            f"{c['speed_mm_s']} mm/s (the touched point towards it at {c['towards_mm_s']} mm/s), "
            f"floor {c['floor']} ({c['x_mm']}, {c['y_mm']})"
        )
    print(f"\n(elapsed {elapsed:.1f} s)")


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--runs", type=int, default=8)
    parser.add_argument("--seed", type=int, default=1)
    parser.add_argument("--speed", type=float, default=4.0, help="simulated time per wall time")
    parser.add_argument("--floorplan", type=Path, default=PLAN_PATH, help="the building")
    parser.add_argument("--json", action="store_true")
    args = parser.parse_args(argv)
    started = time.monotonic()
    result = asyncio.run(bench(args.runs, args.seed, args.speed, args.floorplan.resolve()))
    if args.json:
        print(json.dumps({k: v for k, v in result.items() if k != "rows"}))
    else:
        print_table(result, time.monotonic() - started)
    return 0


if __name__ == "__main__":
    sys.exit(main())
