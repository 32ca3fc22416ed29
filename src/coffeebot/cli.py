"""The ``coffeebot`` command: run on the robot, run the simulator, and the tools around them."""

from __future__ import annotations

import argparse
import asyncio
import contextlib
import faulthandler
import logging
import os
import sys
from pathlib import Path

from coffeebot.board import Board
from coffeebot.board.recording import Player, Recorder, RecordingError, recording_info
from coffeebot.clock import ScaledClock
from coffeebot.config import ConfigError, RobotConfig, load_robot_config
from coffeebot.daemon import Daemon
from coffeebot.floorplan_svg import add_render_arguments, render_command
from coffeebot.install import install_service
from coffeebot.logs import setup_logging
from coffeebot.messages import ALL_TOPICS
from coffeebot.modules.orders import OrdersModule
from coffeebot.modules.web import WebModule
from coffeebot.store import OrderStore
from coffeebot.systemd import Notifier, control_loop_check, run_as_service
from coffeebot.web import WebDeps

log = logging.getLogger("coffeebot")

REPO_ROOT = Path(__file__).resolve().parents[2]
DEFAULT_BOARD = REPO_ROOT / "boards" / "coffeebot-v1.toml"
DEFAULT_FLOORPLAN = REPO_ROOT / "floorplans" / "cs-building.toml"


def _add_common(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("--board", type=Path, default=DEFAULT_BOARD, help="robot description")
    parser.add_argument("--floorplan", type=Path, default=DEFAULT_FLOORPLAN, help="floor plan")
    parser.add_argument("--log-level", choices=["DEBUG", "INFO", "WARNING", "ERROR"])


def _positive(text: str) -> float:
    value = float(text)
    if value <= 0:
        raise argparse.ArgumentTypeError(f"must be positive, got {text}")
    return value


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
    replay = sub.add_parser("replay", help="republish a recording onto a board")
    _add_common(replay)
    replay.add_argument("file", type=Path, help="an MCAP recording")
    replay.add_argument("--speed", type=_positive, default=1.0, help="times real time (default 1)")
    replay.add_argument("--topic", action="append", help="replay only this topic (repeatable)")
    for p in (run, sim, replay):
        p.add_argument("--record", type=Path, metavar="FILE.mcap", help="record the board")
    record = sub.add_parser("record", help="inspect a recording")
    record.add_argument("--info", type=Path, metavar="FILE", required=True, help="print summary")
    install = sub.add_parser("install-service", help="install the systemd unit and /etc config")
    install.add_argument("--root", type=Path, default=Path("/"), help="install under this root")
    return parser


def _recorder(
    board: Board, path: Path | None, config: RobotConfig
) -> contextlib.AbstractAsyncContextManager[object]:
    """``--record``: started before the modules, closed after their shutdown is on the board."""
    if path is None:
        return contextlib.nullcontext()
    return Recorder(board, path, metadata={"robot": config.name})


async def _run_daemon(config: RobotConfig, record: Path | None) -> None:
    # systemd's watchdog kills a stalled daemon with SIGABRT: leave its stacks in the journal.
    faulthandler.enable()
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
    watchdog = config.watchdog
    try:
        async with _recorder(board, record, config):
            await run_as_service(
                daemon,
                Notifier.from_env(),
                control_loop_check(board, watchdog.topics, watchdog.max_age_s),
                max_loop_lag_s=watchdog.max_loop_lag_s,
            )
    finally:
        store.close()


async def _replay(config: RobotConfig, args: argparse.Namespace) -> None:
    """Replay onto a board whose clock follows the recording's stamps at ``--speed``."""
    clock = ScaledClock(args.speed, start=recording_info(args.file).start_s)
    board = Board(ALL_TOPICS, clock=clock)
    daemon = Daemon(board, modules=[], supervision=config.supervision)
    daemon.install_signal_handlers()
    player = Player(board, args.file, args.topic, on_start=clock.restart)
    async with _recorder(board, args.record, config):
        playing = asyncio.create_task(player.run())
        playing.add_done_callback(lambda _: daemon.request_stop("replay finished"))
        await daemon.run()
        playing.cancel()  # a no-op unless the replay was interrupted
        with contextlib.suppress(asyncio.CancelledError):
            await playing
    log.info("replayed %d messages from %s", player.stats.total, args.file)


def _without_config(args: argparse.Namespace) -> int:
    """The commands that need no robot configuration."""
    try:
        if args.command == "record":
            print(recording_info(args.info).format())
        else:
            # The console script next to this interpreter: on the robot, /opt/coffeebot/.venv's.
            executable = Path(sys.executable).absolute().parent / "coffeebot"
            for line in install_service(REPO_ROOT, args.root, executable, DEFAULT_BOARD):
                print(line)
    except (OSError, RecordingError) as exc:
        print(f"coffeebot: {exc}", file=sys.stderr)
        return 1
    return 0


def main(argv: list[str] | None = None) -> int:
    args = build_parser().parse_args(argv)
    if args.command == "floorplan":
        return render_command(args)
    if args.command in ("record", "install-service"):
        return _without_config(args)
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
    if args.command == "replay":
        try:
            asyncio.run(_replay(config, args))
        except (OSError, RecordingError) as exc:
            print(f"coffeebot: {exc}", file=sys.stderr)
            return 1
    else:
        asyncio.run(_run_daemon(config, args.record))
    return 0


if __name__ == "__main__":
    sys.exit(main())
