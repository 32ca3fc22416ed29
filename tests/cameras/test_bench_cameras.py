"""The camera benchmark's trial (bench/cameras.py) on one short trial: a robot standing in
the north hall camera's view drives off along the hallway while a person walks past the
other way; the camera must name it on its own track within the deadline, and place it."""

from __future__ import annotations

import importlib.util
import json
import sys
from pathlib import Path
from types import ModuleType

ROOT = Path(__file__).resolve().parents[2]


def load_bench() -> ModuleType:
    spec = importlib.util.spec_from_file_location("cameras_bench", ROOT / "bench" / "cameras.py")
    assert spec is not None and spec.loader is not None
    module = importlib.util.module_from_spec(spec)
    sys.modules[spec.name] = module  # dataclasses look their module up
    spec.loader.exec_module(module)
    return module


bench = load_bench()


def test_one_robot_among_one_person_is_named_on_its_own_track_and_placed() -> None:
    setup = bench.load_setup()
    camera, floor = setup.cameras["north-hall-2"]
    robot = bench.RobotPlan(
        name="robot1",
        kind="along",
        path=bench.Polyline([(23300.0, -300.0), (27000.0, -300.0)]),
        speed_mm_s=400.0,
        depart_s=1.0,
        entering=False,
        cup=True,
    )
    # On the other side of the hallway, coming the other way, through the view.
    person = bench.walker("person1", floor, [(27000.0, 500.0), (20000.0, 500.0)], 1200.0, 3.0)
    plan = bench.TrialPlan(
        index=0,
        group="single",
        camera=camera,
        floor=floor,
        placed_s=2.0,
        duration_s=5.0,
        robots=(robot,),
        people=(person,),
        parallel=frozenset(),
        seed=1,
    )

    result = bench.run_trial(plan, setup)

    assert result.frames == 50
    assert result.pipeline_s > 0.0
    assert result.contacts == 0
    (run,) = result.runs
    assert run.name == "robot1"
    assert not run.wrong
    assert run.moved_in_view_s is not None and 1.0 <= run.moved_in_view_s <= 1.3
    assert run.outcome == "correct"
    assert run.time_to_identify_s is not None and run.time_to_identify_s <= bench.DEADLINE_S
    assert run.errors_mm and max(run.errors_mm) < 50.0

    cart = bench.run_map_trial(0, setup, seed=3)
    assert cart.latency_s is not None and cart.false_objects == 0
    # Three seconds to be still, ten standing: then it is on the map.
    assert 13.0 <= cart.latency_s <= 15.0

    summary = bench.summarise([result], [cart])
    assert set(summary) == {
        "identification",
        "fix_error_mm",
        "gross_errors_over_300mm",
        "map_update_latency_s_p95",
        "map",
        "pipeline_fps",
        "camera_fps",
    }
    assert summary["identification"] == {
        "trials": 1,
        "correct": 1,
        "refused": 0,
        "wrong": 0,
        "time_to_identify_s_p95": round(run.time_to_identify_s, 2),
    }
    assert set(summary["fix_error_mm"]) == {"p50", "p95", "max"}
    assert summary["gross_errors_over_300mm"] == 0
    assert summary["map_update_latency_s_p95"] == round(cart.latency_s, 1)
    assert summary["map"] == {"trials": 1, "found": 1, "false_objects": 0}
    assert summary["pipeline_fps"] > 0.0
    assert summary["camera_fps"] == camera.fps
    json.dumps(summary)
