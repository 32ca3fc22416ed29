"""A fleet put together: the dispatcher's daemon, and (in simulation) several robots' daemons
in one simulated building, all talking over an MQTT broker.

The dispatcher (``coffeebot fleet``) is a daemon of its own: a board, the dispatcher module
(orders, assignment, leases, the broker connection), with ``[cameras] enabled`` the fleet's
camera service (every robot's fixes and the map's camera layer), and the same web app a
single robot serves, given the dispatcher as its orders and the fleet's robots as its map.
Each robot is
the very assembly a single robot runs (:func:`~coffeebot.runtime.assemble.assemble`) with
``[fleet] broker`` set: the fleet bridge takes the orders module's place.

:func:`build_fleet_sim` co-hosts everything in one process, as the demo, the tests and the
benchmark need: one simulated world holding every robot (each one's sensors see the others),
each robot with its own simulated buses and its own whole daemon (board, modules, safety
loop), as each would run on its own Pi, and the dispatcher (with the cameras on, the camera
service watching the simulated ceiling cameras); one simulated clock for all, in lockstep
with all their worker threads, and the fleet's shared time base. Only the broker is
outside: they reach each other through it alone.
"""

from __future__ import annotations

import asyncio
import contextlib
import functools
import logging
import time
from collections.abc import AsyncIterator, Callable, Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path

from coffeebot.board import Board
from coffeebot.cameras.sources import FrameSource, stream_sources
from coffeebot.clock import Clock, SteppedClock
from coffeebot.config import RobotConfig
from coffeebot.daemon import Daemon
from coffeebot.errors import ConfigError
from coffeebot.fleet.camera_service import CameraServiceModule
from coffeebot.fleet.dispatcher import Announce, Dispatcher
from coffeebot.fleet.estimates import TravelTimes
from coffeebot.fleet.module import DispatcherModule, Send
from coffeebot.fleet.mosquitto import DISPATCHER_USER, BrokerAddress, Credentials
from coffeebot.fleet.protocol import FleetClock
from coffeebot.floorplan import FloorPlan
from coffeebot.logs import ROBOT
from coffeebot.messages import ALL_TOPICS, FLEET, PoseEstimate
from coffeebot.modules.base import Module
from coffeebot.runtime.assemble import Runtime, assemble
from coffeebot.runtime.web import web_module
from coffeebot.sim.cameras import sim_cameras
from coffeebot.sim.rundir import run_directory
from coffeebot.sim.simulation import SimElevatorLink, Simulation
from coffeebot.sim.stepper import SimWorld
from coffeebot.sim.store import SimStore
from coffeebot.sim.world import Pose, RobotSpec, World
from coffeebot.sim.world.elevator import SimElevator
from coffeebot.store import OrderStore
from coffeebot.systemd import Notifier, control_loop_check, run_as_service
from coffeebot.web.eta import Pace
from coffeebot.web.livemap import MapPose

log = logging.getLogger(__name__)

STALE_VIEW_S = 5.0
"""The fleet's view is published every second: silent this long, the inspector alerts."""


@dataclass
class DispatcherRuntime:
    board: Board
    module: DispatcherModule
    store: OrderStore
    daemon: Daemon = field(init=False)


def fleet_poses(board: Board) -> Callable[[], Mapping[str, MapPose]]:
    """The robots the dispatcher knows, for the live map, the freshest first; a silent one
    stays where it was last heard of, marked with how long it has been silent."""

    def poses() -> Mapping[str, MapPose]:
        view = board.latest(FLEET)
        if view is None:
            return {}
        robots = sorted(view.msg.robots, key=lambda r: (r.stale, r.robot))
        return {
            r.robot: MapPose(
                x_mm=r.x_mm,
                y_mm=r.y_mm,
                heading_deg=r.heading_deg,
                floor=r.floor,
                silent_s=r.heard_ago_s if r.stale else None,
            )
            for r in robots
            if r.x_mm is not None
            and r.y_mm is not None
            and r.heading_deg is not None
            and r.floor is not None
        }

    return poses


def dispatcher_runtime(
    config: RobotConfig,
    plan: FloorPlan,
    store: OrderStore,
    broker: str,
    login: Credentials,
    clock: Clock,
    *,
    web: bool = True,
    extra: Sequence[Module] = (),
    cameras: Mapping[str, FrameSource] | None = None,
    fleet_clock: FleetClock = time.time,
) -> DispatcherRuntime:
    """The dispatcher's daemon: ``config`` is the fleet's robots' description (their pace on
    routes, the web's settings, ``[fleet.dispatch]``, ``[cameras]``); ``extra``: modules
    beside it (the simulated staff). With ``[cameras] enabled`` the camera service watches
    ``cameras`` (default: the streams the config names), its times on ``fleet_clock``."""
    board = Board(ALL_TOPICS, clock=clock)
    travel = TravelTimes(plan, config, Pace(pickup_timeout_s=config.navigation.pickup_timeout_s))

    def make(send: Send, announce: Announce, now: Callable[[], float]) -> Dispatcher:
        return Dispatcher(store, travel, config.fleet.dispatch, send, announce, now)

    module = DispatcherModule(broker, login, make, store)
    runtime = DispatcherRuntime(board, module, store)
    modules: list[Module] = [module, *extra]
    if config.cameras.enabled:
        sources = stream_sources(config.cameras.streams, plan) if cameras is None else cameras
        modules.append(CameraServiceModule(config, plan, sources, broker, login, fleet_clock))
    if web:
        # The dispatcher's board carries no robot's sensors: only its own view must keep coming.
        own = config.web.model_copy(update={"stale_after_s": {FLEET.name: STALE_VIEW_S}})
        modules.append(
            web_module(
                config.model_copy(update={"web": own}),
                plan,
                board,
                module,
                modules=lambda: runtime.daemon.modules,
                health=lambda: runtime.daemon.health(),
                cpu=lambda: runtime.daemon.cpu,
                poses=fleet_poses(board),
            )
        )
    runtime.daemon = Daemon(board, modules, supervision=config.supervision)
    return runtime


