"""Temporary directories of simulated runs (the demo's order database, the devices' ports).

Each is named after the process that made it, ``coffeebot-sim-<pid>-<random>``: a run that
ends normally removes its own, and one that cannot (``kill -9``, a power cut) leaves one
that the next run removes, once no process of that number is alive.
"""

from __future__ import annotations

import os
import shutil
import tempfile
from pathlib import Path

PREFIX = "coffeebot-sim-"


def run_directory() -> tempfile.TemporaryDirectory[str]:
    """A fresh directory for this process, after removing those of runs that died."""
    remove_abandoned()
    return tempfile.TemporaryDirectory(prefix=f"{PREFIX}{os.getpid()}-")


def remove_abandoned(root: Path | None = None) -> list[Path]:
    """Remove this user's run directories whose process is gone; the ones removed."""
    removed = []
    for entry in Path(root or tempfile.gettempdir()).glob(f"{PREFIX}*-*"):
        pid = entry.name.removeprefix(PREFIX).split("-", 1)[0]
        if not pid.isdigit() or entry.is_symlink() or not entry.is_dir():
            continue
        try:
            if entry.stat().st_uid != os.getuid() or _alive(int(pid)):
                continue
        except OSError:
            continue  # removed meanwhile by another run
        shutil.rmtree(entry, ignore_errors=True)
        removed.append(entry)
    return removed


def _alive(pid: int) -> bool:
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    except PermissionError:
        return True  # someone else's process
    return True
