"""Safety among people through the whole daemon: contacts, clearance, stop latency, needless stops.

    python bench/safety.py                  # the tables, for docs/safety.md
    python bench/safety.py --json           # one JSON object
    python bench/safety.py --quick          # a small subset, a few minutes
    python bench/safety.py --case crossing  # only runs whose name contains this (repeatable)
    python bench/safety.py --workers 2      # two runs at once, one process each
    python bench/safety.py --table out.json # the tables of a run saved with --save out.json

Every run is the whole daemon on the simulated robot (``coffeebot.runtime``'s simulated
assembly): the ToF poller over the simulated I2C bus, collision, state, motion, the motor
driver over the controller's pty, the simulated wheels. A small driver module stands in for
navigation and publishes one ``follow_lane`` instruction in the keep-right lane navigation
uses, at the speed under test, allowed to go round what stands still, as navigation sends it
for a hallway leg: so the speed is exactly the one under test and the event happens at full
speed where the case puts it (a delivery route drives at cruise speed and slows for doors
and turns).

Cases, each at every speed the robot may drive (``robot_speeds``: 200 mm/s, the cruise speed
and its rated maximum; ``--speeds`` for others): the seed's obstacle set head-on and
off-centre; a person crossing out of the side hallway at 500, 1000 and 1600 mm/s (ISO
13855's walking speed), from the left and, driving the other way, from the right, at 45, 90
and 135 degrees to the direction of travel, entering the robot's path 1 m and 2 m ahead; a
person stepping out of an open office door 1 m ahead, on either side; a person walking
towards the robot in its lane; one who overtakes it and stops in front; a six-year-old child
standing in the lane and running across; a swivel chair pushed into the lane; a box dropped
into the lane 1 m and 2 m ahead.

People start when the robot comes within a distance computed for the speed under test
(``ObstacleSpec.trigger_mm``), so the event happens as designed whatever the daemon's start-up
took; each run reports how far ahead the obstacle actually entered the robot's path and the
robot's speed when the walk began.

Per run, from ground truth (``coffeebot.sim.world``): each contact (what, where on the body,
relative speed, whether the robot was moving towards it, who caused it:
``coffeebot.sim.world.contact``), the least clearance to the case's obstacles, and the stop
latency: world time from the moment the obstacle was both visible to some sensor (part of it
in a cone, in range, line of sight clear: ``coffeebot.sim.world.visibility``) and in the
protective field (ahead of the body, within the stop distance the robot's own collision
config gives for its true speed then) to the first motor command, as the simulated motor
controller received it, that starts the braking. Then the needless stops: collision "stop"
verdicts per 100 m of empty hallway, stops of an idle robot over 120 simulated seconds, and
how long a robot standing in front of a static obstacle with a way out stays put before it
moves or reports "blocked".

Everything is timed in the simulated world's time. The world steps only once the daemon has
settled (``coffeebot.lockstep``), so a run depends on its seed alone, not on how busy the
machine is; ``--speed`` only paces it. Every run still counts the gaps longer than
``STALL_S`` between two collision verdicts: with the lockstep none comes from a busy machine,
so one would be a fault in the chain from the sensors to the verdict.
"""

from __future__ import annotations

import argparse
import asyncio
import contextlib
import json
import logging
import math
import os
import sys
import time
import zlib
from collections.abc import Callable, Sequence
from concurrent.futures import ProcessPoolExecutor
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import Any

import numpy as np

from coffeebot.config import RobotConfig, load_robot_config
from coffeebot.floorplan import Floor, FloorPlan, load_floorplan
from coffeebot.messages import (
    COLLISION,
    MOTION_STATUS,
    MOVE_INSTRUCTION,
    MotionState,
    MoveInstruction,
)
from coffeebot.modules.base import Module, ModuleContext
from coffeebot.navigation.route import RoutePlanner
from coffeebot.perception.collision import stop_distance_mm
from coffeebot.runtime.assemble import Runtime
from coffeebot.runtime.service import serve
from coffeebot.runtime.sim import build_sim
from coffeebot.sim.simulation import SimSetup, Simulation
from coffeebot.sim.world import ObstacleSpec, Pose, World
from coffeebot.sim.world.contact import MOVING_MM_S, judge_contact
from coffeebot.sim.world.geometry import Surfaces, footprint_contacts
from coffeebot.sim.world.obstacles import SHAPES, Pole
from coffeebot.sim.world.visibility import (
    RobotPose,
    Trajectory,
    first_time,
    in_the_way,
    seeing_sensors,
)

ROOT = Path(__file__).resolve().parents[1]
PLAN_PATH = ROOT / "floorplans" / "cs-building.toml"
BOARD_PATH = ROOT / "boards" / "coffeebot-v1.toml"

FLOOR = 2
EVENT_S_MM = 16500.0
"""Where the events happen along floor 2's hallway: plain wall on both sides for +-1 m."""
LEFT_DOOR, RIGHT_DOOR = "205", "206"
"""The office doors people step out of (left of the direction of travel, and right)."""
CROSSING_FROM = "north hall"
"""Where people cross from: the side hallway, on the robot's left driving towards +s and on
its right driving back. The robot keeps 300 mm from the right wall, so nobody stands between
it and that wall: whoever crosses its path from the right comes out of an opening or a door;
from the side hallway, out of sight until they step out."""
PERSON_HALF_MM, CHILD_HALF_MM = 180.0, 105.0
"""Half the breadth of the simulated person's torso and of the child's."""
QUICK = (
    ("cardboard_box head-on", 500),
    ("person crossing from the left at 1000 mm/s, 90 deg, 2 m ahead", 1000),
    ("box dropped 2 m ahead", 1000),
    ("child standing in the lane", 500),
)

RANGING_MM = 4000.0
"""The long distance mode's range: beyond it a sensor cannot be said to see anything."""

SAMPLE_S = 0.005
"""The probe samples ground truth this often (the world steps every 5 ms)."""
STAND_MM_S = 5.0
"""Slower than this (true speed), the robot stands."""
STOOD_S = 5.0
"""A run ends once the robot has moved and then stood this long."""
STATIC_S, MOVING_S = 20.0, 8.0
"""Simulated seconds a run gets beyond driving past the event: with something that stays in
the lane (time to go round it), and with someone who walks on."""
AFTER_CONTACT_S = 3.0
"""A run goes on this long after a contact, to see whether the robot moves on by itself."""
CONTACT_MERGE_S = 1.0
"""Touches of parts of one obstacle this close in time are one contact."""
BRAKE_STEP_MM_S = 2.0
"""A command this much slower than the one before starts the braking (below: rounding)."""
STALL_S = 0.1
"""A gap this long between two collision verdicts (five scan periods) is a gap in the chain
from the sensors to the verdict (in lockstep, never a busy machine)."""
PATH_DEPTH_MM = 6000.0
"""The body's path ahead, for where an obstacle entered it."""
HELD_LIMIT_S = 60.0
IDLE_S = 120.0


# --- the lane, and the cases --------------------------------------------------------------


