"""The daemon on the simulated robot: a :class:`~coffeebot.sim.simulation.Simulation` (the
world behind a simulated I2C bus and two simulated UART devices) under the very same
modules, the world stepping alongside, the simulated elevator and the true pose on the live
map."""

from __future__ import annotations

import asyncio
import contextlib
import functools
import logging
from collections.abc import AsyncIterator, Callable, Sequence
from pathlib import Path

from coffeebot.clock import Clock, MonotonicClock, SteppedClock
from coffeebot.config import RobotConfig
from coffeebot.floorplan import FloorPlan
from coffeebot.messages import PoseEstimate
from coffeebot.modules.base import Module
from coffeebot.runtime.assemble import Runtime, assemble
from coffeebot.sim.cameras import sim_cameras
from coffeebot.sim.crash import crash_switches
from coffeebot.sim.rundir import run_directory
from coffeebot.sim.simulation import SimElevatorLink, SimSetup, Simulation
from coffeebot.sim.stepper import SimWorld
from coffeebot.sim.store import SimStore
from coffeebot.sim.world import RobotSpec, World
from coffeebot.sim.world.elevator import SimElevator
from coffeebot.web.livemap import MapPose

log = logging.getLogger(__name__)

SimExtraModules = Callable[[Runtime, Simulation], Sequence[Module]]
"""Modules a caller adds once the runtime and its simulation exist (a scenario's driver)."""


def true_pose(sim: Simulation) -> Callable[[], MapPose]:
    def pose() -> MapPose:
        with sim.lock:
            t, level = sim.robot.pose, sim.robot.floor_level
        return MapPose(x_mm=t.x_mm, y_mm=t.y_mm, heading_deg=t.heading_deg, floor=level)

    return pose


@contextlib.asynccontextmanager
async def build_sim(
    config: RobotConfig,
    plan: FloorPlan,
    setup: SimSetup,
    extra: SimExtraModules | None = None,
    web: bool = True,
    state_dir: Path | None = None,
) -> AsyncIterator[tuple[Runtime, Simulation]]:
    """The daemon on the simulated robot, and its simulation; the world runs while the
    context is open. The order store lives in ``state_dir`` (the demo's orders survive a
    restart), or without one in a temporary directory (each run starts with an empty queue;
    one a killed run left behind goes at the next start)."""
    clock: Clock = MonotonicClock() if setup.wall_clock else SteppedClock(setup.speed)
    world = World(
        plan,
        RobotSpec.from_config(config),
        floor=setup.floor,
        pose=setup.pose,
        obstacles=setup.obstacles,
        seed=setup.seed,
        elevators=SimElevator.bank(plan, setup.floor),
    )
    start = PoseEstimate(
        x_mm=setup.pose.x_mm,
        y_mm=setup.pose.y_mm,
        heading_deg=setup.pose.heading_deg,
        floor=setup.floor,
        sigma_x_mm=50.0,
        sigma_y_mm=50.0,
        sigma_heading_deg=5.0,
    )
    with contextlib.ExitStack() as stack:
        if state_dir is None:
            state_dir = Path(stack.enter_context(run_directory()))
        store = SimStore(
            state_dir / "orders.sqlite3", busy_timeout_s=config.store.busy_timeout_s, clock=clock
        )
        shared = SimWorld(world, clock)
        sim = Simulation(shared, world.robot, config, setup.faults, store=store)
        runtime = assemble(
            sim.config,
            plan,
            clock=clock,
            open_i2c=lambda: sim.tof.bus,
            store=store,
            open_serial=sim.open_serial,
            start=start,
            elevator=SimElevatorLink(sim),
            true_pose=true_pose(sim),
            cameras=sim_cameras(world, plan, shared.world_time, seed=setup.seed)
            if config.cameras.enabled
            else None,
            extra=None if extra is None else lambda runtime: extra(runtime, sim),
            web=web,
        )
        switches = crash_switches(runtime.daemon.modules, sim.crashing_modules())
        sim.crashes = {name: switch.trip for name, switch in switches.items()}
        # The world runs from before the daemon's self-check until after its shutdown.
        world_task = shared.start()
        world_task.add_done_callback(functools.partial(_world_ended, runtime))
        try:
            yield runtime, sim
        finally:
            await shared.stop()
            store.close()


def _world_ended(runtime: Runtime, task: asyncio.Task[None]) -> None:
    """A simulator that fails ends the run, saying why (the daemon would wait for time)."""
    if task.cancelled() or task.exception() is None:
        return
    error = task.exception()
    log.error("the simulated world failed: %s", error, exc_info=error)
    runtime.request_stop(f"the simulated world failed: {error}")
