"""The scenario's driver inside the daemon: it places the scenario's orders through the orders
module (the path the web uses), plays the staff and the customers, watches the safety
verdicts and order updates, and ends the run. What it saw, with what only the simulator knows
(collisions, clearance), makes the report (:mod:`coffeebot.scenario.report`).
"""

from __future__ import annotations

import asyncio
import contextlib
import math
from collections.abc import Callable
from dataclasses import dataclass, field

from pydantic import ValidationError

from coffeebot.config import RobotConfig
from coffeebot.errors import OrderError
from coffeebot.floorplan import FloorPlan
from coffeebot.messages import (
    COLLISION,
    HEALTH,
    MOTION_STATUS,
    OPERATOR_EVENT,
    ORDER_UPDATE,
    HealthStatus,
    OrderStatus,
    OrderUpdate,
    SafetyState,
)
from coffeebot.modules.base import Module, ModuleContext
from coffeebot.modules.motor_driver import COMMANDS
from coffeebot.orders import Orders
from coffeebot.scenario.report import (
    OrderOutcome,
    SafetyStopEntry,
    ScenarioReport,
    world_facts,
)
from coffeebot.scenario.spec import OrderSpec, Scenario
from coffeebot.scenario.staff import act
from coffeebot.sim.simulation import Simulation
from coffeebot.sim.world import Pose
from coffeebot.store import NewOrder, OrderRules

MOVING_MM_S = 20.0
"""Faster than this (ground truth) counts as driving for the mean speed."""


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
    inputs = (COLLISION, ORDER_UPDATE, MOTION_STATUS, HEALTH)
    outputs = (OPERATOR_EVENT,)

    def __init__(
        self,
        scenario: Scenario,
        plan: FloorPlan,
        config: RobotConfig,
        sim: Simulation,
        orders: Orders,
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
        watching = [
            asyncio.create_task(self._watch_safety(ctx), name="scenario:safety"),
            asyncio.create_task(self._watch_motor_stops(ctx), name="scenario:motor-stops"),
        ]
        try:
            await self._drive(ctx)
        finally:
            for task in watching:
                task.cancel()
            with contextlib.suppress(asyncio.CancelledError):
                await asyncio.gather(*watching)

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

    async def _watch_motor_stops(self, ctx: ModuleContext) -> None:
        """The motor driver's own stops (no command came in time while moving) are safety
        stops too; it reports each on the health topic."""
        with ctx.board.subscribe(HEALTH) as reports:
            async for report in reports:
                health = report.msg
                if health.component == COMMANDS and health.status is HealthStatus.DEGRADED:
                    self.log.safety_stops.append(SafetyStop(self.sim.t_s, health.detail, None))

    async def _drive(self, ctx: ModuleContext) -> None:
        with ctx.board.subscribe(ORDER_UPDATE) as updates:
            pending = sorted(self.log.orders, key=lambda o: o.spec.at_s)
            while True:
                t = self.sim.t_s
                while pending and pending[0].spec.at_s <= t:
                    await self._place(pending.pop(0))
                while (update := updates.get_nowait()) is not None:
                    self._order_update(update.msg)
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
        for track in self.log.orders:
            if track.id is not None:
                act(
                    ctx,
                    self.scenario.staff,
                    track.id,
                    track.ready_at_s,
                    track.arrived_at_s,
                    track.told,
                    t,
                )

    def _odometer(self) -> None:
        """Ground-truth distance driven and time spent moving, for the mean speed."""
        with self.sim.lock:
            pose, t = self.sim.robot.pose, self.sim.t_s
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

    def _order_update(self, update: OrderUpdate) -> None:
        track = next((o for o in self.log.orders if o.id == update.order_id), None)
        if track is None:
            return
        status = update.status
        track.status, track.detail = status.value, update.detail
        t = self.sim.t_s
        if update.ready_for_cup:
            track.ready_at_s = t
        if status is OrderStatus.ARRIVED:
            track.arrived_at_s = t
            track.stop_error_mm = self._stop_error_mm(track.spec.room)
        elif status is OrderStatus.DELIVERED:
            track.delivered_at_s = t

    def _stop_error_mm(self, room: str) -> float | None:
        """How far along its hallway the robot stands from the centre of the room's door it
        stopped at (the nearest, of a room with two; truth)."""
        doors = self.plan.room_doors(room)
        with self.sim.lock:
            robot = self.sim.robot
            x, y, level = robot.pose.x_mm, robot.pose.y_mm, robot.floor_level
        errors = [
            abs(floor.view_of(door).to_hallway(x, y)[0] - door.at_mm)
            for floor, door in doors
            if floor.level == level and math.dist(floor.behind_door(door, 0.0), (x, y)) < 5000
        ]
        return min(errors, default=None)

    def report(self) -> ScenarioReport:
        """The run so far; ``orders`` as last seen on the board."""
        contacts, final, least, faults = world_facts(self.sim)
        return ScenarioReport(
            scenario=self.scenario.name,
            seed=self.scenario.seed,
            sim_time_s=round(self.sim.t_s, 3),
            ended=self.log.ended,
            orders=[
                OrderOutcome(
                    id=o.id,
                    room=o.spec.room,
                    status=o.status,
                    detail=o.detail,
                    placed_at_s=_round(o.placed_at_s),
                    arrived_at_s=_round(o.arrived_at_s),
                    delivered_at_s=_round(o.delivered_at_s),
                    stop_error_mm=_round(o.stop_error_mm, 0),
                )
                for o in self.log.orders
            ],
            collisions=contacts,
            travelled_mm=round(self.log.travelled_mm),
            moving_s=round(self.log.moving_s, 3),
            min_clearance_mm=least,
            safety_stops=len(self.log.safety_stops),
            safety_stop_log=[
                SafetyStopEntry(t=round(s.t_s, 3), reason=s.reason, sensor=s.sensor)
                for s in self.log.safety_stops
            ],
            faults_injected=faults,
            final_pose=final,
        )


def _round(value: float | None, digits: int = 3) -> float | None:
    return None if value is None else round(value, digits)
