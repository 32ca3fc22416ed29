"""Every message that crosses the board, and the topics that carry them.

This file is the contract between modules: a module may only publish or read a topic that is
declared here, and only with the topic's model. Units are in the field names (mm, mm/s, deg,
s). Poses are in the floor plan's frame: x, y in mm, heading in degrees counter-clockwise
from +x. Robot-frame quantities use x forward, y left, origin at the body centre.
"""

from __future__ import annotations

from enum import StrEnum
from typing import Any, Literal

from pydantic import BaseModel, ConfigDict, Field, model_validator

from coffeebot.board.topic import Delivery, Topic


class Message(BaseModel):
    """Base of every board message: immutable, no unknown fields."""

    model_config = ConfigDict(frozen=True, extra="forbid")


# --- health -------------------------------------------------------------------------------


class HealthStatus(StrEnum):
    STARTING = "starting"
    RUNNING = "running"
    DEGRADED = "degraded"
    RESTARTING = "restarting"
    FAILED = "failed"
    STOPPED = "stopped"


class Health(Message):
    """Health of one module or one component inside it (a sensor, a port)."""

    module: str
    component: str | None = None
    status: HealthStatus
    restarts: int = 0
    detail: str = ""
    publishes: tuple[str, ...] = ()
    """The topics the module publishes, in the supervisor's reports (empty for a component):
    motion knows the health of whatever writes the collision verdicts from this, not from
    a module's name."""
    cpu_pct: float | None = None
    """The module's CPU time as per cent of one core over the last few seconds of the
    machine's time, in the supervisor's snapshot (:mod:`coffeebot.cpu`); None before the
    first window."""


# --- sensors ------------------------------------------------------------------------------


class ReadingStatus(StrEnum):
    """Why a time-of-flight reading is or is not a distance (VL53L1X range status, typed)."""

    VALID = "valid"
    SIGMA_FAIL = "sigma_fail"
    SIGNAL_FAIL = "signal_fail"
    OUT_OF_BOUNDS = "out_of_bounds"
    """Nothing the sensor can range: the path ahead is clear as far as it sees."""
    TOO_CLOSE = "too_close"
    """A target nearer than the sensor's minimum range (~40 mm): an obstacle, not a gap."""
    WRAP_AROUND = "wrap_around"
    HARDWARE_FAIL = "hardware_fail"
    NO_TARGET = "no_target"
    NOT_READY = "not_ready"
    BUS_ERROR = "bus_error"
    OTHER = "other"


NOTHING_IN_RANGE = frozenset(
    {
        ReadingStatus.NO_TARGET,
        ReadingStatus.OUT_OF_BOUNDS,
        ReadingStatus.SIGNAL_FAIL,
        ReadingStatus.SIGMA_FAIL,
    }
)
"""Statuses of a sensor that ranged and found nothing it can measure: the face is clear, not
blind. On the VL53L1X "nothing in view" is a signal fail (too little light came back) and a
far or dark target is a signal or sigma fail; a near target of any size returns enough light
to be valid (docs/sensor-model.md)."""


class RangeReading(Message):
    """One VL53L1X ranging. ``distance_mm`` is set only for a valid status (under a bad one
    the chip's distance register holds a number that is often garbage); signal, ambient and
    sigma say what the reading is worth whatever its status."""

    sensor: int = Field(ge=0, le=7)
    status: ReadingStatus
    distance_mm: int | None = None
    signal_rate_mcps: float | None = None
    ambient_rate_mcps: float | None = None
    sigma_mm: float | None = None
    healthy: bool = True


class RangeScan(Message):
    """One cycle over every configured ToF sensor."""

    cycle_start_s: float
    cycle_time_s: float
    readings: list[RangeReading]


class AnchorRange(Message):
    anchor_id: str
    x_mm: float
    y_mm: float
    z_mm: float
    distance_mm: float
    quality: int | None = None  # `lec` reports no per-anchor quality; the TLV API does


class UwbFix(Message):
    """A DWM1001 position estimate in the anchors' frame (which the floor plan shares)."""

    x_mm: float
    y_mm: float
    z_mm: float
    quality: int = Field(ge=0, le=100)
    anchors: list[AnchorRange] = []


