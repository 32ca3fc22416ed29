"""``coffeebot run`` on the robot loads nothing of the simulator or the scenario harness."""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
BOARD = ROOT / "boards" / "coffeebot-v1.toml"

ROBOT_RUN = """
import importlib.abc, json, sys

class NoSimulator(importlib.abc.MetaPathFinder):
    def find_spec(self, name, path=None, target=None):
        if name.split(".")[:2] in (["coffeebot", "sim"], ["coffeebot", "scenario"]):
            raise ImportError(f"the robot imported {name}")
        return None

sys.meta_path.insert(0, NoSimulator())
from coffeebot.cli import main

code = main(["run", "--board", sys.argv[1]])
loaded = sorted(m for m in sys.modules if m.startswith(("coffeebot.sim", "coffeebot.scenario")))
print(json.dumps({"code": code, "loaded": loaded}))
"""


def test_run_on_the_robot_imports_nothing_of_the_simulator(tmp_path: Path) -> None:
    """The whole ``run`` path up to the self-check (the I2C bus is missing here, so it stops
    there with its one-line error) with ``coffeebot.sim`` made unimportable."""
    board = tmp_path / "board.toml"
    text = BOARD.read_text().replace("bus = 1", "bus = 99")
    board.write_text(text.replace("/var/lib/coffeebot", str(tmp_path)))
    done = subprocess.run(
        [sys.executable, "-c", ROBOT_RUN, str(board)],
        capture_output=True,
        text=True,
        timeout=120,
        cwd=tmp_path,
    )
    assert "Traceback" not in done.stderr, done.stderr
    assert "/dev/i2c-99" in done.stderr
    result = json.loads(done.stdout.strip().splitlines()[-1])
    assert result == {"code": 1, "loaded": []}
