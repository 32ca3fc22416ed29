"""The systemd unit passes `systemd-analyze verify`; install-service puts it and /etc in place.

`systemd-analyze verify` checks that ExecStart= names an existing executable. The shipped unit
names /opt/coffeebot/.venv/bin/coffeebot, where the robot's installation lives, which does not
exist on a CI machine; so the tests verify the unit as install-service writes it, with
ExecStart= rewritten to this checkout's console script, exactly as on the robot.
"""

from __future__ import annotations

import stat
import subprocess
import sys
from pathlib import Path

import pytest

from coffeebot.cli import DEFAULT_BOARD, REPO_ROOT, main
from coffeebot.install import ENV_FILE, ROBOT_CONFIG, SYSUSERS_FILE, UNIT_DIR, UNIT_NAME

SHIPPED_UNIT = REPO_ROOT / "systemd" / UNIT_NAME
EXECUTABLE = Path(sys.executable).absolute().parent / "coffeebot"


def verify(unit: Path) -> subprocess.CompletedProcess[str]:
    return subprocess.run(
        ["systemd-analyze", "verify", str(unit)], capture_output=True, text=True, check=False
    )


@pytest.fixture
def installed(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> tuple[Path, str]:
    assert main(["install-service", "--root", str(tmp_path)]) == 0
    return tmp_path, capsys.readouterr().out


def test_the_unit_is_a_notify_service_with_watchdog_and_sandbox():
    lines = set(SHIPPED_UNIT.read_text().splitlines())
    for required in [
        "Type=notify",
        "WatchdogSec=5",
        "Restart=on-failure",
        "User=coffeebot",
        "SupplementaryGroups=i2c dialout",
        "ProtectSystem=strict",
        "ReadWritePaths=/var/lib/coffeebot",
        "NoNewPrivileges=yes",
        "EnvironmentFile=/etc/coffeebot/coffeebot.env",
    ]:
        assert required in lines


def test_installed_unit_passes_systemd_analyze_verify(installed: tuple[Path, str]):
    root, _ = installed
    unit = root / UNIT_DIR / UNIT_NAME
    assert f"ExecStart={EXECUTABLE} run --board /etc/coffeebot/robot.toml" in unit.read_text()
    result = verify(unit)
    assert (result.returncode, result.stdout + result.stderr) == (0, "")


def test_verify_would_catch_a_broken_unit(tmp_path: Path):
    """The check is real: systemd-analyze complains about what the test above must not have."""
    broken = tmp_path / UNIT_NAME
    text = SHIPPED_UNIT.read_text().replace("Restart=on-failure", "Restart=sometimes")
    broken.write_text(text.replace("/opt/coffeebot/.venv/bin/coffeebot", str(EXECUTABLE)))
    assert "sometimes" in verify(broken).stderr


def test_install_writes_config_secrets_and_user(installed: tuple[Path, str]):
    root, out = installed
    assert (root / ROBOT_CONFIG).read_text() == DEFAULT_BOARD.read_text()
    env = root / ENV_FILE
    assert stat.S_IMODE(env.stat().st_mode) == 0o600
    (token_line,) = [line for line in env.read_text().splitlines() if not line.startswith("#")]
    name, token = token_line.split("=", 1)
    assert name == "COFFEEBOT_OPERATOR_TOKEN" and len(token) >= 32
    sysusers = (root / SYSUSERS_FILE).read_text()
    assert "m coffeebot i2c" in sysusers and "m coffeebot dialout" in sysusers
    assert "next: systemd-sysusers" in out


def test_reinstall_keeps_the_operators_config_and_token(
    installed: tuple[Path, str], capsys: pytest.CaptureFixture[str]
):
    root, _ = installed
    (root / ROBOT_CONFIG).write_text('name = "edited on the robot"\n')
    token = (root / ENV_FILE).read_text()
    assert main(["install-service", "--root", str(root)]) == 0
    assert (root / ROBOT_CONFIG).read_text() == 'name = "edited on the robot"\n'
    assert (root / ENV_FILE).read_text() == token
    assert f"kept {root / ENV_FILE}" in capsys.readouterr().out