class Odometry(Message):
    """Motor-controller telemetry: cumulative encoder ticks and the gyro's z rate."""

    controller_time_ms: int
    left_ticks: int
    right_ticks: int
    gyro_z_dps: float
    left_mm_s: float
    right_mm_s: float
    watchdog_tripped: bool = False


class MotorCommand(Message):
    """Wheel speeds for the motor controller. Only the motion module publishes this."""

    left_mm_s: float
    right_mm_s: float
    reason: str = ""
    brake: bool = False
    """A safety stop: the controller's active braking (its ``S`` line), not its gentler ramp
    towards a zero set-point. Only with both speeds 0."""

    @model_validator(mode="after")
    def _brake_means_standing(self) -> MotorCommand:
        if self.brake and (self.left_mm_s or self.right_mm_s):
            raise ValueError("a braking command must set both wheel speeds to 0")
        return self


# --- operator -----------------------------------------------------------------------------


class EStop(Message):
    engaged: bool
    source: str
    reason: str = ""


class SafetyState(StrEnum):
    STOP = "stop"
    SLOW = "slow"
    GO = "go"


class CollisionStatus(Message):
    """The collision module's verdict for one scan."""

    state: SafetyState
    scan_seq: int
    face: Literal["front", "left", "right", "rear"] | None = None
    sensor: int | None = None
    distance_mm: int | None = None
    reason: str = ""
    speed_limit_mm_s: float = 0.0
    blocked_faces: tuple[Literal["front", "left", "right", "rear"], ...] = ()
    """Faces with an obstacle inside their stop distance (not sensor faults)."""
    front_clearance_mm: int | None = None
    """Nearest front return, remembered ones included; None: nothing in range."""
    may_rotate: bool = False
    """A "stop" whose only cause is an obstacle on the front face, with no sensor fault,
    clear sides, and a front clearance no smaller than when the stop began: turning on the
    spot (zero forward speed) away from it is allowed. Everything else stays stopped."""
    may_creep_ahead: bool = False
    """A "stop" whose only cause is something within a side radius, with nothing in the way
    ahead and a side gap no smaller than when the hold began: creeping straight ahead
    (no turning, which would swing a corner into it) is allowed, the way out of a side hold."""


# --- orders and delivery ------------------------------------------------------------------


class OrderStatus(StrEnum):
    """The lifecycle a customer sees on their status page."""

    QUEUED = "queued"
    PREPARING = "preparing"
    ON_THE_WAY = "on_the_way"
    WAITING_FOR_ELEVATOR = "waiting_for_elevator"
    ARRIVED = "arrived"
    DELIVERED = "delivered"
    CANCELLED = "cancelled"
    FAILED = "failed"

    @property
    def final(self) -> bool:
        return self in (OrderStatus.DELIVERED, OrderStatus.CANCELLED, OrderStatus.FAILED)


class OrderDispatch(Message):
    """The orders module hands the head of the queue to navigation, one order at a time.

    No customer's name: everything on the board can be seen on the inspector."""

    order_id: str
    room: str
    drink: str


class DeliveryProblem(StrEnum):
    """What went wrong with a delivery, for code to act on (``detail`` says it to people)."""

    CUP_NOT_LOADED = "cup_not_loaded"
    NOT_PICKED_UP = "not_picked_up"
    UNKNOWN_ROOM = "unknown_room"
    LOST = "lost"
    """The robot does not know where it is."""
    BLOCKED = "blocked"
    ELEVATOR = "elevator"
    """The elevator does not answer, or the robot cannot confirm the floor it brought it to."""
    MOTION_SILENT = "motion_silent"
    MOTOR_CONTROLLER = "motor_controller"
    """The motor controller does not answer: the robot cannot drive until it does."""


class DeliveryUpdate(Message):
    """Navigation reports progress on the dispatched order; the orders module persists it."""

    order_id: str
    status: OrderStatus
    detail: str = ""
    ready_for_cup: bool = False
    """``preparing``, and the robot stands in the tea room ready for the cup: staff load it
    from now on (an order is dispatched while the robot may still be driving back)."""
    problem: DeliveryProblem | None = None
    """Set on a failure, and while the delivery is held (blocked, an unanswered elevator)."""


