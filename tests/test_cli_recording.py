"""`coffeebot record --info` and `coffeebot replay` from the command line."""

from __future__ import annotations

import asyncio
import logging
from collections.abc import Iterator
from pathlib import Path

import pytest

from coffeebot.board.recording import recording_info
from coffeebot.cli import main
from traffic import make_recording


@pytest.fixture(autouse=True)
def restore_logging() -> Iterator[None]:
    """main() configures the root logger for the process; put it back for the next test."""
    root = logging.getLogger()
    handlers, level = root.handlers[:], root.level
    yield
    root.handlers[:] = handlers
    root.setLevel(level)


@pytest.fixture
def recording(tmp_path: Path) -> Path:
    path = tmp_path / "hallway.mcap"
    asyncio.run(make_recording(path))
    return path


def test_record_info_prints_topics_counts_and_duration(
    recording: Path, capsys: pytest.CaptureFixture[str]
):
    assert main(["record", "--info", str(recording)]) == 0
    out = capsys.readouterr().out
    rows = {line.split()[0]: line.split()[1:] for line in out.splitlines()}
    assert rows["messages"] == ["405"]
    assert rows["duration"][:2] == ["1.990", "s"]
    assert rows["robot"] == ["coffeebot-v1"]
    assert rows["tof/scan"] == ["100", "50.3", "coffeebot.messages.RangeScan"]


def test_record_info_on_a_missing_file_is_an_error(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
):
    assert main(["record", "--info", str(tmp_path / "none.mcap")]) == 1
    assert "none.mcap" in capsys.readouterr().err


def test_record_info_on_a_file_that_is_no_recording_is_one_line(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
):
    junk = tmp_path / "junk.mcap"
    junk.write_bytes(b"not a recording at all")
    assert main(["record", "--info", str(junk)]) == 1
    err = capsys.readouterr().err
    assert err.startswith(f"coffeebot: {junk}: not a readable MCAP file")
    assert len(err.strip().splitlines()) == 1


def test_replay_fast_and_record_the_replayed_board(recording: Path, tmp_path: Path):
    again = tmp_path / "again.mcap"
    assert main(["replay", str(recording), "--speed", "50", "--record", str(again)]) == 0
    original, replayed = recording_info(recording), recording_info(again)
    assert {t.name: t.messages for t in replayed.topics} == {
        t.name: t.messages for t in original.topics
    }
