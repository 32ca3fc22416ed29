"""Scenario files: a reproducible run of the whole daemon on the simulated world, and its report.

A scenario (TOML, ``docs/scenarios.md``) names the floor plan, where the robot starts, the
orders customers place and when, the obstacles, the faults, speed limits, the random seed and
a time limit. :class:`ScenarioModule` places the orders through the orders module (the path
the web uses), watches the safety verdicts and order updates, and ends the run; the report
then combines what the daemon did with what only the simulator knows (collisions, clearance).
"""

from __future__ import annotations

import asyncio
import contextlib
import math
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from pydantic import BaseModel, ConfigDict, Field, ValidationError

from coffeebot.config import ConfigError, RobotConfig, describe_validation_error, read_toml
from coffeebot.floorplan import FloorPlan, load_floorplan
from coffeebot.messages import (
    COLLISION,
    MOTION_STATUS,
    OPERATOR_EVENT,
    ORDER_UPDATE,
    OperatorEvent,
    OrderStatus,
    SafetyState,
)
from coffeebot.modules.base import Module, ModuleContext
from coffeebot.modules.orders import OrderError, OrdersModule
from coffeebot.navigation.lifecycle import READY_FOR_CUP
from coffeebot.sim.faults import Fault
from coffeebot.sim.simulation import SimSetup, Simulation
from coffeebot.sim.world import ObstacleSpec, Pose
from coffeebot.store import NewOrder, OrderRules

MOVING_MM_S = 20.0
"""Faster than this (ground truth) counts as driving for the mean speed."""


class _Model(BaseModel):
    model_config = ConfigDict(extra="forbid", frozen=True)


class StartPose(_Model):
    """Where the robot stands when the run begins (floor frame)."""

    floor: int
    x_mm: float
    y_mm: float
    heading_deg: float = 0.0


class OrderSpec(_Model):
    """A customer placing an order ``at_s`` simulated seconds into the run."""

    room: str
    at_s: float = Field(0.0, ge=0)
    drink: str = "espresso"
    name: str = "scenario"


class Limits(_Model):
    """Speed limits for the run; unset keeps the board file's values."""

    max_speed_mm_s: float | None = Field(None, gt=0, description="the motors' limit")
    cruise_speed_mm_s: float | None = Field(None, gt=0, description="navigation's cruise")


class Staff(_Model):
    """The people around a delivery: staff loading the cup, the customer taking it."""

    load_after_s: float = Field(
        3.0, ge=0, description="after the robot stands ready in the tea room for the cup"
    )
    pickup_after_s: float | None = Field(
        5.0, ge=0, description="after the robot arrived; unset: nobody comes"
    )


class Scenario(_Model):
    name: str
    description: str = ""
    floorplan: Path = Field(description="relative to the scenario file")
    seed: int = 0
    time_limit_s: float = Field(gt=0, description="simulated seconds before the run ends")
    start: StartPose
    orders: list[OrderSpec] = []
    obstacles: list[ObstacleSpec] = []
    faults: list[Fault] = []
    limits: Limits = Limits()
    staff: Staff = Staff()

    def apply_limits(self, config: RobotConfig) -> RobotConfig:
        """The board's config with this scenario's speed limits."""
        motor, motion = config.motor, config.motion
        if self.limits.max_speed_mm_s is not None:
            motor = motor.model_copy(update={"max_speed_mm_s": self.limits.max_speed_mm_s})
        if self.limits.cruise_speed_mm_s is not None:
            motion = motion.model_copy(update={"cruise_speed_mm_s": self.limits.cruise_speed_mm_s})
        return config.model_copy(update={"motor": motor, "motion": motion})

    def setup(self, speed: float = 1.0) -> SimSetup:
        """The simulated world this scenario starts from."""
        start = self.start
        return SimSetup(
            floor=start.floor,
            pose=Pose(start.x_mm, start.y_mm, start.heading_deg),
            obstacles=self.obstacles,
            faults=self.faults,
            seed=self.seed,
            speed=speed,
        )


def load_scenario(path: str | Path) -> tuple[Scenario, FloorPlan]:
    """Read and check a scenario and its floor plan; problems raise :class:`ConfigError`
    naming the file and the field (``orders.1.room: unknown room '299'``)."""
    path = Path(path)
    try:
        scenario = Scenario.model_validate(read_toml(path))
    except ValidationError as exc:
        raise ConfigError(describe_validation_error(path, exc)) from None
    plan_path = path.parent / scenario.floorplan
    scenario = scenario.model_copy(update={"floorplan": plan_path})
    plan = load_floorplan(plan_path)
    levels = {f.level for f in plan.floors}
    problems = []
    if scenario.start.floor not in levels:
        problems.append(f"start.floor: no floor {scenario.start.floor} in {plan_path}")
    rooms = set(plan.rooms)
    problems += [
        f"orders.{i}.room: unknown room {o.room!r}"
        for i, o in enumerate(scenario.orders)
        if o.room not in rooms
    ]
    problems += [
        f"obstacles.{i}.floor: no floor {o.floor} in {plan_path}"
        for i, o in enumerate(scenario.obstacles)
        if o.floor not in levels
    ]
    if problems:
        raise ConfigError("\n".join(f"{path}: {p}" for p in problems))
    return scenario, plan


