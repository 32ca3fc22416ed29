"""A simulated robot under its daemon: its buses and devices, wired to its body in the world.

Each :class:`Simulation` is one robot of a :class:`~coffeebot.sim.stepper.SimWorld` (one
for a single robot, several for a fleet): the simulated I2C bus with a VL53L1X per channel,
and the DWM1001 tag and the motor controller on in-process serial lines
(:meth:`Simulation.open_serial`) whose read timeouts are simulated time. The world answers
the chips from the I2C worker thread while the stepper moves it on the event loop, so every
access goes through the world's lock (:meth:`Simulation.world_time`), which also counts the
CPU the world costs (``cpu_s``), so benchmarks can tell the robot's share of a simulated
run from the simulator's.

Reachable from outside as ``Runtime.sim``: ``robot`` for ground truth (reports, the live
map), :meth:`place_robot` for what moves the robot other than its wheels.
"""

from __future__ import annotations

import contextlib
import math
import threading
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field

from coffeebot.clock import Clock
from coffeebot.config import RobotConfig
from coffeebot.floorplan import FloorPlan
from coffeebot.hardware.serial_port import SerialPort
from coffeebot.hardware.vl53l1x import SpadRoi
from coffeebot.messages import ElevatorRequest, ElevatorState, UwbFix
from coffeebot.sim.dwm1001 import SimDwm1001
from coffeebot.sim.faults import Fault, FaultRecord, ModuleCrash
from coffeebot.sim.i2c import make_tof_hardware
from coffeebot.sim.motor_controller import DriveSample, SimMotorController
from coffeebot.sim.serial_line import MemoryLine
from coffeebot.sim.stepper import SimWorld
from coffeebot.sim.store import SimStore
from coffeebot.sim.world import ObstacleSpec, Pose, World
from coffeebot.sim.world.elevator import SimElevator
from coffeebot.sim.world.tof import Returns
from coffeebot.sim.world.world import WorldRobot


@dataclass
class TruthLog:
    """What only the simulator knows, accumulated while it runs, for the report."""

    min_clearance_mm: float = math.inf
    faults: list[FaultRecord] = field(default_factory=list)


class WorldDrive:
    """The motor controller's motors and sensors: the world's body."""

    def __init__(self, sim: Simulation) -> None:
        self.sim = sim

    def command(
        self,
        left_mm_s: float,
        right_mm_s: float,
        now: float,
        until: float = math.inf,
        brake: bool = False,
    ) -> None:
        robot = self.sim.robot
        with self.sim.world_time():
            robot.command_wheels(
                left_mm_s, right_mm_s, until_s=self.sim.shared.world_t(until), brake=brake
            )

    def sample(self, now: float) -> DriveSample:
        robot = self.sim.robot
        with self.sim.world_time():
            left, right = robot.encoder_ticks
            v_left, v_right = robot.wheel_speeds_mm_s
            return DriveSample(left, right, v_left, v_right, robot.gyro_z_dps())


@dataclass(frozen=True)
class SimSetup:
    """What a simulated run starts from (a scenario fills it; the demo uses defaults)."""

    floor: int
    pose: Pose
    obstacles: Sequence[ObstacleSpec] = ()
    faults: Sequence[Fault] = ()
    seed: int = 0
    speed: float = 1.0
    wall_clock: bool = False
    """Run the daemon on the machine's clock, as on the robot, instead of the simulated
    world's: for benchmarks of the daemon's own timing under load (``speed`` is then 1)."""


def demo_setup(plan: FloorPlan, speed: float = 1.0) -> SimSetup:
    """The robot in the hallway at the tea room door, facing back down the hallway."""
    whole, door = plan.tea_room
    floor = whole.view_of(door)
    x, y = floor.from_hallway(door.at_mm, 0.0)
    return SimSetup(floor.level, Pose(x, y, floor.hallway.heading_deg + 180.0), speed=speed)


