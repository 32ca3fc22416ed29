"""Shared fixtures: a manual clock so time-dependent behaviour is tested without sleeping."""

from __future__ import annotations

import faulthandler
import os
from collections.abc import Iterator
from typing import TextIO

import pytest

from manual_clock import ManualClock


@pytest.fixture
def clock() -> ManualClock:
    return ManualClock(start=1000.0)


TEST_LIMIT_S = 600
"""No single test takes this long: one that does is stuck. Its stacks are printed and the
run fails, instead of waiting for CI's limit."""

EXIT_GRACE_S = 120
"""How long the interpreter may take to exit once the tests are done."""


_terminal: TextIO | None = None
"""The run's real standard error, kept before tests capture it: the stacks of a stuck run
must reach the person (or CI log) watching, not a capture buffer that is never shown."""


def pytest_configure(config: pytest.Config) -> None:
    global _terminal
    _terminal = os.fdopen(os.dup(2), "w")


def _dump_stacks_and_exit_after(seconds: float) -> None:
    assert _terminal is not None
    faulthandler.dump_traceback_later(seconds, exit=True, file=_terminal)


def pytest_sessionfinish(session: pytest.Session, exitstatus: int) -> None:
    """A thread a test left waiting would keep the run from ever exiting: if it has not
    exited ``EXIT_GRACE_S`` after the last test, print every thread's stack and fail. Not
    in a pytest-xdist worker, which rightly waits for the others once its share is done: the
    controlling process is guarded, and it ends its workers."""
    if not hasattr(session.config, "workerinput"):
        _dump_stacks_and_exit_after(EXIT_GRACE_S)


@pytest.fixture(autouse=True)
def _stuck_test_guard() -> Iterator[None]:
    _dump_stacks_and_exit_after(TEST_LIMIT_S)
    yield
    faulthandler.cancel_dump_traceback_later()
