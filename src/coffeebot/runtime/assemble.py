"""One function decides which modules run and how they are wired: :func:`assemble`.

The robot (:mod:`coffeebot.runtime.robot`) and the simulated robot
(:mod:`coffeebot.runtime.sim`) differ only in what they pass in: where the I2C bus comes
from, how the serial ports in the config are opened, the clock, an elevator interface and
the simulator's true pose for the live map. Either way every module reads time from the
board's clock.
"""

from __future__ import annotations

import time
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, field

from coffeebot.board import Board
from coffeebot.cameras.sources import FrameSource, stream_sources
from coffeebot.clock import Clock
from coffeebot.config import RobotConfig
from coffeebot.daemon import Daemon
from coffeebot.fleet.mosquitto import Credentials
from coffeebot.fleet.protocol import FleetClock
from coffeebot.floorplan import FloorPlan
from coffeebot.hardware.i2c import I2CBus
from coffeebot.hardware.selfcheck import service_check
from coffeebot.hardware.serial_port import open_port
from coffeebot.messages import ALL_TOPICS, PoseEstimate
from coffeebot.modules.angle import AngleModule
from coffeebot.modules.base import Module
from coffeebot.modules.cameras import CameraModule
from coffeebot.modules.collision import CollisionModule
from coffeebot.modules.door import DoorModule
from coffeebot.modules.elevator import ElevatorInterface, ElevatorModule
from coffeebot.modules.fleet_bridge import FleetBridge
from coffeebot.modules.motion import MotionModule
from coffeebot.modules.motor_driver import MotorDriver
from coffeebot.modules.navigation import NavigationModule
from coffeebot.modules.orders import OrdersModule
from coffeebot.modules.serial_device import Opener
from coffeebot.modules.state import StateModule
from coffeebot.modules.tof_poller import TofPoller
from coffeebot.modules.uwb_reader import UwbReader
from coffeebot.runtime.web import TruePose, web_module
from coffeebot.store import OrderStore
from coffeebot.systemd import SelfCheck

ExtraModules = Callable[["Runtime"], Sequence[Module]]
"""Modules a caller adds once the runtime exists (the scenario driver, test probes)."""


@dataclass
class Runtime:
    """Everything one daemon run is made of."""

    config: RobotConfig
    """The configuration the modules were built from (in simulation, with the pty ports)."""
    plan: FloorPlan
    board: Board
    store: OrderStore | None
    """The robot's order database; None in a fleet, where the dispatcher keeps the orders."""
    orders: OrdersModule | None
    self_check: SelfCheck
    daemon: Daemon = field(init=False)
    """Made last, from every module; modules that need it call :meth:`request_stop`."""

    def request_stop(self, reason: str) -> None:
        self.daemon.request_stop(reason)

    def own_orders(self) -> OrdersModule:
        """The robot's own order queue: a single robot's (in a fleet the dispatcher's)."""
        if self.orders is None:
            raise ValueError("this robot is part of a fleet: the dispatcher keeps its orders")
        return self.orders

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
    open_serial: Opener,
    start: PoseEstimate | None,
) -> list[Module]:
    """Drivers, perception and state: the modules every run has, in start order."""
    return [
        TofPoller(config.i2c, config.tof, open_i2c),
        UwbReader(config.uwb, opener=open_serial),
        MotorDriver(config.motor, opener=open_serial),
        CollisionModule(config, plan),
        AngleModule(config, plan),
        DoorModule(config, plan),
        StateModule(config, plan, start=start),
    ]


def assemble(
    config: RobotConfig,
    plan: FloorPlan,
    *,
    clock: Clock,
    open_i2c: Callable[[], I2CBus],
    store: OrderStore | None,
    open_serial: Opener = open_port,
    kernel_hz: Callable[[], int | None] | None = None,
    start: PoseEstimate | None = None,
    elevator: ElevatorInterface | None = None,
    true_pose: TruePose | None = None,
    extra: ExtraModules | None = None,
    web: bool = True,
    broker_login: Credentials | None = None,
    fleet_clock: FleetClock = time.time,
    cameras: Mapping[str, FrameSource] | None = None,
) -> Runtime:
    """Build the board and every module from ``config`` and ``plan``.

    ``store``: the order database (the caller opens it: on the robot the board file's path,
    in simulation a temporary one). In a fleet (``[fleet] broker``) there is none: the fleet
    bridge takes the orders module's place, logging in with ``broker_login`` (default: the
    environment's), with ``fleet_clock`` the fleet's shared time base (the simulated clock
    when one process simulates the fleet), and the web UI is the dispatcher's.
    ``open_serial``: opens the serial ports by their names in the config (pyserial on the
    robot, the simulated lines in simulation);
    ``kernel_hz``: the I2C bus clock the kernel runs, for the self-check (a real bus only);
    ``elevator``: the building's elevator, if the robot can talk to it; ``true_pose``: a pose
    the live map draws beside the estimate (the simulator's truth); ``web``: serve the UI;
    ``cameras``: the ceiling cameras' frames by camera id, with ``[cameras] enabled`` (default:
    the streams the config names; the simulator passes its renderings). A robot in a fleet
    watches none: the dispatcher's camera service does, and its fleet bridge sends the
    odometry and takes the fixes.
    """
    board = Board(ALL_TOPICS, clock=clock)
    modules = robot_modules(config, plan, open_i2c, open_serial, start)
    modules += navigation_modules(config, plan, elevator)
    if config.cameras.enabled and not config.fleet.enabled:
        sources = stream_sources(config.cameras.streams, plan) if cameras is None else cameras
        modules.append(CameraModule(config, plan, sources))
    orders: OrdersModule | None = None
    if config.fleet.enabled:
        modules.append(FleetBridge(config, broker_login, fleet_clock))
    elif store is None:
        raise ValueError("a robot outside a fleet keeps its own orders: give it a store")
    else:
        orders = OrdersModule(store, config.store)
        modules.append(orders)
    runtime = Runtime(
        config=config,
        plan=plan,
        board=board,
        store=store,
        orders=orders,
        self_check=service_check(config, open_i2c, kernel_hz, open_serial, clock),
    )
    if web and orders is not None:
        modules.append(
            web_module(
                config,
                plan,
                board,
                orders,
                # The daemon is made below, from every module.
                modules=lambda: runtime.daemon.modules,
                health=lambda: runtime.daemon.health(),
                cpu=lambda: runtime.daemon.cpu,
                true_pose=true_pose,
            )
        )
    if extra is not None:
        modules += extra(runtime)
    runtime.daemon = Daemon(board, modules, supervision=config.supervision)
    return runtime