@dataclass(frozen=True)
class Lane:
    """A hallway's frame and the robot's keep-right lane in it, driven towards ``direction``
    (+1: increasing ``s``). Lateral positions (``lat``) are to the left of the direction of
    travel, so the lane is at a negative ``lat`` either way."""

    floor: Floor
    direction: float
    lane_mm: float
    half_width_mm: float
    half_length_mm: float
    accel_mm_s2: float

    def point(self, s: float, lat: float) -> tuple[float, float]:
        return self.floor.from_hallway(s, self.direction * lat)

    def ahead(self, s: float, mm: float) -> float:
        """The along-hallway position ``mm`` further in the direction of travel."""
        return s + self.direction * mm

    def beyond(self, x: float, y: float, s: float) -> bool:
        """Whether floor point (x, y) is past ``s`` in the direction of travel."""
        return (self.floor.to_hallway(x, y)[0] - s) * self.direction >= 0

    @property
    def heading_deg(self) -> float:
        return self.floor.hallway.heading_deg + (0.0 if self.direction > 0 else 180.0)

    def runup_mm(self, speed: float) -> float:
        """Distance to reach ``speed`` from standstill with motion's speed profile."""
        return speed * speed / (2.0 * self.accel_mm_s2)

    def start_before(self, trigger_centre_s: float, speed: float) -> float:
        """Where to start so the robot has driven one second at ``speed`` before the body's
        centre reaches ``trigger_centre_s``."""
        return self.ahead(trigger_centre_s, -(self.runup_mm(speed) + speed * 1.0 + 300.0))


@dataclass(frozen=True)
class Setup:
    """One run: where the robot starts, what is there, when it is over."""

    start_s: float
    obstacles: list[ObstacleSpec]
    pass_s: float
    """The robot's centre past this: it has gone by (or round) the event."""
    time_limit_s: float
    designed_ahead_mm: float | None = None
    """How far ahead of the front the obstacle is meant to enter the robot's path."""
    open_door: str | None = None


@dataclass(frozen=True)
class Case:
    name: str
    group: str
    build: Callable[[Lane, float], Setup]
    direction: float = 1.0
    """The direction of travel along the hallway (-1: the other way)."""


def _spec(
    ident: str, kind: str, at: tuple[float, float], heading_deg: float = 0.0, **extra: Any
) -> ObstacleSpec:
    return ObstacleSpec.model_validate(
        {
            "id": ident,
            "kind": kind,
            "floor": FLOOR,
            "x_mm": at[0],
            "y_mm": at[1],
            "heading_deg": heading_deg,
            **extra,
        }
    )


def _limit(lane: Lane, start_s: float, pass_s: float, speed: float, extra_s: float) -> float:
    """Simulated seconds for a run: start-up, the drive at ``speed``, and ``extra_s``."""
    return 5.0 + abs(pass_s - start_s) / speed + extra_s


def static_case(kind: str, offset_mm: float) -> Callable[[Lane, float], Setup]:
    """``kind`` standing in the lane ahead, ``offset_mm`` to the left of its centre line."""

    def build(lane: Lane, speed: float) -> Setup:
        start = lane.start_before(lane.ahead(EVENT_S_MM, -lane.half_length_mm - 3000.0), speed)
        at = lane.point(EVENT_S_MM, lane.lane_mm + offset_mm)
        obstacle = _spec(kind, kind, at, lane.heading_deg)
        pass_s = lane.ahead(EVENT_S_MM, 1500.0)
        return Setup(start, [obstacle], pass_s, _limit(lane, start, pass_s, speed, STATIC_S))

    return build


@dataclass(frozen=True)
class Walk:
    """Someone walking out of a side opening or an office door (``origin``) across the
    hallway at ``angle_deg`` to the robot's direction of travel (45: walking its way, 135:
    towards it), on to the far side beyond the robot's path, timed to enter the path
    ``ahead_mm`` ahead of the robot's front (if the robot keeps its speed)."""

    kind: str
    speed_mm_s: float
    origin: str
    """An opening's id, or ``door <id>`` (that door then stands open)."""
    angle_deg: float
    ahead_mm: float
    half_mm: float
    """Half the walker's breadth (the torso's): when that edge meets the robot's path."""

    def start(self, lane: Lane) -> tuple[float, float]:
        """(s, lat) out of sight: 600 mm behind the wall line in the middle of an opening,
        500 mm inside an office in front of its door."""
        wall = lane.floor.hallway.width_mm / 2
        if self.origin.startswith("door "):
            door = lane.floor.door(self.origin.removeprefix("door "))
            at, side, depth = door.at_mm, door.side, wall + door.recess_mm + 500.0
        else:
            opening = next(o for o in lane.floor.openings if o.id == self.origin)
            at, side, depth = opening.at_mm, opening.side, wall + 600.0
        return at, lane.direction * (depth if side == "left" else -depth)

    def build(self, lane: Lane, speed: float) -> Setup:
        s0, lat0 = self.start(lane)
        side = 1.0 if lat0 > lane.lane_mm else -1.0
        edge = lane.lane_mm + side * (lane.half_width_mm + self.half_mm)
        # The far side: against the left wall, or on the right clear of the robot's path
        # (the robot keeps 300 mm from the right wall: a person there stands flat to it).
        end_lat = lane.floor.hallway.width_mm / 2 - self.half_mm - 10.0
        if side > 0:
            end_lat = lane.lane_mm - lane.half_width_mm - self.half_mm - 60.0
        a = math.radians(self.angle_deg)
        w_along, w_lat = math.cos(a), -side * math.sin(a)

        def at(lat: float) -> float:
            """Where along the hallway the walk is when it is at ``lat``."""
            return lane.ahead(s0, (lat - lat0) / w_lat * w_along)

        entry_s = at(edge)
        to_edge = abs(edge - lat0) / math.sin(a)
        trigger_mm = lane.half_length_mm + self.ahead_mm + speed * to_edge / self.speed_mm_s
        walker = _spec(
            self.kind,
            self.kind,
            lane.point(s0, lat0),
            path=[lane.point(at(end_lat), end_lat)],
            speed_mm_s=self.speed_mm_s,
            path_mode="once",
            trigger_mm=trigger_mm,
            trigger_at=lane.point(entry_s, lane.lane_mm),
        )
        start = lane.start_before(lane.ahead(entry_s, -trigger_mm), speed)
        crossed = max(entry_s, at(lane.lane_mm), key=lambda s: s * lane.direction)
        pass_s = lane.ahead(crossed, 2 * lane.half_length_mm)
        door = self.origin.removeprefix("door ") if self.origin.startswith("door ") else None
        limit = _limit(lane, start, pass_s, speed, MOVING_S)
        return Setup(start, [walker], pass_s, limit, self.ahead_mm, door)


def towards_case(walk_mm_s: float) -> Callable[[Lane, float], Setup]:
    """A person walking towards the robot in its lane, starting 5 m ahead of it."""

    def build(lane: Lane, speed: float) -> Setup:
        start_at = lane.ahead(EVENT_S_MM, 1000.0)
        trigger = lane.half_length_mm + 5000.0
        walker = _spec(
            "person",
            "person",
            lane.point(start_at, lane.lane_mm),
            path=[lane.point(lane.ahead(start_at, -15000.0), lane.lane_mm)],
            speed_mm_s=walk_mm_s,
            path_mode="once",
            trigger_mm=trigger,
        )
        start = lane.start_before(lane.ahead(start_at, -trigger), speed)
        pass_s = lane.ahead(start_at, 1500.0)
        return Setup(start, [walker], pass_s, _limit(lane, start, start_at, speed, MOVING_S))

    return build