OperatorKind = Literal["cup_loaded", "pickup_confirmed", "cancel", "elevator_confirm"]


class OperatorEvent(Message):
    """A person acted: staff loaded the cup, the customer took it, an operator cancelled, or an
    operator confirmed the elevator step the robot waits for (the fallback when the elevator
    interface does not answer)."""

    kind: OperatorKind
    order_id: str
    source: str = "web"


# --- perception and state -----------------------------------------------------------------

Side = Literal["left", "right"]


class AngleEstimate(Message):
    """The robot's heading against the hallway, measured from one side's wall (or both).

    ``angle_deg`` is the seed's "angle": robot heading minus the hallway direction it travels
    along, positive counter-clockwise. ``correction_deg`` is what motion should turn: zero when
    the angle is below the seed's 5 degrees. ``heading_deg`` is the same measurement as an
    absolute heading in the floor plan's frame, which is what the state module fuses.
    """

    scan_seq: int
    zone: str
    side: Literal["left", "right", "both"]
    angle_deg: float
    correction_deg: float
    heading_deg: float
    confidence: float = Field(ge=0.0, le=1.0)
    sigma_deg: float = Field(gt=0.0)
    scans: int = Field(ge=1, description="scans averaged into this estimate")
    wall_distance_mm: dict[Side, float] = {}
    """Perpendicular distance from the body centre to each wall that was used."""


class DoorEvent(Message):
    """A door (or opening) seen by one side's sensors while passing it.

    ``side`` is the hallway's side (the floor plan's left/right looking from the hallway's
    start to its end), not the robot's.

    ``x_mm``/``y_mm`` is where the sensors put the door centre; when the door was matched to
    the floor plan, ``room`` names it, ``plan_x_mm``/``plan_y_mm`` is its planned centre and
    ``along_correction_mm`` is how far the robot's along-hallway position was off (add it in
    the direction of travel ``travel_heading_deg``).
    """

    scan_seq: int
    side: Side
    sensor: int
    kind: Literal["door", "opening"]
    floor: int
    x_mm: float
    y_mm: float
    jump_mm: float
    window: int = Field(ge=2, description="readings in the sliding window when it fired")
    travel_heading_deg: float
    room: str | None = None
    plan_x_mm: float | None = None
    plan_y_mm: float | None = None
    along_correction_mm: float | None = None
    arrived_at_target: bool = False


class MoveInstruction(Message):
    """What navigation wants motion to do now; motion reports progress on ``MOTION_STATUS``.

    ``id`` changes with every new instruction so motion knows a repeat from a new goal.
    ``follow_lane``: drive along ``hallway`` (None: the first) of ``floor`` to ``target_s_mm``
    (that hallway's along-hallway coordinate), ``lane_mm`` to the left of its axis (None:
    keep right at the configured wall distance); with ``target_door`` set (a door's id),
    the stop is refined by that door's detection. ``drive_to``: straight to
    ``x_mm``/``y_mm`` (through a doorway, into the elevator car). ``turn``: on the spot to
    ``heading_deg``. ``stop``/``wait``: stand still.
    ``stop``: False passes ``target_s_mm`` at speed (a lane change on the way), True stops
    there. ``avoid``: whether motion may leave the lane around a static obstacle.
    """

    id: int = 0
    action: Literal["stop", "wait", "follow_lane", "drive_to", "turn"]
    floor: int | None = None
    hallway: str | None = None
    target_s_mm: float | None = None
    lane_mm: float | None = None
    x_mm: float | None = None
    y_mm: float | None = None
    heading_deg: float | None = None
    speed_mm_s: float = 0.0
    stop: bool = True
    target_door: str | None = None
    avoid: bool = True
    detail: str = ""


class MotionState(StrEnum):
    IDLE = "idle"
    MOVING = "moving"
    AVOIDING = "avoiding"
    WAITING = "waiting"
    """Stopped for something in the way (a person, an unconfirmed obstacle)."""
    BLOCKED = "blocked"
    """Nothing admissible gets past; waiting for the way to clear."""
    SAFETY_STOP = "safety_stop"
    """Stopped by the safety gate: collision stop, stale or failed safety, e-stop."""
    DONE = "done"


