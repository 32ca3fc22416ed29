"""The ``coffeebot`` command: run on the robot, run the simulator, and the tools around them.

``coffeebot run`` must not load the simulator (the robot has no use for it and should not
pay for it), so everything of ``sim/`` and ``scenario/`` is imported inside the commands that
use it.
"""

from __future__ import annotations

import argparse
import asyncio
import contextlib
import functools
import json
import logging
import math
import os
import signal
import sys
import time
from dataclasses import asdict
from pathlib import Path

from coffeebot.board import Board
from coffeebot.board.recording import Player, RecordingError, recording_info
from coffeebot.cameras.check import check_cameras
from coffeebot.clock import MonotonicClock, ScaledClock
from coffeebot.config import RobotConfig, load_robot_config
from coffeebot.daemon import Daemon
from coffeebot.errors import CoffeebotError, ConfigError
from coffeebot.floorplan import FloorPlan, load_floorplan, plan_warnings
from coffeebot.floorplan_svg import add_render_arguments, render_command
from coffeebot.hardware.dwm1001 import ANCHOR_RANGE_MM
from coffeebot.hardware.i2c import kernel_bus_hz, open_i2c_bus
from coffeebot.hardware.selfcheck import CheckResult, run_checks
from coffeebot.install import install_service
from coffeebot.logs import setup_logging
from coffeebot.messages import ALL_TOPICS
from coffeebot.modules.base import Module
from coffeebot.perception.door import min_visible_recess_mm
from coffeebot.runtime.assemble import Runtime
from coffeebot.runtime.robot import build_robot
from coffeebot.runtime.service import StopAfter, recorder, serve
from coffeebot.survey import check_recording

log = logging.getLogger("coffeebot")

REPO_ROOT = Path(__file__).resolve().parents[2]
DEFAULT_BOARD = REPO_ROOT / "boards" / "coffeebot-v1.toml"
DEFAULT_FLOORPLAN = REPO_ROOT / "floorplans" / "cs-building.toml"
DEFAULT_FOXGLOVE_PORT = 8765
"""Foxglove's own default for a WebSocket data source."""


