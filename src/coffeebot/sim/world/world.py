"""The simulated world: one floor plan, obstacles and robots, stepped by simulated time.

The world owns ground truth and is queried the way devices are, through each robot's
:class:`WorldRobot`: the simulated VL53L1X asks for sensor k's reading at that robot's pose,
the simulated motor controller feeds wheel speed commands and reads encoder ticks and the
gyro, the simulated DWM1001 asks for a UWB fix. A world usually holds one robot
(:attr:`World.robot`); a fleet's holds several, and each one's sensors see the others, whose
bodies are obstacles like any other (and touching one is a collision). Nothing here reads
the wall clock; whoever owns time calls :meth:`World.step`. Every noise source draws from its
own generator spawned from one seed (each robot its own), so a run is reproducible and
adding queries of one kind does not change the noise of another.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
from pydantic import BaseModel, ConfigDict, Field

from coffeebot.floorplan import Floor, FloorPlan, segment_distances
from coffeebot.hardware.dwm1001 import ANCHOR_RANGE_MM
from coffeebot.hardware.vl53l1x import FULL_ROI, SpadRoi
from coffeebot.messages import AnchorRange, UwbFix
from coffeebot.sim.world.elevator import SimElevator
from coffeebot.sim.world.geometry import Contact, Surfaces, footprint_contacts
from coffeebot.sim.world.materials import ROBOT_SHELL, element_reflectance
from coffeebot.sim.world.obstacles import ObstacleSpec, obstacle_surfaces
from coffeebot.sim.world.robot import BodyState, Pose, RobotBody, RobotSpec
from coffeebot.sim.world.tof import (
    DEFAULT_SETUP,
    ConeOptics,
    Layers,
    RangingNoise,
    RangingSetup,
    Returns,
    SensorArray,
    ToFReading,
    range_once,
)

PHYSICS_DT_S = 0.005
"""Longest physics sub-step: 5 mm at 1 m/s, finer than any wall or leg."""

_RELEASE_MM = 20.0
"""A contact ends once the robot is this far clear, so pushing against a wall is one collision."""


class UwbModel(BaseModel):
    """DWM1001 tag error: ~0.1 m on position (seed 000), anchors usable up to a range."""

    model_config = ConfigDict(frozen=True, extra="forbid")

    position_sigma_mm: float = Field(100.0, ge=0)
    range_sigma_mm: float = Field(50.0, ge=0)
    max_anchor_range_mm: float = Field(ANCHOR_RANGE_MM, gt=0)
    max_anchors: int = Field(4, ge=3)


@dataclass(frozen=True)
class Collision:
    """A robot's footprint touched something: what, where, and how fast it was going."""

    t_s: float
    floor: int
    element: str
    x_mm: float
    y_mm: float
    speed_mm_s: float
    body: BodyState | None = None
    """The body just before the touch (pose, signed speed, yaw rate): where it was hit."""


