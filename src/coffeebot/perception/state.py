"""The seed's "current state": feeds every source into a :class:`PoseFusion`, reports it.

The board computes nothing (seed 000); this is where messages become one estimate. Each
``on_*`` method takes one message and returns whether it changed the estimate, so the
module publishes only when there is something new.
"""

from __future__ import annotations

import math
from collections import deque

import numpy as np

from coffeebot.config import GeometryConfig, MotorConfig, RobotConfig, StateConfig
from coffeebot.floorplan import FloorPlan
from coffeebot.messages import (
    AngleEstimate,
    CameraFix,
    CurrentState,
    DeliveryUpdate,
    DoorEvent,
    ElevatorState,
    MoveInstruction,
    Odometry,
    OrderDispatch,
    ParticleCloud,
    PoseEstimate,
    RangeScan,
    Traffic,
    UwbFix,
)
from coffeebot.navigation.others import standing_outlines
from coffeebot.perception.fusion import EkfPoseFusion, Odometer, OdometryStep, PoseFusion
from coffeebot.perception.geometry import TravelFrame
from coffeebot.perception.particles import ParticlePoseFusion

UWB_MIN_QUALITY = 10
ELEVATOR_STATE_FRESH_S = 0.5
"""The elevator's state older than this says nothing of its doors (the elevator module
reports every 0.2 s): they may have opened since."""


def make_fusion(config: RobotConfig, plan: FloorPlan) -> PoseFusion:
    """The fusion the robot description asks for (``[state] fusion``)."""
    if config.state.fusion == "particles":
        return ParticlePoseFusion(
            plan, config.tof, config.state, clearance_mm=config.geometry.width_mm / 2
        )
    return EkfPoseFusion(config.state)


