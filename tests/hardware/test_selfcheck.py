"""`coffeebot check-hardware --sim`, clean and with injected faults."""

from __future__ import annotations

import json
from pathlib import Path

import pytest

from coffeebot.cli import DEFAULT_BOARD, format_table, main
from coffeebot.config import load_robot_config
from coffeebot.hardware.i2c import kernel_bus_hz
from coffeebot.hardware.selfcheck import check_bus_speed


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


def test_an_unknown_fault_is_a_one_line_error(capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["check-hardware", "--sim", "--fault", "tof9-melt"]) == 2
    err = capsys.readouterr().err
    assert err.startswith("coffeebot: unknown fault 'tof9-melt'") and "Traceback" not in err


def fake_sysfs(root: Path, bus: int, hz: int) -> Path:
    node = root / "class" / "i2c-adapter" / f"i2c-{bus}" / "of_node"
    node.mkdir(parents=True)
    (node / "clock-frequency").write_bytes(hz.to_bytes(4, "big"))
    return root


def test_the_kernel_bus_clock_is_read_from_the_device_tree(tmp_path: Path) -> None:
    sys_root = fake_sysfs(tmp_path, 1, 100_000)
    assert kernel_bus_hz(1, sys_root) == 100_000
    assert kernel_bus_hz(3, sys_root) is None  # no such bus: the kernel does not say


def test_a_bus_slower_than_the_robot_needs_is_a_warning_not_a_failure() -> None:
    config = load_robot_config(DEFAULT_BOARD)
    assert config.i2c.frequency_hz == 400_000
    [slow] = check_bus_speed(config, 100_000)
    assert slow.ok and slow.warning and "below the 400 kHz" in slow.detail
    [fast] = check_bus_speed(config, 400_000)
    assert fast.ok and not fast.warning
    assert check_bus_speed(config, None) == []
    assert "WARN" in format_table([slow])
