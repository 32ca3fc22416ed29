"""The daemon assembled: board, modules and their wiring, on real hardware or in simulation.

One function decides which modules run and how they are wired (:func:`assemble`); the two
entry points differ only in where the buses come from. On the robot, :func:`build_robot`
opens ``/dev/i2c-N`` with smbus2 and the serial ports named in the board file. In
simulation, :func:`build_sim` puts a :class:`~coffeebot.sim.simulation.Simulation` (the world
behind a simulated I2C bus and two pty devices) under the very same modules and adds the
``world`` module that steps it. Either way every module reads time from the board's clock.

Navigation and motion (issue 6) plug in at :func:`navigation_modules`, the one place that
lists them.
"""

from __future__ import annotations

import contextlib
import faulthandler
import functools
import os
import tempfile
import time
from collections.abc import AsyncIterator, Callable, Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from coffeebot.board import Board
from coffeebot.board.recording import Recorder
from coffeebot.clock import Clock, MonotonicClock, ScaledClock
from coffeebot.config import RobotConfig
from coffeebot.daemon import Daemon
from coffeebot.floorplan import FloorPlan
from coffeebot.floorplan_svg import render_svg
from coffeebot.hardware.i2c import I2CBus, open_i2c_bus
from coffeebot.hardware.selfcheck import service_check
from coffeebot.messages import ALL_TOPICS, CURRENT_STATE, PoseEstimate
from coffeebot.modules.angle import AngleModule
from coffeebot.modules.base import Module, ModuleContext
from coffeebot.modules.collision import CollisionModule
from coffeebot.modules.door import DoorModule
from coffeebot.modules.elevator import ElevatorInterface, ElevatorModule
from coffeebot.modules.motion import MotionModule
from coffeebot.modules.motor_driver import MotorDriver
from coffeebot.modules.navigation import NavigationModule
from coffeebot.modules.orders import OrdersModule
from coffeebot.modules.state import StateModule
from coffeebot.modules.tof_poller import TofPoller
from coffeebot.modules.uwb_reader import UwbReader
from coffeebot.modules.web import WebModule
from coffeebot.sim.scenario import Scenario, ScenarioModule
from coffeebot.sim.simulation import SimElevatorLink, SimSetup, Simulation, WorldModule
from coffeebot.sim.world import RobotSpec, World
from coffeebot.sim.world.elevator import SimElevator
from coffeebot.store import OrderStore
from coffeebot.systemd import Notifier, SelfCheck, control_loop_check, run_as_service
from coffeebot.web import RoomChoice, WebDeps
from coffeebot.web.livemap import MapPose

ExtraModules = Callable[["Runtime"], Sequence[Module]]
"""Modules a caller adds once the runtime exists (the scenario driver, test probes)."""


@dataclass
class Runtime:
    """Everything one daemon run is made of; ``sim`` is None on the robot."""

    config: RobotConfig
    """The configuration the modules were built from (in simulation, with the pty ports)."""
    plan: FloorPlan
    board: Board
    store: OrderStore
    orders: OrdersModule
    self_check: SelfCheck
    sim: Simulation | None = None
    daemon: Daemon = field(init=False)
    """Made last, from every module; modules that need it call :meth:`request_stop`."""

    def request_stop(self, reason: str) -> None:
        self.daemon.request_stop(reason)

    def module(self, name: str) -> Module:
        return self.daemon.states[name].module


def navigation_modules(
    config: RobotConfig, plan: FloorPlan, elevator: ElevatorInterface | None = None
) -> list[Module]:
    """Navigation and motion: the only publishers of ``nav/instruction`` and
    ``motor/command``. Without an elevator interface (none on the robot yet) navigation asks
    an operator to confirm each elevator step."""
    modules: list[Module] = [NavigationModule(config, plan), MotionModule(config, plan)]
    if elevator is not None:
        modules.append(ElevatorModule(elevator))
    return modules


