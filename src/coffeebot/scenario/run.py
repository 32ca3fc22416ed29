"""Running a scenario through the whole daemon on the simulated robot."""

from __future__ import annotations

import time
from pathlib import Path

from coffeebot.config import RobotConfig
from coffeebot.floorplan import FloorPlan
from coffeebot.modules.base import Module
from coffeebot.runtime.assemble import Runtime
from coffeebot.runtime.service import serve
from coffeebot.runtime.sim import build_sim
from coffeebot.scenario.driver import ScenarioModule
from coffeebot.scenario.report import ScenarioReport
from coffeebot.scenario.spec import Scenario
from coffeebot.sim.simulation import Simulation


async def run_scenario(
    config: RobotConfig,
    scenario: Scenario,
    plan: FloorPlan,
    *,
    speed: float = 1.0,
    web: bool = False,
    record: Path | None = None,
    foxglove_port: int | None = None,
) -> ScenarioReport:
    """Run the whole daemon through ``scenario`` on the simulated robot; the report."""
    config = scenario.configure(config)
    driver: list[ScenarioModule] = []

    def add_driver(runtime: Runtime, sim: Simulation) -> list[Module]:
        driver.append(
            ScenarioModule(
                scenario, plan, runtime.config, sim, runtime.own_orders(), runtime.request_stop
            )
        )
        return [*driver]

    started = time.monotonic()
    async with build_sim(config, plan, scenario.setup(speed), add_driver, web=web) as (runtime, _):
        await serve(runtime, record, foxglove_port)
    report = driver[0].report()
    # What the machine kept up with: below the requested speed, the clock was paced down.
    factor = round(report.sim_time_s / (time.monotonic() - started), 2)
    return report.model_copy(update={"real_time_factor": factor})
