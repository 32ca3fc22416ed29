"""The simulated robot under the daemon: one :class:`World` behind the simulated buses.

The world answers the simulated chips from the I2C worker thread (reading the VL53L1X
registers) while :meth:`Simulation.run` steps it on the event loop, so every access goes
through :attr:`Simulation.lock`. Time is the daemon's clock: the world is stepped to
``clock.now()``, and the chips read the same clock. On the simulator's
:class:`~coffeebot.clock.SteppedClock` the world steps only when the daemon has settled
(:mod:`coffeebot.lockstep`), so a run depends on its seed alone, not on the machine's load.
The two UART devices sit on in-process serial lines (:meth:`Simulation.open_serial`) whose
read timeouts are simulated time, and answer once per step.

Reachable from outside as ``Runtime.sim``: ``world`` for ground truth (reports, the live
map), :meth:`place_robot` for what moves the robot other than its wheels (the elevator).
The CPU time the world itself costs (stepping, ray casts for the sensors, the UWB and motor
samples) is counted in :attr:`Simulation.cpu_s`, so that benchmarks can tell the robot's
share of a simulated run from the simulator's.
"""

from __future__ import annotations

import asyncio
import contextlib
import math
import threading
import time
from collections.abc import Iterator, Sequence, Sized
from dataclasses import dataclass, field

from coffeebot.clock import Clock, SteppedClock
from coffeebot.config import RobotConfig
from coffeebot.floorplan import FloorPlan
from coffeebot.hardware.serial_port import SerialPort
from coffeebot.hardware.vl53l1x import SpadRoi
from coffeebot.lockstep import Lockstep
from coffeebot.messages import ElevatorRequest, ElevatorState, UwbFix
from coffeebot.sim.dwm1001 import SimDwm1001
from coffeebot.sim.faults import Fault, FaultRecord
from coffeebot.sim.i2c import make_tof_hardware
from coffeebot.sim.motor_controller import DriveSample, SimMotorController
from coffeebot.sim.serial_line import MemoryLine
from coffeebot.sim.store import SimStore
from coffeebot.sim.world import ObstacleSpec, Pose, World
from coffeebot.sim.world.tof import Returns


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
        self, left_mm_s: float, right_mm_s: float, now: float, until: float = math.inf
    ) -> None:
        with self.sim.world_time() as world:
            world.command_wheels(left_mm_s, right_mm_s, until_s=self.sim.world_t(until))

    def sample(self, now: float) -> DriveSample:
        with self.sim.world_time() as world:
            left, right = world.encoder_ticks
            v_left, v_right = world.wheel_speeds_mm_s
            return DriveSample(left, right, v_left, v_right, world.gyro_z_dps())


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
    floor, door = plan.tea_room
    x, y = floor.from_hallway(door.at_mm, 0.0)
    return SimSetup(floor.level, Pose(x, y, floor.hallway.heading_deg + 180.0), speed=speed)


