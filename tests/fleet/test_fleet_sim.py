"""Two simulated robots, each its whole daemon, in one simulated building with the dispatcher,
over a real Mosquitto: they share the tea room's loading spot one at a time and both deliver,
one behind the other down the hallway, without touching.

One run (module fixture) as fast as the machine allows, on the simulated clock; what the
tests assert is ground truth the world recorded along the way. The orders: two at once, to
211 and 213, so both robots want the loading spot first thing.

Two robots meeting head-on in the hallway are ``tests/navigation/test_passing_in_world.py``'s;
the fleet at work, 1 to 4 robots for half an hour each, is ``bench/fleet.py``'s.
"""

from __future__ import annotations

import asyncio
import contextlib
import logging
import math
import time
from collections.abc import AsyncIterator
from dataclasses import dataclass, field
from pathlib import Path

import pytest
import pytest_asyncio

from coffeebot.config import load_robot_config
from coffeebot.fleet.mosquitto import mosquitto
from coffeebot.floorplan import load_floorplan
from coffeebot.logs import RobotTag
from coffeebot.messages import OrderStatus
from coffeebot.runtime.fleet import FleetSim, build_fleet_sim, robot_ids, serve_fleet
from coffeebot.scenario.spec import Staff
from coffeebot.scenario.staff import StaffModule
from coffeebot.sim.world.world import WorldRobot
from coffeebot.store import NewOrder, OrderRules

ROOT = Path(__file__).resolve().parents[2]
PLAN = load_floorplan(ROOT / "floorplans" / "cs-building.toml")
BOARD = load_robot_config(ROOT / "boards" / "coffeebot-v1.toml")
RULES = OrderRules(rooms=set(PLAN.rooms), drinks=set(BOARD.web.drinks))
TIME_LIMIT_S = 300.0
"""Simulated seconds the two deliveries may take."""
WALL_LIMIT_S = 900.0
"""The machine's seconds before the run is called stuck."""
SAMPLE_S = 0.1
ORDERS_AT_S = 10.0
"""When both orders are placed, in simulated time: the same moment in every run, once the
dispatcher has heard from both robots (1.5 s in). Placed as soon as the dispatcher took
orders, they arrived at a moment that depended on the machine's load, and with it which
robot took which order."""
SPEED = 2.0
"""The robots' daemons are in lockstep with the world, the broker between them is not: at
most this fast, so a message's time on the wire stays small in simulated time however busy
the machine is."""

pytestmark = pytest.mark.xdist_group("test_fleet_sim")
"""Its tests share one fleet run: on one test worker, made once."""


@dataclass
class Sample:
    t_s: float
    poses: list[tuple[float, float, float, int]]
    """(x, y, heading in degrees, floor) per robot."""


@dataclass
class FleetRun:
    orders: dict[str, OrderStatus] = field(default_factory=dict)
    samples: list[Sample] = field(default_factory=list)
    contacts: list[str] = field(default_factory=list)
    ended: str = ""
    motion_log: list[logging.LogRecord] = field(default_factory=list)
    """The robots' motion lines (state changes), as a handler tagging them sees them."""
    stamps: list[tuple[float, float]] = field(default_factory=list)
    """(simulated time, the order store's clock) when the orders were placed and at the end."""


class Kept(logging.Handler):
    """Keeps the records it handles (after its filters)."""

    def __init__(self, into: list[logging.LogRecord]) -> None:
        super().__init__(logging.INFO)
        self.into = into

    def emit(self, record: logging.LogRecord) -> None:
        self.into.append(record)


def pose_of(robot: WorldRobot) -> tuple[float, float, float, int]:
    pose = robot.pose
    return (pose.x_mm, pose.y_mm, pose.heading_deg, robot.floor_level)