def overtake_case(lane: Lane, speed: float) -> Setup:
    """Someone 1 m/s faster (hurrying, jogging past a fast robot) overtakes on the left,
    cuts in and stops in the lane once they are 1.2 m ahead of the front (if the robot keeps
    its speed). They start behind the robot's rear, out of its cones, once it is at speed."""
    start = lane.ahead(EVENT_S_MM, -6000.0)
    trigger_s = lane.ahead(start, lane.runup_mm(speed) + 800.0)
    trigger_mm, side_lat, walk = 300.0, 300.0, speed + 1000.0
    person_s = lane.ahead(start, -1000.0)
    front_at_trigger = lane.ahead(trigger_s, 2 * lane.half_length_mm - trigger_mm)
    gap = (front_at_trigger - person_s) * lane.direction + 1200.0
    cut_s = lane.ahead(person_s, walk * gap / (walk - speed))
    stop_s = lane.ahead(cut_s, 600.0)
    walker = _spec(
        "person",
        "person",
        lane.point(person_s, side_lat),
        path=[lane.point(cut_s, side_lat), lane.point(stop_s, lane.lane_mm)],
        speed_mm_s=walk,
        path_mode="once",
        trigger_mm=trigger_mm,
        trigger_at=lane.point(trigger_s, lane.lane_mm),
    )
    pass_s = lane.ahead(stop_s, 1500.0)
    return Setup(start, [walker], pass_s, _limit(lane, start, pass_s, speed, STATIC_S))


def chair_case(lane: Lane, speed: float) -> Setup:
    """A swivel chair pushed at 500 mm/s from the left wall into the lane, where it stays; it
    comes to rest with its near edge 2 m ahead of the robot's front (at the speed under
    test)."""
    start_lat, half = 600.0, 240.0
    travel = start_lat - lane.lane_mm
    trigger_mm = half + lane.half_length_mm + 2000.0 + speed * travel / 500.0
    chair = _spec(
        "chair",
        "swivel_chair",
        lane.point(EVENT_S_MM, start_lat),
        path=[lane.point(EVENT_S_MM, lane.lane_mm)],
        speed_mm_s=500.0,
        path_mode="once",
        trigger_mm=trigger_mm,
        trigger_at=lane.point(EVENT_S_MM, lane.lane_mm),
    )
    start = lane.start_before(lane.ahead(EVENT_S_MM, -trigger_mm), speed)
    pass_s = lane.ahead(EVENT_S_MM, 1500.0)
    return Setup(start, [chair], pass_s, _limit(lane, start, pass_s, speed, STATIC_S), 2000.0)


def dropped_box_case(ahead_mm: float) -> Callable[[Lane, float], Setup]:
    """A cardboard box that appears in the lane, its near face ``ahead_mm`` ahead."""

    def build(lane: Lane, speed: float) -> Setup:
        trigger_mm = 250.0 + lane.half_length_mm + ahead_mm
        box = _spec(
            "box",
            "cardboard_box",
            lane.point(EVENT_S_MM, lane.lane_mm),
            lane.heading_deg,
            trigger_mm=trigger_mm,
            appear_s=0.0,
        )
        start = lane.start_before(lane.ahead(EVENT_S_MM, -trigger_mm), speed)
        pass_s = lane.ahead(EVENT_S_MM, 1500.0)
        limit = _limit(lane, start, pass_s, speed, STATIC_S)
        return Setup(start, [box], pass_s, limit, ahead_mm)

    return build


def cases() -> list[Case]:
    found: list[Case] = []
    for kind in ("cardboard_box", "mail_cart", "sofa", "swivel_chair", "wooden_chair"):
        sofa = 300.0 if kind == "sofa" else 0.0  # its 900 mm depth reaches into the lane
        for label, offset in (("head-on", 0.0), ("off-centre", 200.0)):
            found.append(Case(f"{kind} {label}", "obstacle set", static_case(kind, offset + sofa)))
    for walk in (500.0, 1000.0, 1600.0):
        for side, direction in (("left", 1.0), ("right", -1.0)):
            for angle in (45.0, 90.0, 135.0):
                for ahead in (1000.0, 2000.0):
                    name = (
                        f"person crossing from the {side} at {walk:.0f} mm/s, {angle:.0f} deg, "
                        f"{ahead / 1000:.0f} m ahead"
                    )
                    spec = Walk("person", walk, CROSSING_FROM, angle, ahead, PERSON_HALF_MM)
                    found.append(Case(name, "crossing", spec.build, direction))
    for door in (LEFT_DOOR, RIGHT_DOOR):
        for walk in (1000.0, 1600.0):
            name = f"person out of door {door} at {walk:.0f} mm/s, 1 m ahead"
            spec = Walk("person", walk, f"door {door}", 90.0, 1000.0, PERSON_HALF_MM)
            found.append(Case(name, "door", spec.build))
    for walk in (1000.0, 1600.0):
        found.append(
            Case(f"person walking towards at {walk:.0f} mm/s", "towards", towards_case(walk))
        )
    found.append(Case("person overtaking, stops in front", "overtake", overtake_case))
    found.append(Case("child standing in the lane", "child", static_case("child", 0.0)))
    child = Walk("child", 1600.0, CROSSING_FROM, 90.0, 2000.0, CHILD_HALF_MM)
    found.append(Case("child running across from the left, 2 m ahead", "child", child.build))
    found.append(Case("swivel chair pushed into the lane", "chair", chair_case))
    for ahead in (1000.0, 2000.0):
        name = f"box dropped {ahead / 1000:.0f} m ahead"
        found.append(Case(name, "box", dropped_box_case(ahead)))
    return found


# --- the daemon, its stand-in for navigation, and the probe --------------------------------


async def run_daemon(
    config: RobotConfig,
    plan: FloorPlan,
    setup: SimSetup,
    modules: Callable[[Simulation, Callable[[str], None]], list[Module]],
) -> Simulation:
    """The whole daemon on the simulated robot, plus ``modules`` (given the simulation and
    the function that ends the run), until one of them ends it. The one place this benchmark
    uses the runtime."""

    def extra(runtime: Runtime, sim: Simulation) -> list[Module]:
        return modules(sim, runtime.request_stop)

    async with build_sim(config, plan, setup, extra, web=False) as (runtime, sim):
        await serve(runtime)
    return sim


class LaneDriver(Module):
    """Stands in for navigation: one instruction, published once."""

    name = "lane-driver"
    outputs = (MOVE_INSTRUCTION,)

    def __init__(self, instruction: MoveInstruction) -> None:
        self.instruction = instruction

    async def run(self, ctx: ModuleContext) -> None:
        ctx.board.publish(MOVE_INSTRUCTION, self.instruction)


