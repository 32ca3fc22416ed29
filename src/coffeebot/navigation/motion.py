"""What motion does with one instruction, one control period at a time (no I/O).

``follow_lane`` holds the lane with the speed profile until the lane ahead holds an obstacle
on the costmap. Then: while the obstacle has not stood still for ``static_confirm_s`` (a
person walking, or something just seen) the robot stops short of it and waits; once it is
static, and the instruction allows it, the Dynamic Window Approach takes over until the lane
ahead is clear again and the robot is back near its lane; if no arc gets past, the robot is
blocked and waits for the way to clear. ``drive_to`` turns towards a point, then drives to
it on a held heading. ``turn`` turns on the spot. The safety gate sits outside this class,
in the module, and overrides it.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from coffeebot.config import MotionConfig
from coffeebot.floorplan import Floor, FloorPlan
from coffeebot.messages import MotionState, MotionStatus, MoveInstruction, PoseEstimate
from coffeebot.navigation.control import (
    SpeedProfile,
    lane_heading_deg,
    ramp,
    turn_rate_dps,
)
from coffeebot.navigation.costmap import Footprint, LocalCostmap
from coffeebot.navigation.dwa import DynamicWindow, rollout
from coffeebot.perception.geometry import wrap_deg

AIM_BEFORE_DRIVING_DEG = 10.0
"""``drive_to`` turns on the spot until the point is within this of straight ahead."""

AIM_BEFORE_LANE_DEG = 45.0
"""``follow_lane`` facing further than this from the direction of travel turns on the spot."""

DETOUR_TURNS_DEG = tuple(45.0 - 2.5 * k for k in range(17))
"""Blocked close to an obstacle, the robot first turns on the spot this far from its
direction of travel towards the detour lane (the furthest of these the walls allow: the rear
swings out about the axle), from where the dynamic window finds arcs past it."""

TURN_CHECK_STEPS = 7
"""Headings checked along a turn on the spot before it is made."""

REJOIN_MM = 100.0
"""After going round, the dynamic window steers back to the lane until the robot is this
close to it; lane keeping turns at up to ``max_lane_angle_deg`` without looking at the walls,
and from a detour lane beside the far wall that swings the rear corner into it."""

WAIT_ROOM_MM = 200.0
"""Room left beyond the planner's lethal zone where the robot waits in front of an obstacle,
so the dynamic window can still turn away from it."""


@dataclass(frozen=True)
class Command:
    speed_mm_s: float
    yaw_rate_dps: float
    status: MotionStatus


class MotionController:
    """Turns the current instruction and pose into a speed and a yaw rate."""

    def __init__(
        self, cfg: MotionConfig, plan: FloorPlan, costmap: LocalCostmap, footprint: Footprint
    ) -> None:
        self.cfg = cfg
        self.plan = plan
        self.costmap = costmap
        self.footprint = footprint
        self.profile = SpeedProfile.from_config(cfg)
        self.dwa = DynamicWindow(cfg, footprint.axle_x_mm)
        self.speed = 0.0
        self.yaw_rate = 0.0
        self._instruction_id: int | None = None
        self._direction = 1.0
        self._state = MotionState.IDLE
        self._since = 0.0
        self._detour: float | None = None
        self._past: float | None = None
        """Going round: the furthest along-hallway position of the obstacle seen so far."""
        self._rejoining = False
        """Past the obstacle, the dynamic window is steering back to the lane."""
        self._line: float | None = None
        """``drive_to``: the direction of the line being followed, fixed at its start."""

    def halt(self) -> None:
        """The safety gate stopped the motors: plan from standstill when it lets go."""
        self.speed = 0.0
        self.yaw_rate = 0.0

    def safety_status(self, instruction_id: int, now: float, reason: str) -> MotionStatus:
        """The status while the safety gate holds the robot."""
        return self._status(instruction_id, MotionState.SAFETY_STOP, now, None, reason)

    def _status(
        self,
        instruction_id: int,
        state: MotionState,
        now: float,
        remaining: float | None,
        detail: str,
    ) -> MotionStatus:
        if state is not self._state:
            self._state, self._since = state, now
        return MotionStatus(
            instruction_id=instruction_id,
            state=state,
            since_s=max(0.0, now - self._since),
            remaining_mm=remaining,
            detail=detail,
        )

    def _command(
        self,
        target_speed: float,
        target_rate: float,
        dt: float,
        status: MotionStatus,
        speed_limit: float,
    ) -> Command:
        target_speed = min(target_speed, speed_limit)
        self.speed = max(0.0, self.profile.step(self.speed, target_speed, dt))
        self.speed = min(self.speed, speed_limit)
        self.yaw_rate = ramp(self.yaw_rate, target_rate, self.cfg.turn_accel_dps2 * dt)
        return Command(self.speed, self.yaw_rate, status)

    def step(
        self,
        instruction: MoveInstruction | None,
        pose: PoseEstimate,
        now: float,
        dt: float,
        speed_limit: float,
    ) -> Command:
        """One control period: ``speed_limit`` is what the collision verdict allows."""
        if instruction is None or instruction.action in ("stop", "wait"):
            ident = -1 if instruction is None else instruction.id
            status = self._status(ident, MotionState.IDLE, now, None, "standing")
            return self._command(0.0, 0.0, dt, status, speed_limit)
        if instruction.id != self._instruction_id:
            self._instruction_id = instruction.id
            self._detour = self._past = None
            self._rejoining = False
            self._line = None
            self._state = MotionState.MOVING
            self._since = now
            if instruction.target_s_mm is not None and instruction.floor == pose.floor:
                s = self.plan.floor(pose.floor).to_hallway(pose.x_mm, pose.y_mm)[0]
                self._direction = 1.0 if instruction.target_s_mm >= s else -1.0
        if instruction.floor is not None and instruction.floor != pose.floor:
            status = self._status(
                instruction.id,
                MotionState.WAITING,
                now,
                None,
                f"on floor {pose.floor}, instruction is for floor {instruction.floor}",
            )
            return self._command(0.0, 0.0, dt, status, speed_limit)
        floor = self.plan.floor(pose.floor)
        if instruction.action == "turn":
            return self._turn(instruction, pose, now, dt, speed_limit)
        if instruction.action == "drive_to":
            return self._drive_to(instruction, pose, now, dt, speed_limit)
        return self._follow_lane(instruction, floor, pose, now, dt, speed_limit)

    # --- actions ---------------------------------------------------------------------------

    def _turn(
        self, ins: MoveInstruction, pose: PoseEstimate, now: float, dt: float, limit: float
    ) -> Command:
        wanted = ins.heading_deg if ins.heading_deg is not None else pose.heading_deg
        error = wrap_deg(wanted - pose.heading_deg)
        if abs(error) <= self.cfg.heading_tolerance_deg:
            status = self._status(ins.id, MotionState.DONE, now, 0.0, "turned")
            return self._command(0.0, 0.0, dt, status, limit)
        status = self._status(ins.id, MotionState.MOVING, now, None, f"turning, {error:.0f} deg")
        return self._command(0.0, self._turn_rate(pose.heading_deg, wanted), dt, status, limit)

    def _turn_rate(self, heading: float, wanted: float) -> float:
        """Heading hold, but slow enough at the end of a turn to stop within the tolerance."""
        rate = turn_rate_dps(heading, wanted, self.cfg)
        error = abs(wrap_deg(wanted - heading))
        brake = math.sqrt(2.0 * self.cfg.turn_accel_dps2 * max(0.0, error - 1.0))
        return max(-brake, min(brake, rate))

    def _drive_to(
        self, ins: MoveInstruction, pose: PoseEstimate, now: float, dt: float, limit: float
    ) -> Command:
        """Aim at the point, then follow the straight line from where the robot started to
        it (a bearing alone swings wildly as the point comes close)."""
        assert ins.x_mm is not None and ins.y_mm is not None
        if self._line is None:
            self._line = math.degrees(math.atan2(ins.y_mm - pose.y_mm, ins.x_mm - pose.x_mm))
        line = math.radians(self._line)
        ux, uy = math.cos(line), math.sin(line)
        dx, dy = ins.x_mm - pose.x_mm, ins.y_mm - pose.y_mm
        remaining = dx * ux + dy * uy
        left_of_line = dy * ux - dx * uy  # how far the line lies to the robot's left
        if remaining <= self.profile.stop_band_mm:
            status = self._status(ins.id, MotionState.DONE, now, remaining, "at the point")
            return self._command(0.0, 0.0, dt, status, limit)
        status = self._status(ins.id, MotionState.MOVING, now, remaining, ins.detail)
        error = wrap_deg(self._line - pose.heading_deg)
        if abs(error) > AIM_BEFORE_DRIVING_DEG and self.speed < self.cfg.creep_speed_mm_s:
            rate = self._turn_rate(pose.heading_deg, self._line)
            return self._command(0.0, rate, dt, status, limit)
        target = self.profile.target(remaining, ins.speed_mm_s or self.cfg.approach_speed_mm_s)
        heading = lane_heading_deg(self._line, left_of_line, self.cfg)
        rate = turn_rate_dps(pose.heading_deg, heading, self.cfg)
        return self._command(target, rate, dt, status, limit)

    def _follow_lane(
        self,
        ins: MoveInstruction,
        floor: Floor,
        pose: PoseEstimate,
        now: float,
        dt: float,
        limit: float,
    ) -> Command:
        assert ins.target_s_mm is not None
        cfg = self.cfg
        s, d = floor.to_hallway(pose.x_mm, pose.y_mm)
        direction = self._direction
        lane = ins.lane_mm if ins.lane_mm is not None else d
        remaining = (ins.target_s_mm - s) * direction
        travel = floor.hallway.heading_deg + (0.0 if direction > 0 else 180.0)
        if ins.stop and remaining <= self.profile.stop_band_mm:
            detail = (
                "at the target"
                if remaining >= -cfg.stop_tolerance_mm
                else (f"overshot by {-remaining:.0f} mm")
            )
            status = self._status(ins.id, MotionState.DONE, now, remaining, detail)
            return self._command(0.0, 0.0, dt, status, limit)
        if not ins.stop and remaining <= 0:
            status = self._status(ins.id, MotionState.DONE, now, remaining, "passed the point")
        else:
            status = self._status(ins.id, MotionState.MOVING, now, remaining, ins.detail)
        if (
            abs(wrap_deg(travel - pose.heading_deg)) > AIM_BEFORE_LANE_DEG
            and self.speed < cfg.creep_speed_mm_s
        ):
            status = self._status(
                ins.id, MotionState.MOVING, now, remaining, "turning into the lane"
            )
            return self._command(0.0, self._turn_rate(pose.heading_deg, travel), dt, status, limit)
        cruise = ins.speed_mm_s or cfg.cruise_speed_mm_s
        approach = cfg.approach_mm if ins.target_room is not None else 0.0
        target = self.profile.target(
            remaining,
            cruise,
            stop=ins.stop,
            approach_mm=approach,
            approach_mm_s=cfg.approach_speed_mm_s,
        )
        ahead = self._obstacle_ahead(floor, s, lane, direction, now)
        if ahead is not None:
            obstacle_s, static = ahead
            if self._rejoining:  # something new in the lane: judged afresh
                self._detour, self._rejoining = None, False
            if static and ins.avoid:
                # Chosen from what is seen of the obstacle, and moved out (to the nearest lane
                # still free) when more of it shows up while going round and stands still
                # (a long cart is seen bit by bit; a noisy reading comes and goes).
                wanted = lane if self._detour is None else self._detour
                settled = self._detour is not None
                free = self._detour_lane(floor, obstacle_s, wanted, direction, now, settled)
                if free is not None:
                    self._detour = free
            if self._detour is not None:
                far = obstacle_s + direction * cfg.static_tolerance_mm
                if self._past is None or (far - self._past) * direction > 0:
                    self._past = far
            if self._detour is None:
                gap = (obstacle_s - s) * direction - self._wait_distance()
                target = min(target, self.profile.target(gap, cruise))
                if not static:
                    why = "something moving ahead, waiting"
                elif ins.avoid:
                    why = "no way past the obstacle ahead, waiting"
                else:
                    why = "obstacle ahead and not allowed to leave the lane, waiting"
                state = MotionState.WAITING
                if static and ins.avoid:
                    state = MotionState.BLOCKED
                if target > 0:
                    state = MotionState.MOVING
                status = self._status(ins.id, state, now, remaining, why)
        elif self._detour is not None and self._passed(s, direction):
            # Past it and the lane ahead is clear: the dynamic window steers back to the lane,
            # checking the rear's swing against the walls, until lane keeping can take over.
            self._past = None
            self._rejoining = abs(lane - d) > REJOIN_MM
            self._detour = lane if self._rejoining else None
        if self._detour is not None:
            # Hold the detour lane until the body is past everything seen of the obstacle.
            return self._avoid(
                ins, floor, pose, self._detour, direction, target, now, dt, limit, remaining
            )
        heading = lane_heading_deg(travel, (lane - d) * direction, cfg)
        return self._command(
            target, turn_rate_dps(pose.heading_deg, heading, cfg), dt, status, limit
        )

    def _passed(self, s: float, direction: float) -> bool:
        """The body's rear is beyond the furthest obstacle cell seen while going round."""
        if self._past is None:
            return True
        rear = s - direction * (self.footprint.length_mm / 2 + self.cfg.obstacle_clearance_mm)
        return (rear - self._past) * direction > 0

    def _detour_lane(
        self,
        floor: Floor,
        obstacle_s: float,
        lane: float,
        direction: float,
        now: float,
        settled: bool = False,
    ) -> float | None:
        """The lane nearest to ``lane`` whose corridor past the obstacle is free, if any;
        ``settled``: of the cells that have stood still for ``static_confirm_s``."""
        cfg = self.cfg
        xs, ys, since = self.costmap.obstacles(now)
        if settled:
            keep = since <= now - cfg.static_confirm_s
            xs, ys = xs[keep], ys[keep]
        sd = np.array([floor.to_hallway(x, y) for x, y in zip(xs, ys, strict=True)]).reshape(-1, 2)
        along = (sd[:, 0] - obstacle_s) * direction
        near = sd[(along > -self.footprint.length_mm) & (along < cfg.lookahead_mm), 1]
        half_body = self.footprint.width_mm / 2
        reach = floor.hallway.width_mm / 2 - half_body - cfg.side_clearance_mm
        clearance = half_body + cfg.obstacle_clearance_mm + cfg.costmap_resolution_mm
        step = cfg.costmap_resolution_mm
        offsets = sorted(np.arange(-reach, reach + 1.0, step), key=lambda d: abs(d - lane))
        for d in offsets:
            if not np.any(np.abs(near - d) < clearance):
                return float(d)
        return None

    def _avoid(
        self,
        ins: MoveInstruction,
        floor: Floor,
        pose: PoseEstimate,
        lane: float,
        direction: float,
        target: float,
        now: float,
        dt: float,
        limit: float,
        remaining: float,
    ) -> Command:
        cap = min(target, self.cfg.approach_speed_mm_s, limit)
        if limit <= 0.0:
            # Held by something ahead (only turning allowed): arcs are not on offer, and the
            # window would swing back towards the lane, into it. Turn out instead.
            return self._turn_out(ins, floor, pose, lane, direction, now, dt, limit, remaining)
        choice = self.dwa.choose(
            self.costmap,
            floor,
            (pose.x_mm, pose.y_mm, pose.heading_deg),
            self.speed,
            self.yaw_rate,
            lane_mm=lane,
            direction=direction,
            max_speed_mm_s=max(cap, self.cfg.creep_speed_mm_s),
            dt_s=dt,
            now=now,
        )
        if choice is None or (choice.speed_mm_s < 1.0 and abs(choice.yaw_rate_dps) < 1.0):
            # Every arc from here meets the obstacle, or none does better than standing: the
            # window is too small to swing out from a standstill close to a wide obstacle.
            return self._turn_out(ins, floor, pose, lane, direction, now, dt, limit, remaining)
        status = self._status(ins.id, MotionState.AVOIDING, now, remaining, "going around")
        self.speed = min(choice.speed_mm_s, limit)
        self.yaw_rate = choice.yaw_rate_dps
        return Command(self.speed, self.yaw_rate, status)

    def _turn_out(
        self,
        ins: MoveInstruction,
        floor: Floor,
        pose: PoseEstimate,
        lane: float,
        direction: float,
        now: float,
        dt: float,
        limit: float,
        remaining: float,
    ) -> Command:
        """Turn on the spot towards the detour lane, the furthest of ``DETOUR_TURNS_DEG`` the
        costmap allows; blocked if none is free."""
        side = math.copysign(1.0, (lane - floor.to_hallway(pose.x_mm, pose.y_mm)[1]) * direction)
        travel = floor.hallway.heading_deg + (0.0 if direction > 0 else 180.0)
        for angle in DETOUR_TURNS_DEG:
            aim = travel + side * angle
            further_out = wrap_deg(aim - pose.heading_deg) * side
            if further_out > self.cfg.heading_tolerance_deg and self._turn_is_free(pose, aim, now):
                status = self._status(
                    ins.id, MotionState.AVOIDING, now, remaining, "turning out to go around"
                )
                rate = self._turn_rate(pose.heading_deg, aim)
                return self._command(0.0, rate, dt, status, limit)
        status = self._status(ins.id, MotionState.BLOCKED, now, remaining, "no way past")
        return self._command(0.0, 0.0, dt, status, limit)

    def _turn_is_free(self, pose: PoseEstimate, aim_deg: float, now: float) -> bool:
        """Whether turning on the spot (about the axle) from the pose's heading to
        ``aim_deg`` is an admissible path on the costmap. The body alone counts, without the
        zone kept free ahead for driving: a turn on the spot does not drive into anything,
        and the collision verdict still gates it."""
        error = math.radians(wrap_deg(aim_deg - pose.heading_deg))
        start = (pose.x_mm, pose.y_mm, math.radians(pose.heading_deg))
        # At one radian per unit time, the turn is done at time ``error``.
        times = np.linspace(0.0, abs(error), TURN_CHECK_STEPS)
        xs, ys, headings = rollout(
            start,
            np.zeros(1),
            np.array([math.copysign(1.0, error)]),
            times,
            self.footprint.axle_x_mm,
        )
        admissible, _ = self.costmap.admissible(xs, ys, headings, start, now, self.costmap.body)
        return bool(admissible[0])

    def _wait_distance(self) -> float:
        """Centre-to-obstacle distance at which the robot waits: outside the lethal zone."""
        fp = self.footprint
        return (
            fp.length_mm / 2
            + fp.front_extra_mm
            + self.cfg.obstacle_clearance_mm
            + self.cfg.costmap_resolution_mm
            + WAIT_ROOM_MM
        )

    def _obstacle_ahead(
        self, floor: Floor, s: float, lane: float, direction: float, now: float
    ) -> tuple[float, bool] | None:
        """The nearest obstacle cell in the lane ahead and whether it has stood still."""
        xs, ys, since = self.costmap.obstacles(now)
        if xs.size == 0:
            return None
        sd = np.array([floor.to_hallway(x, y) for x, y in zip(xs, ys, strict=True)])
        along = (sd[:, 0] - s) * direction
        half = self.footprint.width_mm / 2 + self.cfg.obstacle_clearance_mm
        behind = self.footprint.length_mm / 2
        in_lane = (
            (np.abs(sd[:, 1] - lane) < half) & (along > -behind) & (along < self.cfg.lookahead_mm)
        )
        if not in_lane.any():
            return None
        nearest = int(np.argmin(np.where(in_lane, along, np.inf)))
        near = in_lane & (along < along[nearest] + self.cfg.static_tolerance_mm)
        static = bool(np.all(since[near] <= now - self.cfg.static_confirm_s))
        return float(sd[nearest, 0]), static