class StopCause(StrEnum):
    """Why motion's safety gate holds the robot."""

    ESTOP = "estop"
    COLLISION_MODULE_DOWN = "collision_module_down"
    """The writer of the collision verdicts is failed, stopped or restarting."""
    NO_VERDICT = "no_verdict"
    STALE_VERDICT = "stale_verdict"
    COLLISION_STOP = "collision_stop"
    NO_FRESH_POSE = "no_fresh_pose"
    MOTOR_SILENT = "motor_silent"
    """No telemetry from the motor controller: hung, unplugged, or its driver is down."""
    SHUTTING_DOWN = "shutting_down"


class MotionStatus(Message):
    """Motion's progress on one instruction: navigation sequences its route on this."""

    instruction_id: int
    state: MotionState
    since_s: float = Field(0.0, ge=0, description="how long it has been in this state")
    remaining_mm: float | None = None
    detail: str = ""
    stopped_by: StopCause | None = None
    """Set while the safety gate holds the robot (``safety_stop``)."""
    detour_phase: Literal["confirming", "going_round", "rejoining"] | None = None
    """Set while lane keeping deals with something in its lane (the detour's phase)."""
    detour_lane_mm: float | None = None
    """The lane (``d``, mm left of the hallway axis) the detour holds, once it has one."""
    detour_until_s_mm: float | None = None
    """Along the hallway, how far the obstacle being gone round reaches."""


class RouteLeg(Message):
    """The part of a route on one floor, as points in the floor plan's frame (mm)."""

    floor: int
    points: list[tuple[float, float]]


class PlannedRoute(Message):
    """The route navigation drives now, for people to see (the live map, the customer's
    arrival estimate); empty ``legs`` once the robot is parked. One leg per floor in order,
    so every leg after the first is reached by an elevator ride."""

    order_id: str | None = None
    """The order the robot carries along it; None on the way back to base."""
    to: str
    """The room at its end."""
    legs: list[RouteLeg] = []


class ElevatorRequest(Message):
    """Navigation asks the elevator: call the car to ``floor``, send it there, or release it.
    ``car``: which (:attr:`~coffeebot.floorplan.FloorPlan.cars`; None: the first)."""

    action: Literal["call", "send", "release"]
    floor: int
    car: str | None = None


class ElevatorState(Message):
    """Where the car is and whether its doors are open, as the elevator interface knows it:
    the car last asked for (``car``; None: the first), the one the robot is using."""

    car: str | None = None
    car_floor: int | None
    doors: Literal["open", "closed", "moving"]
    moving: bool = False
    source: str = "elevator"


class PoseEstimate(Message):
    """One fused pose in the floor plan's frame with its 1-sigma uncertainty."""

    x_mm: float
    y_mm: float
    heading_deg: float
    floor: int
    sigma_x_mm: float = Field(ge=0.0)
    sigma_y_mm: float = Field(ge=0.0)
    sigma_heading_deg: float = Field(ge=0.0)
    cov_xy_mm2: float = 0.0
    """The x-y covariance: with the sigmas, the position's uncertainty ellipse."""
    speed_mm_s: float = 0.0
    yaw_rate_dps: float = 0.0
    initialised: bool = True
    particles: int | None = None
    """The particle filter's particle count (None: the Kalman filter)."""
    effective_sample_size: float | None = None
    """How many of those particles really carry the estimate (1 / sum of squared weights)."""


class ParticleCloud(Message):
    """A sample of the particle filter's particles, drawn by weight, for the live map."""

    floor: int
    x_mm: list[float]
    y_mm: list[float]
    heading_deg: list[float]


class CurrentState(Message):
    """The seed's "current state": the freshest of everything other modules need at once."""

    pose: PoseEstimate
    angle_from_line_deg: float | None = None
    """Heading against the hallway from the last angle estimate; None outside any zone."""
    move_instruction: MoveInstruction | None = None
    order_id: str | None = None
    delivery_status: OrderStatus | None = None
    last_door_room: str | None = None
    sources: dict[str, float] = {}
    """Age in seconds of each input the estimate used (uwb, odometry, angle, door)."""


