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
    coffeebot/v1/robots/{robot}/odometry     robot      QoS 0, twice a second: its dead-
                                                        reckoned path, for the cameras
    coffeebot/v1/robots/{robot}/camera_fix   cameras    QoS 0: a ceiling camera's fix of it
    coffeebot/v1/cameras/layer               cameras    retained, QoS 0, every second: what
                                                        the cameras see standing

The cameras' messages come from the camera service in the dispatcher's daemon
(:mod:`coffeebot.fleet.camera_service`). Times in them that two machines must agree on
(odometry samples, a fix's moment, when an object was seen) are on the fleet's shared time
base (:data:`FleetClock`).

The version is in the topic, so a robot and a dispatcher of different versions do not
misread each other: each ignores (and counts) what it does not understand.
"""

from __future__ import annotations

import itertools
import re
from collections.abc import Callable, Mapping
from enum import StrEnum
from typing import Annotated, Literal, TypeVar

from pydantic import (
    BaseModel,
    ConfigDict,
    Field,
    ValidationError,
    field_validator,
    model_validator,
)

from coffeebot.clock import Clock
from coffeebot.messages import (
    CameraFix,
    CameraLayer,
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


class DeliveryReport(FleetMessage):
    """Navigation's report on the robot's order (``DeliveryUpdate``), numbered per robot so
    the dispatcher sees a gap or a repeat after a reconnect."""

    seq: int = Field(ge=0)
    boot_s: float
    """The run of the robot's software that made it (``RobotState.boot_s``)."""
    order_id: str = Field(min_length=1, max_length=64)
    status: OrderStatus
    detail: str = Field("", max_length=500)
    ready_for_cup: bool = False
    problem: DeliveryProblem | None = None


class RobotState(FleetMessage):
    """A robot's report of itself, a few times a second."""

    seq: int = Field(ge=0)
    at_s: float
    boot_s: float
    """When this run of the robot's software started (its wall clock): numbers start afresh."""
    reports: int = Field(ge=0)
    """Delivery reports made so far in this run: the state's word on its order holds only
    where the dispatcher has every one of them (they travel apart, and may be behind)."""
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
    latest_report: DeliveryReport | None = None
    """The last delivery report of this run, said again with every state: one sent while
    the dispatcher was not subscribed (both reconnecting to a restarted broker, which keeps
    no sessions) reached nobody, and this copy still does."""


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


Place = Literal["elevator", "loading_spot", "holding_point", "crossing", "landing"]


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


FleetClock = Callable[[], float]
"""The fleet's shared time base, for times two machines must agree on: Unix time (the
machines' clocks kept by NTP, as every ``at_s`` stamp already assumes) on a real site, the
one simulated clock when a simulation co-hosts the whole fleet."""


def fleet_offset(clock: Clock, fleet_clock: FleetClock) -> float:
    """What to add to a time on ``clock`` (a board's) to have it on the fleet's time base;
    what to subtract for the way back."""
    return fleet_clock() - clock.now()


Finite = Annotated[float, Field(allow_inf_nan=False)]
MAX_SAMPLES = 64


class OdometrySample(FleetMessage):
    t_s: Finite = Field(description="the fleet's shared time (FleetClock)")
    x_mm: Finite
    y_mm: Finite
    heading_deg: Finite
    """Unwrapped: continuous from one sample to the next, so it may pass 360."""


class PositionSample(FleetMessage):
    """Where the robot's own estimate put it at ``t_s``, with the 1-sigma of its position."""

    t_s: Finite = Field(description="the fleet's shared time (FleetClock)")
    floor: int
    x_mm: Finite
    y_mm: Finite
    sigma_x_mm: Finite = Field(ge=0)
    sigma_y_mm: Finite = Field(ge=0)
    cov_xy_mm2: Finite = 0.0

    @model_validator(mode="after")
    def _a_covariance(self) -> PositionSample:
        if self.cov_xy_mm2**2 > (self.sigma_x_mm * self.sigma_y_mm) ** 2:
            raise ValueError("cov_xy_mm2 is larger than sigma_x_mm * sigma_y_mm allows")
        return self


class OdometryBatch(FleetMessage):
    """A robot's latest stretch of dead-reckoned path, in its odometry's own frame (never
    pulled onto the plan), for the camera service to name it on a camera's tracks; with
    where its own estimate puts it (none while it is not localized), so that it is not
    taken for an object standing there and is told apart from a robot driving beside it."""

    samples: list[OdometrySample] = Field(min_length=1, max_length=MAX_SAMPLES)
    estimate: PositionSample | None = None

    @field_validator("samples")
    @classmethod
    def _in_time_order(cls, samples: list[OdometrySample]) -> list[OdometrySample]:
        times = [sample.t_s for sample in samples]
        if any(later <= earlier for earlier, later in itertools.pairwise(times)):
            raise ValueError("sample times must increase")
        return samples


class CameraFixReport(FleetMessage):
    """A ceiling camera's fix of the robot, for the moment of the robot's odometry sample at
    ``odometry_at_s`` (the newest the service had): the robot carries it on to now along its
    own odometry."""

    odometry_at_s: Finite
    fix: CameraFix


class CameraLayerReport(FleetMessage):
    """The map's camera layer as the service made it at ``at_s``; its objects' times are on
    the fleet's time base too."""

    at_s: Finite
    layer: CameraLayer


def layer_shifted(layer: CameraLayer, by_s: float) -> CameraLayer:
    """``layer`` with its objects' times moved by ``by_s``: from one clock to another."""
    objects = [
        obj.model_copy(
            update={"standing_since_s": obj.standing_since_s + by_s, "seen_s": obj.seen_s + by_s}
        )
        for obj in layer.objects
    ]
    return layer.model_copy(update={"objects": objects})


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
ROBOT_TO_CAMERAS: dict[str, type[OdometryBatch]] = {"odometry": OdometryBatch}
CAMERAS_TO_ROBOT: dict[str, type[FleetMessage]] = {"camera_fix": CameraFixReport}
CAMERA_LAYER_TOPIC = f"{ROOT}/cameras/layer"
"""Every robot's, retained: a robot that (re)connects has it at once."""

QOS: dict[str, int] = {
    "state": 0,
    "traffic": 0,
    "odometry": 0,
    "camera_fix": 0,
    "camera_layer": 0,
}
"""QoS 1 (at least once) for everything but the frequent state reports, traffic and camera
messages: each of those is superseded a fraction of a second later (a lost odometry batch
only delays a fix; a fix lost is followed by the next while the robot is in view, and one
delivered late after a reconnect would be too old to use)."""


def robot_topic(robot: str, kind: str) -> str:
    return f"{ROOT}/robots/{robot}/{kind}"


DISPATCHER_CONNECTION = f"{ROOT}/dispatcher/connection"


def publisher(topic: str) -> str:
    """Who publishes on ``topic`` in this layout: a robot's id, ``dispatcher`` or
    ``cameras``; the topic itself for one outside it. One publisher's messages reach a
    subscriber in the order it sent them, whatever the topic."""
    if topic == DISPATCHER_CONNECTION:
        return "dispatcher"
    if topic == CAMERA_LAYER_TOPIC:
        return "cameras"
    try:
        robot, kind = parse_robot_topic(topic)
    except BadMessage:
        return topic
    if kind in DISPATCHER_TO_ROBOT:
        return "dispatcher"
    if kind in CAMERAS_TO_ROBOT:
        return "cameras"
    return robot


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


def decode(model: type[M], topic: str, payload: object) -> M:
    """The payload as ``model``, or :class:`BadMessage` saying what is wrong with it (the
    broker hands over whatever a client sent: bytes, or nothing)."""
    if not isinstance(payload, bytes | bytearray):
        raise BadMessage(f"{topic}: payload is not bytes")
    try:
        return model.model_validate_json(bytes(payload))
    except ValidationError as exc:
        first = exc.errors()[0]
        where = ".".join(str(p) for p in first["loc"]) or "payload"
        raise BadMessage(f"{topic}: {where}: {first['msg']}") from None


def robot_report(topic: str, payload: object, reports: Mapping[str, type[M]]) -> tuple[str, M]:
    """(robot, message) of what a robot sent on a topic of one of the ``reports`` kinds, or
    :class:`BadMessage` saying what is wrong."""
    robot, kind = parse_robot_topic(topic)
    model = reports.get(kind)
    if model is None:
        raise BadMessage(f"{topic}: no such report")
    return robot, decode(model, topic, payload)


def encode(message: FleetMessage) -> bytes:
    return message.model_dump_json().encode()
