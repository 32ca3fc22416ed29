"""Shared fixtures: a manual clock so time-dependent behaviour is tested without sleeping."""

from __future__ import annotations

import faulthandler
from collections.abc import Iterator

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


def pytest_sessionfinish(session: pytest.Session, exitstatus: int) -> None:
    """A thread a test left waiting would keep the run from ever exiting: if it has not
    exited ``EXIT_GRACE_S`` after the last test, print every thread's stack and fail."""
    faulthandler.dump_traceback_later(EXIT_GRACE_S, exit=True)


@pytest.fixture(autouse=True)
def _stuck_test_guard() -> Iterator[None]:
    faulthandler.dump_traceback_later(TEST_LIMIT_S, exit=True)
    yield
    faulthandler.cancel_dump_traceback_later()
