"""What robots and the dispatcher say to each other over MQTT: topics and messages, v1.

Every payload is the JSON of one of the models below (pydantic, no unknown fields, frozen),
so a message is either exactly what this version means or refused with the reason
(:func:`decode`). The layout (docs/fleet.md has it as a table)::

    coffeebot/v1/robots/{robot}/connection   robot      retained, QoS 1: online/offline/
                                                        connection_broken (the last will)
    coffeebot/v1/robots/{robot}/state        robot      QoS 0, at most a few per second:
                                                        pose, motion, safety, health
    coffeebot/v1/robots/{robot}/delivery     robot      QoS 1: progress on its order, in order
    coffeebot/v1/robots/{robot}/lease        robot      QoS 1: ask for or give back a shared
                                                        place (the elevator, the loading spot)
    coffeebot/v1/robots/{robot}/ack          robot      QoS 1: an assignment or action taken
                                                        (or refused, and why)
    coffeebot/v1/robots/{robot}/assignment   dispatcher QoS 1: the order to deliver next
    coffeebot/v1/robots/{robot}/action       dispatcher QoS 1: e-stop, cancel, cup loaded...
    coffeebot/v1/robots/{robot}/grant        dispatcher QoS 1: a lease granted or refused
    coffeebot/v1/robots/{robot}/traffic      dispatcher QoS 0, about twice a second: the
                                                        other robots' poses, for passing
    coffeebot/v1/dispatcher/connection       dispatcher retained, QoS 1

The version is in the topic, so a robot and a dispatcher of different versions do not
misread each other: each ignores (and counts) what it does not understand.
"""

from __future__ import annotations

import re
from enum import StrEnum
from typing import Literal, TypeVar

from pydantic import BaseModel, ConfigDict, Field, ValidationError

from coffeebot.messages import (
    DeliveryProblem,
    HealthStatus,
    MotionState,
    OrderStatus,
    SafetyState,
)

VERSION = "v1"
ROOT = f"coffeebot/{VERSION}"
ROBOT_ID = re.compile(r"^[a-z0-9][a-z0-9-]{0,31}$")
"""Robot ids are topic levels: lower-case letters, digits and dashes, no wildcards."""


class FleetMessage(BaseModel):
    model_config = ConfigDict(frozen=True, extra="forbid")


class ConnectionState(StrEnum):
    ONLINE = "online"
    OFFLINE = "offline"
    """Left on purpose (shut down)."""
    CONNECTION_BROKEN = "connection_broken"
    """The broker's last will for whoever vanished without saying goodbye."""


class Connection(FleetMessage):
    state: ConnectionState
    at_s: float = Field(description="sender's wall clock, Unix seconds")


class RobotState(FleetMessage):
    """A robot's report of itself, a few times a second."""

    seq: int = Field(ge=0)
    at_s: float
    floor: int | None = None
    x_mm: float | None = None
    y_mm: float | None = None
    heading_deg: float | None = None
    sigma_mm: float | None = None
    """The pose's larger 1-sigma axis: how far the dispatcher should trust the position."""
    motion: MotionState = MotionState.IDLE
    safety: SafetyState = SafetyState.STOP
    health: HealthStatus = HealthStatus.STARTING
    """The worst of its modules."""
    unwell: list[str] = Field(default_factory=list, max_length=32)
    """Modules (and components) not running, in words."""
    order_id: str | None = None
    """The order it works on, if any."""
    estop: bool = False


class DeliveryReport(FleetMessage):
    """Navigation's report on the robot's order (``DeliveryUpdate``), numbered per robot so
    the dispatcher sees a gap or a repeat after a reconnect."""

    seq: int = Field(ge=0)
    order_id: str = Field(min_length=1, max_length=64)
    status: OrderStatus
    detail: str = Field("", max_length=500)
    ready_for_cup: bool = False
    problem: DeliveryProblem | None = None


class Assignment(FleetMessage):
    """The order a robot delivers next."""

    assignment_id: str = Field(min_length=1, max_length=64)
    order_id: str = Field(min_length=1, max_length=64)
    room: str = Field(min_length=1, max_length=64)
    drink: str = Field(min_length=1, max_length=64)


