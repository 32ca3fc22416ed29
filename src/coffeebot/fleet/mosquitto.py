"""A Mosquitto broker of our own, for the fleet demo and the tests: on a free loopback port,
with a generated configuration, users and per-robot access rules, stopped when done.

A building's real broker is configured by whoever runs it (docs/fleet.md shows the same
rules); this is the same configuration made on the spot. Every robot logs in as its robot id
and may write only its own reports and odometry and read only its own orders and camera
fixes, and the cameras' layer (``pattern`` rules with ``%u``); the dispatcher, camera
service included, may read and write everything under ``coffeebot/v1``. The robots here are
simulated: everyone may also read the simulated clock's step markers and write its own
(:mod:`coffeebot.fleet.in_step`).
"""

from __future__ import annotations

import contextlib
import os
import secrets
import shutil
import socket
import subprocess
import tempfile
import time
from collections.abc import Iterable, Iterator
from dataclasses import dataclass
from pathlib import Path

from coffeebot.errors import CoffeebotError
from coffeebot.fleet.in_step import STEP_TOPIC
from coffeebot.fleet.protocol import (
    CAMERA_LAYER_TOPIC,
    CAMERAS_TO_ROBOT,
    DISPATCHER_CONNECTION,
    DISPATCHER_TO_ROBOT,
    ROBOT_TO_CAMERAS,
    ROBOT_TO_DISPATCHER,
    ROOT,
)

DISPATCHER_USER = "dispatcher"
START_TIMEOUT_S = 10.0


class BrokerError(CoffeebotError):
    """The broker could not be started (not installed, no port)."""


@dataclass(frozen=True)
class Credentials:
    username: str
    password: str


@dataclass(frozen=True)
class BrokerAddress:
    host: str
    port: int

    @property
    def url(self) -> str:
        return f"mqtt://{self.host}:{self.port}"


def acl_rules(step_markers: bool = False) -> str:
    """The access rules: the dispatcher everything, each robot its own topics only; with
    ``step_markers`` (a simulated fleet, :mod:`coffeebot.fleet.in_step`) everyone may also
    write its own step markers and read all of them."""
    lines = [f"user {DISPATCHER_USER}", f"topic readwrite {ROOT}/#", ""]
    for kind in (*ROBOT_TO_DISPATCHER, *ROBOT_TO_CAMERAS):
        lines.append(f"pattern write {ROOT}/robots/%u/{kind}")
    for kind in (*DISPATCHER_TO_ROBOT, *CAMERAS_TO_ROBOT):
        lines.append(f"pattern read {ROOT}/robots/%u/{kind}")
    lines.append(f"pattern read {DISPATCHER_CONNECTION}")
    lines.append(f"pattern read {CAMERA_LAYER_TOPIC}")
    if step_markers:
        lines.append(f"pattern write {STEP_TOPIC}/%u")
        lines.append(f"pattern read {STEP_TOPIC}/#")
    return "\n".join(lines) + "\n"


def free_port(host: str = "127.0.0.1") -> int:
    with socket.socket() as probe:
        probe.bind((host, 0))
        return int(probe.getsockname()[1])


class Mosquitto:
    """One broker process; :meth:`stop` and :meth:`start` again keep its port and users (a
    broker restart, as the fault tests need)."""

    def __init__(self, robots: Iterable[str], host: str = "127.0.0.1") -> None:
        binary = shutil.which("mosquitto") or shutil.which("mosquitto", path="/usr/sbin")
        passwd = shutil.which("mosquitto_passwd") or shutil.which(
            "mosquitto_passwd", path="/usr/bin"
        )
        if binary is None or passwd is None:
            raise BrokerError(
                "mosquitto is not installed: apt-get install mosquitto (make fleet-demo and "
                "make test do it)"
            )
        self._binary = binary
        self._dir = tempfile.TemporaryDirectory(prefix="coffeebot-mosquitto-")
        root = Path(self._dir.name)
        self.address = BrokerAddress(host, free_port(host))
        self.credentials = {
            name: Credentials(name, secrets.token_urlsafe(16))
            for name in (DISPATCHER_USER, *robots)
        }
        passwords = root / "passwords"
        passwords.touch(mode=0o600)
        for user in self.credentials.values():
            subprocess.run(
                [passwd, "-b", str(passwords), user.username, user.password],
                check=True,
                capture_output=True,
            )
        (root / "acl").write_text(acl_rules(step_markers=True))
        self._config = root / "mosquitto.conf"
        self._config.write_text(
            f"listener {self.address.port} {host}\n"
            "allow_anonymous false\n"
            f"password_file {passwords}\n"
            f"acl_file {root / 'acl'}\n"
            "persistence false\n"
            "log_dest stderr\n"
            "log_type error\n"
            "log_type warning\n"
        )
        self._log = root / "broker.log"
        if os.geteuid() == 0:  # mosquitto started as root drops to its own user: let it read
            for path in (root, passwords, root / "acl", self._config):
                with contextlib.suppress(LookupError):
                    shutil.chown(path, user="mosquitto")
        self._process: subprocess.Popen[bytes] | None = None

    def start(self) -> None:
        if self._process is not None:
            return
        with self._log.open("ab") as log:
            # A session of its own: Ctrl-C at the demo reaches the daemons, which shut down
            # in order and say goodbye, not the broker they say it through.
            self._process = subprocess.Popen(
                [self._binary, "-c", str(self._config)],
                stdout=log,
                stderr=log,
                start_new_session=True,
            )
        deadline = time.monotonic() + START_TIMEOUT_S
        while time.monotonic() < deadline:
            if self._process.poll() is not None:
                raise BrokerError(f"mosquitto exited at start: {self._log.read_text()[-500:]}")
            with (
                contextlib.suppress(OSError),
                socket.create_connection((self.address.host, self.address.port), timeout=0.2),
            ):
                return
            time.sleep(0.05)
        self.stop()
        raise BrokerError(f"mosquitto did not listen on {self.address.url}")

    def stop(self) -> None:
        """Kill the broker at once (as a crash would)."""
        if self._process is None:
            return
        self._process.kill()
        self._process.wait()
        self._process = None

    @property
    def running(self) -> bool:
        return self._process is not None and self._process.poll() is None

    def close(self) -> None:
        self.stop()
        self._dir.cleanup()


@contextlib.contextmanager
def mosquitto(robots: Iterable[str]) -> Iterator[Mosquitto]:
    broker = Mosquitto(robots)
    try:
        broker.start()
        yield broker
    finally:
        broker.close()