@dataclass
class Record:
    """What the probe saw, in world time."""

    samples: list[tuple[float, float, float, float, float, float]] = field(default_factory=list)
    """(t, x, y, theta, speed, yaw rate) of the body."""
    clearance_mm: float = math.inf
    """The least gap between the body and the watched obstacles."""
    moved: bool = False
    """The body has been more than 100 mm from where it started."""
    still_since: float | None = None
    """Since when the body has stood (None: it is moving)."""
    verdicts: list[tuple[float, str, str]] = field(default_factory=list)
    """Every change of the collision verdict's state: (t, state, reason)."""
    motion: list[tuple[float, str, str]] = field(default_factory=list)
    """Every change of motion's state: (t, state, detail)."""
    stalls: list[tuple[float, float]] = field(default_factory=list)
    """(t, gap) of every gap between two collision verdicts longer than ``STALL_S``."""
    ended: str = ""

    def sample(self, t: float, body: Any) -> None:
        self.samples.append((t, body.x, body.y, body.theta, body.speed_mm_s, body.yaw_rate_rad_s))
        x0, y0 = self.samples[0][1:3]
        self.moved = self.moved or math.hypot(body.x - x0, body.y - y0) > 100.0
        standing = abs(body.speed_mm_s) < STAND_MM_S and abs(body.yaw_rate_rad_s) < 0.01
        if not standing:
            self.still_since = None
        elif self.still_since is None:
            self.still_since = t

    def stood_s(self) -> float:
        """How long the robot has stood since it last moved, once it has driven at all."""
        if not self.moved or self.still_since is None:
            return 0.0
        return self.samples[-1][0] - self.still_since

    def first_moving_s(self) -> float:
        return next((s[0] for s in self.samples if abs(s[4]) >= STAND_MM_S), math.inf)

    def stall_fields(self) -> dict[str, Any]:
        """How often, and for how long at most, the collision verdicts had a gap."""
        longest = max((gap for _, gap in self.stalls), default=0.0)
        return {"stalls": len(self.stalls), "longest_stall_ms": round(longest * 1000.0)}

    def stops_after(self, t_s: float) -> list[tuple[float, str]]:
        """Changes of the collision verdict into "stop" from ``t_s`` on."""
        return [(t, why) for t, state, why in self.verdicts if state == "stop" and t >= t_s]


EndRule = Callable[[Simulation, Record], str | None]


class Probe(Module):
    """Samples ground truth every ``SAMPLE_S`` (and the gap to the ``watch``ed obstacles),
    records every change of the collision verdict and of motion's state, and ends the run
    when ``end`` says why."""

    name = "safety-probe"
    inputs = (COLLISION, MOTION_STATUS)

    def __init__(
        self,
        sim: Simulation,
        finish: Callable[[str], None],
        end: EndRule,
        watch: Sequence[int] = (),
    ) -> None:
        self.sim = sim
        self.finish = finish
        self.end = end
        self.watch = tuple(watch)
        self.record = Record()

    def _world_now(self) -> float:
        now = self.sim.clock.now()
        return self.sim.world_t(now)

    async def _changes(
        self,
        ctx: ModuleContext,
        topic: Any,
        into: list[tuple[float, str, str]],
        state: Callable[[Any], tuple[str, str]],
        stalls: list[tuple[float, float]] | None = None,
    ) -> None:
        """Every change of ``state(message)`` on ``topic``, and the gaps in its stream."""
        previous, last = None, None
        with ctx.board.subscribe(topic) as messages:
            async for envelope in messages:
                now = self._world_now()
                if stalls is not None and last is not None and now - last > STALL_S:
                    stalls.append((last, now - last))
                last = now
                value, detail = state(envelope.msg)
                if value != previous:
                    into.append((now, value, detail))
                    previous = value

    async def run(self, ctx: ModuleContext) -> None:
        record = self.record
        watchers = [
            asyncio.create_task(
                self._changes(
                    ctx, COLLISION, record.verdicts, lambda m: (m.state, m.reason), record.stalls
                )
            ),
            asyncio.create_task(
                self._changes(ctx, MOTION_STATUS, record.motion, lambda m: (m.state, m.detail))
            ),
        ]
        try:
            while True:
                with self.sim.world_time() as world:
                    record.sample(world.t_s, world.robot.body.state)
                    for i in self.watch:
                        gap = world.robot.clearance_mm(world.obstacle_at(i))
                        record.clearance_mm = min(record.clearance_mm, gap)
                why = self.end(self.sim, record)
                if why is not None:
                    record.ended = why
                    self.finish(why)
                    return
                await ctx.clock.sleep(SAMPLE_S)
        finally:
            for task in watchers:
                task.cancel()
                with contextlib.suppress(asyncio.CancelledError):
                    await task


def case_end(lane: Lane, setup: Setup) -> EndRule:
    def end(sim: Simulation, record: Record) -> str | None:
        world = sim.world
        if world.robot.collisions and world.t_s - world.robot.collisions[0].t_s >= AFTER_CONTACT_S:
            return "contact"
        if world.t_s >= setup.time_limit_s:
            return "time limit"
        if lane.beyond(world.robot.pose.x_mm, world.robot.pose.y_mm, setup.pass_s):
            return "passed"
        if record.stood_s() >= STOOD_S:
            return "stood still"
        return None

    return end


# --- judging a run from ground truth --------------------------------------------------------


def forward_commands(sim: Simulation) -> list[tuple[float, float]]:
    """(world time, forward speed) of every command the motor controller accepted."""
    return [(sim.world_t(c.time_s), (c.left_mm_s + c.right_mm_s) / 2.0) for c in sim.motor.commands]


def braking_start(
    commands: Sequence[tuple[float, float]], after_s: float, speed_then_mm_s: float
) -> float | None:
    """When braking started for something that became a hazard at ``after_s``: then, if the
    last command before it already asked for less than the body's speed at that moment;
    otherwise the first later command slower than the one before it. None: never."""
    before = [f for t, f in commands if t < after_s]
    if before and before[-1] < abs(speed_then_mm_s) - 20.0:
        return after_s
    previous = before[-1] if before else 0.0
    for t, forward in commands:
        if t < after_s:
            continue
        if forward < previous - BRAKE_STEP_MM_S or forward <= 0.0 < previous:
            return t
        previous = forward
    return None


def first_stop(commands: Sequence[tuple[float, float]], after_s: float) -> float | None:
    """The first command at or after ``after_s`` asking for no forward speed."""
    before = [f for t, f in commands if t < after_s]
    if before and before[-1] <= 0.0:
        return after_s
    return next((t for t, f in commands if t >= after_s and f <= 0.0), None)


def _object_velocity(world: World, index: int, t_s: float) -> tuple[float, float]:
    """An obstacle's velocity at world time ``t_s`` (over the 10 ms before it)."""
    spec = world.obstacles[index]
    before, now = world.obstacle_clock_s(index, t_s - 0.01), world.obstacle_clock_s(index, t_s)
    if before is None or now is None or not spec.moving:
        return 0.0, 0.0
    x0, y0, _ = spec.pose_at(before)
    x1, y1, _ = spec.pose_at(now)
    return (x1 - x0) / (now - before), (y1 - y0) / (now - before)


def _element(world: World, collision: Any) -> Surfaces:
    """The touched element's surfaces at the moment of the touch."""
    everything = world.surfaces(collision.floor, collision.t_s)
    return everything.take(
        np.flatnonzero(np.array(everything.segment_ids, dtype=object) == collision.element),
        np.flatnonzero(np.array(everything.cylinder_ids, dtype=object) == collision.element),
    )


def judged_contacts(world: World) -> list[dict[str, Any]]:
    """Every contact, judged; touches of parts of one obstacle within ``CONTACT_MERGE_S``
    of each other are one contact."""
    owners = {spec.id: i for i, spec in enumerate(world.obstacles)}
    found: list[dict[str, Any]] = []
    last: dict[str, float] = {}
    for c in world.robot.collisions:
        owner = next((o for o in owners if c.element.startswith(f"{o} ")), None)
        key = owner or c.element
        merged = key in last and c.t_s - last[key] <= CONTACT_MERGE_S
        last[key] = c.t_s
        if merged or c.body is None:
            continue
        velocity = (0.0, 0.0) if owner is None else _object_velocity(world, owners[owner], c.t_s)
        j = judge_contact(
            c.element, (c.x_mm, c.y_mm), c.body, world.robot.spec, velocity, _element(world, c)
        )
        found.append(
            {
                "t": round(c.t_s, 3),
                "what": c.element,
                "where": j.region,
                "robot_speed_mm_s": round(j.robot_speed_mm_s),
                "robot_towards_mm_s": round(j.robot_towards_mm_s),
                "relative_speed_mm_s": round(j.closing_mm_s),
                "robot_moving_towards": j.robot_moving_towards,
                "cause": j.cause,
            }
        )
    return found


