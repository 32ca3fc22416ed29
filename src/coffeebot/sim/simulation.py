"""The simulated robot under the daemon: one :class:`World` behind the simulated buses.

The world answers the simulated chips from several threads (the I2C worker reading the
VL53L1X registers, the two pty devices) while the ``world`` module steps it on the event
loop, so every access goes through :attr:`Simulation.lock`. Time is the daemon's clock: the
world is stepped to ``clock.now()``, and the chips read the same clock, so a sped-up clock
speeds up everything together.

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
from collections.abc import Iterator, Sequence
from dataclasses import dataclass, field

from coffeebot.clock import Clock, SteppedClock
from coffeebot.config import RobotConfig
from coffeebot.floorplan import FloorPlan
from coffeebot.hardware.vl53l1x import SpadRoi
from coffeebot.messages import ElevatorRequest, ElevatorState, UwbFix
from coffeebot.modules.base import Module, ModuleContext
from coffeebot.sim.dwm1001 import SimDwm1001
from coffeebot.sim.faults import Fault, FaultRecord
from coffeebot.sim.i2c import make_tof_hardware
from coffeebot.sim.motor_controller import DriveSample, SimMotorController
from coffeebot.sim.world import ObstacleSpec, Pose, World
from coffeebot.sim.world.tof import Returns

DEVICE_TICK_S = 0.005
"""Simulated seconds between two device thread ticks (motor telemetry is every 20 ms)."""


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
            world.command_wheels(left_mm_s, right_mm_s, until_s=self.sim.world_t(until, now))

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
        speed: float = 1.0,
    ) -> None:
        self.world = world
        self.clock = clock
        self.lock = threading.RLock()
        self.faults = [fault.model_copy() for fault in faults]  # each run starts afresh
        self.truth = TruthLog()
        self.cpu_s = 0.0
        """CPU seconds spent in the world, on whichever thread asked (see :meth:`world_time`)."""
        self._origin: float | None = None  # the world's t = 0 on the clock: its first step
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
            hold=clock.hold if isinstance(clock, SteppedClock) else None,
        )
        tick_s = DEVICE_TICK_S / speed
        self.uwb = SimDwm1001(fix_fn=self._uwb_fix, clock=clock.now, tick_s=tick_s)
        self.motor = SimMotorController(WorldDrive(self), clock=clock.now, tick_s=tick_s)
        self.config = config.model_copy(
            update={
                "uwb": config.uwb.model_copy(update={"port": self.uwb.port}),
                "motor": config.motor.model_copy(update={"port": self.motor.port}),
            }
        )
        """``config`` with the serial ports pointing at the simulated devices."""

    @property
    def t_s(self) -> float:
        """Simulated seconds since the world module started (the world's own time)."""
        return self.world.t_s

    def start(self) -> None:
        self.uwb.start()
        self.motor.start()

    def close(self) -> None:
        self.uwb.close()
        self.motor.close()

    def advance(self) -> None:
        """Step the world to the clock's present, then apply the faults that are due. On a
        :class:`SteppedClock` the UART devices then take their turn too (after the first
        step their own threads stop), so they answer in the same simulated time as the
        world moves."""
        now = self.clock.now()
        stepped = isinstance(self.clock, SteppedClock)
        if self._origin is None:
            self._origin = now  # time spent in the self-check is not part of the run
            if stepped:
                self.uwb.stop_serving()
                self.motor.stop_serving()
        with self.world_time() as world:
            world.step(now - self._origin - world.t_s)
            gap = world.clearance_mm()
            self.truth.min_clearance_mm = min(self.truth.min_clearance_mm, gap)
        if stepped:
            self.uwb.poll(now)
            self.motor.poll(now)
        for fault in self.faults:
            record = fault.update(self)
            if record is not None:
                self.truth.faults.append(record)

    def world_t(self, clock_t: float, now: float) -> float:
        """The world's time at clock time ``clock_t`` (``now`` is the clock's present)."""
        if self._origin is None:  # not stepped yet: the world's t = 0 is about now
            return self.world.t_s + (clock_t - now)
        return clock_t - self._origin

    def place_robot(self, pose: Pose, floor: int | None = None) -> None:
        """Move the robot without driving: the start of a run, an elevator ride."""
        with self.lock:
            self.world.place_robot(pose, floor)

    @contextlib.contextmanager
    def world_time(self) -> Iterator[World]:
        """The world under the lock, the calling thread's CPU time in it added to ``cpu_s``
        (``thread_time`` counts no time spent waiting for the lock). Simulated time stands
        still meanwhile: what the world costs to compute is not time the robot has
        (``SteppedClock.hold``)."""
        hold: contextlib.AbstractContextManager[None] = (
            self.clock.hold() if isinstance(self.clock, SteppedClock) else contextlib.nullcontext()
        )
        start = time.thread_time()
        with self.lock, hold:
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


class WorldModule(Module):
    """Moves simulated time on and steps the world, every ``step_s`` of simulated time.

    On a :class:`SteppedClock` (the simulator's) it is the clock's only advancer, pacing the
    steps to the clock's speed in the machine's time as long as the machine keeps up; when
    it does not, the run goes slower, not differently (a late step is not made up for by a
    burst). On any other clock (a test's manual clock) it just steps the world as time goes.
    """

    name = "world"

    def __init__(self, sim: Simulation, step_s: float = 0.005) -> None:
        self.sim = sim
        self.step_s = step_s

    async def run(self, ctx: ModuleContext) -> None:
        clock = ctx.clock
        if not isinstance(clock, SteppedClock):
            while True:
                self.sim.advance()
                await clock.sleep(self.step_s)
        wall_step = self.step_s / clock.speed
        due = time.monotonic()
        while True:
            if clock.advance(self.step_s):
                self.sim.advance()
            due = max(due + wall_step, time.monotonic() - wall_step)
            await asyncio.sleep(max(0.0, due - time.monotonic()))