class OrderUpdate(Message):
    """The orders module stored a change to an order; pages showing orders refresh from it.
    ``ready_for_cup`` and ``problem`` are navigation's, as reported (``DeliveryUpdate``)."""

    order_id: str
    status: OrderStatus
    detail: str = ""
    ready_for_cup: bool = False
    problem: DeliveryProblem | None = None


# --- fleet ------------------------------------------------------------------------------

SharedPlace = Literal["elevator", "loading_spot", "holding_point", "crossing", "landing"]


class LeaseNeed(Message):
    """Navigation needs a shared place to itself before it goes in (``want``), or is out of
    it again. Only in a fleet (``[fleet] broker``): a single robot has the places alone."""

    place: SharedPlace
    want: bool


class LeaseState(Message):
    """Which shared places this robot may go into now: the fleet bridge's word, from the
    dispatcher's grants (or its own, after ``[fleet] lease_wait_s`` without the broker)."""

    elevator: bool = False
    loading_spot: bool = False
    holding_point: bool = False
    crossing: bool = False
    landing: bool = False
    detail: str = ""

    def holds(self, place: SharedPlace) -> bool:
        held: bool = getattr(self, place)
        return held


class FleetRobot(Message):
    """One robot as the dispatcher knows it, for the fleet's map and operators."""

    robot: str
    online: bool
    stale: bool
    """Not heard of lately: drawn grey, with ``heard_ago_s``."""
    heard_ago_s: float | None = None
    floor: int | None = None
    x_mm: float | None = None
    y_mm: float | None = None
    heading_deg: float | None = None
    motion: MotionState | None = None
    safety: SafetyState | None = None
    health: HealthStatus | None = None
    unwell: list[str] = []
    order_id: str | None = None
    estop: bool = False


class FleetView(Message):
    """The dispatcher's view of its robots (published on its own board)."""

    robots: list[FleetRobot] = []
    broker: bool = False
    """Whether the dispatcher is connected to the broker."""


class OtherRobot(Message):
    """Another robot of the fleet where the dispatcher last heard it was."""

    robot: str
    floor: int
    x_mm: float
    y_mm: float
    heading_deg: float
    moving: bool
    """Driving (moving or going round something) when it reported: not standing."""
    reported_at_s: float
    """Its own wall clock when it reported, Unix seconds."""
    age_s: float = Field(ge=0)
    """How old the report was when the dispatcher sent this (the dispatcher's clock)."""


class Traffic(Message):
    """The fleet's other robots with a known pose, from the dispatcher about twice a
    second: motion keeps to the passing lane when one comes the other way in the hallway
    (:mod:`coffeebot.navigation.passing`). A single robot never gets any."""

    robots: list[OtherRobot] = []


# --- ceiling cameras (seed 003) ------------------------------------------------------------


class CameraFix(Message):
    """A ceiling camera's fix of this robot: a track matched to its odometry (seed 003, IV)
    gives its pose in the building. The pose is for the moment of publishing (the match's
    transform applied to the robot's latest odometry), so the state module fuses it as it
    comes, without looking back."""

    camera_id: str
    floor: int
    x_mm: float
    y_mm: float
    heading_deg: float
    sigma_mm: float = Field(gt=0.0)
    """1-sigma of the position, the same along both axes."""
    sigma_heading_deg: float = Field(gt=0.0)
    fit_error_mm: float = Field(ge=0.0)
    """The similarity fit's mean error (the seed's eq 7) over the waypoints it used."""
    points: int = Field(ge=1)
    """How many waypoints the fit used."""
    track_id: str


class CameraObject(Message):
    """Something a ceiling camera sees standing still that is not a robot (a cart, a box,
    a person waiting): the seed's "map update" (VI.B), on the floor plan's frame."""

    id: str
    """Its camera's track id: the same object keeps it while the camera follows it."""
    camera_id: str
    floor: int
    x_mm: float
    y_mm: float
    length_mm: float = Field(ge=0.0)
    width_mm: float = Field(ge=0.0)
    axis_deg: float
    """Direction of the long side, in [0, 180)."""
    standing_since_s: float
    """Board-clock time it was first seen standing."""
    seen_s: float
    """Board-clock time it was last seen; the layer drops it ``expiry_s`` after this."""


