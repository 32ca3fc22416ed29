"""Scenarios: the whole daemon on the simulated robot, headless, and the report it writes.

Runs use a sped-up clock; assertions are on what happened in simulated time, never on how
long it took.
"""

from __future__ import annotations

import json
import math
from pathlib import Path

import pytest

from coffeebot.cli import main
from coffeebot.config import load_robot_config
from coffeebot.errors import ConfigError
from coffeebot.scenario.report import FinalPose, ScenarioReport
from coffeebot.scenario.run import run_scenario
from coffeebot.scenario.spec import load_scenario

ROOT = Path(__file__).resolve().parents[2]
BOARD = ROOT / "boards" / "coffeebot-v1.toml"
PLAN = ROOT / "floorplans" / "cs-building.toml"
SPEED = math.inf
"""Flat out: the daemon runs in lockstep with the world, the same run at any speed."""

SHORT = f"""
name = "short"
floorplan = "{PLAN}"
seed = 7
time_limit_s = 3

[start]
floor = 2
x_mm = 41500
y_mm = 295
heading_deg = 180

[[orders]]
room = "205"
at_s = 0.5
name = "Ada"
"""


def write(tmp_path: Path, text: str) -> Path:
    path = tmp_path / "scenario.toml"
    path.write_text(text)
    return path


async def run(path: Path) -> ScenarioReport:
    scenario, plan = load_scenario(path)
    return await run_scenario(load_robot_config(BOARD), scenario, plan, speed=SPEED)


async def test_short_scenario_reports_an_undelivered_order(tmp_path: Path) -> None:
    report = await run(write(tmp_path, SHORT))
    assert report.scenario == "short"
    assert report.ended == "time limit"
    assert report.sim_time_s >= 3
    # Placed through the orders module and dispatched; within 3 s no cup is loaded, so it
    # never leaves.
    [order] = report.orders
    assert order.room == "205" and order.id
    assert order.status == "preparing"
    assert order.placed_at_s is not None and order.placed_at_s >= 0.5
    assert order.delivered_at_s is None and order.stop_error_mm is None
    # An order still open at the time limit says so, and what motion was doing.
    assert order.detail.startswith("not ended within the 3 s time limit: motion ")
    assert report.collisions == []
    # Standing still 295 mm left of the axis: 850 - 295 - 255 mm to the left wall.
    assert report.min_clearance_mm == 300
    assert report.faults_injected == []
    assert report.final_pose == FinalPose(floor=2, x_mm=41500, y_mm=295, heading_deg=180.0)
    # The report file's shape: the field names docs/scenarios.md shows.
    written = json.loads(report.model_dump_json())
    assert set(written) >= {"orders", "collisions", "safety_stop_log", "real_time_factor"}
    assert written["final_pose"] == {"floor": 2, "x_mm": 41500, "y_mm": 295, "heading_deg": 180.0}


async def test_sensor_nack_shows_as_a_safety_stop(tmp_path: Path) -> None:
    # The self-check takes about a second of simulated time, and the collision module starts
    # in "stop" and clears within about a second more (sensors initialised, every face seen
    # clear); the fault comes well after that.
    text = (
        SHORT.replace("time_limit_s = 3", "time_limit_s = 5")
        + """
[[faults]]
kind = "sensor_nack"
sensor = 3
from_s = 3
to_s = 4
"""
    )
    report = await run(write(tmp_path, text))
    [fault] = report.faults_injected
    assert fault.fault == "sensor_nack"
    assert fault.cleared_t is not None and 1 <= fault.t < fault.cleared_t
    assert report.safety_stops >= 1
    stop = report.safety_stop_log[0]
    assert stop.sensor == 3 and stop.t >= fault.t


@pytest.mark.parametrize(
    ("change", "message"),
    [
        (('room = "205"', 'room = "299"'), "orders.0.room: unknown room '299'"),
        (("floor = 2", "floor = 9"), "start.floor: no floor 9"),
        (("time_limit_s = 3", "time_limit_s = -1"), "time_limit_s: Input should be greater"),
        (
            ('name = "Ada"', 'name = "Ada"\n[[faults]]\nkind = "uwb_unplug"\nfrom_s = 2\nto_s = 1'),
            "faults.0.uwb_unplug: Value error, to_s (1.0) must be after from_s (2.0)",
        ),
    ],
)
def test_errors_name_the_field(tmp_path: Path, change: tuple[str, str], message: str) -> None:
    path = write(tmp_path, SHORT.replace(*change))
    with pytest.raises(ConfigError) as error:
        load_scenario(path)
    assert f"{path}: {message}" in str(error.value)


@pytest.mark.parametrize("path", sorted((ROOT / "scenarios").glob("*.toml")), ids=lambda p: p.stem)
def test_shipped_scenarios_load(path: Path) -> None:
    scenario, plan = load_scenario(path)
    assert scenario.orders and all(o.room in plan.rooms for o in scenario.orders)


def test_run_without_the_i2c_device_names_it(
    tmp_path: Path, capfd: pytest.CaptureFixture[str]
) -> None:
    board = tmp_path / "board.toml"
    text = BOARD.read_text().replace("bus = 1", "bus = 99")
    board.write_text(text.replace("/var/lib/coffeebot", str(tmp_path)))
    assert main(["run", "--board", str(board)]) == 1
    err = capfd.readouterr().err
    assert "/dev/i2c-99" in err and "Traceback" not in err
