"""Shared fixtures: a manual clock so time-dependent behaviour is tested without sleeping."""

from __future__ import annotations

import pytest

from manual_clock import ManualClock


@pytest.fixture
def clock() -> ManualClock:
    return ManualClock(start=1000.0)