def _ms(start: float | None, end: float | None) -> float | None:
    return None if start is None or end is None else round((end - start) * 1000.0, 1)


def _round(value: float | None, digits: int = 0) -> float | None:
    if value is None or not math.isfinite(value):
        return None
    return round(value, digits)


def judge_run(sim: Simulation, record: Record, config: RobotConfig) -> dict[str, Any]:
    """Contacts, clearance and stop latency of one run whose every obstacle is the case's."""
    world = sim.world
    trajectory = Trajectory.from_samples([s[:5] for s in record.samples])
    mounts = world.robot.sensors.mounts
    max_range = RANGING_MM
    reach = max_range + max(math.hypot(m.x_mm, m.y_mm) for m in mounts)
    commands = forward_commands(sim)

    def target(t: float) -> Surfaces:
        found = Surfaces.empty()
        for i in range(len(world.obstacles)):
            found = found + world.obstacle_at(i, t)
        return found

    def visible(t: float, pose: RobotPose) -> bool:
        seen = target(t)
        if not any(len(i) for i in seen.near(pose.x_mm, pose.y_mm, reach)):
            return False
        return bool(seeing_sensors(seen, world.robot.surfaces(t), mounts, pose, max_range))

    def hazard(t: float, pose: RobotPose) -> bool:
        speed = abs(pose.speed_mm_s)
        if speed < MOVING_MM_S:
            return False
        depth = stop_distance_mm(config.collision, speed)
        return in_the_way(target(t), pose, world.robot.spec, depth) and visible(t, pose)

    def in_path(t: float, pose: RobotPose) -> bool:
        return in_the_way(target(t), pose, world.robot.spec, PATH_DEPTH_MM)

    seen_s = first_time(trajectory, visible)
    hazard_s = first_time(trajectory, hazard)
    entered_s = first_time(trajectory, in_path)
    ahead = None
    if entered_s is not None:
        ahead = distance_ahead_mm(target(entered_s), trajectory.at(entered_s), world)
    speed_then = None if hazard_s is None else trajectory.at(hazard_s).speed_mm_s
    brake_s = None if hazard_s is None else braking_start(commands, hazard_s, speed_then or 0.0)
    seen_brake_s = None if seen_s is None else braking_start(commands, seen_s, 0.0)
    touched = judged_contacts(world)
    reaction_end = brake_s if brake_s is not None else world.t_s
    if touched:
        reaction_end = min(reaction_end, touched[0]["t"])
    starved = hazard_s is not None and any(
        t < reaction_end and t + gap > hazard_s for t, gap in record.stalls
    )
    return {
        "outcome": record.ended,
        "contacts": touched,
        "robot_caused": sum(c["cause"] == "robot_caused" for c in touched),
        "walked_into_robot": sum(c["cause"] == "walked_into_robot" for c in touched),
        "min_clearance_mm": 0.0 if touched else _round(record.clearance_mm),
        "first_visible_s": _round(seen_s, 3),
        "hazard_s": _round(hazard_s, 3),
        "speed_at_hazard_mm_s": _round(speed_then),
        "entered_path_ahead_mm": _round(ahead),
        "brake_s": _round(brake_s, 3),
        "stop_s": _round(None if hazard_s is None else first_stop(commands, hazard_s), 3),
        "stop_latency_ms": _ms(hazard_s, brake_s),
        "never_braked": hazard_s is not None and brake_s is None,
        "starved_in_reaction": starved,
        "visible_to_brake_ms": _ms(seen_s, seen_brake_s),
        "safety_stops": len(record.stops_after(record.first_moving_s())),
        **record.stall_fields(),
        "sim_s": round(world.t_s, 2),
    }


def distance_ahead_mm(surfaces: Surfaces, pose: RobotPose, world: World) -> float | None:
    """How far ahead of the front face the nearest part of ``surfaces`` in the body's path
    (its width, ``PATH_DEPTH_MM`` deep, within its height) is."""
    robot = world.robot.spec
    c, s = math.cos(pose.theta), math.sin(pose.theta)
    ahead = robot.length_mm / 2 + PATH_DEPTH_MM / 2
    hits = footprint_contacts(
        surfaces,
        pose.x_mm + ahead * c,
        pose.y_mm + ahead * s,
        pose.theta,
        PATH_DEPTH_MM / 2,
        robot.width_mm / 2,
        (robot.ground_clearance_mm, robot.height_mm),
    )
    along = [(h.x_mm - pose.x_mm) * c + (h.y_mm - pose.y_mm) * s for h in hits]
    return min(along) - robot.length_mm / 2 if along else None


# --- the runs -------------------------------------------------------------------------------


def load(direction: float = 1.0) -> tuple[RobotConfig, FloorPlan, Lane]:
    """The robot, the building, and floor 2's keep-right lane towards ``direction`` as
    navigation drives it."""
    config = load_robot_config(BOARD_PATH)
    plan = load_floorplan(PLAN_PATH)
    floor = plan.floor(FLOOR)
    planner = RoutePlanner.for_robot(plan, config)
    lane = Lane(
        floor,
        direction,
        direction * planner.lane_mm(floor, direction),
        config.geometry.width_mm / 2,
        config.geometry.length_mm / 2,
        config.motion.accel_mm_s2,
    )
    return config, plan, lane


def with_open_door(plan: FloorPlan, level: int, door_id: str) -> FloorPlan:
    """The plan with one door standing open (the world's and the robot's)."""
    raw = plan.model_dump()
    for floor in raw["floors"]:
        for door in floor["doors"] if floor["level"] == level else ():
            door["open"] = door["open"] or door["id"] == door_id
    return FloorPlan.model_validate(raw)


def _seed(*parts: object) -> int:
    return zlib.crc32(" ".join(map(str, parts)).encode()) % 1_000_000


def lane_instruction(lane: Lane, to_s: float, speed: float) -> MoveInstruction:
    """What navigation sends for a hallway leg: keep right, go round what stands still."""
    return MoveInstruction(
        id=1,
        action="follow_lane",
        floor=lane.floor.level,
        target_s_mm=to_s,
        lane_mm=lane.direction * lane.lane_mm,
        speed_mm_s=speed,
        stop=True,
        avoid=True,
        detail="along the hallway",
    )


def _on_lane(lane: Lane, s: float) -> Pose:
    x, y = lane.point(s, lane.lane_mm)
    return Pose(x, y, lane.heading_deg)


