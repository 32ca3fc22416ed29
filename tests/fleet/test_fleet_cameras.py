"""The fleet's camera service at work: two simulated robots, each its whole daemon, and the
dispatcher with the ceiling cameras on, over a real Mosquitto. The robots send their
odometry; the service watches the simulated cameras of the CS building and names the robots
on its tracks, both in view at once in the tea room (one leaving the loading spot while the
other waits at its parking spot or drives up to it), then out along the hallway under the
lobby's and the north hall's cameras, to offices beyond. Every fix a robot's board receives
is checked against the simulator's truth at that moment (a fix meant for the other robot
would be metres off), and every layer against where both robots are (a robot standing is
not an object).

One run (module fixture), on the simulated clock; it ends once both robots have driven out
past the lobby's camera and one past the north hall's.
"""

from __future__ import annotations

import asyncio
import contextlib
import math
import time
from collections.abc import AsyncIterator
from dataclasses import dataclass, field
from pathlib import Path

import pytest
import pytest_asyncio

from coffeebot.config import load_robot_config
from coffeebot.fleet.camera_service import CameraServiceModule
from coffeebot.fleet.mosquitto import mosquitto
from coffeebot.floorplan import load_floorplan
from coffeebot.messages import CAMERA_FIX, CAMERA_LAYER, CameraLayer
from coffeebot.modules.base import Module, ModuleContext
from coffeebot.runtime.fleet import FleetSim, build_fleet_sim, robot_ids, serve_fleet
from coffeebot.scenario.spec import Staff
from coffeebot.scenario.staff import StaffModule
from coffeebot.sim.simulation import Simulation
from coffeebot.store import NewOrder, OrderRules

ROOT = Path(__file__).resolve().parents[2]
PLAN = load_floorplan(ROOT / "floorplans" / "cs-building.toml")
BASE = load_robot_config(ROOT / "boards" / "coffeebot-v1.toml")
BOARD = BASE.model_copy(update={"cameras": BASE.cameras.model_copy(update={"enabled": True})})
RULES = OrderRules(rooms=set(PLAN.rooms), drinks=set(BOARD.web.drinks))
ROBOTS = 2
ROOMS = ("207", "206")
"""Offices beyond the north hall's camera (x 22.3-25.7 m), one per robot."""
PAST_LOBBY_X_MM = 39000.0
PAST_NORTH_HALL_X_MM = 22000.0
TIME_LIMIT_S = 240.0
WALL_LIMIT_S = 600.0
SPEED = 2.0
"""As test_fleet_sim.py's: the broker is outside the lockstep, so no faster than this."""
FIX_ERROR_MM = 100.0
ROBOT_CLEAR_MM = 500.0
"""No object on the layer this near a robot's true position: it would be the robot."""

pytestmark = pytest.mark.xdist_group("test_fleet_cameras")


@dataclass
class Fix:
    robot: str
    camera: str
    error_mm: float
    floor_right: bool


@dataclass
class CameraRun:
    fixes: list[Fix] = field(default_factory=list)
    robots_on_layer: list[str] = field(default_factory=list)
    """Objects of a layer a robot's board received that stood where a robot was."""
    layers: dict[str, CameraLayer | None] = field(default_factory=dict)
    """The latest layer on each robot's board at the end."""
    sent: dict[str, int] = field(default_factory=dict)
    """Fixes the service sent, by robot."""
    ended: str = ""


class CameraProbe(Module):
    """On a robot's board: every camera fix it gets, against where the simulator has the
    robot as the fix is published; every layer, against where all the robots are."""

    name = "probe"
    inputs = (CAMERA_FIX, CAMERA_LAYER)

    def __init__(self, robot: str, sims: dict[str, Simulation], run: CameraRun) -> None:
        self.robot, self.sims, self.seen = robot, sims, run

    async def run(self, ctx: ModuleContext) -> None:
        async def fixes() -> None:
            with ctx.board.subscribe(CAMERA_FIX) as subscription:
                async for envelope in subscription:
                    fix, sim = envelope.msg, self.sims[self.robot]
                    with sim.lock:
                        pose, level = sim.robot.pose, sim.robot.floor_level
                    error = math.hypot(fix.x_mm - pose.x_mm, fix.y_mm - pose.y_mm)
                    self.seen.fixes.append(
                        Fix(self.robot, fix.camera_id, error, fix.floor == level)
                    )

        async def layers() -> None:
            with ctx.board.subscribe(CAMERA_LAYER) as subscription:
                async for envelope in subscription:
                    for sim in self.sims.values():
                        with sim.lock:
                            pose, level = sim.robot.pose, sim.robot.floor_level
                        self.seen.robots_on_layer += [
                            f"{obj.id} at {sim.robot.name}"
                            for obj in envelope.msg.objects
                            if obj.floor == level
                            and math.hypot(obj.x_mm - pose.x_mm, obj.y_mm - pose.y_mm)
                            < ROBOT_CLEAR_MM
                        ]

        await asyncio.gather(fixes(), layers())


