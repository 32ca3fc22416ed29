"""What motion does with one instruction, one control period at a time (no I/O).

``follow_lane`` holds the lane with the speed profile and delegates what to do about an
obstacle in the lane to the detour (:mod:`coffeebot.navigation.detour`): while it is being
confirmed the robot stops short of it; while going round and rejoining the Dynamic Window
Approach steers to the detour's lane; if no arc gets past, the robot is blocked and waits for
the way to clear. In a fleet, while another robot comes the other way in the hallway ahead,
the lane followed is the passing lane, nearer the wall (:mod:`coffeebot.navigation.passing`):
only on a keep-right lane, never over a detour going round, and given up for the last
``approach_mm`` before a stop, where the route's turn into a door or the elevator starts
from the lane. ``drive_to`` turns towards a point, then drives to it on a held heading.
``turn`` turns on the spot. The safety gate sits outside this class, in the module, and
overrides it.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from functools import partial

import numpy as np

from coffeebot.config import MotionConfig
from coffeebot.floorplan import Floor, FloorPlan
from coffeebot.messages import (
    MotionState,
    MotionStatus,
    MoveInstruction,
    PoseEstimate,
    StopCause,
    Traffic,
)
from coffeebot.navigation.control import (
    SpeedProfile,
    lane_heading_deg,
    ramp,
    turn_rate_dps,
)
from coffeebot.navigation.costmap import Clearances, Footprint, LocalCostmap
from coffeebot.navigation.detour import DetourPlanner, Phase, Sighting
from coffeebot.navigation.dwa import DwaChoice, DynamicWindow, axle_point, rollout
from coffeebot.navigation.others import standing_outlines
from coffeebot.navigation.passing import oncoming, right_lane_mm
from coffeebot.navigation.trails import FleetTrails
from coffeebot.perception.geometry import wrap_deg

AIM_BEFORE_DRIVING_DEG = 10.0
"""``drive_to`` turns on the spot until the point is within this of straight ahead."""

AIM_BEFORE_LANE_DEG = 45.0
"""``follow_lane`` facing further than this from the direction of travel turns on the spot."""

DETOUR_TURNS_DEG = tuple(45.0 - 2.5 * k for k in range(17))
"""Blocked close to an obstacle, the robot first turns on the spot this far from its
direction of travel towards the detour lane (the furthest of these the walls allow: the rear
swings out about the axle), from where the dynamic window finds arcs past it."""

TURN_CHECK_DEG = 7.5
"""Between the headings checked along a turn on the spot before it is made: a rear corner
522 mm from the axle swings about 1 mm further out between two of them."""

STANDING_MM_S = 20.0
"""Slower than this the robot stands: a turn on the spot begins only then."""
TURNING_DPS = 1.0
"""Turning slower than this, the robot is taken to stand: a turn from here is checked first."""

CENTRE_LINE_MM = 50.0
"""Within this of the hallway's centre line the axle is on it, for a robot making room."""

MAKING_ROOM = "no room to turn into the lane: making room towards the hallway's middle"

NO_ROOM_TO_MAKE = "no room to turn into the lane, and no way towards the hallway's middle"

FRAME_LEAD_MM = 1500.0
"""How far ahead of a door frame across the hallway the lane moves in to pass its opening."""

HALF_TURN_DEG = 150.0
"""A turn at least this large, in the hallway beside a wall, goes the way that swings the
front through the hallway's middle (:meth:`MotionController._way_round`)."""

