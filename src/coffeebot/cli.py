"""The ``coffeebot`` command: run on the robot, run the simulator, and the tools around them."""

from __future__ import annotations

import argparse
import asyncio
import logging
import os
import sys
from pathlib import Path

from coffeebot.board import Board
from coffeebot.config import ConfigError, RobotConfig, load_robot_config
from coffeebot.daemon import Daemon
from coffeebot.floorplan_svg import add_render_arguments, render_command
from coffeebot.logs import setup_logging
from coffeebot.messages import ALL_TOPICS
from coffeebot.modules.orders import OrdersModule
from coffeebot.modules.web import WebModule
from coffeebot.store import OrderStore
from coffeebot.web import WebDeps

log = logging.getLogger("coffeebot")

REPO_ROOT = Path(__file__).resolve().parents[2]
DEFAULT_BOARD = REPO_ROOT / "boards" / "coffeebot-v1.toml"
DEFAULT_FLOORPLAN = REPO_ROOT / "floorplans" / "cs-building.toml"


def _add_common(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("--board", type=Path, default=DEFAULT_BOARD, help="robot description")
    parser.add_argument("--floorplan", type=Path, default=DEFAULT_FLOORPLAN, help="floor plan")
    parser.add_argument("--log-level", choices=["DEBUG", "INFO", "WARNING", "ERROR"])


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(
        prog="coffeebot", description="Software of an indoor coffee-delivery robot."
    )
    sub = parser.add_subparsers(dest="command", required=True)
    run = sub.add_parser("run", help="run the daemon on the robot's real hardware")
    _add_common(run)
    sim = sub.add_parser("sim", help="run the daemon on the simulated robot and world")
    _add_common(sim)
    check = sub.add_parser("check-hardware", help="probe every device once and print a table")
    _add_common(check)
    check.add_argument("--sim", action="store_true", help="probe the simulated buses instead")
    check.add_argument("--json", action="store_true", help="print the table as JSON")
    check.add_argument("--fault", help="with --sim: inject a fault, e.g. tof3-nack, uwb-unplug")
    floorplan = sub.add_parser("floorplan", help="floor plan tools")
    floorplan_sub = floorplan.add_subparsers(dest="floorplan_command", required=True)
    add_render_arguments(floorplan_sub.add_parser("render", help="draw a floor plan as SVG"))
    return parser


async def _run_daemon(config: RobotConfig) -> None:
    board = Board(ALL_TOPICS)
    store = OrderStore(config.store.path)
    orders = OrdersModule(store)
    # Rooms, floor SVGs and the pose source come from the floor plan and the state module.
    web = WebModule(
        WebDeps(
            board=board,
            bus=board,
            orders=orders,
            rooms=[],
            config=config.web,
            operator_token=os.environ.get(config.web.operator_token_env),
            modules=[orders],
            sensors=config.tof.sensors,
            geometry=config.geometry,
            health=lambda: daemon.health(),
        )
    )
    daemon = Daemon(board, modules=[orders, web], supervision=config.supervision)
    daemon.install_signal_handlers()
    try:
        await daemon.run()
    finally:
        store.close()


def main(argv: list[str] | None = None) -> int:
    args = build_parser().parse_args(argv)
    if args.command == "floorplan":
        return render_command(args)
    try:
        config = load_robot_config(args.board)
    except ConfigError as exc:
        print(f"coffeebot: configuration error\n{exc}", file=sys.stderr)
        return 2
    setup_logging(args.log_level or config.logging.level)
    if args.command == "check-hardware":
        from coffeebot.hardware import selfcheck

        return selfcheck.main(config, sim=args.sim, as_json=args.json, fault=args.fault)
    log.info("starting %s", args.command, extra={"board": str(args.board)})
    asyncio.run(_run_daemon(config))
    return 0


if __name__ == "__main__":
    sys.exit(main())
