"""``coffeebot fleet`` refuses what it cannot run with one line naming the problem."""

from __future__ import annotations

import pytest

from coffeebot.cli import main


def refusals(capsys: pytest.CaptureFixture[str]) -> list[str]:
    """What the command said to its user (the log lines beside them start with ``ts=``)."""
    err = capsys.readouterr().err
    assert "Traceback" not in err
    return [line for line in err.splitlines() if line.startswith("coffeebot:")]


def test_the_dispatcher_without_a_broker_says_which_setting_is_missing(
    capsys: pytest.CaptureFixture[str],
) -> None:
    assert main(["fleet"]) == 2
    [line] = refusals(capsys)
    assert line.startswith("coffeebot: configuration error: ")
    assert "[fleet] broker" in line


def test_more_simulated_robots_than_parking_spots_is_one_line(
    capsys: pytest.CaptureFixture[str],
) -> None:
    assert main(["fleet", "--sim", "9"]) == 2
    [line] = refusals(capsys)
    assert "9 robots but 4 parking spots" in line