def run_case(name: str, speed: float, sim_speed: float) -> dict[str, Any]:
    """One case at one robot speed, through the whole daemon."""
    case = next(c for c in cases() if c.name == name)
    config, plan, lane = load(case.direction)
    setup = case.build(lane, speed)
    if setup.open_door is not None:
        plan = with_open_door(plan, FLOOR, setup.open_door)
        lane = replace(lane, floor=plan.floor(FLOOR))
    sim_setup = SimSetup(
        FLOOR,
        _on_lane(lane, setup.start_s),
        obstacles=setup.obstacles,
        seed=_seed(name, speed),
        speed=sim_speed,
    )
    probe: list[Probe] = []

    def modules(sim: Simulation, finish: Callable[[str], None]) -> list[Module]:
        probe.append(Probe(sim, finish, case_end(lane, setup), range(len(setup.obstacles))))
        target = lane.ahead(setup.pass_s, 6000.0)
        return [LaneDriver(lane_instruction(lane, target, speed)), probe[0]]

    started = time.monotonic()
    sim = asyncio.run(run_daemon(config, plan, sim_setup, modules))
    record = probe[0].record
    row = judge_run(sim, record, config)
    triggered = [t for t in sim.world.obstacle_start_s if t is not None and t > 0]
    at_trigger = None
    if triggered:
        at_trigger = Trajectory.from_samples([r[:5] for r in record.samples]).at(triggered[0])
    return {
        "case": name,
        "group": case.group,
        "speed_mm_s": speed,
        **row,
        "designed_ahead_mm": setup.designed_ahead_mm,
        "speed_at_trigger_mm_s": None if at_trigger is None else round(at_trigger.speed_mm_s),
        "wall_s": round(time.monotonic() - started),
    }


def run_hallway(level: int, speed: float, sim_speed: float) -> dict[str, Any]:
    """Floor ``level``'s empty hallway, end to end at ``speed``: every stop is needless."""
    config, plan, lane = load()
    lane = replace(lane, floor=plan.floor(level))
    start_s, end_s = 1500.0, lane.floor.hallway.length_mm - 4000.0
    setup = SimSetup(level, _on_lane(lane, start_s), seed=_seed(level, speed), speed=sim_speed)
    limit = 10.0 + (end_s - start_s) / speed * 1.5
    probe: list[Probe] = []

    def end(sim: Simulation, record: Record) -> str | None:
        if record.motion and record.motion[-1][1] == MotionState.DONE:
            return "at the end"
        return "time limit" if sim.world.t_s >= limit else None

    def modules(sim: Simulation, finish: Callable[[str], None]) -> list[Module]:
        probe.append(Probe(sim, finish, end))
        return [LaneDriver(lane_instruction(lane, end_s, speed)), probe[0]]

    sim = asyncio.run(run_daemon(config, plan, setup, modules))
    record = probe[0].record
    xy = np.array([s[1:3] for s in record.samples]).reshape(-1, 2)
    driven_mm = float(np.hypot(*np.diff(xy, axis=0).T).sum())
    moving = record.first_moving_s()
    stops = record.stops_after(moving)
    gate = [why for t, state, why in record.motion if state == "safety_stop" and t >= moving]
    return {
        "floor": level,
        "speed_mm_s": speed,
        "driven_m": round(driven_mm / 1000.0, 2),
        "outcome": record.ended,
        "collision_stops": len(stops),
        "stop_reasons": [why for _, why in stops],
        "safety_stops": len(gate),
        "safety_stop_reasons": gate,
        "standstills": standstills(record),
        **record.stall_fields(),
        "contacts": len(sim.robot.collisions),
        "sim_s": round(sim.world.t_s, 1),
    }


def standstills(record: Record) -> int:
    """Times the robot came to a stand after driving, before motion reported "done"."""
    done = next((t for t, state, _ in record.motion if state == MotionState.DONE), math.inf)
    count, driving = 0, False
    for t, _x, _y, _h, speed, _yaw in record.samples:
        if t >= done:
            break
        if abs(speed) >= 50.0:
            driving = True
        elif driving and abs(speed) < STAND_MM_S:
            count, driving = count + 1, False
    return count


def idle_poses(plan: FloorPlan, config: RobotConfig) -> dict[str, tuple[int, Pose]]:
    """The demo's start at the tea room door, and the parking spot inside the tea room."""
    floor, door = plan.tea_room
    x, y = floor.from_hallway(door.at_mm, 0.0)
    inside = floor.hallway.width_mm / 2 + door.recess_mm + config.navigation.base_depth_mm
    sign = 1.0 if door.side == "left" else -1.0
    px, py = floor.from_hallway(door.at_mm, sign * inside)
    facing_out = floor.hallway.heading_deg - sign * 90.0
    return {
        "at the tea room door, facing down the hallway": (
            floor.level,
            Pose(x, y, floor.hallway.heading_deg + 180.0),
        ),
        "parked in the tea room, facing its door": (floor.level, Pose(px, py, facing_out)),
    }


def run_idle(where: str, sim_speed: float) -> dict[str, Any]:
    """The robot standing ``IDLE_S`` with nothing to do: every collision stop is needless."""
    config, plan, _ = load()
    level, pose = idle_poses(plan, config)[where]
    setup = SimSetup(level, pose, seed=_seed(where), speed=sim_speed)
    probe: list[Probe] = []

    def end(sim: Simulation, record: Record) -> str | None:
        return "time limit" if sim.world.t_s >= IDLE_S else None

    def modules(sim: Simulation, finish: Callable[[str], None]) -> list[Module]:
        probe.append(Probe(sim, finish, end))
        return [probe[0]]

    asyncio.run(run_daemon(config, plan, setup, modules))
    record = probe[0].record
    first_go = next((t for t, state, _ in record.verdicts if state != "stop"), math.inf)
    stops = record.stops_after(first_go)
    return {
        "where": where,
        "stops": len(stops),
        "stop_reasons": sorted({why for _, why in stops}),
        "never_cleared": math.isinf(first_go),
        **record.stall_fields(),
        "sim_s": IDLE_S,
    }


HELD = {
    "cardboard_box off-centre, 400 mm ahead": ("cardboard_box", 400.0, 365.0),
    "mail_cart head-on, 400 mm ahead": ("mail_cart", 400.0, 0.0),
    "wooden_chair off-centre, 400 mm ahead": ("wooden_chair", 400.0, 200.0),
}
"""A robot standing in front of a static obstacle: (kind, gap ahead of the front face, offset
of the obstacle to the left of the lane). The box is seen by one front sensor only (a narrow
return), the cart's corner bars by the outer two. In each the hallway behind is empty and the
lane can be left to one side, so backing off or turning out is a way out."""


def _near_reach_mm(kind: str) -> float:
    """How far an obstacle's parts reach from its centre towards the robot (its -x side)."""
    return max((p.radius if isinstance(p, Pole) else p.length / 2) - p.cx for p in SHAPES[kind])


def held_out(record: Record) -> tuple[float, str] | None:
    """When a held robot first moved (50 mm or 5 degrees) or reported blocked, and which."""
    blocked = [(t, f"reported blocked: {why}") for t, s, why in record.motion if s == "blocked"]
    x0, y0, h0 = record.samples[0][1:4]
    moved = [
        (t, "moved")
        for t, x, y, h, _v, _w in record.samples
        if math.hypot(x - x0, y - y0) > 50.0 or abs(h - h0) > math.radians(5.0)
    ]
    found = blocked[:1] + moved[:1]
    return min(found) if found else None