async def drive(fleet: FleetSim, staff: StaffModule, run: FleetRun) -> FleetRun:
    orders = fleet.dispatcher.module
    shared = fleet.world

    clock = fleet.dispatcher.board.clock

    async def place(room: str) -> None:
        new = NewOrder.model_validate(
            {"room": room, "drink": BOARD.web.drinks[0], "name": "Ada"}, context=RULES
        )
        placed = await orders.place(new, "test")
        run.orders[placed.id] = placed.status

    def both_robots_heard() -> bool:
        return orders.dispatcher is not None and len(orders.dispatcher.free_robots()) == 2

    while not both_robots_heard():
        assert clock.now() < ORDERS_AT_S, "the dispatcher has not heard from both robots"
        await clock.sleep(SAMPLE_S)
    await clock.sleep(ORDERS_AT_S - clock.now())
    run.stamps.append((clock.now(), fleet.dispatcher.store.now()))
    await place("211")
    await place("213")
    started = time.monotonic()
    while True:
        with shared.lock:
            run.samples.append(Sample(clock.now(), [pose_of(sim.robot) for sim in fleet.sims]))
        for order_id in run.orders:
            times = staff.orders.get(order_id)
            if times is not None:
                run.orders[order_id] = times.status
        if all(s.final for s in run.orders.values()):
            run.ended = "every order ended"
            break
        if clock.now() > TIME_LIMIT_S or time.monotonic() - started > WALL_LIMIT_S:
            run.ended = f"time limit at {clock.now():.0f} s"
            break
        await clock.sleep(SAMPLE_S)
    run.stamps.append((clock.now(), fleet.dispatcher.store.now()))
    for sim in fleet.sims:
        run.contacts += [f"{sim.robot.name}: {c}" for c in sim.robot.collisions]
    return run


@pytest_asyncio.fixture(scope="module", loop_scope="module")
async def fleet_run() -> AsyncIterator[FleetRun]:
    names = robot_ids(2)
    staff = StaffModule(Staff(load_after_s=3.0, pickup_after_s=5.0))
    run = FleetRun()
    kept = Kept(run.motion_log)
    kept.addFilter(RobotTag())
    motion = logging.getLogger("coffeebot.module.motion")
    level = motion.level
    motion.addHandler(kept)
    motion.setLevel(logging.INFO)
    with contextlib.ExitStack() as restore, mosquitto(names) as broker:
        restore.callback(motion.setLevel, level)
        restore.callback(motion.removeHandler, kept)
        async with build_fleet_sim(
            BOARD,
            PLAN,
            2,
            broker.address,
            broker.credentials,
            speed=SPEED,
            web=False,
            dispatcher_extra=[staff],
        ) as fleet:
            serving = asyncio.create_task(serve_fleet(fleet))
            try:
                yield await drive(fleet, staff, run)
            finally:
                fleet.request_stop("test over")
                await asyncio.wait_for(serving, 60)


@pytest.mark.asyncio(loop_scope="module")
async def test_every_order_is_delivered_without_a_contact(fleet_run: FleetRun) -> None:
    assert fleet_run.ended == "every order ended"
    assert list(fleet_run.orders.values()) == [OrderStatus.DELIVERED] * 2
    assert fleet_run.contacts == []


@pytest.mark.asyncio(loop_scope="module")
async def test_the_loading_spot_holds_one_robot_at_a_time(fleet_run: FleetRun) -> None:
    base = PLAN.tea_room
    spot = base.floor.behind_door(base.door, base.door.recess_mm + BOARD.navigation.base_depth_mm)
    near = BOARD.geometry.width_mm / 2

    def at_spot(pose: tuple[float, float, float, int]) -> bool:
        return math.dist(pose[:2], spot) < near

    visits = [sum(at_spot(p) for p in s.poses) for s in fleet_run.samples]
    assert max(visits) == 1, "both robots stood on the loading spot at once"
    loaded_by = {i for s in fleet_run.samples for i, p in enumerate(s.poses) if at_spot(p)}
    assert loaded_by == {0, 1}, "one of the robots never loaded"


@pytest.mark.asyncio(loop_scope="module")
async def test_orders_are_stamped_in_simulated_time(fleet_run: FleetRun) -> None:
    """How long an order has waited is what joint assignment weighs: in a simulated fleet
    it is simulated time, not the machine's, whose pace follows the machine's load."""
    (sim_0, store_0), (sim_1, store_1) = fleet_run.stamps
    assert sim_1 - sim_0 > 10.0
    assert store_1 - store_0 == pytest.approx(sim_1 - sim_0, abs=1e-6)


@pytest.mark.asyncio(loop_scope="module")
async def test_each_robots_log_lines_name_it(fleet_run: FleetRun) -> None:
    """Both daemons log through the same loggers in one process: each line says whose it
    is, or a run's log cannot be read back."""
    by_robot = {getattr(r, "robot", None) for r in fleet_run.motion_log}
    assert by_robot == set(robot_ids(2))