MAKE_ROOM_MM = 3000.0
"""How far a robot whose turn into the lane has no room drives towards the hallway's centre
line to find room, before it calls itself blocked: the centre is at most half the hallway
away, and a turn there that still has none is held by something else."""


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
        self._spin_room = Clearances(wall_mm=cfg.turn_clearance_mm, obstacle_mm=0.0)
        """What a turn on the spot keeps to the walls before it is begun."""
        self.speed = 0.0
        self.yaw_rate = 0.0
        self._instruction_id: int | None = None
        self._direction = 1.0
        self._state = MotionState.IDLE
        self._since = 0.0
        self.detour = DetourPlanner(cfg, costmap, footprint)
        self._line: float | None = None
        """``drive_to``: the direction of the line being followed, fixed at its start."""
        self._way: float | None = None
        """``turn``: which way round (+1 left, -1 right, 0 the shorter), fixed at its start."""
        self._traffic: Traffic | None = None
        self._traffic_at = 0.0
        self.trails = FleetTrails.of_robots(
            footprint.length_mm, footprint.width_mm, costmap.half_fov_deg, cfg.obstacle_memory_s
        )
        self.passing: str | None = None
        """The robot the passing lane is kept for, if any."""
        self.yielding = False
        """Kept to the passing lane short of crossing the hallway until ``passing`` is by."""
        self._room_from: tuple[float, float] | None = None
        """Where the robot began driving to find room for a turn into the lane, until the
        turn is begun (kept when it gives up, so the distance is not begun again)."""

    def note_traffic(self, traffic: Traffic, now: float) -> None:
        """Where the fleet's other robots are, as the dispatcher said at ``now``; the marks
        they left behind where they no longer are go from the costmap."""
        self._traffic, self._traffic_at = traffic, now
        self.trails.note(traffic, now)
        if self.costmap.floor is not None:
            self.costmap.forget_marks(
                now, partial(self.trails.left_behind, self.costmap.floor.level)
            )

    def standing_robots(self, floor_level: int, now: float) -> list[np.ndarray]:
        """The outlines of the fleet's other robots standing on ``floor_level``, for the
        costmap (none without a fleet)."""
        if self._traffic is None:
            return []
        return standing_outlines(
            self._traffic.robots,
            floor_level,
            self.footprint.length_mm,
            self.footprint.width_mm,
            age_s=max(0.0, now - self._traffic_at),
        )

    def halt(self) -> None:
        """The safety gate stopped the motors: plan from standstill when it lets go."""
        self.speed = 0.0
        self.yaw_rate = 0.0

    def safety_status(
        self, instruction_id: int, now: float, reason: str, cause: StopCause | None
    ) -> MotionStatus:
        """The status while the safety gate holds the robot."""
        status = self._status(instruction_id, MotionState.SAFETY_STOP, now, None, reason)
        return status.model_copy(update={"stopped_by": cause})

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
            self.detour.reset()
            self._line = None
            self._way = None
            self._room_from = None
            self._state = MotionState.MOVING
            self._since = now
            if instruction.target_s_mm is not None and instruction.floor == pose.floor:
                along = self.plan.floor(pose.floor).view(instruction.hallway)
                s = along.to_hallway(pose.x_mm, pose.y_mm)[0]
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
        floor = self.plan.floor(pose.floor).view(instruction.hallway)
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
        if abs(self.yaw_rate) < TURNING_DPS and abs(pose.speed_mm_s) > STANDING_MM_S:
            # Begun rolling, a turn sweeps from further on than its room was checked: a
            # robot turning round in the elevator car rolled 76 mm deeper as it began, the
            # monitor stopped it, and from there its sweep had no room.
            status = self._status(ins.id, MotionState.MOVING, now, None, "stopping to turn")
            return self._command(0.0, 0.0, dt, status, limit)
        if self._way is None:
            floor = self.plan.floor(pose.floor).view_near(pose.x_mm, pose.y_mm)
            self._way = self._way_round(floor, pose, error, now)
        left = turn_deg(error, self._way)
        # The long way round: towards a quarter turn ahead until the rest is the shorter way.
        aim = wanted if left == error else pose.heading_deg + self._way * 90.0
        return self._spin(ins, pose, aim, now, dt, limit, None, f"turning, {left:.0f} deg")

    def _way_round(self, floor: Floor, pose: PoseEstimate, error: float, now: float) -> float:
        """Which way a turn of ``error`` degrees goes (0: the shorter). A half turn in the
        hallway off its centre line, facing along it, goes the way that swings the front
        (near the axle) through the hallway's middle and the rear (the far end, whose
        corners swing half a metre) along the nearer wall, if that sweep has room. Swung the
        other way, a robot turning round at an office door swept its rear across the
        hallway into a robot that had come up beside the other wall, and the two stood
        pressed together for good."""
        if abs(error) < HALF_TURN_DEG:
            return 0.0
        d = floor.to_hallway(pose.x_mm, pose.y_mm)[1]
        along = math.cos(math.radians(pose.heading_deg - floor.hallway.heading_deg))
        if not CENTRE_LINE_MM < abs(d) <= floor.hallway.width_mm / 2.0 or abs(along) < 0.5:
            return 0.0  # on the centre line, in a doorway or a room, or facing across
        way = -math.copysign(1.0, d) * math.copysign(1.0, along)
        if way * error > 0:
            return 0.0  # the shorter way is that way
        free = self._turn_is_free(pose, pose.heading_deg + error, now, self._spin_room, way)
        return way if free else 0.0

    def _spin(
        self,
        ins: MoveInstruction,
        pose: PoseEstimate,
        wanted: float,
        now: float,
        dt: float,
        limit: float,
        remaining: float | None,
        detail: str,
    ) -> Command:
        """Turn on the spot towards ``wanted``. A turn is begun (from standstill, or again
        after something stopped it) only if its sweep is admissible on the costmap: the
        rear corners swing 522 mm about the axle, and a turn begun beside another robot or
        too near a wall ends pressed against it (the collision monitor stops the turn, and
        neither moves). Refused, the robot stands blocked until the sweep clears."""
        if self._no_room_to_begin_turn(pose, wanted, now):
            error = wrap_deg(wanted - pose.heading_deg)
            why = f"no room to turn, {error:.0f} deg"
            status = self._status(ins.id, MotionState.BLOCKED, now, remaining, why)
            return self._command(0.0, 0.0, dt, status, limit)
        status = self._status(ins.id, MotionState.MOVING, now, remaining, detail)
        return self._command(0.0, self._turn_rate(pose.heading_deg, wanted), dt, status, limit)

    def _turn_into_lane(
        self,
        ins: MoveInstruction,
        floor: Floor,
        pose: PoseEstimate,
        travel: float,
        now: float,
        dt: float,
        limit: float,
        remaining: float,
    ) -> Command:
        """Turn on the spot to the direction of travel, from where any turn has room: nearer
        a wall, first drive towards the hallway's centre line. A robot that ended going
        round past its stop, its axle 415 mm from the wall and facing the wrong way, began
        its half turn there (the body's sweep had room); the collision monitor stopped it
        with the wall 224 mm ahead of the front, and there it stood for good."""
        in_band = self._any_turn_has_room(floor, pose)
        if in_band and self._room_from is not None and self.speed >= self.cfg.creep_speed_mm_s:
            # Room made: stand before turning (a turn begun rolling is a wide arc).
            status = self._status(ins.id, MotionState.AVOIDING, now, remaining, MAKING_ROOM)
            return self._command(0.0, 0.0, dt, status, limit)
        if not in_band and self._room_left(pose):
            return self._make_room(ins, floor, pose, now, dt, limit, remaining)
        # In the band, or no room found within MAKE_ROOM_MM: the turn if its sweep has room
        # (checked by the spin, while ``_room_from`` still says the robot stands).
        command = self._spin(ins, pose, travel, now, dt, limit, remaining, "turning into the lane")
        if in_band and command.status.state is not MotionState.BLOCKED:
            self._room_from = None
        return command

    def _room_left(self, pose: PoseEstimate) -> bool:
        """Whether the robot has driven less than ``MAKE_ROOM_MM`` making room."""
        if self._room_from is None:
            self._room_from = (pose.x_mm, pose.y_mm)
        return math.dist(self._room_from, (pose.x_mm, pose.y_mm)) <= MAKE_ROOM_MM

    def _any_turn_has_room(self, floor: Floor, pose: PoseEstimate) -> bool:
        """Whether the axle is far enough from both walls for the body's furthest corner
        to swing all the way round keeping ``turn_clearance_mm`` (or on the centre line, in
        a hallway too narrow for that). There the front, its corridor and the collision
        monitor's stop distance ahead of it also keep clear of the walls at any heading
        (in a 1700 mm hallway, 70 mm to spare)."""
        fp = self.footprint
        reach = math.hypot(fp.length_mm / 2.0 + abs(fp.axle_x_mm), fp.width_mm / 2.0)
        band = floor.hallway.width_mm / 2.0 - reach - self.cfg.turn_clearance_mm
        axle = axle_point(pose.x_mm, pose.y_mm, math.radians(pose.heading_deg), fp.axle_x_mm)
        return abs(floor.to_hallway(*axle)[1]) <= max(band, CENTRE_LINE_MM)

    def _make_room(
        self,
        ins: MoveInstruction,
        floor: Floor,
        pose: PoseEstimate,
        now: float,
        dt: float,
        limit: float,
        remaining: float,
    ) -> Command:
        """One period of driving the way the robot faces, along the hallway, towards its
        centre line, where a turn on the spot sweeps furthest from both walls: squared up
        along the hallway first if it faces the nearer wall, then on the dynamic window's
        arcs; blocked while neither that turn nor any arc is admissible."""
        axis = floor.hallway.heading_deg
        facing = 1.0 if math.cos(math.radians(pose.heading_deg - axis)) >= 0.0 else -1.0
        along = axis + (0.0 if facing > 0 else 180.0)
        d = floor.to_hallway(pose.x_mm, pose.y_mm)[1]
        outwards = math.sin(math.radians(pose.heading_deg - axis)) * d > 0.0
        off = abs(wrap_deg(along - pose.heading_deg)) > self.cfg.heading_tolerance_deg
        if outwards and off and self.speed < self.cfg.creep_speed_mm_s:
            # Standing, facing towards the nearer wall: square up first, if that turn has
            # room (all the way: the window's arcs from a turn still braking find none).
            if not self._turn_is_free(pose, along, now, self._spin_room):
                return self._blocked(ins, now, dt, limit, remaining, NO_ROOM_TO_MAKE)
            status = self._status(ins.id, MotionState.AVOIDING, now, remaining, MAKING_ROOM)
            return self._command(0.0, self._turn_rate(pose.heading_deg, along), dt, status, limit)
        cap = min(self.cfg.approach_speed_mm_s, limit)
        choice = self._window_arc(floor, pose, 0.0, facing, cap, dt, now)
        if choice is None:
            return self._blocked(ins, now, dt, limit, remaining, NO_ROOM_TO_MAKE)
        status = self._status(ins.id, MotionState.AVOIDING, now, remaining, MAKING_ROOM)
        return self._drive_arc(choice, limit, status)

    def _window_arc(
        self,
        floor: Floor,
        pose: PoseEstimate,
        lane_mm: float,
        direction: float,
        cap_mm_s: float,
        dt: float,
        now: float,
    ) -> DwaChoice | None:
        """The dynamic window's best arc towards ``lane_mm``, at least at creep speed; None
        if every arc from here meets something, or none does better than standing."""
        choice = self.dwa.choose(
            self.costmap,
            floor,
            (pose.x_mm, pose.y_mm, pose.heading_deg),
            self.speed,
            self.yaw_rate,
            lane_mm=lane_mm,
            direction=direction,
            max_speed_mm_s=max(cap_mm_s, self.cfg.creep_speed_mm_s),
            dt_s=dt,
            now=now,
        )
        if choice is None or (choice.speed_mm_s < 1.0 and abs(choice.yaw_rate_dps) < 1.0):
            return None
        return choice

    def _drive_arc(self, choice: DwaChoice, limit: float, status: MotionStatus) -> Command:
        self.speed = min(choice.speed_mm_s, limit)
        self.yaw_rate = choice.yaw_rate_dps
        return Command(self.speed, self.yaw_rate, status)

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
        error = wrap_deg(self._line - pose.heading_deg)
        if abs(error) > AIM_BEFORE_DRIVING_DEG and self.speed < self.cfg.creep_speed_mm_s:
            return self._spin(ins, pose, self._line, now, dt, limit, remaining, ins.detail)
        status = self._status(ins.id, MotionState.MOVING, now, remaining, ins.detail)
        target = self.profile.target(remaining, ins.speed_mm_s or self.cfg.room_speed_mm_s)
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
        remaining = (ins.target_s_mm - s) * direction
        lane = self._through_frames(
            floor, s, direction, self._lane(ins, floor, s, d, direction, remaining, now)
        )
        travel = floor.travel_deg(direction)
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
            detail = ins.detail
            if self.passing is not None:
                detail = f"{detail}; passing lane, {self.passing} coming"
            status = self._status(ins.id, MotionState.MOVING, now, remaining, detail)
        if abs(wrap_deg(travel - pose.heading_deg)) > AIM_BEFORE_LANE_DEG and (
            self.speed < cfg.creep_speed_mm_s or self._room_from is not None
        ):
            return self._turn_into_lane(ins, floor, pose, travel, now, dt, limit, remaining)
        self._room_from = None
        cruise = ins.speed_mm_s or cfg.cruise_speed_mm_s
        approach = cfg.approach_mm if ins.target_door is not None else 0.0
        target = self.profile.target(
            remaining,
            cruise,
            stop=ins.stop,
            approach_mm=approach,
            approach_mm_s=cfg.approach_speed_mm_s,
        )
        if self.yielding:
            gap = remaining - cfg.approach_mm
            target = min(target, self.profile.target(gap, cruise))
            if target <= 0:
                why = f"letting {self.passing} pass before crossing the hallway"
                status = self._status(ins.id, MotionState.WAITING, now, remaining, why)
        # Something the body and the zone kept free ahead of it do not reach at the stop is
        # neither waited for nor gone round: a robot waiting for the tea room swerved round
        # one coming out of its door beyond.
        horizon = remaining + self.detour.keep_distance_mm() if ins.stop else None
        # A stop that is not a door's (where the robot turns, or waits its turn) is made in
        # the lane: one that ended going round stood off it, its turn refused for the wall.
        in_lane_by = ins.target_s_mm if ins.stop and ins.target_door is None else None
        sighting = self.detour.update(
            floor, s, d, lane, direction, ins.avoid, now, horizon, in_lane_by
        )
        detour_lane = self.detour.lane_mm
        if self.detour.phase is Phase.CONFIRMING and sighting is not None:
            gap = (sighting.near_edge(direction) - s) * direction - self.detour.wait_distance_mm()
            target = min(target, self.profile.target(gap, cruise))
            why = _waiting_why(sighting, ins.avoid)
            if self.detour.detour is not None and self.detour.detour.too_near_stop:
                why = "obstacle ahead, too near the stop to go round, waiting"
            status = self._status(
                ins.id, _waiting_state(sighting, ins.avoid, target), now, remaining, why
            )
        elif detour_lane is not None:
            # Going round (or back to the lane): hold the detour lane until the body is past
            # everything seen of the obstacle.
            return self._go_round(
                ins, floor, pose, detour_lane, direction, target, now, dt, limit, remaining
            )
        heading = lane_heading_deg(travel, (lane - d) * direction, cfg)
        rate = turn_rate_dps(pose.heading_deg, heading, cfg)
        if (
            target <= 0.0
            and self.speed < cfg.creep_speed_mm_s
            and not self._turn_is_free(pose, heading, now, self._spin_room)
        ):
            # Standing to wait (for something ahead), it turns towards the lane's heading
            # only as far as a turn on the spot has room, checked every period: a turn begun
            # while it still rolled goes on once it stands. A robot holding the car, waiting
            # beside the wall to cross to it, turned 14 degrees towards the lane across and
            # swung its rear about the axle to 49 mm of the wall, where its side sensor held
            # it 71 s.
            rate = 0.0
        return self._command(target, rate, dt, status, limit)

    def _lane(
        self,
        ins: MoveInstruction,
        floor: Floor,
        s: float,
        d: float,
        direction: float,
        remaining: float,
        now: float,
    ) -> float:
        """The instruction's lane, or the passing lane while another robot comes: in place
        of a keep-right lane, not over the last ``approach_mm`` before a stop; in place of a
        lane across the hallway (to a door on the left) while a robot drives towards this
        one, which then waits ``approach_mm`` short of its stop (``yielding``) rather than
        cross in front of it."""
        self.passing, self.yielding = None, False
        if ins.lane_mm is None:
            return d
        passing = right_lane_mm(
            floor, direction, self.cfg.passing_wall_distance_mm, self.footprint.width_mm
        )
        keeps_right = ins.lane_mm * direction < 0
        nearer_wall = abs(passing) > abs(ins.lane_mm)
        before_stop = not ins.stop or remaining > self.cfg.approach_mm
        if self._traffic is None or not before_stop or (keeps_right and not nearer_wall):
            return ins.lane_mm
        self.passing = oncoming(
            self._traffic.robots,
            floor,
            s,
            direction,
            passed_mm=self.footprint.length_mm,
            age_s=max(0.0, now - self._traffic_at),
            standing=keeps_right,
        )
        self.yielding = self.passing is not None and not keeps_right
        return ins.lane_mm if self.passing is None else passing

    def _through_frames(self, floor: Floor, s: float, direction: float, lane: float) -> float:
        """``lane``, or nearer the axis where a door frame across the hallway lies within
        ``FRAME_LEAD_MM`` ahead or under the body: as far out as its opening leaves
        ``side_clearance_mm`` beside the body (a keep-right lane passes a 1400 mm frame
        with its side 50 mm from a jamb)."""
        reach = self.footprint.length_mm / 2
        for frame in floor.frames_along():
            lo, hi = frame.jambs
            near, far = (lo, hi) if direction > 0 else (hi, lo)
            if (near - s) * direction <= FRAME_LEAD_MM and (far - s) * direction >= -reach:
                limit = max(
                    0.0,
                    frame.clear_width_mm / 2
                    - self.footprint.width_mm / 2
                    - self.cfg.side_clearance_mm,
                )
                lane = max(-limit, min(limit, lane))
        return lane

    def _go_round(
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
            turn = self._turn_out(ins, floor, pose, lane, direction, now, dt, limit, remaining)
            return turn or self._blocked(ins, now, dt, limit, remaining)
        shift = abs(lane - floor.to_hallway(pose.x_mm, pose.y_mm)[1])
        if self.speed < self.cfg.creep_speed_mm_s and shift > self.footprint.width_mm / 2:
            # A wide shift from a standstill in front of the obstacle: the window's arcs from
            # rest only creep towards it. Turn out on the spot first, as far as the walls let.
            turn = self._turn_out(ins, floor, pose, lane, direction, now, dt, limit, remaining)
            if turn is not None:
                return turn
        choice = self._window_arc(floor, pose, lane, direction, cap, dt, now)
        if choice is None:
            # The window is too small to swing out from a standstill close to a wide obstacle.
            turn = self._turn_out(ins, floor, pose, lane, direction, now, dt, limit, remaining)
            return turn or self._blocked(ins, now, dt, limit, remaining)
        status = self._status(ins.id, MotionState.AVOIDING, now, remaining, "going around")
        return self._drive_arc(choice, limit, status)

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
    ) -> Command | None:
        """Turn on the spot towards the detour lane, the furthest of ``DETOUR_TURNS_DEG`` the
        costmap allows; None if no turn further out than the heading is free."""
        side = math.copysign(1.0, (lane - floor.to_hallway(pose.x_mm, pose.y_mm)[1]) * direction)
        travel = floor.travel_deg(direction)
        for angle in DETOUR_TURNS_DEG:
            aim = travel + side * angle
            further_out = wrap_deg(aim - pose.heading_deg) * side
            if further_out > self.cfg.heading_tolerance_deg and self._turn_is_free(pose, aim, now):
                status = self._status(
                    ins.id, MotionState.AVOIDING, now, remaining, "turning out to go around"
                )
                rate = self._turn_rate(pose.heading_deg, aim)
                return self._command(0.0, rate, dt, status, limit)
        return None

    def _blocked(
        self,
        ins: MoveInstruction,
        now: float,
        dt: float,
        limit: float,
        remaining: float,
        why: str = "no way past",
    ) -> Command:
        status = self._status(ins.id, MotionState.BLOCKED, now, remaining, why)
        return self._command(0.0, 0.0, dt, status, limit)

    def _no_room_to_begin_turn(self, pose: PoseEstimate, wanted_deg: float, now: float) -> bool:
        """Standing (not turning yet, or driving to find room), whether the turn on the spot
        to ``wanted_deg`` lacks the room a turn keeps to the walls (``turn_clearance_mm``)."""
        standing = abs(self.yaw_rate) < TURNING_DPS or self._room_from is not None
        return standing and not self._turn_is_free(pose, wanted_deg, now, self._spin_room)

    def _turn_is_free(
        self,
        pose: PoseEstimate,
        aim_deg: float,
        now: float,
        clearances: Clearances | None = None,
        way: float = 0.0,
    ) -> bool:
        """Whether turning on the spot (about the axle) from the pose's heading to
        ``aim_deg`` the shorter way (or ``way`` round, :func:`turn_deg`) is an admissible
        path on the costmap, keeping ``clearances`` (default: the costmap's). The body alone
        counts, without the zone kept free ahead for driving: a turn on the spot does not
        drive into anything, and the collision verdict still gates it."""
        error = math.radians(turn_deg(wrap_deg(aim_deg - pose.heading_deg), way))
        start = (pose.x_mm, pose.y_mm, math.radians(pose.heading_deg))
        # At one radian per unit time, the turn is done at time ``error``.
        steps = max(2, math.ceil(math.degrees(abs(error)) / TURN_CHECK_DEG) + 1)
        times = np.linspace(0.0, abs(error), steps)
        xs, ys, headings = rollout(
            start,
            np.zeros(1),
            np.array([math.copysign(1.0, error)]),
            times,
            self.footprint.axle_x_mm,
        )
        admissible, _ = self.costmap.admissible(
            xs, ys, headings, start, now, self.costmap.body, clearances
        )
        return bool(admissible[0])


def turn_deg(error_deg: float, way: float) -> float:
    """The signed turn to a heading ``error_deg`` away (the shorter way, as
    :func:`wrap_deg` folds it) made ``way`` round: +1 left, -1 right, 0 the shorter."""
    return error_deg + way * 360.0 if way * error_deg < 0 else error_deg


def _waiting_state(sighting: Sighting, avoid: bool, target_mm_s: float) -> MotionState:
    """Confirming an obstacle: still closing the gap, waiting, or blocked with no way past."""
    if target_mm_s > 0:
        return MotionState.MOVING
    if sighting.static and avoid:
        return MotionState.BLOCKED
    return MotionState.WAITING


def _waiting_why(sighting: Sighting, avoid: bool) -> str:
    if not sighting.static:
        return "something moving ahead, waiting"
    if avoid:
        return "no way past the obstacle ahead, waiting"
    return "obstacle ahead and not allowed to leave the lane, waiting"