@dataclass
class FleetSim:
    dispatcher: DispatcherRuntime
    robots: list[Runtime]
    sims: list[Simulation]
    world: SimWorld

    def request_stop(self, reason: str) -> None:
        for runtime in self.robots:
            runtime.request_stop(reason)
        self.dispatcher.daemon.request_stop(reason)


def robot_ids(count: int) -> list[str]:
    return [f"robot-{i + 1}" for i in range(count)]


@contextlib.asynccontextmanager
async def build_fleet_sim(
    config: RobotConfig,
    plan: FloorPlan,
    count: int,
    broker: BrokerAddress,
    logins: Mapping[str, Credentials],
    *,
    speed: float = 1.0,
    seed: int = 0,
    state_dir: Path | None = None,
    web: bool = True,
    dispatcher_extra: Sequence[Module] = (),
    robot_extra: Callable[[str], Sequence[Module]] | None = None,
) -> AsyncIterator[FleetSim]:
    """``count`` simulated robots, each parked at its spot in the tea room, and the
    dispatcher, on the broker at ``broker`` with ``logins`` (by user name); the world runs
    while the context is open. ``dispatcher_extra`` and ``robot_extra(robot id)``: modules
    added to their daemons (simulated staff, a benchmark's probes)."""
    clock = SteppedClock(speed)
    base = plan.tea_room
    spots = base.floor.parking
    if count > len(spots):
        raise ConfigError(
            f"{plan.name}: {count} robots but {len(spots)} parking spots in "
            f"{base.door.room} on floor {base.floor.level}"
        )
    spec = RobotSpec.from_config(config)
    poses = [Pose(s.x_mm, s.y_mm, s.heading_deg) for s in spots[:count]]
    world = World(
        plan,
        spec,
        floor=base.floor.level,
        pose=poses[0],
        seed=seed,
        elevators=SimElevator.bank(plan, base.floor.level),
        robot_name=robot_ids(1)[0],
    )
    shared = SimWorld(world, clock)
    url = broker.url
    with contextlib.ExitStack() as stack:
        if state_dir is None:
            state_dir = Path(stack.enter_context(run_directory()))
        # Orders stamped in simulated time: how long one has waited is what joint
        # assignment weighs, and the machine's clock runs at whatever pace it steps the fleet.
        epoch = time.time() - clock.now()
        store = SimStore(
            state_dir / "orders.sqlite3",
            lambda: epoch + clock.now(),
            busy_timeout_s=config.store.busy_timeout_s,
            clock=clock,
        )
        robots, sims = [], []
        for index, robot in enumerate(robot_ids(count)):
            body = (
                world.robot
                if index == 0
                else world.add_robot(spec, base.floor.level, poses[index], name=robot)
            )
            fleet = config.fleet.model_copy(
                update={"broker": url, "robot_id": robot, "parking_spot": index}
            )
            sim = Simulation(shared, body, config.model_copy(update={"fleet": fleet}))
            pose = poses[index]
            start = PoseEstimate(
                x_mm=pose.x_mm,
                y_mm=pose.y_mm,
                heading_deg=pose.heading_deg,
                floor=base.floor.level,
                sigma_x_mm=50.0,
                sigma_y_mm=50.0,
                sigma_heading_deg=5.0,
            )
            robots.append(
                assemble(
                    sim.config,
                    plan,
                    clock=clock,
                    open_i2c=functools.partial(lambda s: s.tof.bus, sim),
                    store=None,
                    open_serial=sim.open_serial,
                    start=start,
                    elevator=SimElevatorLink(sim),
                    web=False,
                    broker_login=logins[robot],
                    fleet_clock=clock.now,
                    extra=None
                    if robot_extra is None
                    else functools.partial(lambda name, _: robot_extra(name), robot),
                )
            )
            sims.append(sim)
        dispatcher = dispatcher_runtime(
            config,
            plan,
            store,
            url,
            logins[DISPATCHER_USER],
            clock,
            web=web,
            extra=dispatcher_extra,
            cameras=sim_cameras(world, plan, shared.world_time, seed=seed)
            if config.cameras.enabled
            else None,
            fleet_clock=clock.now,
        )
        shared.start()
        try:
            yield FleetSim(dispatcher, robots, sims, shared)
        finally:
            await shared.stop()
            store.close()


async def serve_fleet(fleet: FleetSim) -> None:
    """Run the dispatcher and every robot until a stop is requested of them."""

    async def robot(runtime: Runtime) -> None:
        ROBOT.set(runtime.config.fleet.robot_id)  # this task's copy: its log lines name it
        watchdog = runtime.config.watchdog
        await run_as_service(
            runtime.daemon,
            Notifier.from_env(),
            control_loop_check(runtime.board, watchdog.topics, watchdog.max_age_s),
            self_check=runtime.self_check,
        )

    async def dispatcher() -> None:
        daemon = fleet.dispatcher.daemon
        await daemon.start()
        try:
            await daemon.wait_stop_requested()
        finally:
            await daemon.shutdown()

    await asyncio.gather(dispatcher(), *(robot(r) for r in fleet.robots))
