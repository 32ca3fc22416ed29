"""The survey check: a recorded pass finds a door recess that a copy of the plan moved.

The pass is made offline and fast: the simulated world driven on ground truth past door 206
on floor 2, the particle filter localizing on the true plan, and the scans and poses written
to an MCAP recording through a board, as ``--record`` writes them.
"""

from __future__ import annotations

import asyncio
from pathlib import Path

import pytest

from coffeebot.board import Board
from coffeebot.board.recording import Recorder
from coffeebot.cli import main
from coffeebot.config import load_robot_config
from coffeebot.floorplan import FloorPlan, load_floorplan
from coffeebot.messages import (
    ALL_TOPICS,
    CURRENT_STATE,
    RANGE_SCAN,
    Odometry,
    RangeScan,
)
from coffeebot.perception.state import StateEstimator, make_fusion
from coffeebot.sim.world import RobotSpec, World
from coffeebot.sim.world.tof import as_range_reading, robot_setup
from coffeebot.sim.world.trace import hallway_pose, lane_wheel_speeds
from coffeebot.survey import check_recording
from manual_clock import ManualClock

ROOT = Path(__file__).resolve().parents[2]
CONFIG = load_robot_config(ROOT / "boards" / "coffeebot-v1.toml")
CONFIG = CONFIG.model_copy(
    update={"state": CONFIG.state.model_copy(update={"fusion": "particles"})}
)
PLAN_FILE = ROOT / "floorplans" / "cs-building.toml"
PLAN = load_floorplan(PLAN_FILE)
SETUP = robot_setup(CONFIG.tof)
"""The chips set up as the ToF poller sets them up."""

pytestmark = pytest.mark.xdist_group("test_survey_check")
"""Its tests share one recorded pass: on one test worker, made once."""


async def record_pass(path: Path) -> None:
    """Floor 2 from 15.5 to 20.5 m keeping right: door 206 (right, 18 m) 300 mm away."""
    floor = PLAN.floor(2)
    start = hallway_pose(floor, 15500, -295)
    world = World(PLAN, RobotSpec.from_config(CONFIG), floor=2, pose=start, seed=31)
    state = StateEstimator(PLAN, CONFIG.motor, CONFIG.state, make_fusion(CONFIG, PLAN))
    state.place(start.x_mm, start.y_mm, start.heading_deg, 2)
    clock = ManualClock(start=0.0)
    board = Board(ALL_TOPICS, clock=clock)
    async with Recorder(board, path):
        tick = 0
        while floor.to_hallway(world.robot.pose.x_mm, world.robot.pose.y_mm)[0] < 20500:
            tick += 1
            now = world.t_s
            left, right = world.robot.encoder_ticks
            odo = Odometry(
                controller_time_ms=round(now * 1000),
                left_ticks=left,
                right_ticks=right,
                gyro_z_dps=world.robot.gyro_z_dps(),
                left_mm_s=0.0,
                right_mm_s=0.0,
            )
            state.on_odometry(odo, now)
            if tick % 5 == 0:
                fix = world.robot.uwb_fix()
                if fix is not None:
                    state.on_uwb(fix, now)
                readings = [as_range_reading(i, r) for i, r in enumerate(world.robot.scan(SETUP))]
                scan = RangeScan(cycle_start_s=now, cycle_time_s=0.1, readings=readings)
                state.on_scan(scan, now)
                board.publish(CURRENT_STATE, state.current(now))
                board.publish(RANGE_SCAN, scan)
                await asyncio.sleep(0)  # let the recorder take both
            moving = world.t_s > 1.0  # the gyro calibrates at rest first
            speeds = lane_wheel_speeds(world, 400.0, -295) if moving else (0.0, 0.0)
            world.robot.command_wheels(*speeds)
            world.step(0.02)
            await clock.advance(0.02)


@pytest.fixture(scope="module")
def recording(tmp_path_factory: pytest.TempPathFactory) -> Path:
    path = tmp_path_factory.mktemp("survey") / "pass.mcap"
    asyncio.run(record_pass(path))
    return path


def moved_door(recess_mm: float) -> FloorPlan:
    """A copy of the plan whose door 206 is recessed ``recess_mm`` instead of 100 mm."""
    data = PLAN.model_dump()
    for door in data["floors"][0]["doors"]:
        if door["id"] == "206":
            door["recess_mm"] = recess_mm
    return FloorPlan.model_validate(data)


def test_the_true_plan_agrees_with_the_pass(recording: Path) -> None:
    check = check_recording(recording, PLAN, CONFIG.tof.sensors)
    assert len(check.observations) > 300
    assert check.disagreements(50.0) == []


def test_a_moved_door_recess_is_found_with_where_and_how_much(recording: Path) -> None:
    check = check_recording(recording, moved_door(200.0), CONFIG.tof.sensors)
    (found,) = check.disagreements(50.0)
    assert found.floor == 2 and found.element == "door 206"
    # The real leaf is 100 mm in front of where the copy puts it.
    assert found.offset_mm == pytest.approx(-100.0, abs=20.0)
    x0, x1 = sorted((found.from_xy_mm[0], found.to_xy_mm[0]))
    assert x0 >= 17550 - 1 and x1 <= 18450 + 1
    # On the leaf of the copy: 850 mm (half the hallway) plus its 200 mm recess, right side.
    assert found.from_xy_mm[1] == pytest.approx(-1050.0, abs=1.0)


def test_the_command_lists_it_and_fails(
    recording: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    plan_file = tmp_path / "moved.toml"
    plan_file.write_text(
        PLAN_FILE.read_text().replace(
            'room = "206"\nside = "right"\nat_mm = 18000\nwidth_mm = 900\nrecess_mm = 100',
            'room = "206"\nside = "right"\nat_mm = 18000\nwidth_mm = 900\nrecess_mm = 200',
        )
    )
    args = ["floorplan", "check", "--recording", str(recording), "--floorplan"]
    assert main([*args, str(plan_file)]) == 1
    out = capsys.readouterr().out
    assert "door 206" in out and "nearer than planned" in out
    assert main([*args, str(PLAN_FILE)]) == 0


def test_a_missing_recording_is_one_line(tmp_path: Path, capsys: pytest.CaptureFixture) -> None:
    code = main(["floorplan", "check", "--recording", str(tmp_path / "none.mcap")])
    assert code == 2
    err = capsys.readouterr().err.strip()
    assert err.startswith("coffeebot: ") and "none.mcap" in err and "\n" not in err
