"""A simulated run depends on its seed alone, not on how busy the machine is.

The whole daemon (drivers over the simulated buses, perception, state, navigation, motion,
orders) runs the first seconds of a delivery round a box, once on its own and once beside
two processes that keep both of the machine's cores busy. The robot's true pose, the motor
commands and the collision verdicts, sampled every 100 ms of simulated time, must be the
same to the last bit: the world steps only when the daemon has settled
(``coffeebot.lockstep``), so the daemon's computing takes no simulated time however long
the machine makes it take.
"""

from __future__ import annotations

import contextlib
import itertools
import subprocess
import sys
from collections.abc import Iterator
from pathlib import Path

from coffeebot.config import load_robot_config
from coffeebot.messages import COLLISION, MOTOR_COMMAND
from coffeebot.modules.base import Module, ModuleContext
from coffeebot.runtime.assemble import Runtime
from coffeebot.runtime.service import serve
from coffeebot.runtime.sim import build_sim
from coffeebot.scenario.driver import ScenarioModule
from coffeebot.scenario.spec import load_scenario
from coffeebot.sim.simulation import Simulation

ROOT = Path(__file__).resolve().parents[2]
CONFIG = load_robot_config(ROOT / "boards" / "coffeebot-v1.toml")
SCENARIO, PLAN = load_scenario(ROOT / "scenarios" / "floor2-box-in-lane.toml")
RUN_S = 14.0
"""Long enough to leave the tea room, drive down the hallway and meet the box."""

Sample = tuple[float, float, float, float, tuple[int, int] | None, str | None]


class Probe(Module):
    """Samples what the robot does every 100 ms of simulated time, then ends the run."""

    name = "probe"
    inputs = (MOTOR_COMMAND, COLLISION)

    def __init__(self, runtime: Runtime, sim: Simulation) -> None:
        self.runtime = runtime
        self.sim = sim
        self.samples: list[Sample] = []

    async def run(self, ctx: ModuleContext) -> None:
        while ctx.clock.now() < RUN_S:
            with self.sim.lock:
                pose = self.sim.robot.pose
            command = ctx.board.latest(MOTOR_COMMAND)
            verdict = ctx.board.latest(COLLISION)
            self.samples.append(
                (
                    ctx.clock.now(),
                    pose.x_mm,
                    pose.y_mm,
                    pose.heading_deg,
                    None if command is None else (command.msg.left_mm_s, command.msg.right_mm_s),
                    None if verdict is None else verdict.msg.state.value,
                )
            )
            await ctx.clock.sleep(0.1)
        self.runtime.request_stop("probe done")


async def run_once() -> list[Sample]:
    probes: list[Probe] = []

    def modules(runtime: Runtime, sim: Simulation) -> list[Module]:
        probes.append(Probe(runtime, sim))
        driver = ScenarioModule(
            SCENARIO, PLAN, runtime.config, sim, runtime.own_orders(), runtime.request_stop
        )
        return [driver, probes[0]]

    setup = SCENARIO.setup(speed=4.0)
    async with build_sim(CONFIG, PLAN, setup, modules, web=False) as (runtime, _):
        await serve(runtime)
    return probes[0].samples


@contextlib.contextmanager
def two_busy_processes() -> Iterator[None]:
    burners = [subprocess.Popen([sys.executable, "-c", "while True: pass"]) for _ in range(2)]
    try:
        yield
    finally:
        for burner in burners:
            burner.kill()
            burner.wait()


async def test_the_same_run_on_a_busy_machine_is_the_same_run() -> None:
    idle = await run_once()
    with two_busy_processes():
        busy = await run_once()
    moved = max(abs(a[1] - b[1]) for a, b in itertools.pairwise(idle))
    assert moved > 0, "the robot never moved: nothing was compared"
    assert len(idle) == len(busy)
    for before, after in zip(idle, busy, strict=True):
        assert before == after