def robot_modules(
    config: RobotConfig,
    plan: FloorPlan,
    open_i2c: Callable[[], I2CBus],
    start: PoseEstimate | None,
) -> list[Module]:
    """Drivers, perception and state: the modules every run has, in start order."""
    return [
        TofPoller(config.i2c, config.tof, open_i2c),
        UwbReader(config.uwb),
        MotorDriver(config.motor),
        CollisionModule(config),
        AngleModule(config, plan),
        DoorModule(config, plan),
        StateModule(config, plan, start=start),
    ]


def floor_svgs(plan: FloorPlan) -> Callable[[int], str | None]:
    """One floor's drawing for the web map, rendered once per floor."""
    levels = {f.level for f in plan.floors}

    @functools.cache
    def svg(level: int) -> str | None:
        return render_svg(plan, [level]) if level in levels else None

    return svg


def assemble(
    config: RobotConfig,
    plan: FloorPlan,
    *,
    clock: Clock,
    open_i2c: Callable[[], I2CBus],
    store_path: Path,
    start: PoseEstimate | None = None,
    sim: Simulation | None = None,
    extra: ExtraModules | None = None,
    web: bool = True,
) -> Runtime:
    """Build the board and every module from ``config`` and ``plan`` (``web``: serve the UI)."""
    board = Board(ALL_TOPICS, clock=clock)
    store = OrderStore(store_path)
    orders = OrdersModule(store)
    modules: list[Module] = []
    if sim is not None:
        modules.append(WorldModule(sim))
    modules += robot_modules(config, plan, open_i2c, start)
    modules += navigation_modules(config, plan, None if sim is None else SimElevatorLink(sim))
    modules.append(orders)

    def poses() -> Mapping[str, MapPose]:
        """The estimate first (the map draws scans from it), then the simulator's truth."""
        found: dict[str, MapPose] = {}
        state = board.latest(CURRENT_STATE)
        if state is not None and state.msg.pose.initialised:
            p = state.msg.pose
            found["estimated"] = MapPose(
                x_mm=p.x_mm, y_mm=p.y_mm, heading_deg=p.heading_deg, floor=p.floor
            )
        if sim is not None:
            with sim.lock:
                t, level = sim.world.pose, sim.world.floor_level
            found["true"] = MapPose(
                x_mm=t.x_mm, y_mm=t.y_mm, heading_deg=t.heading_deg, floor=level
            )
        return found

    runtime = Runtime(
        config=config,
        plan=plan,
        board=board,
        store=store,
        orders=orders,
        self_check=service_check(config, open_i2c),
        sim=sim,
    )
    if web:
        modules.append(web_module(runtime, modules, poses))
    if extra is not None:
        modules += extra(runtime)
    runtime.daemon = Daemon(board, modules, supervision=config.supervision)
    return runtime


def web_module(
    runtime: Runtime, modules: Sequence[Module], poses: Callable[[], Mapping[str, MapPose]]
) -> WebModule:
    """The web UI: order form for the plan's offices, floor maps, the inspector."""
    config, plan, board = runtime.config, runtime.plan, runtime.board
    return WebModule(
        WebDeps(
            board=board,
            bus=board,
            orders=runtime.orders,
            rooms=[
                RoomChoice(id=door.room, floor=floor.level, label=f"Office {door.room}")
                for floor in plan.floors
                for door in sorted(floor.doors, key=lambda d: d.at_mm)
                if door.kind == "office"
            ],
            config=config.web,
            operator_token=os.environ.get(config.web.operator_token_env),
            modules=modules,
            floor_svg=floor_svgs(plan),
            poses=poses,
            sensors=config.tof.sensors,
            geometry=config.geometry,
            health=lambda: runtime.daemon.health(),
        )
    )


def build_robot(config: RobotConfig, plan: FloorPlan) -> Runtime:
    """The daemon on the robot: smbus2 on ``/dev/i2c-<i2c.bus>``, the board file's ports."""
    return assemble(
        config,
        plan,
        clock=MonotonicClock(),
        open_i2c=functools.partial(open_i2c_bus, config.i2c.bus),
        store_path=config.store.path,
    )


