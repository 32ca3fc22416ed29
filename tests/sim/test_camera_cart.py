"""A mail cart left across the hallway under a ceiling camera (scenario
``floor2-cart-seen-by-camera``), through the whole daemon with the cameras on: the robot
learns of it from the camera's map layer while the cart is still beyond its own sensors'
reach, holds short of it and says why, and goes on once the cart is wheeled away. On the way
the camera names the robot and its fixes reach the state estimate."""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from pathlib import Path

import pytest

from coffeebot.config import load_robot_config
from coffeebot.messages import (
    CAMERA_FIX,
    CAMERA_LAYER,
    CURRENT_STATE,
    DELIVERY_STATUS,
    DeliveryProblem,
)
from coffeebot.modules.base import Module, ModuleContext
from coffeebot.runtime.assemble import Runtime
from coffeebot.runtime.service import serve
from coffeebot.runtime.sim import build_sim
from coffeebot.scenario.driver import ScenarioModule
from coffeebot.scenario.spec import load_scenario
from coffeebot.sim.simulation import Simulation

ROOT = Path(__file__).resolve().parents[2]
SCENARIO, PLAN = load_scenario(ROOT / "scenarios" / "floor2-cart-seen-by-camera.toml")
CONFIG = SCENARIO.configure(load_robot_config(ROOT / "boards" / "coffeebot-v1.toml"))
(CART,) = SCENARIO.obstacles
CART_HALF_DEPTH_MM = 250.0
"""The cart stands across the hallway: 900 mm across it, 500 mm along it."""


@dataclass
class Seen:
    """What the probe saw, each with the simulator's truth at that moment."""

    holds: list[tuple[float, float, str]] = field(default_factory=list)
    """(time, gap from the robot's front to the cart's near face, what the customer is
    told) of each hold for a blocked hallway."""
    statuses: list[str] = field(default_factory=list)
    fix_errors_mm: list[float] = field(default_factory=list)
    sources: set[str] = field(default_factory=set)
    least_gap_mm: float = math.inf
    """While the cart stood: the robot's front to its near face."""


class Probe(Module):
    name = "probe"
    inputs = (DELIVERY_STATUS, CAMERA_FIX, CAMERA_LAYER, CURRENT_STATE)

    def __init__(self, sim: Simulation, seen: Seen) -> None:
        self.sim, self.seen = sim, seen

    def _gap(self) -> tuple[float, float]:
        with self.sim.lock:
            pose, t_s = self.sim.robot.pose, self.sim.t_s
        front = pose.x_mm - CONFIG.geometry.length_mm / 2
        return t_s, front - (CART.x_mm + CART_HALF_DEPTH_MM)

    async def run(self, ctx: ModuleContext) -> None:
        statuses = ctx.board.subscribe(DELIVERY_STATUS)
        fixes = ctx.board.subscribe(CAMERA_FIX)
        with statuses, fixes:
            while True:
                t_s, gap = self._gap()
                if CART.gone_s is not None and (CART.appear_s or 0.0) <= t_s < CART.gone_s:
                    self.seen.least_gap_mm = min(self.seen.least_gap_mm, gap)
                while (status := statuses.get_nowait()) is not None:
                    update = status.msg
                    self.seen.statuses.append(update.detail)
                    if update.problem is DeliveryProblem.BLOCKED:
                        self.seen.holds.append((t_s, gap, update.detail))
                while (fix := fixes.get_nowait()) is not None:
                    with self.sim.lock:
                        pose = self.sim.robot.pose
                    self.seen.fix_errors_mm.append(
                        math.hypot(fix.msg.x_mm - pose.x_mm, fix.msg.y_mm - pose.y_mm)
                    )
                state = ctx.board.latest(CURRENT_STATE)
                if state is not None:
                    self.seen.sources |= set(state.msg.sources)
                await ctx.clock.sleep(0.05)


@pytest.mark.slow
async def test_the_robot_holds_short_of_a_cart_only_a_camera_sees_and_goes_on_when_it_goes() -> (
    None
):
    seen = Seen()
    drivers: list[ScenarioModule] = []

    def modules(runtime: Runtime, sim: Simulation) -> list[Module]:
        drivers.append(
            ScenarioModule(
                SCENARIO, PLAN, runtime.config, sim, runtime.own_orders(), runtime.request_stop
            )
        )
        return [drivers[0], Probe(sim, seen)]

    async with build_sim(CONFIG, PLAN, SCENARIO.setup(speed=math.inf), modules, web=False) as (
        runtime,
        _,
    ):
        await serve(runtime)
    report = drivers[0].report()

    # It learned of the cart from the camera while the cart was beyond its sensors' reach.
    assert seen.holds, f"no hold for the cart: {seen.statuses}"
    first_hold_s, gap_at_hold, told = seen.holds[0]
    assert gap_at_hold > CONFIG.tof.max_range_mm, (first_hold_s, gap_at_hold)
    assert "blocking the hallway near room 208 (seen by a ceiling camera)" in told
    # It held well short of it, and never drove up to it.
    assert seen.least_gap_mm > 1000.0
    # Once the cart was gone it went on and delivered, touching nothing.
    assert any(s.startswith("on the way again") for s in seen.statuses)
    (order,) = report.orders
    assert order.status == "delivered", order.detail
    assert report.collisions == []
    # The camera named the robot on the way, and the state estimate took its fixes.
    assert seen.fix_errors_mm and max(seen.fix_errors_mm) < 100.0
    assert "camera" in seen.sources
