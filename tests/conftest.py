"""Shared fixtures: a manual clock so time-dependent behaviour is tested without sleeping."""

from __future__ import annotations

import os
from collections.abc import Iterator

import pytest

from manual_clock import ManualClock
from stuck_guard import StuckGuard


@pytest.fixture
def clock() -> ManualClock:
    return ManualClock(start=1000.0)


TEST_LIMIT_S = 600
"""No single test takes this long, its fixtures' setup and teardown included (a module's
fixtures end with its last test): one that does is stuck. What it waits for is printed and the
run fails, instead of waiting for CI's limit."""

EXIT_GRACE_S = 120
"""How long the interpreter may take to exit once the tests are done."""


_guard: StuckGuard | None = None


def pytest_configure(config: pytest.Config) -> None:
    """The guard writes to the run's real standard error, kept before tests capture it: the
    stacks of a stuck run must reach the person (or CI log) watching."""
    global _guard
    _guard = StuckGuard(os.fdopen(os.dup(2), "w"))


@pytest.hookimpl(wrapper=True)
def pytest_runtest_protocol(item: pytest.Item, nextitem: pytest.Item | None) -> Iterator[None]:
    """Guards the whole of a test: setup, call and every teardown it triggers, a module's
    fixtures' included, which a fixture of the test's own would miss."""
    assert _guard is not None
    _guard.arm(item.nodeid, TEST_LIMIT_S)
    try:
        return (yield)
    finally:
        _guard.disarm()


def pytest_sessionfinish(session: pytest.Session, exitstatus: int) -> None:
    """A thread a test left waiting would keep the run from ever exiting: if it has not
    exited ``EXIT_GRACE_S`` after the last test, print every stack and fail. Not in a
    pytest-xdist worker, which rightly waits for the others once its share is done: the
    controlling process is guarded, and it ends its workers."""
    if not hasattr(session.config, "workerinput"):
        assert _guard is not None
        _guard.arm("the run's exit", EXIT_GRACE_S)
