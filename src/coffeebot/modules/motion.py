"""Motion module: the only writer of motor commands, and every command passes the safety gate.

Each control period (and at once on every new collision verdict) it runs the
:class:`~coffeebot.navigation.motion.MotionController` on the latest instruction and pose,
then gates the result on the freshest safety state. The robot stops when any of these holds:
no collision verdict yet, a verdict older than ``stale_safety_s``, a "stop" verdict, the
e-stop engaged, the collision module reported failed (or stopped, or restarting), no pose
fresher than ``stale_pose_s``, or no motor telemetry within ``[motor] telemetry_timeout_s``
(a silent controller obeys nothing, and its wheels' state is unknown). A "slow" verdict
caps the speed at its limit, and so does a slow zone at an opening of the floor plan
(:mod:`coffeebot.navigation.openings`: someone may step out of a side hallway unseen). A
front "stop" that the verdict marks ``may_rotate`` (sides clear, nothing coming closer)
still lets the robot turn on the spot, so a turn into a door or away from a box is not
frozen half-way, and a turn is all it gets: the forward speed stays zero. On shutdown it
sends a stop before anything is cancelled; if it crashes it sends a stop on the way out, the
motor driver replaces a silent motion module's command by a stop, and the controller's own
watchdog stops the wheels if everything above it is gone.

What the ceiling cameras see standing (``cameras/layer``) goes into the costmap as a layer of
its own, so the detour picks its side before the sensors see the thing; it only ever adds
obstacles to plan round, and the safety gate knows nothing of it.
"""

from __future__ import annotations

import asyncio
import contextlib
import math
from dataclasses import dataclass

from coffeebot.board import Envelope
from coffeebot.config import RobotConfig
from coffeebot.floorplan import FloorPlan
from coffeebot.messages import (
    CAMERA_LAYER,
    COLLISION,
    CURRENT_STATE,
    ESTOP,
    HEALTH,
    MOTION_STATUS,
    MOTOR_COMMAND,
    MOVE_INSTRUCTION,
    ODOMETRY,
    RANGE_SCAN,
    TRAFFIC,
    CollisionStatus,
    EStop,
    HealthStatus,
    MotionState,
    MotionStatus,
    MotorCommand,
    PoseEstimate,
    SafetyState,
    StopCause,
)
from coffeebot.modules.base import Module, ModuleBoard, ModuleContext
from coffeebot.navigation.camera_blocks import camera_marks
from coffeebot.navigation.control import wheel_speeds
from coffeebot.navigation.costmap import Footprint, LocalCostmap
from coffeebot.navigation.motion import MotionController
from coffeebot.navigation.openings import OpeningZones, ZoneLimit

MIN_TURN_DPS = 1.0
"""Below this a turn on the spot under a front stop is not worth sending: stand still."""
BRAKE_BEFORE_TURN_MM_S = 50.0
"""A robot held by something ahead while still rolling faster than this brakes to a stand
before it may turn on the spot: a turn command would only ramp the wheels down."""
UNSAFE_HEALTH = (HealthStatus.FAILED, HealthStatus.STOPPED, HealthStatus.RESTARTING)


@dataclass(frozen=True)
class Gate:
    """The safety gate's verdict: how fast the robot may go now (0: stop) and why."""

    speed_limit_mm_s: float
    reason: str
    cause: StopCause | None = None
    """Why it stops the robot; None when it lets the robot go (at a limit, or clear)."""
    may_rotate: bool = False
    """A front stop that still allows turning on the spot (the collision verdict's call)."""
    may_creep_ahead: bool = False
    """A side hold that still allows creeping straight ahead (the collision verdict's call)."""

    @property
    def stop(self) -> bool:
        return self.speed_limit_mm_s <= 0.0


def safety_gate(
    collision: Envelope[CollisionStatus] | None,
    collision_age_s: float | None,
    estop: EStop | None,
    collision_health: HealthStatus | None,
    stale_after_s: float,
) -> Gate:
    """Stop on any doubt; otherwise the verdict's speed limit."""
    if estop is not None and estop.engaged:
        return Gate(0.0, f"e-stop engaged by {estop.source}", StopCause.ESTOP)
    if collision_health in UNSAFE_HEALTH:
        return Gate(
            0.0, f"collision module {collision_health.value}", StopCause.COLLISION_MODULE_DOWN
        )
    if collision is None or collision_age_s is None:
        return Gate(0.0, "no collision verdict yet", StopCause.NO_VERDICT)
    if collision_age_s > stale_after_s:
        return Gate(0.0, f"collision verdict {collision_age_s:.2f} s old", StopCause.STALE_VERDICT)
    verdict = collision.msg
    if verdict.state is SafetyState.STOP:
        return Gate(
            0.0,
            f"collision stop: {verdict.reason}",
            StopCause.COLLISION_STOP,
            may_rotate=verdict.may_rotate,
            may_creep_ahead=verdict.may_creep_ahead,
        )
    if verdict.state is SafetyState.SLOW:
        return Gate(verdict.speed_limit_mm_s, f"slow: {verdict.reason}")
    return Gate(verdict.speed_limit_mm_s or float("inf"), "clear")


