"""The delivery test scenarios through the whole daemon, with each pose fusion.

    python bench/deliveries_by_fusion.py                       # both fusions, a table
    python bench/deliveries_by_fusion.py --fusion particles --json

The six scenarios of ``tests/sim/test_deliveries.py`` (the test suite runs all six with the
particle filter, the default, and two with the Kalman filter, to keep its time), each with
``[state] fusion`` set as asked, at 4x. Per run: whether every order was delivered, collisions, the
worst stop error at the door (ground truth) and the real-time factor the machine kept.
"""

from __future__ import annotations

import argparse
import asyncio
import json
import sys
from pathlib import Path
from typing import Any

from coffeebot.config import load_robot_config
from coffeebot.scenario.run import run_scenario
from coffeebot.scenario.spec import load_scenario

ROOT = Path(__file__).resolve().parents[1]
SCENARIOS = [
    "floor2-delivery",
    "floor2-far",
    "floor2-two-orders",
    "floor2-box-in-lane",
    "floor3-elevator",
    "floor3-walker",
]


async def run(name: str, fusion: str, speed: float) -> dict[str, Any]:
    config = load_robot_config(ROOT / "boards" / "coffeebot-v1.toml")
    config = config.model_copy(update={"state": config.state.model_copy(update={"fusion": fusion})})
    scenario, plan = load_scenario(ROOT / "scenarios" / f"{name}.toml")
    report = await run_scenario(config, scenario, plan, speed=speed)
    orders = report.orders
    errors = [o.stop_error_mm for o in orders if o.stop_error_mm is not None]
    return {
        "scenario": name,
        "fusion": fusion,
        "delivered": sum(o.status == "delivered" for o in orders),
        "orders": len(orders),
        "collisions": len(report.collisions),
        "worst_stop_error_mm": round(max(errors), 1) if errors else None,
        "real_time_factor": report.real_time_factor,
    }


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--json", action="store_true", help="print one JSON object")
    parser.add_argument("--fusion", choices=["ekf", "particles"], action="append")
    parser.add_argument("--speed", type=float, default=4.0)
    args = parser.parse_args(argv)
    runs = [
        asyncio.run(run(name, fusion, args.speed))
        for fusion in args.fusion or ["ekf", "particles"]
        for name in SCENARIOS
    ]
    if args.json:
        json.dump({"runs": runs}, sys.stdout, indent=1)
        print()
        return 0
    print("| scenario | fusion | delivered | collisions | worst stop error | real-time factor |")
    print("|---|---|---|---|---|---|")
    for r in runs:
        print(
            f"| {r['scenario']} | {r['fusion']} | {r['delivered']} of {r['orders']} "
            f"| {r['collisions']} | {r['worst_stop_error_mm']} mm | {r['real_time_factor']} |"
        )
    return 0


if __name__ == "__main__":
    sys.exit(main())