ActionKind = Literal[
    "estop", "release_estop", "cancel", "cup_loaded", "pickup_confirmed", "elevator_confirm"
]


class InstantAction(FleetMessage):
    """Something to do now, whatever the robot is doing (VDA 5050's instant actions)."""

    action_id: str = Field(min_length=1, max_length=64)
    kind: ActionKind
    order_id: str = Field("", max_length=64)


class Ack(FleetMessage):
    """An assignment or action (by its id) taken, or refused with the reason."""

    ref: str = Field(min_length=1, max_length=64)
    accepted: bool
    reason: str = Field("", max_length=500)


Place = Literal["elevator", "loading_spot", "holding_point"]


class LeaseRequest(FleetMessage):
    """Ask for a shared place (``want``), or give it back (``want=False``)."""

    request_id: str = Field(min_length=1, max_length=64)
    place: Place
    want: bool = True


class LeaseGrant(FleetMessage):
    """The dispatcher's answer: the place is the robot's for ``expires_in_s`` (renewed by
    asking again), or not yet (``granted=False``: someone else holds it; ask again)."""

    request_id: str = Field(min_length=1, max_length=64)
    place: Place
    granted: bool
    expires_in_s: float = Field(0.0, ge=0.0)
    holder: str | None = None


class TrafficRobot(FleetMessage):
    """Another robot where it last said it was."""

    robot: str = Field(pattern=ROBOT_ID.pattern)
    floor: int
    x_mm: float
    y_mm: float
    heading_deg: float
    moving: bool
    """Its motion was moving or going round something, not standing."""
    reported_at_s: float = Field(description="the reporting robot's wall clock, Unix seconds")
    age_s: float = Field(ge=0, description="how long ago the dispatcher heard it")


class Traffic(FleetMessage):
    """The fleet's other robots with a known pose, so two meeting in the hallway both move
    over to their passing lanes (docs/fleet.md, "Passing in the hallway")."""

    robots: list[TrafficRobot] = Field(default_factory=list, max_length=64)


M = TypeVar("M", bound=FleetMessage)

ROBOT_TO_DISPATCHER: dict[str, type[FleetMessage]] = {
    "connection": Connection,
    "state": RobotState,
    "delivery": DeliveryReport,
    "lease": LeaseRequest,
    "ack": Ack,
}
DISPATCHER_TO_ROBOT: dict[str, type[FleetMessage]] = {
    "assignment": Assignment,
    "action": InstantAction,
    "grant": LeaseGrant,
    "traffic": Traffic,
}
QOS: dict[str, int] = {"state": 0, "traffic": 0}
"""QoS 1 (at least once) for everything but the frequent state reports and traffic: each of
those is superseded a fraction of a second later."""


def robot_topic(robot: str, kind: str) -> str:
    return f"{ROOT}/robots/{robot}/{kind}"


DISPATCHER_CONNECTION = f"{ROOT}/dispatcher/connection"


class BadMessage(ValueError):
    """A message this version cannot take: the reason, naming topic and field."""


def parse_robot_topic(topic: str) -> tuple[str, str]:
    """(robot, kind) of a ``coffeebot/v1/robots/{robot}/{kind}`` topic."""
    parts = topic.split("/")
    if len(parts) != 5 or "/".join(parts[:3]) != f"{ROOT}/robots":
        raise BadMessage(f"{topic}: not a {VERSION} robot topic")
    robot, kind = parts[3], parts[4]
    if not ROBOT_ID.match(robot):
        raise BadMessage(f"{topic}: {robot!r} is not a robot id")
    return robot, kind


def decode(model: type[M], topic: str, payload: bytes) -> M:
    """The payload as ``model``, or :class:`BadMessage` saying what is wrong with it."""
    try:
        return model.model_validate_json(payload)
    except ValidationError as exc:
        first = exc.errors()[0]
        where = ".".join(str(p) for p in first["loc"]) or "payload"
        raise BadMessage(f"{topic}: {where}: {first['msg']}") from None


def encode(message: FleetMessage) -> bytes:
    return message.model_dump_json().encode()