async def drive(fleet: FleetSim, run: CameraRun) -> None:
    orders, clock = fleet.dispatcher.module, fleet.dispatcher.board.clock
    for room in ROOMS:
        new = NewOrder.model_validate(
            {"room": room, "drink": BOARD.web.drinks[0], "name": "Ada"}, context=RULES
        )
        while True:
            with contextlib.suppress(Exception):
                await orders.place(new, "test")
                break
            await asyncio.sleep(0.05)  # the dispatcher is still starting
    started = time.monotonic()
    out: set[str] = set()
    passed: set[str] = set()
    while True:
        for sim in fleet.sims:
            with sim.lock:
                x_mm = sim.robot.pose.x_mm
            if x_mm < PAST_LOBBY_X_MM:
                out.add(sim.robot.name)
            if x_mm < PAST_NORTH_HALL_X_MM:
                passed.add(sim.robot.name)
        if len(out) == ROBOTS and passed:
            run.ended = "all out past the lobby, one past the north hall"
            break
        if clock.now() > TIME_LIMIT_S or time.monotonic() - started > WALL_LIMIT_S:
            run.ended = f"time limit at {clock.now():.0f} s: out {sorted(out)}, {sorted(passed)}"
            break
        await clock.sleep(0.5)
    for name, runtime in zip(robot_ids(ROBOTS), fleet.robots, strict=True):
        latest = runtime.board.latest(CAMERA_LAYER)
        run.layers[name] = None if latest is None else latest.msg
    service = fleet.dispatcher.daemon.states["cameras"].module
    assert isinstance(service, CameraServiceModule)
    run.sent = dict(service.fixes)


@pytest_asyncio.fixture(scope="module", loop_scope="module")
async def camera_run() -> AsyncIterator[CameraRun]:
    run = CameraRun()
    sims: dict[str, Simulation] = {}
    staff = StaffModule(Staff(load_after_s=3.0, pickup_after_s=5.0))
    with mosquitto(robot_ids(ROBOTS)) as broker:
        async with build_fleet_sim(
            BOARD,
            PLAN,
            ROBOTS,
            broker.address,
            broker.credentials,
            speed=SPEED,
            web=False,
            dispatcher_extra=[staff],
            robot_extra=lambda name: [CameraProbe(name, sims, run)],
        ) as fleet:
            sims.update({sim.robot.name: sim for sim in fleet.sims})
            serving = asyncio.create_task(serve_fleet(fleet))
            try:
                await drive(fleet, run)
                yield run
            finally:
                fleet.request_stop("test over")
                await asyncio.wait_for(serving, 60)


@pytest.mark.slow
@pytest.mark.asyncio(loop_scope="module")
async def test_every_fix_a_robot_gets_is_its_own_pose(camera_run: CameraRun) -> None:
    assert camera_run.ended == "all out past the lobby, one past the north hall"
    assert camera_run.fixes, f"no robot got a fix; the service sent {camera_run.sent}"
    wrong = [f for f in camera_run.fixes if f.error_mm > FIX_ERROR_MM or not f.floor_right]
    assert wrong == [], wrong
    fixed = {f.robot for f in camera_run.fixes}
    assert fixed == set(robot_ids(ROBOTS)), f"the service sent {camera_run.sent}"
    assert {f.camera for f in camera_run.fixes} == {"tea-room", "lobby-2", "north-hall-2"}


@pytest.mark.slow
@pytest.mark.asyncio(loop_scope="module")
async def test_the_camera_layer_reaches_every_robots_board_without_the_robots(
    camera_run: CameraRun,
) -> None:
    cameras = sorted(camera.id for floor in PLAN.floors for camera in floor.cameras)
    for robot, layer in camera_run.layers.items():
        assert layer is not None, f"{robot} has no camera layer"
        assert sorted(view.camera_id for view in layer.cameras) == cameras
        assert all(view.working for view in layer.cameras)
    assert camera_run.robots_on_layer == []