class Simulation:
    """One robot's simulated I2C bus, DWM1001 and motor controller, wired to its body."""

    def __init__(
        self,
        shared: SimWorld,
        robot: WorldRobot,
        config: RobotConfig,
        faults: Sequence[Fault] = (),
        store: SimStore | None = None,
    ) -> None:
        self.shared = shared
        self.robot = robot
        self.store = store
        """The order database the store faults act on (None: a run without one)."""
        self.faults = [fault.model_copy() for fault in faults]  # each run starts afresh
        self.crashes: dict[str, Callable[[str], None]] = {}
        """Module name to what makes it crash (set up by whoever runs the daemon, for the
        ``module_crash`` faults)."""
        self.truth = TruthLog()
        clock, world = shared.clock, shared.world
        by_id = sorted(config.tof.sensors, key=lambda s: s.id)
        self._index = {s.channel: i for i, s in enumerate(by_id)}
        self.sensor_channel = {s.id: s.channel for s in by_id}
        self.tof = make_tof_hardware(
            self._tof_returns,
            self._index,
            mux_address=config.i2c.mux_address,
            clock=clock.now,
            noise=world.noise,
            seed=world.seed + 1000 * len(shared.robots),
            simulating=shared.simulated,
        )
        lockstep = shared.lockstep
        prefix = f"{robot.name}/" if shared.robots else ""
        # Polled once per step (:meth:`advance`), never in threads of their own.
        self.uwb = SimDwm1001(
            fix_fn=self._uwb_fix, clock=clock.now, line=MemoryLine(f"{prefix}uwb", lockstep)
        )
        self.motor = SimMotorController(
            WorldDrive(self), clock=clock.now, line=MemoryLine(f"{prefix}motor", lockstep)
        )
        self._lines = {device.port: device.line for device in (self.uwb, self.motor)}
        self.config = config.model_copy(
            update={
                "uwb": config.uwb.model_copy(update={"port": self.uwb.port}),
                "motor": config.motor.model_copy(update={"port": self.motor.port}),
            }
        )
        """``config`` with the serial ports pointing at the simulated devices."""
        shared.robots.append(self)

    # --- the shared world, as seen from this robot -------------------------------------------

    @property
    def world(self) -> World:
        return self.shared.world

    @property
    def clock(self) -> Clock:
        return self.shared.clock

    @property
    def lock(self) -> threading.RLock:
        return self.shared.lock

    @property
    def t_s(self) -> float:
        """Simulated seconds since the world started (the world's own time)."""
        return self.shared.world.t_s

    def world_time(self) -> contextlib.AbstractContextManager[World]:
        return self.shared.world_time()

    def world_t(self, clock_t: float) -> float:
        return self.shared.world_t(clock_t)

    # --- this robot ---------------------------------------------------------------------------

    def open_serial(self, url: str, baudrate: int, timeout_s: float) -> SerialPort:
        """Opens the simulated devices' ports, as ``open_port`` opens real ones."""
        line = self._lines.get(url)
        if not isinstance(line, MemoryLine):
            raise OSError(f"could not open port {url}: not a simulated device's port")
        return line.open(url, baudrate, timeout_s)

    def close(self) -> None:
        self.uwb.close()
        self.motor.close()

    def advance(self, now: float) -> None:
        """After the world has stepped to ``now``: the run's least clearance, the UART
        devices' turn, the faults that are due."""
        with self.world_time():
            gap = self.robot.clearance_mm()
        self.truth.min_clearance_mm = min(self.truth.min_clearance_mm, gap)
        self.motor.poll(now)
        self.uwb.poll(now)
        for fault in self.faults:
            record = fault.update(self)
            if record is not None:
                self.truth.faults.append(record)

    def crash_module(self, name: str, why: str) -> None:
        """Make module ``name`` raise where it is (the ``module_crash`` fault)."""
        crash = self.crashes.get(name)
        if crash is None:
            raise RuntimeError(f"module {name!r} cannot be crashed in this run")
        crash(why)

    def crashing_modules(self) -> set[str]:
        """The modules this run's faults crash."""
        return {f.module for f in self.faults if isinstance(f, ModuleCrash)}

    def place_robot(self, pose: Pose, floor: int | None = None) -> None:
        """Move the robot without driving: the start of a run."""
        with self.lock:
            self.robot.place(pose, floor)

    def _tof_returns(self, channel: int, roi: SpadRoi) -> Returns:
        with self.world_time():
            return self.robot.tof_returns(self._index[channel], roi)

    def _uwb_fix(self) -> UwbFix | None:
        with self.world_time():
            return self.robot.uwb_fix()


class SimElevatorLink:
    """The world's cars as the elevator module sees them, every call under the lock: a
    request goes to the car it names (None: the first), the state is that of the car last
    asked for."""

    def __init__(self, sim: Simulation) -> None:
        self.sim = sim
        self._car: str | None = None

    def _find(self, car: str | None) -> SimElevator | None:
        cars = self.sim.world.elevators
        return next((e for e in cars if car in (None, e.car)), None)

    def request(self, request: ElevatorRequest) -> None:
        with self.sim.lock:
            self._car = request.car
            elevator = self._find(request.car)
            if elevator is not None:
                elevator.request(request)

    def state(self) -> ElevatorState:
        with self.sim.lock:
            elevator = self._find(self._car)
            if elevator is None:
                return ElevatorState(car=self._car, car_floor=None, doors="closed", source="none")
            return elevator.state()
