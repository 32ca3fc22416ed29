"""Temporary directories of simulated runs: one left by a killed run goes at the next start."""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

from coffeebot.sim.rundir import PREFIX, remove_abandoned, run_directory


def dead_pid() -> int:
    """The number of a process that has ended."""
    child = subprocess.Popen([sys.executable, "-c", "pass"])
    child.wait()
    return child.pid


def test_directories_of_dead_runs_are_removed_live_ones_kept(tmp_path: Path) -> None:
    killed = tmp_path / f"{PREFIX}{dead_pid()}-abc123"
    (killed / "motor").mkdir(parents=True)
    (killed / "orders.sqlite3").write_text("x")
    alive = tmp_path / f"{PREFIX}{os.getpid()}-def456"
    alive.mkdir()
    other = tmp_path / f"{PREFIX}notapid"
    other.mkdir()
    assert remove_abandoned(tmp_path) == [killed]
    assert not killed.exists() and alive.exists() and other.exists()


def test_a_run_directory_is_named_after_its_process() -> None:
    with run_directory() as name:
        assert Path(name).name.startswith(f"{PREFIX}{os.getpid()}-")
        assert Path(name).is_dir()
    assert not Path(name).exists()
