"""`coffeebot check-hardware --sim`, clean and with injected faults."""

from __future__ import annotations

import asyncio
import errno
import json
import subprocess
import sys
from pathlib import Path

import pytest

from coffeebot.cli import DEFAULT_BOARD, format_table, main
from coffeebot.config import load_robot_config
from coffeebot.hardware.i2c import I2CBus, kernel_bus_hz
from coffeebot.hardware.selfcheck import SelfCheckFailed, check_bus_speed, service_check


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


def run_cli(*args: str) -> subprocess.CompletedProcess[str]:
    return subprocess.run(
        [sys.executable, "-m", "coffeebot.cli", *args],
        capture_output=True,
        text=True,
        timeout=60,
        check=False,
    )


def missing_devices_board(tmp_path: Path) -> Path:
    """The robot description with a bus and ports this machine does not have (as a Pi
    without I2C enabled and nothing plugged in)."""
    text = DEFAULT_BOARD.read_text()
    text = text.replace("bus = 1\n", "bus = 97\n", 1)
    text = text.replace('"/dev/serial0"', '"/dev/serial97"').replace(
        '"/dev/ttyACM0"', '"/dev/ttyACM97"'
    )
    board = tmp_path / "robot.toml"
    board.write_text(text)
    return board


def test_a_missing_bus_and_ports_are_fail_rows_that_say_what_to_check(tmp_path: Path) -> None:
    board = missing_devices_board(tmp_path)
    done = run_cli("check-hardware", "--board", str(board))
    assert done.returncode == 1, done.stderr
    assert "Traceback" not in done.stdout + done.stderr
    rows = {line.split("  ")[0]: line for line in done.stdout.splitlines()}
    bus = rows["I2C bus"]
    assert "FAIL" in bus and "/dev/i2c-97 does not exist" in bus
    assert "I2C is enabled" in bus and "permissions" in bus and "i2c group" in bus
    assert "FAIL" in rows["TCA9548A mux"] and "not probed" in rows["TCA9548A mux"]
    assert all("FAIL" in rows[f"VL53L1X tof{i}"] for i in range(8))
    uwb = rows["DWM1001 UWB tag"]
    assert "/dev/serial97 does not exist" in uwb and "dialout group" in uwb
    assert "serial console off" in uwb  # the Pi's own UART
    motor = rows["motor controller"]
    assert "/dev/ttyACM97 does not exist" in motor and "serial console" not in motor
    assert done.stdout.rstrip().splitlines()[-1].startswith("FAILED")


def test_a_missing_bus_in_json_too(tmp_path: Path) -> None:
    done = run_cli("check-hardware", "--board", str(missing_devices_board(tmp_path)), "--json")
    assert done.returncode == 1 and "Traceback" not in done.stderr
    report = json.loads(done.stdout)
    failed = {r["component"]: r["detail"] for r in report["results"] if not r["ok"]}
    assert not report["ok"] and len(failed) == 12
    assert failed["I2C bus"].startswith("/dev/i2c-97 does not exist")


def test_the_self_check_names_a_missing_bus() -> None:
    config = load_robot_config(DEFAULT_BOARD)

    def no_bus() -> I2CBus:
        raise FileNotFoundError(errno.ENOENT, "No such file or directory", "/dev/i2c-1")

    with pytest.raises(SelfCheckFailed, match=r"I2C bus \(i2c-1\): /dev/i2c-1 does not exist"):
        asyncio.run(service_check(config, no_bus)())


def test_an_unknown_fault_from_the_command_line_is_a_usage_error() -> None:
    done = run_cli("check-hardware", "--sim", "--fault", "bogus")
    assert done.returncode == 2
    assert (
        done.stderr.strip().splitlines() == [done.stderr.strip()]
        and "unknown fault 'bogus'" in done.stderr
    )
    assert "Traceback" not in done.stderr