class CameraView(Message):
    """One ceiling camera as the map draws it: where it looks and whether it works."""

    camera_id: str
    floor: int
    corners_mm: list[tuple[float, float]]
    """Its field of view on the floor, four corners in order."""
    working: bool
    problem: str | None = None
    """Why it is not working, in plain words (no frames for 3 s, no stream)."""


class CameraLayer(Message):
    """The map's camera layer: every object the cameras saw standing, until it expires,
    and every camera's view. Published whenever it changes and at least once a second."""

    objects: list[CameraObject] = []
    cameras: list[CameraView] = []
    expiry_s: float = Field(gt=0.0)
    """How long an object stays on the layer after it was last seen."""


HEALTH = Topic("system/health", Health, Delivery.RELIABLE, queue_size=1024)
RANGE_SCAN = Topic("tof/scan", RangeScan, Delivery.LATEST)
UWB_FIX = Topic("uwb/fix", UwbFix, Delivery.LATEST)
ODOMETRY = Topic("motor/odometry", Odometry, Delivery.RELIABLE, queue_size=512)
MOTOR_COMMAND = Topic("motor/command", MotorCommand, Delivery.LATEST)
ESTOP = Topic("operator/estop", EStop, Delivery.RELIABLE)
COLLISION = Topic("safety/collision", CollisionStatus, Delivery.LATEST)
ORDER_DISPATCH = Topic("orders/dispatch", OrderDispatch, Delivery.RELIABLE)
DELIVERY_STATUS = Topic("delivery/status", DeliveryUpdate, Delivery.RELIABLE)
OPERATOR_EVENT = Topic("operator/event", OperatorEvent, Delivery.RELIABLE)
ANGLE = Topic("perception/angle", AngleEstimate, Delivery.LATEST)
DOOR = Topic("perception/door", DoorEvent, Delivery.RELIABLE)
MOVE_INSTRUCTION = Topic("nav/instruction", MoveInstruction, Delivery.LATEST)
CURRENT_STATE = Topic("state/current", CurrentState, Delivery.LATEST)
PARTICLES = Topic("state/particles", ParticleCloud, Delivery.LATEST)
ORDER_UPDATE = Topic("orders/update", OrderUpdate, Delivery.RELIABLE)
MOTION_STATUS = Topic("motion/status", MotionStatus, Delivery.LATEST)
ROUTE = Topic("nav/route", PlannedRoute, Delivery.LATEST)
ELEVATOR_REQUEST = Topic("elevator/request", ElevatorRequest, Delivery.RELIABLE)
ELEVATOR_STATE = Topic("elevator/state", ElevatorState, Delivery.LATEST)
LEASE_NEED = Topic("fleet/lease_need", LeaseNeed, Delivery.RELIABLE)
LEASE_STATE = Topic("fleet/leases", LeaseState, Delivery.LATEST)
FLEET = Topic("fleet/robots", FleetView, Delivery.LATEST)
TRAFFIC = Topic("fleet/traffic", Traffic, Delivery.LATEST)
CAMERA_FIX = Topic("cameras/fix", CameraFix, Delivery.RELIABLE)
CAMERA_LAYER = Topic("cameras/layer", CameraLayer, Delivery.LATEST)

ALL_TOPICS: tuple[Topic[Any], ...] = (
    HEALTH,
    RANGE_SCAN,
    UWB_FIX,
    ODOMETRY,
    MOTOR_COMMAND,
    ESTOP,
    COLLISION,
    ORDER_DISPATCH,
    DELIVERY_STATUS,
    OPERATOR_EVENT,
    ANGLE,
    DOOR,
    MOVE_INSTRUCTION,
    CURRENT_STATE,
    PARTICLES,
    ORDER_UPDATE,
    MOTION_STATUS,
    ROUTE,
    ELEVATOR_REQUEST,
    ELEVATOR_STATE,
    LEASE_NEED,
    LEASE_STATE,
    FLEET,
    TRAFFIC,
    CAMERA_FIX,
    CAMERA_LAYER,
)
