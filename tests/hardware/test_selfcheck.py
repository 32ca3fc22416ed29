"""`coffeebot check-hardware --sim`, clean and with injected faults."""

from __future__ import annotations

import json

import pytest

from coffeebot.cli import DEFAULT_BOARD, main


def test_sim_check_passes(capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["check-hardware", "--sim", "--board", str(DEFAULT_BOARD)]) == 0
    out = capsys.readouterr().out
    assert "all parts ok" in out and "FAIL" not in out.replace("FAILED", "")


@pytest.mark.parametrize(
    ("fault", "part"),
    [
        ("tof3-nack", "VL53L1X tof3"),
        ("tof5-status", "VL53L1X tof5"),
        ("uwb-unplug", "DWM1001 UWB tag"),
        ("motor-unplug", "motor controller"),
    ],
)
def test_sim_check_names_the_faulty_part(
    fault: str, part: str, capsys: pytest.CaptureFixture[str], monkeypatch: pytest.MonkeyPatch
) -> None:
    monkeypatch.setenv("COFFEEBOT_SIM_FAULT", fault)
    assert main(["check-hardware", "--sim", "--json"]) == 1
    report = json.loads(capsys.readouterr().out)
    assert not report["ok"]
    assert [r["component"] for r in report["results"] if not r["ok"]] == [part]


def test_mux_fault_fails_the_mux(capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["check-hardware", "--sim", "--fault", "mux-nack"]) == 1
    assert "0x70 selecting no channel" in capsys.readouterr().out
