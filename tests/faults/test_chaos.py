"""The chaos bench's machinery (bench/faults.py): its verdicts on known records, and one real
run with a fault for good, judged as the bench judges it. Assertions are on what happened in
simulated time, never on how long it took."""

from __future__ import annotations

import importlib.util
import sys
from pathlib import Path
from types import ModuleType
from typing import Any

import pytest

from coffeebot.scenario.report import FinalPose, OrderOutcome, ScenarioReport

ROOT = Path(__file__).resolve().parents[2]


def load_bench() -> ModuleType:
    spec = importlib.util.spec_from_file_location("chaos_bench", ROOT / "bench" / "faults.py")
    assert spec is not None and spec.loader is not None
    module = importlib.util.module_from_spec(spec)
    sys.modules[spec.name] = module  # dataclasses look their module up
    spec.loader.exec_module(module)
    return module


chaos = load_bench()


def report(status: str, detail: str = "", stop_error_mm: float | None = 40.0) -> ScenarioReport:
    return ScenarioReport(
        scenario="known",
        seed=1,
        sim_time_s=60.0,
        ended="every order ended",
        orders=[
            OrderOutcome(
                id="o1",
                room="213",
                status=status,
                detail=detail,
                placed_at_s=2.0,
                arrived_at_s=None if stop_error_mm is None else 20.0,
                delivered_at_s=None,
                stop_error_mm=stop_error_mm,
            )
        ],
        collisions=[],
        travelled_mm=3000,
        moving_s=10.0,
        min_clearance_mm=300,
        safety_stops=0,
        safety_stop_log=[],
        faults_injected=[],
        final_pose=FinalPose(floor=2, x_mm=39000, y_mm=0, heading_deg=0.0),
    )


STILL = chaos.EndState(t_s=60.0, speed_mm_s=0.0, floor=2)
MOVING = chaos.EndState(t_s=60.0, speed_mm_s=300.0, floor=2)
BLOCKED = "blocked for 45 s: collision stop: sensor 5 unhealthy"


@pytest.mark.parametrize(
    ("kinds", "status", "detail", "stop_error", "stored", "end", "lost", "false", "safe"),
    [
        # Delivered at the door, as stored: nothing to say.
        (("store_full",), "delivered", "picked up", 40.0, "delivered", STILL, "", "", True),
        # "delivered" with the robot never at the door is a false status.
        ((), "delivered", "picked up", None, "delivered", STILL, "", "delivered with", True),
        # A failure whose reason names the sensor fault is true; the same under a motor fault
        # is not, nor any failure without a fault.
        (("sensor_nack",), "failed", BLOCKED, None, "failed", STILL, "", "", True),
        (("motor_silent",), "failed", BLOCKED, None, "failed", STILL, "", "names none", True),
        ((), "failed", BLOCKED, None, "failed", STILL, "", "without a fault", True),
        # The database behind what the customer was told: an update lost; gone: lost.
        (("store_locked",), "delivered", "x", 40.0, "arrived", STILL, "announced", "", True),
        (("store_locked",), "delivered", "x", 40.0, None, STILL, "not in the database", "", True),
        # The database ahead of the customer's page: the page shows a false status.
        (("store_locked",), "arrived", "x", 40.0, "delivered", STILL, "", "database says", True),
        # Still "on the way" at the end: true while the robot drives, lost once it rests.
        (("uwb_unplug",), "on_the_way", "x", None, "on_the_way", MOVING, "", "", False),
        (("module_crash",), "on_the_way", "x", None, "on_the_way", STILL, "still", "", True),
    ],
)
def test_verdicts_on_known_records(
    kinds: tuple[str, ...],
    status: str,
    detail: str,
    stop_error: float | None,
    stored: str | None,
    end: Any,
    lost: str,
    false: str,
    safe: bool,
) -> None:
    rows = {} if stored is None else {"o1": {"status": stored, "detail": detail}}
    verdict = chaos.judge(kinds, report(status, detail, stop_error), rows, end)
    [order] = verdict["orders"]
    assert (order["lost"] == "") is (lost == "") and lost in order["lost"]
    assert (order["false"] == "") is (false == "") and false in order["false"]
    assert verdict["ended_safe"] is safe


def test_every_kind_is_dealt_and_drawn_from_the_seed() -> None:
    plans = chaos.plan_runs(26, seed=3)
    dealt = [k for p in plans for k in p.kinds]
    assert set(dealt) == set(chaos.KINDS)
    assert sum(not p.kinds for p in plans) == 2  # the baseline, once per round
    assert all(p.upstairs for p in plans if "elevator_silent" in p.kinds)
    assert plans == chaos.plan_runs(26, seed=3)
    # Each fault is a valid scenario fault, starting after the order is placed.
    for plan in plans:
        scenario = chaos.scenario_of(plan)
        assert [f.kind for f in scenario.faults] == list(plan.kinds)
        assert all(f.from_s > chaos.ORDER_AT_S for f in scenario.faults)


@pytest.mark.slow
async def test_a_silent_motor_controller_for_good_ends_safe_with_the_true_reason() -> None:
    plan = chaos.RunPlan(
        index=0,
        room="213",
        seed=5,
        kinds=("motor_silent",),
        faults=({"kind": "motor_silent", "from_s": 9.0},),  # on the way, never back
    )
    row = await chaos.run_one(plan, speed=float("inf"))
    [order] = row["orders"]
    assert order["status"] == "failed"
    assert "motor controller" in order["detail"]
    assert order["lost"] == order["false"] == ""
    assert row["ended_safe"] and row["end"]["speed_mm_s"] < chaos.STILL_MM_S
    assert row["contacts"] == []
    # What the operator read: the motor driver's fault, once.
    faults = [e for e in row["events"] if e["event"] == "fault"]
    assert [e["logger"] for e in faults] == ["module.motor"]
    summary = chaos.summarize([row])
    assert summary["by_fault"]["motor_silent"]["ended_safe"] == 1
    assert summary["orders_lost"] == summary["orders_with_false_status"] == 0
