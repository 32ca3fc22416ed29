"""Shared fixtures: a manual clock so time-dependent behaviour is tested without sleeping."""

from __future__ import annotations

import faulthandler

import pytest

from manual_clock import ManualClock


@pytest.fixture
def clock() -> ManualClock:
    return ManualClock(start=1000.0)


EXIT_GRACE_S = 120
"""How long the interpreter may take to exit once the tests are done."""


def pytest_sessionfinish(session: pytest.Session, exitstatus: int) -> None:
    """A thread a test left waiting would keep the run from ever exiting: if it has not
    exited ``EXIT_GRACE_S`` after the last test, print every thread's stack and fail."""
    faulthandler.dump_traceback_later(EXIT_GRACE_S, exit=True)