class World:
    """The building and what is in it; robots are added with :meth:`add_robot` (the first
    one by the constructor)."""

    def __init__(
        self,
        plan: FloorPlan,
        robot: RobotSpec,
        *,
        floor: int,
        pose: Pose,
        obstacles: Sequence[ObstacleSpec] = (),
        seed: int = 0,
        optics: ConeOptics | None = None,
        noise: RangingNoise | None = None,
        uwb: UwbModel | None = None,
        elevators: Sequence[SimElevator] = (),
        robot_name: str = "robot",
    ) -> None:
        """``robot`` stands at ``pose`` on ``floor``, named ``robot_name`` (what another
        robot's collision with it is called)."""
        self.plan = plan
        self.elevators = tuple(elevators)
        """The building's cars, simulated (none: the elevator doors stay shut)."""
        self.seed = seed
        self.obstacles = tuple(obstacles)
        for obstacle in self.obstacles:
            plan.floor(obstacle.floor)  # raises KeyError naming the missing floor
        self.optics = optics or ConeOptics()
        self.noise = RangingNoise() if noise is None else noise
        self.uwb_model = uwb or UwbModel()
        self._static: dict[int, Surfaces] = {}
        self._scenes: dict[int, tuple[tuple[object, ...], Surfaces]] = {}
        self.t_s = 0.0
        self.obstacle_start_s: list[float | None] = [
            None if o.trigger_mm is not None else 0.0 for o in self.obstacles
        ]
        """World time at which each obstacle's own clock started (None: not triggered yet)."""
        self.robots: list[WorldRobot] = []
        self.add_robot(robot, floor, pose, robot_name)

    @property
    def robot(self) -> WorldRobot:
        """The robot of a single-robot world (a fleet's first)."""
        return self.robots[0]

    def add_robot(self, spec: RobotSpec, floor: int, pose: Pose, name: str) -> WorldRobot:
        """Another robot, standing at ``pose`` on ``floor``; ``name`` is what the others'
        collisions with it are called."""
        index = len(self.robots)
        entropy = self.seed if index == 0 else [self.seed, index]
        rngs = [np.random.default_rng(s) for s in np.random.SeedSequence(entropy).spawn(4)]
        robot = WorldRobot(self, spec, floor, pose, name, rngs)
        self.robots.append(robot)
        for other in self.robots:
            other.forget_returns()
        robot.place(pose, floor)  # starting inside something counts as a collision
        return robot

    # --- what is where -----------------------------------------------------------------------

    def surfaces(
        self, level: int, t_s: float | None = None, without: WorldRobot | None = None
    ) -> Surfaces:
        """Everything on floor ``level`` now, or at an earlier world time ``t_s`` (the
        obstacles are functions of their clocks; the elevator and the robots are as they
        are now), the robots but ``without`` included."""
        surfaces = self._scene(level, t_s)
        for robot in self.robots:
            if robot is not without and robot.floor_level == level:
                surfaces = surfaces + robot.outline()
        return surfaces

    def near(
        self, level: int, x: float, y: float, radius: float, without: WorldRobot | None = None
    ) -> Surfaces:
        """What of floor ``level`` comes within ``radius`` of (x, y) now, the robots but
        ``without`` included: ``surfaces(level, without=...)`` narrowed to it, element for
        element (a robot whose centre is too far for any side of it to reach is passed
        over). What a robot's cones are cast against."""
        scene = self._scene(level, None)
        found = scene.take(*scene.near(x, y, radius))
        for robot in self.robots:
            if robot is without or robot.floor_level != level:
                continue
            s = robot.body.state
            if math.hypot(s.x - x, s.y - y) - robot.half_diagonal_mm > radius + 1.0:
                continue
            outline = robot.outline()
            found = found + outline.take(*outline.near(x, y, radius))
        return found

    def touching(
        self,
        level: int,
        pose: tuple[float, float, float],
        half_size: tuple[float, float],
        z_range: tuple[float, float],
        without: WorldRobot | None = None,
    ) -> list[Contact]:
        """What on floor ``level`` touches a rectangle (centre x, y and heading in rad;
        half its length and width) now, the robots but ``without`` included, in the order
        of :meth:`surfaces`. The floor is tested whole: compiled, that costs less than
        narrowing it down first."""
        x, y, theta = pose
        found = footprint_contacts(self._scene(level, None), x, y, theta, *half_size, z_range)
        reach = math.hypot(*half_size) + 1.0
        for robot in self.robots:
            if robot is without or robot.floor_level != level:
                continue
            s = robot.body.state
            if math.hypot(s.x - x, s.y - y) - robot.half_diagonal_mm > reach:
                continue
            found += footprint_contacts(robot.outline(), x, y, theta, *half_size, z_range)
        return found

    def _scene(self, level: int, t_s: float | None) -> Surfaces:
        """Floor ``level`` without the robots: the plan, the elevator, the obstacles. Kept
        while nothing in it can have changed (every robot asks for it every physics step)."""
        lifts = [elevator.surfaces(level) for elevator in self.elevators]
        # A car keeps each of its outlines: the same object while its doors stay.
        key = (self.t_s, tuple(id(lift) for lift in lifts), tuple(self.obstacle_start_s))
        if t_s is None and self._scenes.get(level, (None,))[0] == key:
            return self._scenes[level][1]
        surfaces = self._static_surfaces(level)
        for lift in lifts:
            surfaces = surfaces + lift
        for i, obstacle in enumerate(self.obstacles):
            if obstacle.timed and obstacle.floor == level:
                surfaces = surfaces + self.obstacle_at(i, t_s)
        if t_s is None:
            self._scenes[level] = (key, surfaces)
        return surfaces

    def obstacle_clock_s(self, index: int, t_s: float | None = None) -> float | None:
        """Obstacle ``index``'s own time now or at world time ``t_s`` (None: its trigger had
        not fired yet)."""
        start = self.obstacle_start_s[index]
        t = self.t_s if t_s is None else t_s
        return None if start is None or t < start else t - start

    def obstacle_at(self, index: int, t_s: float | None = None) -> Surfaces:
        """Obstacle ``index`` now or at world time ``t_s``; empty while it is absent."""
        obstacle = self.obstacles[index]
        clock = self.obstacle_clock_s(index, t_s)
        if not obstacle.present_at(clock):
            return Surfaces.empty()
        return obstacle_surfaces(obstacle, clock or 0.0)

    def _static_surfaces(self, level: int) -> Surfaces:
        if level not in self._static:
            floor = self.plan.floor(level)
            # A simulated car's doors stand in for the plan's door leaf.
            doors = {elevator.door_element(level) for elevator in self.elevators}
            keep = [i for i, s in enumerate(floor.segments) if s.element not in doors]
            elements = tuple(floor.segments[i].element for i in keep)
            surfaces = Surfaces(
                floor.segment_array[keep],
                elements,
                np.zeros((0, 5)),
                (),
                np.array([element_reflectance(e) for e in elements]),
            )
            for obstacle in self.obstacles:
                if obstacle.floor == level and not obstacle.timed:
                    surfaces = surfaces + obstacle_surfaces(obstacle)
            self._static[level] = surfaces
        return self._static[level]

    # --- time ------------------------------------------------------------------------------

    def step(self, dt_s: float) -> None:
        """Advance simulated time by ``dt_s``: obstacles move, the robots drive (one after
        the other in each physics sub-step, each against where the others are), contacts are
        recorded."""
        if dt_s <= 0:
            return
        for elevator in self.elevators:
            riding = [r for r in self.robots if elevator.inside(r.floor_level, *r.pose[:2])]
            arrived = elevator.step(dt_s)
            if arrived is not None:
                for robot in riding:
                    if arrived != robot.floor_level:
                        robot.place(robot.pose, arrived)
        n = max(1, math.ceil(dt_s / PHYSICS_DT_S - 1e-9))
        h = dt_s / n
        for _ in range(n):
            self.t_s += h
            for robot in self.robots:
                robot.drive(h)
            self._fire_triggers()
        for robot in self.robots:
            robot.forget_returns()

    def _fire_triggers(self) -> None:
        """Start the clock of every obstacle whose trigger point a robot has come close to."""
        for i, obstacle in enumerate(self.obstacles):
            if self.obstacle_start_s[i] is not None or obstacle.trigger_mm is None:
                continue
            at = obstacle.trigger_at or (obstacle.x_mm, obstacle.y_mm)
            for robot in self.robots:
                s = robot.body.state
                near = math.dist(at, (s.x, s.y)) <= obstacle.trigger_mm
                if near and obstacle.floor == robot.floor_level:
                    self.obstacle_start_s[i] = self.t_s
                    break


