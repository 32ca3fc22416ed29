"""``coffeebot install-service``: put the unit, its user and a default config in place.

Everything is written under ``root`` (``/`` on the robot, a scratch directory in tests).
Files the operator edits (the robot config, the secrets file) are created once and never
overwritten; the files that belong to the package (unit, sysusers entry) are replaced.
"""

from __future__ import annotations

import re
import secrets
import shutil
import subprocess
from pathlib import Path

from coffeebot.config import WebConfig

UNIT_NAME = "coffeebot.service"
UNIT_DIR = Path("etc/systemd/system")
SYSUSERS_FILE = Path("etc/sysusers.d/coffeebot.conf")
CONFIG_DIR = Path("etc/coffeebot")
ROBOT_CONFIG = CONFIG_DIR / "robot.toml"
ENV_FILE = CONFIG_DIR / "coffeebot.env"


def unit_text(template: str, executable: Path) -> str:
    """The shipped unit with ``ExecStart`` pointing at this installation's ``coffeebot``."""
    text, count = re.subn(
        r"^ExecStart=\S+", f"ExecStart={executable}", template, count=1, flags=re.MULTILINE
    )
    if count != 1:
        raise ValueError("the unit template has no ExecStart= line")
    return text


def _write(path: Path, text: str, mode: int) -> None:
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_text(text)
    path.chmod(mode)


def install_service(source: Path, root: Path, executable: Path, default_config: Path) -> list[str]:
    """Install under ``root``; returns one line per action, for the operator to read."""
    done = []
    unit = root / UNIT_DIR / UNIT_NAME
    _write(unit, unit_text((source / "systemd" / UNIT_NAME).read_text(), executable), 0o644)
    done.append(f"wrote {unit}")
    sysusers = root / SYSUSERS_FILE
    _write(sysusers, (source / "systemd" / "coffeebot.sysusers").read_text(), 0o644)
    done.append(f"wrote {sysusers}")
    config = root / ROBOT_CONFIG
    if config.exists():
        done.append(f"kept {config}")
    else:
        config.parent.mkdir(parents=True, exist_ok=True)
        shutil.copyfile(default_config, config)
        config.chmod(0o644)
        done.append(f"wrote {config} (from {default_config})")
    env = root / ENV_FILE
    if env.exists():
        done.append(f"kept {env}")
    else:
        token = secrets.token_urlsafe(24)
        # Created 0600 before the secret goes in, so it is never readable by others.
        env.touch(mode=0o600)
        env.write_text(
            "# Secrets for coffeebot.service, root-only: the token for the web page's operator\n"
            "# actions.\n"
            f"{WebConfig().operator_token_env}={token}\n"
        )
        done.append(f"wrote {env} with a new operator token (mode 0600)")
    if root == Path("/") and Path("/run/systemd/system").is_dir():
        for command in (["systemd-sysusers", str(sysusers)], ["systemctl", "daemon-reload"]):
            subprocess.run(command, check=True)
            done.append("ran " + " ".join(command))
        done.append("next: systemctl enable --now coffeebot")
    else:
        done.append(
            f"next: systemd-sysusers {sysusers}; systemctl daemon-reload; "
            "systemctl enable --now coffeebot"
        )
    return done