def _add_common(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("--board", type=Path, default=DEFAULT_BOARD, help="robot description")
    parser.add_argument("--floorplan", type=Path, default=DEFAULT_FLOORPLAN, help="floor plan")
    parser.add_argument("--log-level", choices=["DEBUG", "INFO", "WARNING", "ERROR"])


def _positive(text: str) -> float:
    value = float(text)
    if not math.isfinite(value) or value <= 0:
        raise argparse.ArgumentTypeError(f"must be a positive number, got {text}")
    return value


def _robots(text: str) -> int:
    value = int(text)
    if value < 1:
        raise argparse.ArgumentTypeError(f"at least one robot, got {text}")
    return value


def _speed(text: str) -> float:
    """``--speed``: times real time, or ``max`` for as fast as the machine can."""
    return math.inf if text == "max" else _positive(text)


def _refused(what: str, exc: Exception) -> None:
    """One line per problem on stderr, each naming the file and the field (or the part)."""
    for line in str(exc).splitlines() or [type(exc).__name__]:
        print(f"coffeebot: {what}{line}", file=sys.stderr)


def _port(text: str) -> int:
    value = int(text)
    if not 0 <= value <= 65535:
        raise argparse.ArgumentTypeError(f"a port is 0..65535, got {text}")
    return value


def default_state_dir() -> Path:
    """The demo's orders: ``$XDG_STATE_HOME/coffeebot/sim`` (``~/.local/state/...``)."""
    root = os.environ.get("XDG_STATE_HOME") or Path.home() / ".local" / "state"
    return Path(root) / "coffeebot" / "sim"


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(
        prog="coffeebot", description="Software of an indoor coffee-delivery robot."
    )
    sub = parser.add_subparsers(dest="command", required=True)
    run = sub.add_parser("run", help="run the daemon on the robot's real hardware")
    _add_common(run)
    sim = sub.add_parser("sim", help="run the daemon on the simulated robot and world")
    _add_common(sim)
    sim.add_argument("--scenario", type=Path, help="run this scenario file and report on it")
    sim.add_argument("--report", type=Path, metavar="OUT.json", help="scenario report file")
    sim.add_argument("--headless", action="store_true", help="no web UI")
    sim.add_argument("--duration", type=_positive, metavar="S", help="stop after S sim seconds")
    sim.add_argument(
        "--speed",
        type=_speed,
        default=1.0,
        help="times real time, or 'max': as fast as the machine can (default 1); a run is "
        "the same at any speed",
    )
    sim.add_argument("--host", default="127.0.0.1", help="web UI address (default 127.0.0.1)")
    sim.add_argument("--port", type=int, default=8080, help="web UI port (default 8080)")
    sim.add_argument(
        "--state-dir",
        type=Path,
        default=default_state_dir(),
        help="where the demo keeps its orders across restarts (default %(default)s)",
    )
    sim.add_argument(
        "--fresh", action="store_true", help="start with an empty queue that is not kept"
    )
    fleet = sub.add_parser(
        "fleet", help="run a fleet's dispatcher: the order queue and web UI for every robot"
    )
    _add_common(fleet)
    fleet.add_argument(
        "--sim",
        type=_robots,
        metavar="N",
        help="the demo: N simulated robots in one building, on a Mosquitto of its own",
    )
    fleet.add_argument("--speed", type=_speed, default=1.0, help="with --sim: as for sim")
    fleet.add_argument("--host", default="127.0.0.1", help="web UI address (default 127.0.0.1)")
    fleet.add_argument("--port", type=int, default=8080, help="web UI port (default 8080)")
    check = sub.add_parser("check-hardware", help="probe every device once and print a table")
    _add_common(check)
    check.add_argument("--sim", action="store_true", help="probe the simulated buses instead")
    check.add_argument("--json", action="store_true", help="print the table as JSON")
    check.add_argument("--fault", help="with --sim: inject a fault, e.g. tof3-nack, uwb-unplug")
    floorplan = sub.add_parser("floorplan", help="floor plan tools")
    floorplan_sub = floorplan.add_subparsers(dest="floorplan_command", required=True)
    add_render_arguments(floorplan_sub.add_parser("render", help="draw a floor plan as SVG"))
    survey = floorplan_sub.add_parser(
        "check",
        help="warn of what the plan leaves the robot to do poorly; with --recording, compare "
        "a recorded pass with the plan and list what disagrees",
    )
    survey.add_argument("--recording", type=Path, metavar="PASS.mcap")
    survey.add_argument("--floorplan", type=Path, default=DEFAULT_FLOORPLAN, help="floor plan")
    survey.add_argument("--board", type=Path, default=DEFAULT_BOARD, help="robot description")
    survey.add_argument(
        "--threshold-mm", type=_positive, default=50.0, help="report larger errors (default 50)"
    )
    survey.add_argument("--json", action="store_true", help="print the list as JSON")
    survey.add_argument(
        "--uwb-range-mm",
        type=_positive,
        default=ANCHOR_RANGE_MM,
        help=f"anchors reach this far (default {ANCHOR_RANGE_MM:.0f})",
    )
    replay = sub.add_parser("replay", help="republish a recording onto a board")
    _add_common(replay)
    replay.add_argument("file", type=Path, help="an MCAP recording")
    replay.add_argument("--speed", type=_positive, default=1.0, help="times real time (default 1)")
    replay.add_argument("--topic", action="append", help="replay only this topic (repeatable)")
    for p in (run, sim, replay):
        p.add_argument("--record", type=Path, metavar="FILE.mcap", help="record the board")
    for p in (run, sim):
        p.add_argument(
            "--foxglove",
            type=_port,
            nargs="?",
            const=DEFAULT_FOXGLOVE_PORT,
            metavar="PORT",
            help="serve the board live to Foxglove on the web UI's address "
            f"(port {DEFAULT_FOXGLOVE_PORT} if not given)",
        )
    record = sub.add_parser("record", help="inspect a recording")
    record.add_argument("--info", type=Path, metavar="FILE", required=True, help="print summary")
    install = sub.add_parser("install-service", help="install the systemd unit and /etc config")
    install.add_argument("--root", type=Path, default=Path("/"), help="install under this root")
    return parser


async def _sim(config: RobotConfig, plan: FloorPlan, args: argparse.Namespace) -> None:
    """The demo: daemon, world and web UI (or headless for ``--duration`` seconds)."""
    from coffeebot.runtime.sim import build_sim
    from coffeebot.sim.simulation import Simulation, demo_setup

    duration = args.duration

    def extra(rt: Runtime, _sim: Simulation) -> list[Module]:
        return [] if duration is None else [StopAfter(rt, duration)]

    setup = demo_setup(plan, args.speed)
    state_dir = None if args.fresh else args.state_dir
    if state_dir is not None:
        log.info("orders kept in %s (--fresh for an empty queue)", state_dir)
    async with build_sim(config, plan, setup, extra, not args.headless, state_dir) as (rt, _):
        await serve(rt, args.record, args.foxglove)


def _sim_command(config: RobotConfig, args: argparse.Namespace) -> int:
    from coffeebot.scenario.run import run_scenario
    from coffeebot.scenario.spec import load_scenario

    config = config.model_copy(
        update={"web": config.web.model_copy(update={"host": args.host, "port": args.port})}
    )
    if args.scenario is None:
        if args.headless and args.duration is None:
            print("coffeebot: --headless without --scenario needs --duration", file=sys.stderr)
            return 2
        asyncio.run(_sim(config, load_floorplan(args.floorplan), args))
        return 0
    scenario, plan = load_scenario(args.scenario)
    report = asyncio.run(
        run_scenario(
            config,
            scenario,
            plan,
            speed=args.speed,
            web=not args.headless,
            record=args.record,
            foxglove_port=args.foxglove,
        )
    )
    text = report.model_dump_json(indent=2)
    if args.report is None:
        print(text)
    else:
        args.report.write_text(text + "\n")
        log.info(
            "report written to %s: %s; %d safety stops; %.1f simulated s at %sx real time",
            args.report,
            report.ended,
            report.safety_stops,
            report.sim_time_s,
            report.real_time_factor,
            extra={"path": str(args.report), "real_time_factor": report.real_time_factor},
        )
    return 0


async def _fleet(config: RobotConfig, plan: FloorPlan, args: argparse.Namespace) -> None:
    """The dispatcher on the broker of ``[fleet] broker``; with ``--sim N`` the whole demo:
    a broker of its own, the dispatcher and N simulated robots."""
    from coffeebot.fleet.mosquitto import DISPATCHER_USER
    from coffeebot.modules.fleet_bridge import credentials_from_env
    from coffeebot.runtime.fleet import dispatcher_runtime
    from coffeebot.store import OrderStore

    if args.sim is not None:
        from coffeebot.fleet.mosquitto import mosquitto
        from coffeebot.runtime.fleet import build_fleet_sim, robot_ids, serve_fleet

        with mosquitto(robot_ids(args.sim)) as broker:
            log.info("broker on %s, %d simulated robots", broker.address.url, args.sim)
            async with build_fleet_sim(
                config, plan, args.sim, broker.address, broker.credentials, speed=args.speed
            ) as fleet:
                loop = asyncio.get_running_loop()
                for signum in (signal.SIGINT, signal.SIGTERM):
                    loop.add_signal_handler(signum, fleet.request_stop, signum.name)
                await serve_fleet(fleet)
        return
    if not config.fleet.broker:
        raise ConfigError(f"{args.board}: [fleet] broker: the dispatcher needs the broker's URL")
    store = OrderStore(config.store.path, busy_timeout_s=config.store.busy_timeout_s)
    try:
        dispatcher = dispatcher_runtime(
            config,
            plan,
            store,
            config.fleet.broker,
            credentials_from_env(DISPATCHER_USER),
            MonotonicClock(),
        )
        dispatcher.daemon.install_signal_handlers()
        await dispatcher.daemon.run()
    finally:
        store.close()


def format_table(results: list[CheckResult]) -> str:
    rows = [("component", "channel/port", "result", "detail")] + [
        (r.component, r.where, "FAIL" if not r.ok else "WARN" if r.warning else "ok", r.detail)
        for r in results
    ]
    widths = [max(len(row[i]) for row in rows) for i in range(3)]
    return "\n".join(
        "  ".join(cell.ljust(w) for cell, w in zip(row[:3], widths, strict=True)) + "  " + row[3]
        for row in rows
    )


def _check_hardware(config: RobotConfig, args: argparse.Namespace) -> int:
    """Run every probe, print the table (or JSON); 0 only if every part passed."""
    started = time.monotonic()
    if args.sim:
        from coffeebot.sim.selfcheck import FAULT_ENV, simulated_robot

        with contextlib.ExitStack() as devices:
            try:
                robot = simulated_robot(config, args.fault or os.environ.get(FAULT_ENV))
                sim_config, bus = devices.enter_context(robot)
            except ValueError as exc:  # an unknown fault
                print(f"coffeebot: {exc}", file=sys.stderr)
                return 2
            results = run_checks(sim_config, lambda: bus)
    else:
        results = run_checks(
            config,
            functools.partial(open_i2c_bus, config.i2c.bus),
            kernel_hz=kernel_bus_hz(config.i2c.bus),
        )
        results += check_cameras(config.cameras, load_floorplan(args.floorplan))
    ok = all(r.ok for r in results)
    if args.json:
        print(json.dumps({"ok": ok, "results": [asdict(r) for r in results]}, indent=2))
    else:
        print(format_table(results))
        print(f"\n{'all parts ok' if ok else 'FAILED'} ({time.monotonic() - started:.1f} s)")
    return 0 if ok else 1


async def _replay(config: RobotConfig, args: argparse.Namespace) -> None:
    """Replay onto a board whose clock follows the recording's stamps at ``--speed``."""
    clock = ScaledClock(args.speed, start=recording_info(args.file).start_s)
    board = Board(ALL_TOPICS, clock=clock)
    daemon = Daemon(board, modules=[], supervision=config.supervision)
    daemon.install_signal_handlers()
    player = Player(board, args.file, args.topic, on_start=clock.restart)
    async with recorder(board, args.record, config):
        playing = asyncio.create_task(player.run())
        playing.add_done_callback(lambda _: daemon.request_stop("replay finished"))
        await daemon.run()
        playing.cancel()  # a no-op unless the replay was interrupted
        with contextlib.suppress(asyncio.CancelledError):
            await playing
    log.info("replayed %d messages from %s", player.stats.total, args.file)


def _survey_check(args: argparse.Namespace) -> int:
    """``coffeebot floorplan check``: exit 0 if the plan agrees, 1 if something does not.

    The plan's warnings (stretches without a UWB fix, doors too shallow to detect) go to
    stderr and do not fail the check: the robot copes, only less well.
    """
    try:
        config = load_robot_config(args.board)
        plan = load_floorplan(args.floorplan)
        warnings = plan_warnings(
            plan,
            uwb_range_mm=args.uwb_range_mm,
            min_recess_mm=min_visible_recess_mm(config.door),
        )
        for warning in warnings:
            print(f"warning: {warning.describe(args.floorplan)}", file=sys.stderr)
        if args.recording is None:
            return 0
        check = check_recording(args.recording, plan, config.tof.sensors)
    except (ConfigError, OSError, RecordingError) as exc:
        print(f"coffeebot: {exc}", file=sys.stderr)
        return 2
    found = check.disagreements(args.threshold_mm)
    if args.json:
        print(json.dumps([asdict(d) for d in found], indent=1))
    else:
        print(
            f"{len(check.observations)} readings faced a plan surface squarely; "
            f"{len(found)} stretches disagree by more than {args.threshold_mm:g} mm"
        )
        for disagreement in found:
            print(disagreement.describe())
    return 1 if found else 0


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
        return _survey_check(args) if args.floorplan_command == "check" else render_command(args)
    if args.command in ("record", "install-service"):
        return _without_config(args)
    try:
        config = load_robot_config(args.board)
    except ConfigError as exc:
        _refused("configuration error: ", exc)
        return 2
    setup_logging(args.log_level or config.logging.level)
    if args.command == "check-hardware":
        return _check_hardware(config, args)
    log.info("starting %s", args.command, extra={"board": str(args.board)})
    if args.command == "replay":
        try:
            asyncio.run(_replay(config, args))
        except (OSError, RecordingError) as exc:
            print(f"coffeebot: {exc}", file=sys.stderr)
            return 1
        return 0
    try:
        if args.command == "sim":
            return _sim_command(config, args)
        if args.command == "fleet":
            web = config.web.model_copy(update={"host": args.host, "port": args.port})
            asyncio.run(
                _fleet(config.model_copy(update={"web": web}), load_floorplan(args.floorplan), args)
            )
            return 0
        robot = build_robot(config, load_floorplan(args.floorplan))
        asyncio.run(serve(robot, args.record, args.foxglove))
    except ConfigError as exc:
        _refused("configuration error: ", exc)
        return 2
    except (CoffeebotError, OSError) as exc:
        _refused("", exc)
        return 1
    return 0


if __name__ == "__main__":
    sys.exit(main())
