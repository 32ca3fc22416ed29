"""What a test's code logged under the event convention (``coffeebot.logs``)."""

from __future__ import annotations

import logging

import pytest


def events(caplog: pytest.LogCaptureFixture, kind: str) -> list[logging.LogRecord]:
    """The records logged as ``event=<kind>``, in order."""
    return [r for r in caplog.records if getattr(r, "event", None) == kind]


def causes(caplog: pytest.LogCaptureFixture, kind: str) -> list[str]:
    """The ``cause=`` of each ``event=<kind>`` record, in order."""
    return [r.cause for r in events(caplog, kind)]  # type: ignore[attr-defined]