def run_held(name: str, sim_speed: float) -> dict[str, Any]:
    """How long a robot standing in front of a static obstacle, with a way out, stays put."""
    config, plan, lane = load()
    kind, gap, offset = HELD[name]
    start_s = EVENT_S_MM - _near_reach_mm(kind) - gap - lane.half_length_mm
    obstacle = _spec(kind, kind, lane.point(EVENT_S_MM, lane.lane_mm + offset))
    setup = SimSetup(FLOOR, _on_lane(lane, start_s), [obstacle], seed=_seed(name), speed=sim_speed)
    probe: list[Probe] = []

    def end(sim: Simulation, record: Record) -> str | None:
        if record.samples and held_out(record) is not None:
            return "out"
        return "time limit" if sim.world.t_s >= HELD_LIMIT_S else None

    def modules(sim: Simulation, finish: Callable[[str], None]) -> list[Module]:
        probe.append(Probe(sim, finish, end, [0]))
        cruise = config.motion.cruise_speed_mm_s
        return [LaneDriver(lane_instruction(lane, EVENT_S_MM + 8000.0, cruise)), probe[0]]

    sim = asyncio.run(run_daemon(config, plan, setup, modules))
    record = probe[0].record
    ready = record.verdicts[0][0] if record.verdicts else 0.0
    out = held_out(record)
    stops = [why for _, state, why in record.verdicts if state == "stop"]
    return {
        "case": name,
        "held_s": round((out[0] if out else sim.world.t_s) - ready, 1),
        "how": out[1] if out else f"still held at the {HELD_LIMIT_S:.0f} s limit",
        "capped": out is None,
        "held_by": stops[-1] if stops else "",
        "contacts": len(sim.robot.collisions),
        **record.stall_fields(),
    }


# --- the benchmark --------------------------------------------------------------------------

Job = tuple[str, tuple[Any, ...]]
RUNNERS: dict[str, Callable[..., dict[str, Any]]] = {
    "case": run_case,
    "hallway": run_hallway,
    "idle": run_idle,
    "held": run_held,
}


def _run_job(job: tuple[str, tuple[Any, ...], float]) -> tuple[str, dict[str, Any]]:
    """One run in its own process; a run that fails is reported, not lost with the rest."""
    kind, args, sim_speed = job
    # Safety stops are warnings, and a run has many: only errors (faults) reach stderr.
    logging.getLogger("coffeebot").setLevel(logging.ERROR)
    try:
        return kind, RUNNERS[kind](*args, sim_speed)
    except Exception as exc:  # reported with the results, and in the exit code
        return "failed", {"run": f"{kind} {args}", "error": f"{type(exc).__name__}: {exc}"}


def jobs(
    selected: Sequence[tuple[str, float]], extras: bool, hallway_speeds: Sequence[float]
) -> list[Job]:
    """The case runs, and (``extras``) the hallway (at ``hallway_speeds``), idle and held
    runs."""
    found: list[Job] = [("case", (name, speed)) for name, speed in selected]
    if extras:
        found += [("hallway", (level, v)) for level in (2, 3) for v in hallway_speeds]
        found += [("idle", (where,)) for where in IDLE_PLACES]
        found += [("held", (name,)) for name in HELD]
    return found


IDLE_PLACES = (
    "at the tea room door, facing down the hallway",
    "parked in the tea room, facing its door",
)


def percentile(values: Sequence[float], q: float) -> float | None:
    """The ``q``th percentile, one of the values; ``inf`` entries (never braked) count as
    the slowest, and a percentile that falls on one is None."""
    if not values:
        return None
    value = float(np.percentile(np.array(values, dtype=float), q, method="higher"))
    return round(value, 1) if math.isfinite(value) else None


def summarize(results: Sequence[tuple[str, dict[str, Any]]]) -> dict[str, Any]:
    rows = [r for kind, r in results if kind == "case"]
    hallway = [r for kind, r in results if kind == "hallway"]
    idle = [r for kind, r in results if kind == "idle"]
    held = [r for kind, r in results if kind == "held"]
    latencies = [
        math.inf if r["never_braked"] else r["stop_latency_ms"]
        for r in rows
        if r["hazard_s"] is not None
    ]
    by_case = []
    for name in dict.fromkeys(r["case"] for r in rows):
        mine = [r for r in rows if r["case"] == name]
        lat = [r["stop_latency_ms"] for r in mine if r["stop_latency_ms"] is not None]
        clear = [r["min_clearance_mm"] for r in mine if r["min_clearance_mm"] is not None]
        by_case.append(
            {
                "case": name,
                "group": mine[0]["group"],
                "runs": len(mine),
                "robot_caused": sum(r["robot_caused"] for r in mine),
                "walked_into_robot": sum(r["walked_into_robot"] for r in mine),
                "failing_speeds_mm_s": [r["speed_mm_s"] for r in mine if r["robot_caused"]],
                "min_clearance_mm": min(clear) if clear else None,
                "stop_latency_ms_max": max(lat) if lat else None,
                "never_braked": sum(r["never_braked"] for r in mine),
                "slowed_before": sum(slowed_before(r) for r in mine),
            }
        )
    driven = sum(r["driven_m"] for r in hallway)
    stops = sum(r["collision_stops"] for r in hallway)
    gate_stops = sum(r["safety_stops"] for r in hallway)
    return {
        "runs": len(rows),
        "contacts": sum(len(r["contacts"]) for r in rows),
        "robot_caused": sum(r["robot_caused"] for r in rows),
        "walked_into_robot": sum(r["walked_into_robot"] for r in rows),
        "by_case": by_case,
        "stop_latency_ms_p95": percentile(latencies, 95),
        "stop_latency_runs": len(latencies),
        "stop_latency_never_braked": sum(math.isinf(v) for v in latencies),
        "stop_latency_ms_p50": percentile(latencies, 50),
        "false_stops_per_100m": round(stops / driven * 100.0, 2) if driven else None,
        "safety_stops_per_100m": round(gate_stops / driven * 100.0, 2) if driven else None,
        "hallway_driven_m": round(driven, 1),
        "stalled_runs": sum(r["stalls"] > 0 for r in [*rows, *hallway, *idle, *held]),
        "longest_stall_ms": max(
            (r["longest_stall_ms"] for r in [*rows, *hallway, *idle, *held]), default=None
        ),
        "idle_stops": sum(r["stops"] for r in idle) if idle else None,
        "held_with_way_out_s_max": max(r["held_s"] for r in held) if held else None,
        "min_clearance_mm": min(
            (
                r["min_clearance_mm"]
                for r in rows
                if not r["contacts"] and r["min_clearance_mm"] is not None
            ),
            default=None,
        ),
        "failed_runs": [r for kind, r in results if kind == "failed"],
        "rows": rows,
        "hallway": hallway,
        "idle": idle,
        "held": held,
    }


# --- output ---------------------------------------------------------------------------------


def slowed_before(row: dict[str, Any]) -> bool:
    """Whether the robot was below 90 % of its speed when the walk (or drop) began: the
    event then did not happen as designed."""
    at_trigger = row.get("speed_at_trigger_mm_s")
    return at_trigger is not None and at_trigger < 0.9 * row["speed_mm_s"]


def _cell(row: dict[str, Any]) -> str:
    """One run in the per-case table."""
    caused = [c for c in row["contacts"] if c["cause"] == "robot_caused"]
    if caused:
        c = caused[0]
        text = f"**contact** {c['where']}, {c['relative_speed_mm_s']} mm/s"
    elif row["walked_into_robot"]:
        text = f"walked into ({row['contacts'][0]['where']})"
    else:
        text = "-" if row["min_clearance_mm"] is None else f"{row['min_clearance_mm']:.0f} mm"
    if row["never_braked"]:
        text += ", never braked"
    elif row["stop_latency_ms"] is not None:
        text += f", {row['stop_latency_ms']:.0f} ms"
    if row["starved_in_reaction"]:
        text += " (verdict gap)"
    return text + (" (slowed before)" if slowed_before(row) else "")