@dataclass
class OrderTrack:
    """One order the scenario placed, as the run saw it."""

    spec: OrderSpec
    id: str | None = None
    status: str = "not placed"
    detail: str = ""
    placed_at_s: float | None = None
    ready_at_s: float | None = None
    """When the robot stood ready in the tea room for this order's cup."""
    arrived_at_s: float | None = None
    delivered_at_s: float | None = None
    stop_error_mm: float | None = None
    told: set[str] = field(default_factory=set)
    """Operator events the staff or the customer already sent for this order."""


@dataclass
class SafetyStop:
    t_s: float
    reason: str
    sensor: int | None


@dataclass
class RunLog:
    orders: list[OrderTrack] = field(default_factory=list)
    safety_stops: list[SafetyStop] = field(default_factory=list)
    ended: str = ""
    travelled_mm: float = 0.0
    moving_s: float = 0.0
    last_pose: Pose | None = None
    last_t: float = 0.0


class ScenarioModule(Module):
    """Places the scenario's orders on time, records what happens, ends the run."""

    name = "scenario"
    inputs = (COLLISION, ORDER_UPDATE, MOTION_STATUS)
    outputs = (OPERATOR_EVENT,)

    def __init__(
        self,
        scenario: Scenario,
        plan: FloorPlan,
        config: RobotConfig,
        sim: Simulation,
        orders: OrdersModule,
        finish: Callable[[str], None],
    ) -> None:
        self.scenario = scenario
        self.plan = plan
        self.sim = sim
        self.orders = orders
        self.finish = finish
        self.rules = OrderRules(rooms=set(plan.rooms), drinks=set(config.web.drinks))
        self.log = RunLog([OrderTrack(spec) for spec in scenario.orders])

    async def run(self, ctx: ModuleContext) -> None:
        # Verdicts come 50 times a second on a "latest" topic: a poll would miss a stop that
        # lasts one scan, so a task of its own reads every one as it is published.
        watching = asyncio.create_task(self._watch_safety(ctx), name="scenario:safety")
        try:
            await self._drive(ctx)
        finally:
            watching.cancel()
            with contextlib.suppress(asyncio.CancelledError):
                await watching

    async def _watch_safety(self, ctx: ModuleContext) -> None:
        previous = SafetyState.STOP  # the collision module starts in "stop"
        with ctx.board.subscribe(COLLISION) as verdicts:
            async for verdict in verdicts:
                state = verdict.msg.state
                if state is SafetyState.STOP and previous is not SafetyState.STOP:
                    self.log.safety_stops.append(
                        SafetyStop(self.sim.t_s, verdict.msg.reason, verdict.msg.sensor)
                    )
                previous = state

    async def _drive(self, ctx: ModuleContext) -> None:
        with ctx.board.subscribe(ORDER_UPDATE) as updates:
            pending = sorted(self.log.orders, key=lambda o: o.spec.at_s)
            while True:
                t = self.sim.t_s
                while pending and pending[0].spec.at_s <= t:
                    await self._place(pending.pop(0))
                while (update := updates.get_nowait()) is not None:
                    self._order_update(update.msg.order_id, update.msg.status, update.msg.detail)
                self._people(ctx, t)
                self._odometer()
                if t >= self.scenario.time_limit_s:
                    self._unfinished(ctx)
                    return self._end("time limit")
                placed = [o for o in self.log.orders if o.id is not None]
                if not pending and placed and all(OrderStatus(o.status).final for o in placed):
                    return self._end("every order ended")
                await ctx.clock.sleep(0.05)

    def _people(self, ctx: ModuleContext, t: float) -> None:
        """Staff load the cup, the customer takes it, each after the scenario's delay."""
        staff = self.scenario.staff
        for track in self.log.orders:
            if track.id is None:
                continue
            due: list[tuple[str, float | None, float | None]] = [
                ("cup_loaded", track.ready_at_s, staff.load_after_s),
                ("pickup_confirmed", track.arrived_at_s, staff.pickup_after_s),
            ]
            for kind, since, delay in due:
                if since is None or delay is None or kind in track.told or t < since + delay:
                    continue
                track.told.add(kind)
                ctx.board.publish(
                    OPERATOR_EVENT,
                    OperatorEvent.model_validate(
                        {"kind": kind, "order_id": track.id, "source": "scenario"}
                    ),
                )

    def _odometer(self) -> None:
        """Ground-truth distance driven and time spent moving, for the mean speed."""
        with self.sim.lock:
            pose, t = self.sim.world.pose, self.sim.t_s
        last = self.log.last_pose
        if last is not None:
            step = math.dist(last[:2], pose[:2])
            dt = t - self.log.last_t
            if dt > 0 and step / dt > MOVING_MM_S:
                self.log.travelled_mm += step
                self.log.moving_s += dt
        self.log.last_pose, self.log.last_t = pose, t

    def _unfinished(self, ctx: ModuleContext) -> None:
        """Orders still open at the time limit: their detail says so, with what motion was
        last doing, so a run never ends without a reason."""
        motion = ctx.board.latest(MOTION_STATUS)
        doing = "no motion status"
        if motion is not None:
            m = motion.msg
            doing = f"motion {m.state.value} for {m.since_s:.0f} s ({m.detail})"
        for track in self.log.orders:
            if track.id is not None and not OrderStatus(track.status).final:
                track.detail = (
                    f"not ended within the {self.scenario.time_limit_s:.0f} s time limit: "
                    f"{doing}; last: {track.detail}"
                )

    def _end(self, why: str) -> None:
        self.log.ended = why
        self.finish(f"scenario {self.scenario.name!r}: {why}")

    async def _place(self, track: OrderTrack) -> None:
        spec = track.spec
        try:
            new = NewOrder.model_validate(
                {"room": spec.room, "drink": spec.drink, "name": spec.name}, context=self.rules
            )
            order = await self.orders.place(new, client="scenario")
        except (ValidationError, OrderError) as exc:
            track.status, track.detail = "refused", str(exc)
            return
        track.id, track.status, track.placed_at_s = order.id, order.status.value, self.sim.t_s

    def _order_update(self, order_id: str, status: OrderStatus, detail: str) -> None:
        track = next((o for o in self.log.orders if o.id == order_id), None)
        if track is None:
            return
        track.status, track.detail = status.value, detail
        t = self.sim.t_s
        if status is OrderStatus.PREPARING and detail == READY_FOR_CUP:
            track.ready_at_s = t
        if status is OrderStatus.ARRIVED:
            track.arrived_at_s = t
            track.stop_error_mm = self._stop_error_mm(track.spec.room)
        elif status is OrderStatus.DELIVERED:
            track.delivered_at_s = t

    def _stop_error_mm(self, room: str) -> float | None:
        """How far along the hallway the robot stands from the door's centre (truth)."""
        floor, door = self.plan.find_room(room)
        with self.sim.lock:
            world = self.sim.world
            if world.floor_level != floor.level:
                return None
            s, _ = floor.to_hallway(world.pose.x_mm, world.pose.y_mm)
        return abs(s - door.at_mm)

    def report(self) -> dict[str, Any]:
        """The report's content; ``orders`` as last seen on the board."""
        sim = self.sim
        with sim.lock:
            world = sim.world
            collisions = [
                {
                    "t": round(c.t_s, 3),
                    "with": c.element,
                    "speed_mm_s": round(c.speed_mm_s, 1),
                    "floor": c.floor,
                    "x_mm": round(c.x_mm),
                    "y_mm": round(c.y_mm),
                }
                for c in world.collisions
            ]
            pose = world.pose
            final = {
                "floor": world.floor_level,
                "x_mm": round(pose.x_mm),
                "y_mm": round(pose.y_mm),
                "heading_deg": round(pose.heading_deg, 1),
            }
        clearance = sim.truth.min_clearance_mm
        return {
            "scenario": self.scenario.name,
            "seed": self.scenario.seed,
            "sim_time_s": round(sim.t_s, 3),
            "ended": self.log.ended,
            "orders": [
                {
                    "id": o.id,
                    "room": o.spec.room,
                    "status": o.status,
                    "detail": o.detail,
                    "placed_at_s": _round(o.placed_at_s),
                    "arrived_at_s": _round(o.arrived_at_s),
                    "delivered_at_s": _round(o.delivered_at_s),
                    "stop_error_mm": _round(o.stop_error_mm, 0),
                }
                for o in self.log.orders
            ],
            "collisions": collisions,
            "travelled_mm": round(self.log.travelled_mm),
            "moving_s": round(self.log.moving_s, 3),
            "min_clearance_mm": round(clearance) if math.isfinite(clearance) else None,
            "safety_stops": len(self.log.safety_stops),
            "safety_stop_log": [
                {"t": round(s.t_s, 3), "reason": s.reason, "sensor": s.sensor}
                for s in self.log.safety_stops
            ],
            "faults_injected": [
                {
                    "t": round(f.t_s, 3),
                    "fault": f.fault,
                    "detail": f.detail,
                    "cleared_t": _round(f.cleared_s),
                }
                for f in sim.truth.faults
            ],
            "final_pose": final,
        }


def _round(value: float | None, digits: int = 3) -> float | None:
    return None if value is None else round(value, digits)