class MotionModule(Module):
    name = "motion"
    inputs = (
        MOVE_INSTRUCTION,
        CURRENT_STATE,
        COLLISION,
        ESTOP,
        HEALTH,
        RANGE_SCAN,
        ODOMETRY,
        TRAFFIC,
        CAMERA_LAYER,
    )
    outputs = (MOTOR_COMMAND, MOTION_STATUS)
    shutdown_order = 0  # with the motor driver: first to stop
    critical = True

    def __init__(self, config: RobotConfig, plan: FloorPlan) -> None:
        self.config = config
        self.cfg = config.motion
        self.plan = plan
        self.footprint = Footprint(
            config.geometry.length_mm,
            config.geometry.width_mm,
            # Keep the collision module's front stop distance free, so going round never
            # trips it: its radius, the narrow-return margin (a box corner is narrow) and
            # the hysteresis, less the clearance kept anyway.
            front_extra_mm=max(
                0.0,
                config.collision.front_radius_mm
                + config.collision.narrow_margin_mm
                + config.collision.hysteresis_mm
                - config.motion.obstacle_clearance_mm,
            ),
            axle_x_mm=config.motor.axle_x_mm,
        )
        self.costmap = LocalCostmap(
            self.cfg,
            config.tof.sensors,
            self.footprint,
            config.tof.cone_half_deg,
            narrow=config.collision,
        )
        self.controller = MotionController(self.cfg, plan, self.costmap, self.footprint)
        self.zones = OpeningZones(
            config.openings,
            config.collision,
            config.tof.sensors,
            config.geometry.width_mm,
            config.geometry.length_mm,
        )
        self.collision_health: HealthStatus | None = None
        self._board: ModuleBoard | None = None
        self._stopping = False
        self._last_state: MotionState | None = None

    def _stop(self, board: ModuleBoard, reason: str) -> None:
        """Stand still, braking actively: every stop here is one the safety gate (or the
        module's start and end) calls for, never the end of a profile."""
        board.publish(
            MOTOR_COMMAND, MotorCommand(left_mm_s=0.0, right_mm_s=0.0, reason=reason, brake=True)
        )

    async def _watch_health(self, ctx: ModuleContext) -> None:
        with ctx.board.subscribe(HEALTH) as reports:
            async for envelope in reports:
                health = envelope.msg
                if COLLISION.name in health.publishes and health.component is None:
                    self.collision_health = health.status

    async def _map(self, ctx: ModuleContext) -> None:
        """Every scan into the costmap, placed with the freshest pose."""
        with ctx.board.subscribe(RANGE_SCAN) as scans:
            async for envelope in scans:
                state = ctx.board.latest(CURRENT_STATE)
                if state is None or not state.msg.pose.initialised:
                    continue
                pose = state.msg.pose
                self.costmap.update(
                    envelope.msg,
                    self.plan.floor(pose.floor),
                    pose.x_mm,
                    pose.y_mm,
                    pose.heading_deg,
                    ctx.clock.now(),
                    heading_error_deg=self.cfg.clear_heading_sigmas * pose.sigma_heading_deg
                    + abs(pose.yaw_rate_dps) * self.cfg.pose_lag_s,
                    robots=self.controller.standing_robots(pose.floor, ctx.clock.now()),
                )

    async def _watch_traffic(self, ctx: ModuleContext) -> None:
        """The fleet's other robots, for the passing lane (a single robot gets none)."""
        with ctx.board.subscribe(TRAFFIC) as traffic:
            async for envelope in traffic:
                self.controller.note_traffic(envelope.msg, ctx.clock.now())

    async def _watch_cameras(self, ctx: ModuleContext) -> None:
        """What the ceiling cameras see standing, into the costmap's camera layer until the
        layer goes stale (a robot without cameras gets none)."""
        stale_s = self.config.navigation.camera_stale_s
        spacing = self.cfg.costmap_resolution_mm / 2
        with ctx.board.subscribe(CAMERA_LAYER) as layers:
            async for envelope in layers:
                marks = camera_marks(envelope.msg.objects, spacing)
                self.costmap.mark_camera(marks, envelope.stamp + stale_s)

    def gate(self, ctx: ModuleContext) -> Gate:
        """The safety gate from the freshest state on the board: made once per command."""
        if self._stopping:
            return Gate(0.0, "shutting down", StopCause.SHUTTING_DOWN)
        estop = ctx.board.latest(ESTOP)
        gate = safety_gate(
            ctx.board.latest(COLLISION),
            ctx.board.age(COLLISION),
            None if estop is None else estop.msg,
            self.collision_health,
            self.cfg.stale_safety_s,
        )
        if gate.cause is not StopCause.ESTOP:
            telemetry_age = ctx.board.age(ODOMETRY)
            if telemetry_age is None or telemetry_age > self.config.motor.telemetry_timeout_s:
                since = "yet" if telemetry_age is None else f"for {telemetry_age:.1f} s"
                return Gate(
                    0.0, f"no telemetry from the motor controller {since}", StopCause.MOTOR_SILENT
                )
        state, age = ctx.board.latest(CURRENT_STATE), ctx.board.age(CURRENT_STATE)
        if (not gate.stop or gate.may_rotate or gate.may_creep_ahead) and (
            state is None
            or age is None
            or age > self.cfg.stale_pose_s
            or not state.msg.pose.initialised
        ):
            return Gate(0.0, "no fresh pose", StopCause.NO_FRESH_POSE)
        return gate

    def control(self, ctx: ModuleContext, dt: float, gate: Gate) -> None:
        """One period under ``gate``: plan, publish the command and the status."""
        now = ctx.clock.now()
        instruction = ctx.board.latest(MOVE_INSTRUCTION)
        ins = None if instruction is None else instruction.msg
        state = ctx.board.latest(CURRENT_STATE)
        rolling = state is not None and abs(state.msg.pose.speed_mm_s) > BRAKE_BEFORE_TURN_MM_S
        if (
            gate.cause is StopCause.COLLISION_STOP
            and gate.may_rotate
            and state is not None
            and not rolling
        ):
            # Held by something ahead, but turning on the spot is allowed: the turn the
            # controller wants (into a door, away from a jamb, round a box) may clear it.
            command = self.controller.step(ins, state.msg.pose, now, dt, 0.0)
            if abs(command.yaw_rate_dps) >= MIN_TURN_DPS:
                reason = f"turning on the spot; {gate.reason}"
                status = self.controller.safety_status(
                    command.status.instruction_id, now, reason, gate.cause
                )
                self._send(ctx, 0.0, command.yaw_rate_dps, reason, status)
                return
            if command.status.state is MotionState.BLOCKED:
                # Held, and no turn or lane gets past: say so, so navigation can act on it.
                reason = f"{command.status.detail}; {gate.reason}"
                status = command.status.model_copy(update={"detail": reason})
                self.controller.halt()
                self._send(ctx, 0.0, 0.0, reason, status)
                return
        if gate.stop and gate.may_creep_ahead and state is not None and ins is not None:
            # Held by something beside the body, nothing ahead: straight on keeps the gap.
            limit = self.config.collision.creep_ahead_mm_s
            command = self.controller.step(ins, state.msg.pose, now, dt, limit)
            if command.speed_mm_s > 0:
                reason = f"creeping straight ahead; {gate.reason}"
                status = self.controller.safety_status(
                    command.status.instruction_id, now, reason, gate.cause
                )
                self._send(ctx, command.speed_mm_s, 0.0, reason, status)
                return
        if gate.stop or state is None:
            self.controller.halt()
            self._stop(ctx.board, gate.reason)
            self._publish_status(
                ctx,
                self.controller.safety_status(
                    -1 if ins is None else ins.id, now, gate.reason, gate.cause
                ),
            )
            return
        limit = min(gate.speed_limit_mm_s, self.cfg.max_speed_mm_s)
        zone = self.zone(state.msg.pose, limit, None if ins is None else ins.hallway)
        if zone is not None:
            limit = zone.speed_mm_s
        command = self.controller.step(ins, state.msg.pose, now, dt, limit)
        reason = command.status.state.value
        if gate.speed_limit_mm_s < self.cfg.cruise_speed_mm_s:
            reason = f"{reason}; {gate.reason}"
        if zone is not None:
            reason = f"{reason}; slow: {zone.reason}"
        self._send(ctx, command.speed_mm_s, command.yaw_rate_dps, reason, command.status)

    def zone(
        self, pose: PoseEstimate, limit_mm_s: float, hallway: str | None = None
    ) -> ZoneLimit | None:
        """The slow zone of an opening that caps the speed below ``limit_mm_s`` here, if any:
        the robot taken to drive along ``hallway`` (its instruction's; None: the one it
        stands in) the way it faces. Where hallways meet, the one it stands in may be the
        one it is turning out of, whose side hallway it is driving into."""
        floor = self.plan.floor(pose.floor)
        floor = floor.view_near(pose.x_mm, pose.y_mm) if hallway is None else floor.view(hallway)
        s, d = floor.to_hallway(pose.x_mm, pose.y_mm)
        facing = math.cos(math.radians(pose.heading_deg - floor.hallway.heading_deg))
        return self.zones.limit(floor, s, d, 1.0 if facing >= 0 else -1.0, limit_mm_s)

    def _send(
        self,
        ctx: ModuleContext,
        speed_mm_s: float,
        yaw_rate_dps: float,
        reason: str,
        status: MotionStatus,
    ) -> None:
        """One motor command (with the reason it was allowed) and the status that goes with it."""
        left, right = wheel_speeds(speed_mm_s, yaw_rate_dps, self.config.motor.wheel_base_mm)
        ctx.board.publish(
            MOTOR_COMMAND, MotorCommand(left_mm_s=left, right_mm_s=right, reason=reason)
        )
        self._publish_status(ctx, status)

    def _publish_status(self, ctx: ModuleContext, status: MotionStatus) -> None:
        """The status on the board; a change of state in the log too (INFO), with its detail
        and where the robot believed it was, so a run's log says when, where and why the robot
        waited, went round or was held."""
        if status.state is not self._last_state:
            state = ctx.board.latest(CURRENT_STATE)
            where = {}
            if state is not None and state.msg.pose.initialised:
                pose = state.msg.pose
                where = {
                    "floor": pose.floor,
                    "x_mm": round(pose.x_mm),
                    "y_mm": round(pose.y_mm),
                    "heading_deg": round(pose.heading_deg),
                }
            ctx.log.info(
                "motion %s -> %s: %s",
                "start" if self._last_state is None else self._last_state.value,
                status.state.value,
                status.detail,
                extra=where,
            )
            self._last_state = status.state
        ctx.board.publish(MOTION_STATUS, self._with_detour(status))

    def _with_detour(self, status: MotionStatus) -> MotionStatus:
        """The status with the detour lane keeping is on, if any, for people to see."""
        planner = self.controller.detour
        detour = planner.detour
        if detour is None:
            return status
        return status.model_copy(
            update={
                "detour_phase": detour.phase.value,
                "detour_lane_mm": detour.lane_mm,
                "detour_until_s_mm": detour.extent_s_mm,
            }
        )

    async def run(self, ctx: ModuleContext) -> None:
        self._board = ctx.board
        self.controller.halt()
        self._stop(ctx.board, "motion starting")
        try:
            async with asyncio.TaskGroup() as group:
                group.create_task(self._watch_health(ctx))
                group.create_task(self._map(ctx))
                group.create_task(self._watch_traffic(ctx))
                group.create_task(self._watch_cameras(ctx))
                group.create_task(self._loop(ctx))
        finally:
            # A crash or a cancel: the last word to the motors is "stop".
            self.controller.halt()
            self._stop(ctx.board, "motion stopped")

    async def _loop(self, ctx: ModuleContext) -> None:
        """Plan once per period; a new verdict in between is only gated, which is cheap, so
        a stop reaches the motors in the loop turn the scan arrived in."""
        last = ctx.clock.now()
        while True:
            with contextlib.suppress(TimeoutError):
                await ctx.board.next(COLLISION, timeout=self.cfg.period_s)
            now = ctx.clock.now()
            gate = self.gate(ctx)
            if now - last >= self.cfg.period_s or gate.stop:
                self.control(ctx, max(0.0, now - last), gate)
                last = now

    async def shutdown(self) -> None:
        """Stop the motors before the daemon cancels anything."""
        self._stopping = True
        if self._board is not None:
            self.controller.halt()
            self._stop(self._board, "shutdown")
