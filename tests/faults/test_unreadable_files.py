"""A board file or floor plan that is not text, or is a directory, and a render into a
directory that does not exist: one line naming the path, never a traceback."""

from __future__ import annotations

from pathlib import Path

import pytest

from coffeebot.cli import main
from coffeebot.config import load_robot_config
from coffeebot.errors import ConfigError
from coffeebot.floorplan import FloorPlanError, load_floorplan

ROOT = Path(__file__).resolve().parents[2]
BOARD = ROOT / "boards" / "coffeebot-v1.toml"
PLAN = ROOT / "floorplans" / "example.toml"


def latin1(tmp_path: Path, source: Path) -> Path:
    """The file with a Latin-1 comment, as an editor set to the wrong encoding saves it."""
    path = tmp_path / source.name
    path.write_bytes(b"# caf\xe9\n" + source.read_bytes())
    return path


def test_board_file_not_utf8(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    path = latin1(tmp_path, BOARD)
    with pytest.raises(ConfigError, match=r"not UTF-8 text \(byte 5 is 0xe9\)"):
        load_robot_config(path)
    assert main(["run", "--board", str(path)]) == 2
    [line] = capsys.readouterr().err.splitlines()
    assert line.startswith(f"coffeebot: configuration error: {path}: not UTF-8")


def test_board_file_is_a_directory(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    with pytest.raises(ConfigError, match="is a directory, not a file"):
        load_robot_config(tmp_path)
    assert main(["run", "--board", str(tmp_path)]) == 2
    [line] = capsys.readouterr().err.splitlines()
    assert line == f"coffeebot: configuration error: {tmp_path}: is a directory, not a file"


def test_floor_plan_not_utf8_or_a_directory(tmp_path: Path) -> None:
    path = latin1(tmp_path, PLAN)
    with pytest.raises(FloorPlanError) as error:
        load_floorplan(path)
    assert str(error.value) == f"{path}: file: not UTF-8 text (byte 5 is 0xe9)"
    with pytest.raises(FloorPlanError) as error:
        load_floorplan(tmp_path)
    assert str(error.value) == f"{tmp_path}: file: is a directory, not a file"


def test_render_into_a_missing_directory(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    out = tmp_path / "missing" / "plan.svg"
    assert main(["floorplan", "render", str(PLAN), "-o", str(out)]) == 1
    [line] = capsys.readouterr().err.splitlines()
    assert line == f"coffeebot: cannot write {out}: No such file or directory"