@contextlib.asynccontextmanager
async def build_sim(
    config: RobotConfig,
    plan: FloorPlan,
    setup: SimSetup,
    extra: ExtraModules | None = None,
    web: bool = True,
) -> AsyncIterator[Runtime]:
    """The daemon on the simulated robot; the devices run while the context is open and the
    order store lives in a temporary directory (each run starts with an empty queue)."""
    clock = ScaledClock(setup.speed)
    world = World(
        plan,
        RobotSpec.from_config(config),
        floor=setup.floor,
        pose=setup.pose,
        obstacles=setup.obstacles,
        seed=setup.seed,
        elevator=SimElevator(plan, car_floor=setup.floor),
    )
    sim = Simulation(world, config, clock, setup.faults, speed=setup.speed)
    start = PoseEstimate(
        x_mm=setup.pose.x_mm,
        y_mm=setup.pose.y_mm,
        heading_deg=setup.pose.heading_deg,
        floor=setup.floor,
        sigma_x_mm=50.0,
        sigma_y_mm=50.0,
        sigma_heading_deg=5.0,
    )
    with tempfile.TemporaryDirectory(prefix="coffeebot-sim-") as tmp:
        # Modules first (the particle filter builds its floors' likelihood fields, ~1 s),
        # then the clock starts from zero with the simulated devices: building is not
        # simulated time.
        runtime = assemble(
            sim.config,
            plan,
            clock=clock,
            open_i2c=lambda: sim.tof.bus,
            store_path=Path(tmp) / "orders.sqlite3",
            start=start,
            sim=sim,
            extra=extra,
            web=web,
        )
        clock.restart(0.0)
        sim.start()
        try:
            yield runtime
        finally:
            sim.close()


def recorder(
    board: Board, path: Path | None, config: RobotConfig
) -> contextlib.AbstractAsyncContextManager[object]:
    """``--record``: started before the modules, closed after their shutdown is on the board."""
    if path is None:
        return contextlib.nullcontext()
    return Recorder(board, path, metadata={"robot": config.name})


async def serve(runtime: Runtime, record: Path | None = None) -> None:
    """Run the daemon as a service until asked to stop (a signal, a scenario's end)."""
    # systemd's watchdog kills a stalled daemon with SIGABRT: leave its stacks in the journal.
    faulthandler.enable()
    config = runtime.config
    daemon = runtime.daemon
    daemon.install_signal_handlers()
    watchdog = config.watchdog
    try:
        async with recorder(runtime.board, record, config):
            await run_as_service(
                daemon,
                Notifier.from_env(),
                control_loop_check(runtime.board, watchdog.topics, watchdog.max_age_s),
                self_check=runtime.self_check,
                max_loop_lag_s=watchdog.max_loop_lag_s,
            )
    finally:
        runtime.store.close()


class StopAfter(Module):
    """Ends the run after ``seconds`` of the board's clock (``--duration``)."""

    name = "duration"

    def __init__(self, runtime: Runtime, seconds: float) -> None:
        self.runtime = runtime
        self.seconds = seconds

    async def run(self, ctx: ModuleContext) -> None:
        await ctx.clock.sleep(self.seconds)
        self.runtime.request_stop(f"--duration {self.seconds:g} s reached")


async def run_scenario(
    config: RobotConfig,
    scenario: Scenario,
    plan: FloorPlan,
    *,
    speed: float = 1.0,
    web: bool = False,
    record: Path | None = None,
) -> dict[str, Any]:
    """Run the whole daemon through ``scenario`` on the simulated robot; the report."""
    config = scenario.apply_limits(config)
    driver: list[ScenarioModule] = []

    def add_driver(runtime: Runtime) -> list[Module]:
        assert runtime.sim is not None
        driver.append(
            ScenarioModule(
                scenario, plan, runtime.config, runtime.sim, runtime.orders, runtime.request_stop
            )
        )
        return driver

    started = time.monotonic()
    async with build_sim(config, plan, scenario.setup(speed), add_driver, web=web) as runtime:
        await serve(runtime, record)
    report = driver[0].report()
    # What the machine kept up with: below the requested speed, the clock was paced down.
    report["real_time_factor"] = round(report["sim_time_s"] / (time.monotonic() - started), 2)
    return report