def table(result: dict[str, Any]) -> str:
    rows = result["rows"]
    speeds = sorted({r["speed_mm_s"] for r in rows})
    lat = result["stop_latency_ms_p95"]
    latency = f"{lat} ms" if lat is not None else "-"
    if lat is None and result["stop_latency_never_braked"]:
        latency = "never (too many runs never braked)"
    lines = [
        "| figure | value | target |",
        "|---|---|---|",
        f"| runs | {result['runs']} | |",
        f"| contacts | {result['contacts']} | |",
        f"| robot-caused contacts | {result['robot_caused']} | 0 |",
        f"| walked into the robot | {result['walked_into_robot']} | (counted apart) |",
        f"| least clearance (runs without contact) | {result['min_clearance_mm']} mm | |",
        f"| stop latency p95 ({result['stop_latency_runs']} runs with a hazard) | "
        f"{latency} "
        f"({result['stop_latency_never_braked']} never braked; p50 "
        f"{result['stop_latency_ms_p50']} ms) | <= 100 ms |",
        f"| false stops per 100 m of empty hallway ({result['hallway_driven_m']} m) | "
        f"{result['false_stops_per_100m']} | <= 1 |",
        f"| safety-gate stops per 100 m of empty hallway (any reason) | "
        f"{result['safety_stops_per_100m']} | |",
        f"| stops of an idle robot ({len(result['idle'])} x {IDLE_S:.0f} s) | "
        f"{result['idle_stops']} | 0 |",
        f"| held with a way out, longest | {result['held_with_way_out_s_max']} s | <= 10 s |",
        f"| runs with a gap in the collision verdicts ({STALL_S * 1000:.0f}+ ms) | "
        f"{result['stalled_runs']}, longest gap {result['longest_stall_ms']} ms | 0 |",
        "",
        "Per case and robot speed: the first robot-caused contact (where on the body, "
        "relative speed) or the least clearance, then the stop latency (from visible and in "
        "the protective field to the first braking command) where the obstacle became a "
        "hazard; (verdict gap): a gap in the verdicts overlapped that reaction; (slowed before): "
        "the robot was below 90 % of its speed when the walk began.",
        "",
        "| case | " + " | ".join(f"{v:.0f} mm/s" for v in speeds) + " |",
        "|---|" + "---|" * len(speeds),
    ]
    for name in dict.fromkeys(r["case"] for r in rows):
        cells = {r["speed_mm_s"]: _cell(r) for r in rows if r["case"] == name}
        lines.append(f"| {name} | " + " | ".join(cells.get(v, "") for v in speeds) + " |")
    lines.append("")
    for r in rows:
        for c in r["contacts"]:
            lines.append(
                f"- {c['cause'].replace('_', ' ')}: {r['case']} at {r['speed_mm_s']:.0f} mm/s: "
                f"{c['what']} on the {c['where']} at t={c['t']} s, robot {c['robot_speed_mm_s']} "
                f"mm/s ({c['robot_towards_mm_s']} towards it), relative "
                f"{c['relative_speed_mm_s']} mm/s; entered the path "
                f"{r['entered_path_ahead_mm']} mm ahead, visible at {r['first_visible_s']} s, "
                f"hazard at {r['hazard_s']} s, braking at {r['brake_s']} s"
            )
    if result["hallway"]:
        lines += [
            "",
            "| empty hallway | speed mm/s | driven m | collision stops | safety-gate stops "
            "| standstills | end |",
            "|---|---|---|---|---|---|---|",
        ]
        for h in result["hallway"]:
            lines.append(
                f"| floor {h['floor']} | {h['speed_mm_s']:.0f} | {h['driven_m']} | "
                f"{h['collision_stops']} | {h['safety_stops']} | {h['standstills']} | "
                f"{h['outcome']} |"
            )
        for h in result["hallway"]:
            for why in h["safety_stop_reasons"]:
                lines.append(f"- floor {h['floor']} at {h['speed_mm_s']:.0f} mm/s: {why}")
    if result["idle"]:
        lines += ["", "| idle robot, 120 s | stops | reasons |", "|---|---|---|"]
        for i in result["idle"]:
            lines.append(f"| {i['where']} | {i['stops']} | {'; '.join(i['stop_reasons'])} |")
    if result["held"]:
        lines += ["", "| held with a way out | held s | then | held by |", "|---|---|---|---|"]
        for h in result["held"]:
            lines.append(f"| {h['case']} | {h['held_s']} | {h['how']} | {h['held_by']} |")
    lines += [f"- **run failed**: {f['run']}: {f['error']}" for f in result["failed_runs"]]
    load = result["load_average"]
    lines.append(
        f"\n(elapsed {result['elapsed_s'] / 60:.1f} min; machine load average (1, 5, 15 min) "
        f"before {load['before']}, after {load['after']})"
    )
    return "\n".join(lines)


def robot_speeds(config: RobotConfig) -> list[float]:
    """The speeds the robot may drive, from 200 mm/s to its rated maximum (the motion
    module's cap), with the cruise speed between (``--speeds`` adds others)."""
    return sorted({200.0, config.motion.cruise_speed_mm_s, config.motion.max_speed_mm_s})


def load_average() -> list[float]:
    """The machine's load over 1, 5 and 15 minutes: how much else was running."""
    return [round(x, 2) for x in os.getloadavg()]


def select(args: argparse.Namespace) -> list[Job]:
    if args.quick:
        return [("case", c) for c in QUICK] + [("held", (next(iter(HELD)),))]
    config = load()[0]
    speeds = args.speeds or robot_speeds(config)
    cruise = {config.motion.cruise_speed_mm_s, config.motion.max_speed_mm_s}
    found = jobs([(c.name, float(v)) for c in cases() for v in speeds], True, sorted(cruise))
    if args.case:
        found = [j for j in found if any(text in f"{j[0]} {j[1][0]}" for text in args.case)]
    return found


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--json", action="store_true", help="print one JSON object")
    parser.add_argument("--quick", action="store_true", help="a small subset")
    parser.add_argument(
        "--case", action="append", help="only runs whose name contains this (repeatable)"
    )
    parser.add_argument("--speeds", type=float, nargs="+", help="robot speeds, mm/s")
    parser.add_argument("--workers", type=int, default=1, help="runs at once, one process each")
    parser.add_argument("--speed", type=float, default=1.0, help="simulated time per wall time")
    parser.add_argument("--save", type=Path, help="also write the JSON object to this file")
    parser.add_argument("--table", type=Path, help="print the tables of a saved JSON object")
    args = parser.parse_args(argv)
    if args.table is not None:
        print(table(json.loads(args.table.read_text())))
        return 0
    selected = select(args)
    if not selected:
        print(f"--case {' '.join(args.case)!r}: no run matches", file=sys.stderr)
        return 2
    load_before = load_average()
    started = time.monotonic()
    # A fresh process per run: each daemon starts from nothing, as it does on the robot.
    with ProcessPoolExecutor(max_workers=args.workers, max_tasks_per_child=1) as pool:
        results = list(pool.map(_run_job, [(kind, a, args.speed) for kind, a in selected]))
    result = summarize(results)
    elapsed = time.monotonic() - started
    result["elapsed_s"] = round(elapsed)
    result["load_average"] = {"before": load_before, "after": load_average()}
    if args.save is not None:
        args.save.write_text(json.dumps(result))
    if args.json:
        print(json.dumps(result))
    else:
        print(table(result))
    return 1 if result["failed_runs"] else 0


if __name__ == "__main__":
    sys.exit(main())