class StateEstimator:
    """Position, heading, floor and the rest of the seed's state, always the freshest."""

    def __init__(
        self,
        plan: FloorPlan,
        motor: MotorConfig,
        cfg: StateConfig,
        fusion: PoseFusion | None = None,
        body: GeometryConfig | None = None,
    ) -> None:
        """``body``: this robot's, and so the fleet's other robots' (all one model; None:
        the board file's default)."""
        self.plan = plan
        self.body = body or GeometryConfig()
        self.cfg = cfg
        self.odometer = Odometer(motor, cfg)
        self.fusion: PoseFusion = fusion or EkfPoseFusion(cfg)
        self.floor = cfg.initial_floor
        self.fusion.change_floor(self.floor)
        # The particle filter reads the walls from the scans itself; the angle and door
        # modules' outputs come from the same readings and are only added if asked.
        particles = cfg.fusion == "particles"
        self._fuse_angles = not particles or cfg.particles.use_wall_angle
        self._fuse_doors = not particles or cfg.particles.use_doors
        self._anchor_floor = {a.id: f.level for f in plan.floors for a in f.anchors}
        self._levels = {f.level for f in plan.floors}
        self._recent: deque[OdometryStep] = deque()
        self.angle_from_line_deg: float | None = None
        self.move_instruction: MoveInstruction | None = None
        self.order_id: str | None = None
        self.delivery_status: DeliveryUpdate | None = None
        self.last_door_room: str | None = None
        self.stamps: dict[str, float] = {}
        self._shut_doors: tuple[dict[int, frozenset[str]], float] | None = None
        """The elevator doors shut per floor by the latest state, and when it came."""
        self._traffic: tuple[Traffic, float] | None = None
        """Where the fleet's other robots are, and when the dispatcher said so."""

    def place(self, x_mm: float, y_mm: float, heading_deg: float, floor: int) -> None:
        """A known start (the dock in the tea room) or a known arrival (out of the elevator)."""
        self._set_floor(floor)
        self.fusion.reset(x_mm, y_mm, heading_deg, 50.0, 5.0)

    def _set_floor(self, floor: int) -> None:
        if floor != self.floor:
            self.floor = floor
            self.fusion.change_floor(floor)

    def on_odometry(self, odo: Odometry, now: float) -> bool:
        step = self.odometer.step(odo)
        if step is None:
            return False
        self._recent.append(step)
        span = sum(s.dt_s for s in self._recent)
        while span - self._recent[0].dt_s >= self.cfg.speed_window_s:
            span -= self._recent.popleft().dt_s
        self.stamps["odometry"] = now
        if self.fusion.initialised:
            self.fusion.predict(step)
        return True

    def on_uwb(self, fix: UwbFix, now: float) -> bool:
        if fix.quality < UWB_MIN_QUALITY:
            return False
        floors = {self._anchor_floor.get(a.anchor_id) for a in fix.anchors} - {None}
        if len(floors) == 1:
            self._set_floor(floors.pop())  # type: ignore[arg-type]
        sigma = self.cfg.uwb_sigma_mm * max(1.0, 50.0 / fix.quality)
        self.stamps["uwb"] = now
        return self.fusion.update_position(fix.x_mm, fix.y_mm, sigma)

    def on_camera_fix(self, fix: CameraFix, now: float) -> bool:
        """A ceiling camera's pose of the robot, with its floor, for now.

        Its floor is believed only to place a fusion that has no pose yet: once tracking, the
        floor follows the elevator rides, and a fix for another floor is a wrong match, not
        a ride. Without a pose the fix places the robot (the particle filter's first
        particles); with one it is fused behind a gate (the Kalman filter's, or the particle
        filter's distance to its cloud): one wrong match must not carry a robot metres off.
        """
        values = (fix.x_mm, fix.y_mm, fix.heading_deg, fix.sigma_mm, fix.sigma_heading_deg)
        if fix.floor not in self._levels or not all(math.isfinite(v) for v in values):
            return False
        if not self.fusion.initialised:
            self._set_floor(fix.floor)
            self.fusion.reset(*values)
            used = True
        elif fix.floor != self.floor:
            return False
        elif isinstance(self.fusion, ParticlePoseFusion):
            used = self.fusion.update_pose_fix(*values)
        else:
            # Position first: a position the gate rejects takes its heading with it, since
            # both come from the same match.
            used = self.fusion.update_position(fix.x_mm, fix.y_mm, fix.sigma_mm)
            if used:
                self.fusion.update_heading(fix.heading_deg, fix.sigma_heading_deg)
        if used:
            self.stamps["camera"] = now
        return used

    def on_elevator(self, state: ElevatorState, now: float) -> bool:
        """Where the car is and its doors: which of them are shut, for the scans. Changes
        no estimate (False)."""
        self._shut_doors = (self._shut_by_floor(state), now)
        return False

    def _shut_by_floor(self, state: ElevatorState) -> dict[int, frozenset[str]]:
        """Per floor, the doors ``state`` says are shut: those of the car the interface
        reports, with the car elsewhere, travelling or there with its doors closed. A door
        of another car may be open; an interface without a car says nothing."""
        if state.source == "none" or not self.plan.cars:
            return {}
        car = state.car if state.car is not None else next(iter(self.plan.cars))
        shut: dict[int, frozenset[str]] = {}
        for stop in self.plan.cars.get(car, []):
            level = stop.floor.level
            if state.moving or state.car_floor != level or state.doors == "closed":
                shut[level] = shut.get(level, frozenset()) | {stop.door.id}
        return shut

    def shut_elevator_doors(self, now: float) -> frozenset[str]:
        """The elevator doors on this floor known shut at ``now``, by a fresh state."""
        if self._shut_doors is None:
            return frozenset()
        shut, stamp = self._shut_doors
        if now - stamp > ELEVATOR_STATE_FRESH_S:
            return frozenset()
        return shut.get(self.floor, frozenset())

    def on_traffic(self, traffic: Traffic, now: float) -> bool:
        """Where the fleet's other robots are: the next scans leave out what they explain,
        and nothing changes until then."""
        self._traffic = (traffic, now)
        return False

    def other_robots(self, now: float) -> list[np.ndarray]:
        """The outlines of the fleet's other robots standing on this floor at ``now``,
        grown by ``[state.particles] robot_margin_mm`` (none without a fleet)."""
        if self._traffic is None:
            return []
        traffic, at = self._traffic
        grow = 2.0 * self.cfg.particles.robot_margin_mm
        return standing_outlines(
            traffic.robots,
            self.floor,
            self.body.length_mm + grow,
            self.body.width_mm + grow,
            age_s=max(0.0, now - at),
        )

    def on_scan(self, scan: RangeScan, now: float) -> bool:
        used = self.fusion.update_ranges(
            scan, self.shut_elevator_doors(now), self.other_robots(now)
        )
        if used:
            self.stamps["ranges"] = now
        return used

    def on_angle(self, angle: AngleEstimate, now: float) -> bool:
        self.angle_from_line_deg = angle.angle_deg
        self.stamps["angle"] = now
        if not self._fuse_angles:
            return False
        used = self.fusion.update_heading(angle.heading_deg, angle.sigma_deg)
        # Each wall distance fixes the position across the hallway.
        x, y, heading = self.fusion.pose()
        floor = self.plan.floor(self.floor).view_near(x, y)
        frame = TravelFrame.for_heading(floor, heading)
        half = floor.hallway.width_mm / 2.0
        lateral = frame.lateral(x, y)
        for side, wall in angle.wall_distance_mm.items():
            measured = half - wall if side == "left" else wall - half
            left_of_travel = frame.direction_deg + 90.0
            used |= self.fusion.update_offset(
                left_of_travel, measured - lateral, self.cfg.wall_sigma_mm
            )
        return used

    def on_door(self, door: DoorEvent, now: float) -> bool:
        if door.room is not None:
            self.last_door_room = door.room
        self.stamps["door"] = now
        if door.along_correction_mm is None or not self._fuse_doors:
            return False
        return self.fusion.update_offset(
            door.travel_heading_deg, door.along_correction_mm, self.cfg.door_sigma_mm
        )

    def on_instruction(self, instruction: MoveInstruction) -> None:
        self.move_instruction = instruction

    def on_dispatch(self, dispatch: OrderDispatch) -> None:
        self.order_id = dispatch.order_id
        self.delivery_status = None

    def on_delivery(self, update: DeliveryUpdate) -> None:
        if update.order_id == self.order_id:
            self.delivery_status = update

    def _rates(self) -> tuple[float, float]:
        """Speed (mm/s) and yaw rate (deg/s) over the recent odometry window: each step's
        distance and turn summed in order, over the window's span summed once."""
        recent = self._recent
        span = sum(s.dt_s for s in recent)
        if not span > 0:
            return 0.0, 0.0
        distance = sum(s.distance_mm for s in recent)
        turned = sum(s.heading_change_deg for s in recent)
        return distance / span, turned / span

    def pose(self) -> PoseEstimate:
        x, y, heading = self.fusion.pose()
        cov = self.fusion.covariance()
        summary = self.fusion.summary()
        speed, yaw_rate = self._rates()
        return PoseEstimate(
            x_mm=x,
            y_mm=y,
            heading_deg=heading,
            floor=self.floor,
            sigma_x_mm=math.sqrt(max(cov[0, 0], 0.0)),
            sigma_y_mm=math.sqrt(max(cov[1, 1], 0.0)),
            sigma_heading_deg=math.sqrt(max(cov[2, 2], 0.0)),
            cov_xy_mm2=float(cov[0, 1]),
            speed_mm_s=speed,
            yaw_rate_dps=yaw_rate,
            initialised=self.fusion.initialised,
            particles=None if summary is None else summary.count,
            effective_sample_size=None if summary is None else summary.effective_sample_size,
        )

    def cloud(self, points: int) -> ParticleCloud | None:
        """A weighted sample of the particles for the map (None for the Kalman filter)."""
        samples = self.fusion.cloud(points)
        if samples is None:
            return None
        return ParticleCloud(
            floor=self.floor,
            x_mm=[round(float(v), 1) for v in samples[:, 0]],
            y_mm=[round(float(v), 1) for v in samples[:, 1]],
            heading_deg=[round(float(v), 1) for v in samples[:, 2]],
        )

    def current(self, now: float) -> CurrentState:
        return CurrentState(
            pose=self.pose(),
            angle_from_line_deg=self.angle_from_line_deg,
            move_instruction=self.move_instruction,
            order_id=self.order_id,
            delivery_status=None if self.delivery_status is None else self.delivery_status.status,
            last_door_room=self.last_door_room,
            sources={name: max(0.0, now - t) for name, t in self.stamps.items()},
        )