class Simulation:
    """The world, the simulated I2C bus, DWM1001 and motor controller wired to it."""

    def __init__(
        self,
        world: World,
        config: RobotConfig,
        clock: Clock,
        faults: Sequence[Fault] = (),
        store: SimStore | None = None,
    ) -> None:
        self.world = world
        self.store = store
        """The order database the store faults act on (None: a run without one)."""
        self.clock = clock
        self.lock = threading.RLock()
        self.faults = [fault.model_copy() for fault in faults]  # each run starts afresh
        self.truth = TruthLog()
        self.cpu_s = 0.0
        """CPU seconds spent in the world, on whichever thread asked (see :meth:`world_time`)."""
        self._origin = clock.now()
        """The world's t = 0 on the clock: the robot is switched on (its self-check included)."""
        by_id = sorted(config.tof.sensors, key=lambda s: s.id)
        self._index = {s.channel: i for i, s in enumerate(by_id)}
        self.sensor_channel = {s.id: s.channel for s in by_id}
        self.tof = make_tof_hardware(
            self._tof_returns,
            self._index,
            mux_address=config.i2c.mux_address,
            clock=clock.now,
            noise=world.noise,
            seed=world.seed,
        )
        if isinstance(clock, SteppedClock):
            self.lockstep = clock.lockstep
        else:  # the machine's clock (a benchmark of the daemon's own timing): never engaged
            self.lockstep = Lockstep(clock.now)
        # Polled once per step (:meth:`advance`), never in threads of their own.
        self.uwb = SimDwm1001(
            fix_fn=self._uwb_fix, clock=clock.now, line=MemoryLine("uwb", self.lockstep)
        )
        self.motor = SimMotorController(
            WorldDrive(self), clock=clock.now, line=MemoryLine("motor", self.lockstep)
        )
        self._lines = {device.port: device.line for device in (self.uwb, self.motor)}
        self.config = config.model_copy(
            update={
                "uwb": config.uwb.model_copy(update={"port": self.uwb.port}),
                "motor": config.motor.model_copy(update={"port": self.motor.port}),
            }
        )
        """``config`` with the serial ports pointing at the simulated devices."""

    def open_serial(self, url: str, baudrate: int, timeout_s: float) -> SerialPort:
        """Opens the simulated devices' ports, as ``open_port`` opens real ones."""
        line = self._lines.get(url)
        if not isinstance(line, MemoryLine):
            raise OSError(f"could not open port {url}: not a simulated device's port")
        return line.open(url, baudrate, timeout_s)

    @property
    def t_s(self) -> float:
        """Simulated seconds since the world module started (the world's own time)."""
        return self.world.t_s

    def close(self) -> None:
        self.uwb.close()
        self.motor.close()

    async def run(self, step_s: float = 0.005) -> None:
        """Move simulated time on and step the world, every ``step_s`` of simulated time,
        for as long as the daemon runs (from before its self-check to after its shutdown).

        On a :class:`SteppedClock` (the simulator's) this is the clock's only advancer. Before
        each step it waits until the daemon has settled: the event loop has nothing else to
        run and every worker thread has finished or waits for a later step
        (:mod:`coffeebot.lockstep`); the results of the threads' calls are handed over in the
        order the calls were made. So the daemon's reaction to a step takes no simulated time
        and a run is the same on a busy machine as on an idle one, only slower. The steps are
        paced to the clock's speed in the machine's time as long as the machine keeps up (a
        late step is not made up for by a burst). On the machine's clock (a benchmark of the
        daemon's own timing) the world just steps as time goes.
        """
        clock = self.clock
        if not isinstance(clock, SteppedClock):
            while True:
                self.advance()
                await clock.sleep(step_s)
        loop = asyncio.get_running_loop()
        wall_step = step_s / clock.speed
        self.lockstep.engage(True)
        try:
            due = time.monotonic()
            while True:
                await settle(loop, self.lockstep)
                # One step is one event for the worker threads: a read that times out at
                # this step sees the bytes the step brings, whichever thread wakes first.
                with self.lockstep.lock:
                    clock.advance(step_s)
                    self.advance()
                if wall_step > 0:
                    due = max(due + wall_step, time.monotonic() - wall_step)
                    if due > time.monotonic():
                        await asyncio.sleep(due - time.monotonic())
        finally:
            self.lockstep.engage(False)

    def advance(self) -> None:
        """Step the world to the clock's present, let the UART devices take their turn and
        apply the faults that are due."""
        now = self.clock.now()
        with self.world_time() as world:
            world.step(now - self._origin - world.t_s)
            gap = world.clearance_mm()
            self.truth.min_clearance_mm = min(self.truth.min_clearance_mm, gap)
        self.motor.poll(now)
        self.uwb.poll(now)
        for fault in self.faults:
            record = fault.update(self)
            if record is not None:
                self.truth.faults.append(record)

    def world_t(self, clock_t: float) -> float:
        """The world's time at clock time ``clock_t``."""
        return clock_t - self._origin

    def place_robot(self, pose: Pose, floor: int | None = None) -> None:
        """Move the robot without driving: the start of a run, an elevator ride."""
        with self.lock:
            self.world.place_robot(pose, floor)

    @contextlib.contextmanager
    def world_time(self) -> Iterator[World]:
        """The world under the lock, the calling thread's CPU time in it added to ``cpu_s``
        (``thread_time`` counts no time spent waiting for the lock)."""
        start = time.thread_time()
        with self.lock:
            try:
                yield self.world
            finally:
                self.cpu_s += time.thread_time() - start

    def _tof_returns(self, channel: int, roi: SpadRoi) -> Returns:
        with self.world_time() as world:
            return world.tof_returns(self._index[channel], roi)

    def _uwb_fix(self) -> UwbFix | None:
        with self.world_time() as world:
            return world.uwb_fix()


class SimElevatorLink:
    """The world's elevator as the elevator module sees it, every call under the lock."""

    def __init__(self, sim: Simulation) -> None:
        self.sim = sim

    def request(self, request: ElevatorRequest) -> None:
        with self.sim.lock:
            if self.sim.world.elevator is not None:
                self.sim.world.elevator.request(request)

    def state(self) -> ElevatorState:
        with self.sim.lock:
            if self.sim.world.elevator is None:
                return ElevatorState(car_floor=None, doors="closed", source="none")
            return self.sim.world.elevator.state()


async def settle(loop: asyncio.AbstractEventLoop, lockstep: Lockstep) -> None:
    """Return once nothing in the daemon can happen before simulated time moves on: no task
    or callback is ready to run (``loop._ready``, CPython's run queue, is the only place
    that says so) and no worker thread is busy; finished calls' results are handed over
    meanwhile, in the order the calls were made."""
    ready: Sized | None = getattr(loop, "_ready", None)
    if ready is None:
        raise RuntimeError("the simulator steps time on asyncio's own event loop only")
    while True:
        await asyncio.sleep(0)
        if ready:
            continue
        results = lockstep.settle()
        if not results and not ready:
            return
        for deliver in results:
            deliver()