class WorldRobot:
    """One robot in the world: its body, the floor it is on, what it touched, and what its
    devices measure (ToF returns, encoders, gyro, UWB)."""

    def __init__(
        self,
        world: World,
        spec: RobotSpec,
        floor: int,
        pose: Pose,
        name: str,
        rngs: list[np.random.Generator],
    ) -> None:
        self.world = world
        self.spec = spec
        self.name = name
        self.sensors = SensorArray(spec.sensors, world.optics)
        self._tof_rng, self._gyro_rng, self._uwb_rng, self._slip_rng = rngs
        reach = max((math.hypot(m.x_mm, m.y_mm) for m in spec.sensors), default=0.0)
        self._cast_radius = world.optics.max_path_mm + reach
        self.half_diagonal_mm = math.hypot(spec.length_mm, spec.width_mm) / 2
        """How far from its centre the body reaches."""
        self.body = RobotBody(spec, pose)
        self.floor_level = world.plan.floor(floor).level
        self._command_until = math.inf
        """The motor controller's watchdog deadline for the wheel set-point (world time)."""
        self.collisions: list[Collision] = []
        self._touching: set[str] = set()
        self._layers: Layers | None = None
        self._returns: dict[tuple[int, SpadRoi], Returns] = {}

    # --- state -----------------------------------------------------------------------------

    @property
    def floor(self) -> Floor:
        return self.world.plan.floor(self.floor_level)

    @property
    def pose(self) -> Pose:
        """Ground-truth pose of the body centre."""
        return self.body.pose

    def surfaces(self, t_s: float | None = None) -> Surfaces:
        """Everything on this robot's floor but itself (see :meth:`World.surfaces`)."""
        return self.world.surfaces(self.floor_level, t_s, without=self)

    def outline(self) -> Surfaces:
        """The body as the others see and touch it: its four sides, ground to top."""
        s, spec = self.body.state, self.spec
        c, sn = math.cos(s.theta), math.sin(s.theta)
        hl, hw = spec.length_mm / 2, spec.width_mm / 2
        corners = [
            (s.x + c * dx - sn * dy, s.y + sn * dx + c * dy)
            for dx, dy in ((hl, hw), (hl, -hw), (-hl, -hw), (-hl, hw))
        ]
        sides = np.array(
            [
                [*corners[i], *corners[(i + 1) % 4], spec.ground_clearance_mm, spec.height_mm]
                for i in range(4)
            ]
        )
        return Surfaces(sides, (self.name,) * 4, np.zeros((0, 5)), (), np.full(4, ROBOT_SHELL))

    def place(self, pose: Pose, floor: int | None = None) -> None:
        """Put the robot at rest somewhere, on another floor after an elevator ride."""
        if floor is not None:
            self.floor_level = self.world.plan.floor(floor).level
        self.body.place(pose)
        self._touching.clear()
        for robot in self.world.robots:
            robot.forget_returns()
        s = self.body.state
        self._record_contacts(self._contacts(s.x, s.y, s.theta))

    def drive(self, h: float) -> None:
        """One physics sub-step of ``h`` seconds: wheels, slip, contacts."""
        if self.world.t_s >= self._command_until:
            self.command_wheels(0.0, 0.0)
        proposed = self.body.propose(h, self._slip_rng)
        contacts = self._contacts(proposed.x, proposed.y, proposed.theta)
        if contacts:
            self._record_contacts(contacts)
            self.body.stall()
        else:
            self.body.state = proposed
            if self._touching:
                clear_of = self._contacts(proposed.x, proposed.y, proposed.theta, _RELEASE_MM)
                self._touching &= clear_of.keys()

    def _contacts(
        self, x: float, y: float, theta: float, inflate_mm: float = 0.0
    ) -> dict[str, tuple[float, float]]:
        """Elements touching the footprint at a pose (grown by ``inflate_mm`` on each side)."""
        spec = self.spec
        found = self.world.touching(
            self.floor_level,
            (x, y, theta),
            (spec.length_mm / 2 + inflate_mm, spec.width_mm / 2 + inflate_mm),
            (spec.ground_clearance_mm, spec.height_mm),
            without=self,
        )
        return {c.element: (c.x_mm, c.y_mm) for c in found}

    def _record_contacts(self, contacts: dict[str, tuple[float, float]]) -> None:
        """A contact is a new collision unless the robot has stayed against that element."""
        speed = abs(self.body.state.speed_mm_s)
        for element, (x, y) in contacts.items():
            if element not in self._touching:
                self.collisions.append(
                    Collision(
                        self.world.t_s, self.floor_level, element, x, y, speed, self.body.state
                    )
                )
        self._touching |= contacts.keys()

    def clearance_mm(self, surfaces: Surfaces | None = None, radius_mm: float = 2000.0) -> float:
        """Gap between the body's rectangle and the nearest surface within the body's height
        (``surfaces``: default everything on the floor); 0 while touching, ``inf`` when
        nothing is within ``radius_mm``. Called every physics step: few, whole-array numpy
        operations."""
        if self._touching and surfaces is None:
            return 0.0
        s, spec = self.body.state, self.spec
        if surfaces is None:
            surfaces = self.surfaces()
        lo, hi = spec.ground_clearance_mm, spec.height_mm
        seg = surfaces.segments
        seg = seg[(seg[:, 5] >= lo) & (seg[:, 4] <= hi)]
        cyl = surfaces.cylinders
        cyl = cyl[(cyl[:, 4] >= lo) & (cyl[:, 3] <= hi)]
        c, sn = math.cos(s.theta), math.sin(s.theta)
        rotation = np.array([[c, -sn], [sn, c]])  # row vectors times this: the body's frame
        half = np.array([spec.length_mm / 2, spec.width_mm / 2])
        best = math.inf
        if len(seg):
            ends = (seg[:, :4].reshape(-1, 2) - (s.x, s.y)) @ rotation
            best = float(np.hypot(*np.maximum(np.abs(ends) - half, 0.0).T).min())
            corners = np.array([[1.0, 1.0], [1.0, -1.0], [-1.0, 1.0], [-1.0, -1.0]]) * half
            to_corners = segment_distances(ends.reshape(-1, 4), corners[:, :1], corners[:, 1:])
            best = min(best, float(to_corners.min()))
        if len(cyl):
            centres = (cyl[:, :2] - (s.x, s.y)) @ rotation
            rims = np.hypot(*np.maximum(np.abs(centres) - half, 0.0).T) - cyl[:, 2]
            best = min(best, max(float(rims.min()), 0.0))
        return best if best <= radius_mm else math.inf

    # --- motor controller ------------------------------------------------------------------

    def command_wheels(
        self, left_mm_s: float, right_mm_s: float, until_s: float = math.inf, brake: bool = False
    ) -> None:
        """Wheel speeds the motor controller is driving towards (nominal mm/s), until the
        world's time ``until_s``, when its watchdog stops them; ``brake``: its stop line."""
        self.body.command(left_mm_s, right_mm_s, brake)
        self._command_until = until_s

    @property
    def encoder_ticks(self) -> tuple[int, int]:
        return self.body.encoder_ticks

    @property
    def wheel_speeds_mm_s(self) -> tuple[float, float]:
        return self.body.wheel_speeds_mm_s

    def gyro_z_dps(self) -> float:
        """One gyro sample now (true rate + bias + noise)."""
        return self.body.gyro_z_dps(self._gyro_rng)

    # --- time-of-flight sensors ------------------------------------------------------------

    def forget_returns(self) -> None:
        """Something moved: the cones are cast again when next asked."""
        self._layers = None
        self._returns.clear()

    def tof_returns(self, sensor: int, roi: SpadRoi = FULL_ROI) -> Returns:
        """What sensor ``sensor`` (index into the robot's mounts) collects now through
        ``roi``, noiseless; every sensor's optics are cast, and its returns through ``roi``
        summed, once until the world moves."""
        key = (sensor, roi)
        if key not in self._returns:
            if self._layers is None:
                s = self.body.state
                near = self.world.near(self.floor_level, s.x, s.y, self._cast_radius, self)
                self._layers = self.sensors.layers(s.x, s.y, s.theta, near)
            for k, returns in enumerate(self.sensors.every_return(self._layers, roi)):
                self._returns[k, roi] = returns
        return self._returns[key]

    def tof_reading(
        self, sensor: int, setup: RangingSetup = DEFAULT_SETUP, roi: SpadRoi = FULL_ROI
    ) -> ToFReading:
        """One ranging of sensor ``sensor`` with the chip set up as ``setup``, with noise."""
        return range_once(self.tof_returns(sensor, roi), setup, self.world.noise, self._tof_rng)

    def scan(self, setup: RangingSetup = DEFAULT_SETUP) -> list[ToFReading]:
        """One ranging of every sensor through its full ROI."""
        return [self.tof_reading(k, setup) for k in range(len(self.sensors.mounts))]

    # --- UWB -------------------------------------------------------------------------------

    def uwb_tag_position(self) -> tuple[float, float, float]:
        """Ground truth of the tag antenna in the floor frame."""
        s = self.body.state
        tx, ty, tz = self.spec.uwb_tag_mm
        c, sn = math.cos(s.theta), math.sin(s.theta)
        return s.x + c * tx - sn * ty, s.y + sn * tx + c * ty, tz

    def uwb_fix(self) -> UwbFix | None:
        """What the tag would report now; ``None`` with fewer than three anchors in range."""
        model, rng = self.world.uwb_model, self._uwb_rng
        truth = np.array(self.uwb_tag_position())
        anchors = sorted(
            (float(np.linalg.norm(truth - (a.x_mm, a.y_mm, a.z_mm))), a.id, a)
            for a in self.floor.anchors
        )
        used = [(d, a) for d, _, a in anchors if d <= model.max_anchor_range_mm]
        used = used[: model.max_anchors]
        if len(used) < 3:
            return None
        ranges = [
            AnchorRange(
                anchor_id=a.id,
                x_mm=a.x_mm,
                y_mm=a.y_mm,
                z_mm=a.z_mm,
                distance_mm=max(0.0, d + model.range_sigma_mm * rng.standard_normal()),
                quality=int(np.clip(100 - d / 300, 0, 100)),
            )
            for d, a in used
        ]
        x, y, z = truth + model.position_sigma_mm * rng.standard_normal(3)
        quality = round(sum(r.quality or 0 for r in ranges) / len(ranges))
        return UwbFix(x_mm=x, y_mm=y, z_mm=z, quality=quality, anchors=ranges)
