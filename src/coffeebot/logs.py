"""Structured logging: one line per event, ``key=value`` pairs, to stderr (journald keeps it).

The convention every module follows for the events an operator reads back after an incident
(safety stops, faults, reconnects, order transitions) is :func:`log_event` for one-off events
and :class:`Transitions` for conditions a loop sees every cycle: each is logged once, when it
changes, with its cause. docs/operations.md ("Logging") shows examples.
"""

from __future__ import annotations

import logging
import os
import sys
import time
from collections.abc import Hashable, Mapping
from contextvars import ContextVar
from enum import StrEnum
from typing import TextIO

_RESERVED = set(vars(logging.LogRecord("", 0, "", 0, "", None, None))) | {"message", "asctime"}

# sd-daemon(3) priority prefixes: journald strips them and files the line at that priority,
# so `journalctl -p warning` works on our lines.
_SYSLOG_PRIORITY = {
    logging.CRITICAL: 2,
    logging.ERROR: 3,
    logging.WARNING: 4,
    logging.INFO: 6,
    logging.DEBUG: 7,
}


ROBOT: ContextVar[str | None] = ContextVar("robot", default=None)
"""The robot whose daemon the running task belongs to, where one process runs several (a
simulated fleet); its tasks inherit it from the task that starts the daemon."""


class RobotTag(logging.Filter):
    """Puts ``robot=<id>`` on the records logged by a robot's tasks in a process that runs
    several daemons (:data:`ROBOT`): their modules share the loggers, and a line that does
    not say which robot waited or went round cannot be read back."""

    def filter(self, record: logging.LogRecord) -> bool:
        robot = ROBOT.get()
        if robot is not None:
            record.robot = robot
        return True


class Event(StrEnum):
    """The kinds of event every module logs once, with its cause, as ``event=<kind>``."""

    SAFETY_STOP = "safety_stop"
    SAFETY_CLEAR = "safety_clear"
    FAULT = "fault"
    RECOVERED = "recovered"
    DISCONNECT = "disconnect"
    RECONNECT = "reconnect"
    ORDER = "order"

    @property
    def level(self) -> int:
        if self is Event.FAULT:
            return logging.ERROR
        if self in (Event.SAFETY_STOP, Event.DISCONNECT):
            return logging.WARNING
        return logging.INFO


def log_event(logger: logging.Logger, event: Event, cause: str, **fields: object) -> None:
    """Log one event as ``msg="<event>: <cause>" event=<event> cause=<cause> <fields>``."""
    logger.log(
        event.level,
        "%s: %s",
        event.value,
        cause,
        extra={"event": event.value, "cause": cause, **fields},
    )


class Transitions:
    """Remembers the last state of each subject, so that a state is logged when it changes.

    A collision module that sees an obstacle in 50 scans a second calls :meth:`update` on every
    scan; only the scan that turns "go" into "stop" produces a log line.

    ``initial`` gives subjects the state they are taken to start in, so that reaching it is
    not an event: a port that opens at start-up is no "reconnect", one that fails is a
    "disconnect".
    """

    def __init__(
        self, logger: logging.Logger, initial: Mapping[str, Hashable] | None = None
    ) -> None:
        self._logger = logger
        self._states: dict[str, Hashable] = dict(initial or {})

    def update(
        self, subject: str, state: Hashable, event: Event, cause: str, **fields: object
    ) -> bool:
        """Log ``event`` if ``subject`` was not already in ``state``; True when it logged."""
        previous = self._states.get(subject)
        if subject in self._states and previous == state:
            return False
        self._states[subject] = state
        log_event(
            self._logger, event, cause, subject=subject, state=state, previous=previous, **fields
        )
        return True


def _quote(value: object) -> str:
    text = str(value)
    if text == "" or any(c in text for c in ' ="\n'):
        text = '"' + text.replace("\\", "\\\\").replace('"', '\\"').replace("\n", "\\n") + '"'
    return text


class LogfmtFormatter(logging.Formatter):
    """``ts=... level=... logger=... msg="..." key=value``; tracebacks stay on one line.

    With ``syslog_prefix`` each line starts with its ``<priority>`` for journald.
    """

    def __init__(self, syslog_prefix: bool = False) -> None:
        super().__init__()
        self.syslog_prefix = syslog_prefix

    def format(self, record: logging.LogRecord) -> str:
        created = time.strftime("%Y-%m-%dT%H:%M:%S", time.gmtime(record.created))
        parts = [
            f"ts={created}.{int(record.msecs):03d}Z",
            f"level={record.levelname}",
            f"logger={record.name}",
            f"msg={_quote(record.getMessage())}",
        ]
        parts += [f"{k}={_quote(v)}" for k, v in vars(record).items() if k not in _RESERVED]
        if record.exc_info:
            parts.append(f"exc={_quote(self.formatException(record.exc_info))}")
        line = " ".join(parts)
        if self.syslog_prefix:
            line = f"<{_SYSLOG_PRIORITY.get(record.levelno, 6)}>{line}"
        return line


def attached_to_journal(stream: TextIO, environ: Mapping[str, str] | None = None) -> bool:
    """Whether ``stream`` is the journald stream systemd gave us (``JOURNAL_STREAM=dev:ino``)."""
    value = (os.environ if environ is None else environ).get("JOURNAL_STREAM", "")
    try:
        device, inode = (int(part) for part in value.split(":"))
        stat = os.fstat(stream.fileno())
    except (ValueError, OSError):
        return False
    return (stat.st_dev, stat.st_ino) == (device, inode)


class StderrHandler(logging.StreamHandler[TextIO]):
    """Writes to whatever ``sys.stderr`` is at the time, as ``logging.lastResort`` does, so a
    replaced stderr (a test's capture, a redirected daemon) never receives writes once closed."""

    @property
    def stream(self) -> TextIO:
        return sys.stderr

    @stream.setter
    def stream(self, _value: TextIO) -> None:
        """The base class assigns the stream at init; it is always read from ``sys``."""


def setup_logging(level: str = "INFO") -> None:
    handler = StderrHandler()
    handler.setFormatter(LogfmtFormatter(syslog_prefix=attached_to_journal(sys.stderr)))
    handler.addFilter(RobotTag())
    root = logging.getLogger()
    root.handlers[:] = [handler]
    root.setLevel(level)
