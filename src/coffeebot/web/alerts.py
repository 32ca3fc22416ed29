"""The operator's alerts: what needs a person now, most severe first, longest-standing first.

Each alert is a condition read off the board at one moment (the robot held or blocked, a
delivery held, an order that failed, a module or a sensor unwell, a topic gone quiet) with
how long it has held and how fresh the value it was read from is: a dashboard that shows a
stale value as if it were current misleads the person who acts on it.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from typing import Any, Literal

from pydantic import BaseModel

from coffeebot.board import BoardView, Envelope
from coffeebot.messages import (
    DELIVERY_STATUS,
    ESTOP,
    MOTION_STATUS,
    RANGE_SCAN,
    Health,
    HealthStatus,
    MotionState,
    OrderUpdate,
)

Severity = Literal["critical", "warning", "info"]
RANK: dict[Severity, int] = {"critical": 0, "warning": 1, "info": 2}

HELD_AFTER_S = 2.0
"""A safety stop shorter than this is the gate doing its job (a person passing), not news."""
WAITING_AFTER_S = 10.0
FAILED_ORDERS_KEPT_S = 3600.0
"""A failed order stays in the list this long (board-clock seconds)."""


class Alert(BaseModel):
    key: str
    """Stable while the condition holds (how its age is kept)."""
    severity: Severity
    title: str
    detail: str = ""
    source: str
    """The topic or module it was read from."""
    since_s: float = 0.0
    """How long the condition has held, as far as this app has watched."""
    fresh_s: float | None = None
    """Age of the value it was read from (None: not from a timed value)."""


@dataclass
class Seen:
    """What the web app has gathered from the board beyond the latest values: the last health
    report of every component, and recent failed orders."""

    components: dict[tuple[str, str], tuple[Health, float]]
    failed: list[tuple[OrderUpdate, float]]

    def note_health(self, health: Health, now: float) -> None:
        if health.component is not None:
            self.components[(health.module, health.component)] = (health, now)

    def note_order(self, update: OrderUpdate, now: float) -> None:
        if update.status.value == "failed":
            self.failed.append((update, now))
        self.failed = [(u, t) for u, t in self.failed if now - t < FAILED_ORDERS_KEPT_S]


def _age(board: BoardView, stamp: float) -> float:
    return max(0.0, board.clock.now() - stamp)


def robot_alerts(board: BoardView) -> list[Alert]:
    """The e-stop, the robot held or blocked, and a delivery navigation reports as held."""
    alerts = []
    estop = board.latest(ESTOP)
    if estop is not None and estop.msg.engaged:
        alerts.append(
            Alert(
                key="estop",
                severity="critical",
                title="Emergency stop engaged",
                detail=f"{estop.msg.source}: {estop.msg.reason}".rstrip(": "),
                source=ESTOP.name,
                fresh_s=_age(board, estop.stamp),
            )
        )
    motion = board.latest(MOTION_STATUS)
    if motion is not None:
        status, fresh = motion.msg, _age(board, motion.stamp)
        held = status.state is MotionState.SAFETY_STOP and status.since_s >= HELD_AFTER_S
        if held and not (estop is not None and estop.msg.engaged):
            alerts.append(
                Alert(
                    key=f"held:{status.stopped_by}",
                    severity="warning",
                    title="Robot held by the safety gate",
                    detail=status.detail,
                    source=MOTION_STATUS.name,
                    fresh_s=fresh,
                )
            )
        elif status.state is MotionState.BLOCKED:
            alerts.append(
                Alert(
                    key="blocked",
                    severity="warning",
                    title="Robot blocked",
                    detail=status.detail,
                    source=MOTION_STATUS.name,
                    fresh_s=fresh,
                )
            )
        elif status.state is MotionState.WAITING and status.since_s >= WAITING_AFTER_S:
            alerts.append(
                Alert(
                    key="waiting",
                    severity="info",
                    title="Robot waiting for the way to clear",
                    detail=status.detail,
                    source=MOTION_STATUS.name,
                    fresh_s=fresh,
                )
            )
    report = board.latest(DELIVERY_STATUS)
    if report is not None and report.msg.problem is not None and not report.msg.status.final:
        alerts.append(
            Alert(
                key=f"delivery:{report.msg.problem.value}",
                severity="warning",
                title=f"Delivery held: {report.msg.problem.value.replace('_', ' ')}",
                detail=report.msg.detail,
                source=DELIVERY_STATUS.name,
                fresh_s=_age(board, report.stamp),
            )
        )
    return alerts


def health_alerts(board: BoardView, modules: Sequence[Health], seen: Seen) -> list[Alert]:
    """Modules the supervisor reports unwell, components (a sensor, a port) their module
    reports unwell, and sensors whose last reading was a fault."""
    alerts = []
    for h in modules:
        if h.status in (HealthStatus.FAILED, HealthStatus.RESTARTING, HealthStatus.DEGRADED):
            alerts.append(
                Alert(
                    key=f"module:{h.module}:{h.status.value}",
                    severity="critical" if h.status is HealthStatus.FAILED else "warning",
                    title=f"Module {h.module} {h.status.value}",
                    detail=h.detail,
                    source="supervisor",
                )
            )
    for (module, component), (h, at) in sorted(seen.components.items()):
        if h.status in (HealthStatus.DEGRADED, HealthStatus.FAILED):
            alerts.append(
                Alert(
                    key=f"component:{module}:{component}",
                    severity="warning",
                    title=f"{component} ({module}) {h.status.value}",
                    detail=h.detail,
                    source=f"system/health from {module}",
                    fresh_s=_age(board, at),
                )
            )
    scan = board.latest(RANGE_SCAN)
    if scan is not None:
        for reading in scan.msg.readings:
            if not reading.healthy:
                alerts.append(
                    Alert(
                        key=f"sensor:{reading.sensor}",
                        severity="warning",
                        title=f"Sensor tof{reading.sensor} gives no reading",
                        detail=reading.status.value.replace("_", " "),
                        source=RANGE_SCAN.name,
                        fresh_s=_age(board, scan.stamp),
                    )
                )
    return alerts


def order_alerts(board: BoardView, seen: Seen) -> list[Alert]:
    return [
        Alert(
            key=f"failed:{update.order_id}",
            severity="warning",
            title="An order failed",
            detail=update.detail,
            source="orders/update",
            fresh_s=_age(board, at),
        )
        for update, at in seen.failed
    ]


def stale_alerts(board: BoardView, limits: Mapping[str, float]) -> list[Alert]:
    """Topics that must keep coming, silent for longer than their limit (or never heard)."""
    alerts = []
    declared = {t.name for t in board.topics}
    for name, limit in limits.items():
        if name not in declared:
            continue
        latest: Envelope[Any] | None = board.latest(name)
        if latest is None:
            alerts.append(
                Alert(
                    key=f"stale:{name}",
                    severity="warning",
                    title=f"No {name} yet",
                    detail=f"expected at least every {limit:g} s",
                    source=name,
                )
            )
            continue
        age = _age(board, latest.stamp)
        if age > limit:
            alerts.append(
                Alert(
                    key=f"stale:{name}",
                    severity="warning",
                    title=f"{name} is stale",
                    detail=f"last message {age:.1f} s ago, expected at least every {limit:g} s",
                    source=name,
                    fresh_s=age,
                )
            )
    return alerts


class AlertList:
    """Keeps when each condition was first seen, so every alert says how long it has held."""

    def __init__(self) -> None:
        self._first: dict[str, float] = {}

    def update(self, alerts: Sequence[Alert], now: float) -> list[Alert]:
        first = {a.key: self._first.get(a.key, now) for a in alerts}
        self._first = first
        aged = [a.model_copy(update={"since_s": now - first[a.key]}) for a in alerts]
        return sorted(aged, key=lambda a: (RANK[a.severity], -a.since_s, a.key))
