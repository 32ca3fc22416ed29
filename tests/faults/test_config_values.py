"""Impossible values in the board file, floor plans and scenarios are refused at start, one
line naming the file and the field: a NaN threshold makes every comparison false, so the check
built on it never fires."""

from __future__ import annotations

import re
from pathlib import Path

import pytest

from coffeebot.cli import main
from coffeebot.config import load_robot_config
from coffeebot.errors import ConfigError
from coffeebot.floorplan import FloorPlanError, load_floorplan
from coffeebot.scenario.spec import load_scenario

ROOT = Path(__file__).resolve().parents[2]
BOARD = ROOT / "boards" / "coffeebot-v1.toml"
EXAMPLE_PLAN = ROOT / "floorplans" / "example.toml"
CS_BUILDING = ROOT / "floorplans" / "cs-building.toml"


def board_with(tmp_path: Path, old: str, new: str) -> Path:
    text = BOARD.read_text()
    assert old in text
    path = tmp_path / "robot.toml"
    path.write_text(text.replace(old, new, 1))
    return path


def board_without_sensors(tmp_path: Path) -> Path:
    text = BOARD.read_text()
    text = re.sub(r"\[\[tof\.sensors\]\].*?(?=\[uwb\])", "", text, flags=re.S)
    path = tmp_path / "robot.toml"
    path.write_text(text.replace("[tof]\n", "[tof]\nsensors = []\n"))
    return path


@pytest.mark.parametrize(
    ("old", "new", "field", "problem"),
    [
        ("x_mm = 305.0", "x_mm = nan", "tof.sensors.2.x_mm", "finite number"),
        ("front_radius_mm = 200.0", "front_radius_mm = inf", "collision.front_radius_mm", "finite"),
        (
            "[collision]\n",
            "[collision]\nbraking_mm_s2 = inf\n",
            "collision.braking_mm_s2",
            "finite number",
        ),
        ("wheel_base_mm = 450.0", "wheel_base_mm = -nan", "motor.wheel_base_mm", "finite number"),
        ("[motor]\n", "[motor]\nmax_speed_mm_s = 30000\n", "motor.max_speed_mm_s", "less than"),
        ("x_mm = 305.0", "x_mm = 30500.0", "tof.sensors.2.x_mm", "less than or equal to 1000"),
        ("[web]\n", "[web]\ndrinks = []\n", "web.drinks", "at least 1 item"),
        ("[web]\n", '[web]\ndrinks = ["tea", "tea"]\n', "web", "drinks listed twice"),
    ],
)
def test_impossible_board_values_are_refused(
    tmp_path: Path, old: str, new: str, field: str, problem: str
) -> None:
    path = board_with(tmp_path, old, new)
    with pytest.raises(ConfigError) as error:
        load_robot_config(path)
    assert f"{path}: {field}: " in str(error.value)
    assert problem in str(error.value)


def test_a_robot_without_a_front_sensor_is_refused(tmp_path: Path) -> None:
    path = tmp_path / "robot.toml"
    path.write_text(BOARD.read_text().replace('face = "front"', 'face = "rear"'))
    with pytest.raises(ConfigError, match=rf"{re.escape(str(path))}: tof: .*no sensor faces front"):
        load_robot_config(path)


def test_empty_sensor_list_is_refused_by_check_hardware(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    path = board_without_sensors(tmp_path)
    assert main(["check-hardware", "--board", str(path)]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1, err
    assert f"{path}: tof.sensors: " in err and "at least 1 item" in err
    assert "all parts ok" not in err


def test_every_problem_is_one_line_naming_the_file(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    path = board_with(tmp_path, "x_mm = 305.0", "x_mm = nan")
    path.write_text(path.read_text().replace("front_radius_mm = 200.0", "front_radius_mm = inf"))
    assert main(["run", "--board", str(path)]) == 2
    lines = capsys.readouterr().err.splitlines()
    assert len(lines) == 2
    assert all(line.startswith(f"coffeebot: configuration error: {path}: ") for line in lines)


def plan_with(tmp_path: Path, old: str, new: str, source: Path = EXAMPLE_PLAN) -> Path:
    text = source.read_text()
    assert old in text
    path = tmp_path / "plan.toml"
    path.write_text(text.replace(old, new, 1))
    return path


@pytest.mark.parametrize(
    ("old", "new", "element", "field"),
    [
        ("at_mm = 2500", "at_mm = nan", "floor 1 / door 101", "at_mm"),
        ("end = [12000, 0]", "end = [inf, 0]", "floor 1 / hallway main", "end.0"),
        ("width_mm = 1600", "width_mm = inf", "floor 1 / hallway main", "width_mm"),
        ("start = [0, 0]", "start = [0, 2e9]", "floor 1 / hallway main", "start.1"),
    ],
)
def test_impossible_floor_plan_values_are_refused(
    tmp_path: Path, old: str, new: str, element: str, field: str
) -> None:
    path = plan_with(tmp_path, old, new)
    with pytest.raises(FloorPlanError) as error:
        load_floorplan(path)
    assert error.value.element == element
    assert str(error.value).startswith(f"{path}: {element}: {field}:")
    assert "\n" not in str(error.value)


SCENARIO = f"""
name = "values"
floorplan = "{CS_BUILDING}"
time_limit_s = 3

[start]
floor = 2
x_mm = 41500
y_mm = 295

[[orders]]
room = "205"
at_s = 0.5
"""


@pytest.mark.parametrize(
    ("old", "new", "field"),
    [
        ("x_mm = 41500", "x_mm = nan", "start.x_mm"),
        ("at_s = 0.5", "at_s = inf", "orders.0.at_s"),
        ("time_limit_s = 3", "time_limit_s = inf", "time_limit_s"),
        (
            "at_s = 0.5",
            'at_s = 0.5\n[[faults]]\nkind = "motor_silent"\nfrom_s = 1\nto_s = nan',
            "faults.0.motor_silent.to_s",
        ),
    ],
)
def test_impossible_scenario_values_are_refused(
    tmp_path: Path, old: str, new: str, field: str
) -> None:
    path = tmp_path / "scenario.toml"
    path.write_text(SCENARIO.replace(old, new, 1))
    with pytest.raises(ConfigError) as error:
        load_scenario(path)
    assert f"{path}: {field}: " in str(error.value)
    assert "finite" in str(error.value)
