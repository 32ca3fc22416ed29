"""Navigation module: takes the dispatched order, drives its route, reports its lifecycle.

One order at a time: wait in ``preparing`` for the cup (``cup_loaded``), drive the route step
by step (each motion step waits for motion's "done"), ride the elevator when the route says,
report ``arrived`` at the door, wait for ``pickup_confirmed``, then go back to base. Every
wait has a timeout from config and ends in a report: the cup never loaded, nobody picked it
up, the elevator never came (after retries and an operator fallback), blocked for too long.
An operator's cancel ends the order at once and sends the robot home.

The elevator procedure talks to whatever serves ``elevator/request`` (the simulated
elevator, or a building interface); when it does not answer within the timeout the call is
repeated, then an operator is asked to confirm the step on the operator page
(``elevator_confirm``), and when nobody does the delivery fails with the reason.

Along the hallway it also acts on what the ceiling cameras see (``cameras/layer``): something
standing on the rest of the leg with no room to pass holds the robot short of it, the
customer told why, until it is gone (:mod:`coffeebot.navigation.camera_blocks`).
"""

from __future__ import annotations

import asyncio
import contextlib
import itertools
from collections.abc import Callable, Sequence

from coffeebot.board import Subscription
from coffeebot.config import RobotConfig
from coffeebot.errors import ConfigError, DeliveryError
from coffeebot.floorplan import FloorPlan, ParkingSpot
from coffeebot.messages import (
    CAMERA_LAYER,
    CURRENT_STATE,
    DELIVERY_STATUS,
    ELEVATOR_REQUEST,
    ELEVATOR_STATE,
    LEASE_NEED,
    LEASE_STATE,
    MOTION_STATUS,
    MOVE_INSTRUCTION,
    OPERATOR_EVENT,
    ORDER_DISPATCH,
    ROUTE,
    DeliveryProblem,
    DeliveryUpdate,
    ElevatorRequest,
    ElevatorState,
    LeaseNeed,
    MotionState,
    MoveInstruction,
    OperatorEvent,
    OrderDispatch,
    OrderStatus,
    PlannedRoute,
    PoseEstimate,
    SharedPlace,
    StopCause,
)
from coffeebot.modules.base import Module, ModuleContext
from coffeebot.navigation.camera_blocks import Block, BlockRule, Leg, fresh_objects, leg_ends
from coffeebot.navigation.lifecycle import MOVING, DeliveryLifecycle
from coffeebot.navigation.path import nearest, route_legs
from coffeebot.navigation.route import (
    ElevatorRide,
    Lease,
    Move,
    Place,
    Route,
    RoutePlanner,
    Step,
)

POLL_S = 0.2
"""How often waits re-check the board when nothing new arrives."""

NOT_MOVING = (MotionState.WAITING, MotionState.BLOCKED, MotionState.SAFETY_STOP)

PROGRESS_MM = 100.0
"""Getting this much nearer the end of a move, driving, counts as progress: creeping to and
fro round something without getting on is as blocked as standing still, and so is edging up
to something while waiting for it (a robot that crept 100 mm nearer a mail cart it could not
pass every minute or two, waiting, never gave up)."""


class DeliveryAborted(DeliveryError):
    """The delivery cannot go on; the message is the reason the customer sees."""

    def __init__(self, reason: str, problem: DeliveryProblem) -> None:
        super().__init__(reason)
        self.problem = problem


def parking_spot(config: RobotConfig, plan: FloorPlan) -> ParkingSpot:
    """A fleet robot's own place to wait in the base room (``[fleet] parking_spot``); and
    a fleet's building has one car (its robots take turns in it: one lease)."""
    if len(plan.cars) > 1:
        raise ConfigError(
            f"a fleet shares one elevator car, and {plan.name!r} has {len(plan.cars)} "
            f"({', '.join(plan.cars)}): run its robots on their own"
        )
    loc = plan.tea_room
    spots = loc.floor.parking
    index = config.fleet.parking_spot
    if index >= len(spots):
        raise ConfigError(
            f"[fleet] parking_spot = {index}, but floor {loc.floor.level} of {plan.name!r} has "
            f"{len(spots)} parking spot(s): add [[floors.parking]] entries, one per robot"
        )
    return spots[index]


class NavigationModule(Module):
    name = "navigation"
    inputs = (
        ORDER_DISPATCH,
        OPERATOR_EVENT,
        CURRENT_STATE,
        MOTION_STATUS,
        ELEVATOR_STATE,
        LEASE_STATE,
        CAMERA_LAYER,
    )
    outputs = (MOVE_INSTRUCTION, DELIVERY_STATUS, ELEVATOR_REQUEST, ROUTE, LEASE_NEED)

    def __init__(self, config: RobotConfig, plan: FloorPlan) -> None:
        self.config = config
        self.nav = config.navigation
        self.fleet = config.fleet.enabled
        self.planner = RoutePlanner.for_robot(
            plan, config, parking_spot(config, plan) if self.fleet else None
        )
        self.blocks = BlockRule.from_config(config)
        self._ids = itertools.count(1)
        self._handled: set[str] = set()
        self._life: DeliveryLifecycle | None = None
        self._events: dict[str, asyncio.Event] = {}
        self._task: asyncio.Task[None] | None = None
        self._asked: set[SharedPlace] = set()
        """Shared places asked for (a fleet's) and not given back."""
        self._holding: set[SharedPlace] = set()
        """...and of those, the ones granted."""
        self._on_loading_spot = False
        """A fleet's robot that came home with its next order taken and waits for the cup on
        the loading spot, holding it (:meth:`_go_home`)."""
        self._home: Place = self.planner.base
        """The pickup point the robot last went back to."""

    # --- board helpers ---------------------------------------------------------------------

    def _report(self, ctx: ModuleContext, update: DeliveryUpdate | None) -> None:
        if update is not None:
            ctx.log.info(
                "delivery %s: %s (%s)", update.order_id, update.status.value, update.detail
            )
            ctx.board.publish(DELIVERY_STATUS, update)

    def _instruct(self, ctx: ModuleContext, instruction: MoveInstruction) -> int:
        ident = next(self._ids)
        ctx.board.publish(MOVE_INSTRUCTION, instruction.model_copy(update={"id": ident}))
        return ident

    def _pose(self, ctx: ModuleContext) -> PoseEstimate | None:
        state = ctx.board.latest(CURRENT_STATE)
        return None if state is None or not state.msg.pose.initialised else state.msg.pose

    async def _wait_for(
        self, ctx: ModuleContext, check: Callable[[], bool], timeout_s: float
    ) -> bool:
        """Poll ``check`` on the board clock until it holds (True) or the time is up."""
        deadline = ctx.clock.now() + timeout_s
        while not check():
            if ctx.clock.now() >= deadline:
                return False
            await ctx.clock.sleep(POLL_S)
        return True

    def _event(self, kind: str) -> asyncio.Event:
        return self._events.setdefault(kind, asyncio.Event())

    async def _pump(self, ctx: ModuleContext, events: Subscription[OperatorEvent]) -> None:
        """Operator events for the current order: a cancel ends it, the rest are flags."""
        async for envelope in events:
            event = envelope.msg
            life = self._life
            if life is None or event.order_id != life.order_id:
                continue
            if event.kind == "cancel":
                self._report(ctx, life.cancel())
                if self._task is not None:
                    self._task.cancel()
            else:
                self._event(event.kind).set()

    # --- motion ----------------------------------------------------------------------------

    async def _move(self, ctx: ModuleContext, move: Move, leg_end_s: float | None = None) -> None:
        """Send one instruction and wait until motion reports it done; on a hallway leg
        ending at ``leg_end_s`` (:func:`~coffeebot.navigation.camera_blocks.leg_ends`), hold
        short of whatever the ceiling cameras see blocking the rest of it first."""
        leg = self._leg(ctx, move.instruction, leg_end_s)
        while (block := await self._until_done(ctx, move, leg)) is not None and leg is not None:
            if not await self._hold_short(ctx, move, leg, block):
                return

    async def _until_done(self, ctx: ModuleContext, move: Move, leg: Leg | None) -> Block | None:
        """Send the instruction and wait until motion reports it done (None), or until the
        cameras see something blocking ``leg`` ahead (that)."""
        ident = self._instruct(ctx, move.instruction)
        reported_blocked = False
        heard = progressed = ctx.clock.now()
        nearest = float("inf")
        while True:
            with contextlib.suppress(TimeoutError):
                await ctx.board.next(MOTION_STATUS, timeout=1.0)
            block = None if leg is None else self._camera_block(ctx, leg)
            if block is not None:
                return block
            latest = ctx.board.latest(MOTION_STATUS)
            if latest is None or latest.msg.instruction_id != ident:
                if ctx.clock.now() - heard > self.nav.blocked_give_up_s:
                    raise DeliveryAborted(
                        "the motion module does not answer", DeliveryProblem.MOTION_SILENT
                    )
                continue
            heard = ctx.clock.now()
            status = latest.msg
            if status.instruction_id == ident and status.state is MotionState.DONE:
                if reported_blocked:
                    self._progress(ctx, f"on the way again: {move.instruction.detail}")
                return None
            if (
                status.state not in NOT_MOVING
                and status.remaining_mm is not None
                and status.remaining_mm < nearest - PROGRESS_MM
            ):
                nearest, progressed = status.remaining_mm, heard
            held = status.since_s if status.state in NOT_MOVING else 0.0
            stalled = heard - progressed
            # Held: motion says why. Moving without getting nearer: that is the news.
            why = status.detail
            if status.state not in NOT_MOVING and stalled > held:
                why = f"no progress for {stalled:.0f} s ({status.detail})"
            stuck_s = max(held, stalled)
            # A silent motor controller is a fault of the robot, not the way: told at once.
            motors = status.stopped_by is StopCause.MOTOR_SILENT
            problem = DeliveryProblem.MOTOR_CONTROLLER if motors else DeliveryProblem.BLOCKED
            held_as = "stopped" if motors else "blocked"
            if stuck_s >= self.nav.blocked_give_up_s:
                raise DeliveryAborted(f"{held_as} for {stuck_s:.0f} s: {why}", problem)
            stuck = motors or stuck_s >= self.nav.blocked_report_s
            if stuck and not reported_blocked:
                reported_blocked = True
                self._progress(ctx, f"{held_as}: {why}", problem)
                if self.nav.on_blocked == "return" and not motors:
                    raise DeliveryAborted(f"blocked: {why}", DeliveryProblem.BLOCKED)
            elif not stuck and reported_blocked:
                reported_blocked = False
                self._progress(ctx, f"on the way again: {move.instruction.detail}")

    # --- what the ceiling cameras see -------------------------------------------------------

    def _leg(self, ctx: ModuleContext, ins: MoveInstruction, end_s: float | None) -> Leg | None:
        """The hallway leg a lane move drives, from where the robot stands now; None for any
        other move, or when the robot is not on its floor."""
        pose = self._pose(ctx)
        target = ins.target_s_mm
        if end_s is None or target is None or pose is None or pose.floor != ins.floor:
            return None
        floor = self.planner.plan.floor(pose.floor).view(ins.hallway)
        s = floor.to_hallway(pose.x_mm, pose.y_mm)[0]
        return Leg(floor, 1.0 if target >= s else -1.0, target, end_s)

    def _camera_block(self, ctx: ModuleContext, leg: Leg) -> Block | None:
        """The nearest thing the camera layer shows blocking the rest of ``leg``, if any."""
        pose = self._pose(ctx)
        if pose is None or pose.floor != leg.floor.level:
            return None
        layer = ctx.board.latest(CAMERA_LAYER)
        objects = fresh_objects(
            None if layer is None else layer.msg,
            ctx.board.age(CAMERA_LAYER),
            self.nav.camera_stale_s,
        )
        s = leg.floor.to_hallway(pose.x_mm, pose.y_mm)[0]
        return self.blocks.blocking(leg, s, abs(pose.speed_mm_s), objects)

    async def _hold_short(self, ctx: ModuleContext, move: Move, leg: Leg, block: Block) -> bool:
        """Hold short of ``block`` until the camera layer no longer shows the way blocked
        (then whether ``move`` still has way to go), telling the customer why. The route has
        no other way to take (one hallway per floor), so this waits, up to
        ``blocked_give_up_s`` (``on_blocked = "return"``: not at all)."""
        ins = move.instruction
        ctx.log.info(
            "holding short of %s at s=%.0f: camera object %s, %.0f mm free beside it",
            block.what,
            block.stop_s_mm,
            block.object_id,
            block.free_mm,
        )
        self._progress(ctx, block.waiting_detail, DeliveryProblem.BLOCKED)
        if self.nav.on_blocked == "return":
            raise DeliveryAborted(f"blocked: {block.what}", DeliveryProblem.BLOCKED)
        since = ctx.clock.now()
        held_at: float | None = None
        current: Block | None = block
        while current is not None:
            # Held further back when something nearer blocks; never moved on while blocked.
            if held_at is None or (held_at - current.stop_s_mm) * leg.direction > (
                self.config.motion.stop_tolerance_mm
            ):
                held_at = current.stop_s_mm
                hold = {"target_s_mm": held_at, "stop": True, "target_door": None}
                detail = f"holding short of {current.what}"
                self._instruct(ctx, ins.model_copy(update={**hold, "detail": detail}))
            waited = ctx.clock.now() - since
            if waited >= self.nav.blocked_give_up_s:
                raise DeliveryAborted(
                    f"blocked for {waited:.0f} s: {current.what}", DeliveryProblem.BLOCKED
                )
            await ctx.clock.sleep(POLL_S)
            current = self._camera_block(ctx, leg)
        ctx.log.info("the camera layer shows the way clear: going on")
        self._progress(ctx, f"on the way again: {ins.detail}")
        pose = self._pose(ctx)
        if pose is None or pose.floor != leg.floor.level:
            return True
        s = leg.floor.to_hallway(pose.x_mm, pose.y_mm)[0]
        return (leg.target_s_mm - s) * leg.direction > self.config.motion.stop_tolerance_mm

    def _progress(
        self, ctx: ModuleContext, detail: str, problem: DeliveryProblem | None = None
    ) -> None:
        life = self._life
        if life is not None and not life.final:
            self._report(ctx, life.progress(detail, problem))

    async def _drive(self, ctx: ModuleContext, steps: Sequence[Step]) -> None:
        for step, leg_end_s in zip(steps, leg_ends(steps), strict=True):
            if isinstance(step, ElevatorRide):
                await self._ride(ctx, step)
            elif isinstance(step, Lease):
                await self._lease(ctx, step)
            else:
                await self._move(ctx, step, leg_end_s)

    # --- shared places (a fleet's) ---------------------------------------------------------

    async def _lease(self, ctx: ModuleContext, lease: Lease) -> None:
        """Ask for a shared place and wait until it is this robot's, or give it back."""
        ctx.board.publish(LEASE_NEED, LeaseNeed(place=lease.place, want=lease.want))
        if not lease.want:
            self._asked.discard(lease.place)
            self._holding.discard(lease.place)
            return
        self._asked.add(lease.place)

        def held() -> bool:
            state = ctx.board.latest(LEASE_STATE)
            return state is not None and state.msg.holds(lease.place)

        if not held():
            what = lease.place.replace("_", " ")
            self._hold_still(ctx, f"waiting for the {what}")
            self._progress(ctx, f"waiting for the {what}: another robot is using it")
            if not await self._wait_for(ctx, held, self.nav.blocked_give_up_s):
                raise DeliveryAborted(
                    f"the {what} stayed taken for {self.nav.blocked_give_up_s:.0f} s",
                    DeliveryProblem.BLOCKED,
                )
            self._progress(ctx, f"the {what} is free: going on")
        self._holding.add(lease.place)
        pose = self._pose(ctx)
        if lease.place == "elevator" and pose is not None:
            # The car is this robot's: call it now, as a person presses the button walking
            # up, so it travels while the robot drives to its door (the call at the door,
            # :meth:`_ride`, then finds it there).
            ctx.board.publish(ELEVATOR_REQUEST, ElevatorRequest(action="call", floor=pose.floor))

    # --- elevator --------------------------------------------------------------------------

    async def _elevator_step(
        self,
        ctx: ModuleContext,
        request: ElevatorRequest,
        ready: Callable[[ElevatorState], bool],
        timeout_s: float,
        what: str,
    ) -> None:
        """Request, wait for ``ready``; repeat; then fall back to an operator; then give up."""
        cfg = self.nav.elevator
        confirmed = self._event("elevator_confirm")
        confirmed.clear()

        def done() -> bool:
            state = ctx.board.latest(ELEVATOR_STATE)
            return confirmed.is_set() or (state is not None and ready(state.msg))

        for _ in range(cfg.call_retries + 1):
            ctx.board.publish(ELEVATOR_REQUEST, request)
            if await self._wait_for(ctx, done, timeout_s):
                return
        life = self._life
        if life is not None and not life.final:
            self._report(
                ctx,
                life.waiting_for_elevator(
                    f"the elevator does not answer ({what}); an operator is asked to confirm",
                    DeliveryProblem.ELEVATOR,
                ),
            )
        if not await self._wait_for(ctx, confirmed.is_set, cfg.operator_timeout_s):
            raise DeliveryAborted(
                f"the elevator did not answer ({what}) and nobody confirmed it",
                DeliveryProblem.ELEVATOR,
            )

    async def _ride(self, ctx: ModuleContext, ride: ElevatorRide) -> None:
        cfg = self.nav.elevator
        here, there = ride.from_floor, ride.to_floor
        await self._move(ctx, ride.face_doors)
        if self.fleet:
            await self._lease(ctx, Lease("elevator", True))
        self._hold_still(ctx, f"waiting for the car on floor {here}")
        life = self._life
        if life is not None and not life.final:
            self._report(
                ctx, life.waiting_for_elevator(f"waiting for the elevator on floor {here}")
            )
        await self._elevator_step(
            ctx,
            ElevatorRequest(action="call", floor=here, car=ride.car),
            lambda s: s.car in (None, ride.car) and s.car_floor == here and s.doors == "open",
            cfg.call_timeout_s,
            f"car to floor {here}",
        )
        await self._drive(ctx, ride.enter)
        # Sent at once: the doors close and the car travels while the robot turns round.
        ctx.board.publish(
            ELEVATOR_REQUEST, ElevatorRequest(action="send", floor=there, car=ride.car)
        )
        await self._move(ctx, ride.turn_round)
        self._hold_still(ctx, f"in the car to floor {there}")
        await self._elevator_step(
            ctx,
            ElevatorRequest(action="send", floor=there, car=ride.car),
            lambda s: s.car in (None, ride.car) and s.car_floor == there and s.doors == "open",
            cfg.ride_timeout_s,
            f"ride to floor {there}",
        )
        # Confirm the floor independently: the pose's floor comes from the UWB anchors.
        confirmed = self._event("elevator_confirm")
        on_floor = await self._wait_for(
            ctx,
            lambda: ((p := self._pose(ctx)) is not None and p.floor == there) or confirmed.is_set(),
            cfg.call_timeout_s,
        )
        if not on_floor:
            raise DeliveryAborted(
                f"the elevator opened but the robot cannot confirm floor {there}",
                DeliveryProblem.ELEVATOR,
            )
        self._progress(ctx, f"on floor {there}")
        await self._drive(ctx, ride.exit)
        ctx.board.publish(
            ELEVATOR_REQUEST, ElevatorRequest(action="release", floor=there, car=ride.car)
        )
        # A fleet's route gives the elevator back now: the robot is out and the car released.

    # --- deliveries ------------------------------------------------------------------------

    def _route_to(self, ctx: ModuleContext, room: str | None) -> Route:
        """To ``room``'s nearest door, or (None) home: a fleet's robot to the loading spot,
        where :meth:`_go_home` decides whether it parks; a single robot to the nearest
        pickup point; by the nearest car (nearest: fewest elevator rides, then the shortest
        way)."""
        pose = self._pose(ctx)
        if pose is None:
            raise DeliveryAborted("the robot does not know where it is", DeliveryProblem.LOST)
        hallway, s, leave = self.planner.where(pose.floor, pose.x_mm, pose.y_mm)
        if room is not None:
            goals = self.planner.door_places(room)  # a room may have two doors
        elif self.fleet:
            goals = [self.planner.base]
        else:
            goals = self.planner.pickup_points  # a single robot's cup at the nearest
        # Each goal by each car that goes there (a building may have several).
        routes = {
            (place, car): self.planner.route(
                pose.floor, s, place, leave, park=room is not None, hallway=hallway, car=car
            )
            for place in goals
            for car in (
                self.planner.cars_to(pose.floor, place) if place.floor != pose.floor else [None]
            )
        }
        way = nearest(routes, self.planner.plan, pose.floor, (pose.x_mm, pose.y_mm))
        goal, route = way[0], routes[way]
        if room is None:
            self._home = goal
        life = self._life
        ctx.board.publish(
            ROUTE,
            PlannedRoute(
                order_id=None if room is None or life is None else life.order_id,
                to=goal.door.room,
                legs=route_legs(route, self.planner.plan, pose.floor, (pose.x_mm, pose.y_mm)),
            ),
        )
        return route

    async def _serve(self, ctx: ModuleContext, life: DeliveryLifecycle) -> None:
        """The delivery from wherever ``life`` stands: from the start, or (after a restart)
        on the way, at the door."""
        nav = self.nav
        if not life.left_base:
            if self.fleet and not (self._on_loading_spot and "loading_spot" in self._holding):
                # From its parking spot onto the loading spot, which it then holds.
                await self._drive(ctx, self.planner.loading())
                self._hold_still(ctx, "on the loading spot, for the cup")
            self._on_loading_spot = False
            self._report(ctx, life.ready_for_cup())
            if not await self._wait_for(
                ctx, self._event("cup_loaded").is_set, nav.loading_timeout_s
            ):
                self._report(
                    ctx,
                    life.fail(
                        f"the cup was not loaded within {nav.loading_timeout_s:.0f} s",
                        DeliveryProblem.CUP_NOT_LOADED,
                    ),
                )
                return
            route = self._route_to(ctx, life.room)  # raises before leaving if the room is unknown
            self._report(ctx, life.cup_loaded())
            await self._drive(ctx, route.steps)
        elif life.status in MOVING:  # resumed on the way: from where the robot is now
            await self._drive(ctx, self._route_to(ctx, life.room).steps)
        if life.status in MOVING:
            self._arrived(ctx, life)
        if life.status is not OrderStatus.ARRIVED:
            return
        picked = await self._wait_for(
            ctx, self._event("pickup_confirmed").is_set, nav.pickup_timeout_s
        )
        if picked:
            self._report(ctx, life.pickup_confirmed())
        else:
            self._report(
                ctx,
                life.fail(
                    f"nobody picked the cup up within {nav.pickup_timeout_s:.0f} s; "
                    "taking it back to the tea room",
                    DeliveryProblem.NOT_PICKED_UP,
                ),
            )

    def _arrived(self, ctx: ModuleContext, life: DeliveryLifecycle) -> None:
        status = ctx.board.latest(MOTION_STATUS)
        detail = f"at the door of {life.room}"
        if status is not None and status.msg.remaining_mm is not None:
            detail += f" ({-status.msg.remaining_mm:+.0f} mm)"
        self._hold_still(ctx, f"at the door of {life.room}, for the cup to be taken")
        self._report(ctx, life.arrived(detail))

    def _hold_still(self, ctx: ModuleContext, where: str) -> None:
        """Stand where the last move left the robot for as long as it waits (at a door for
        the cup to be taken, on the loading spot, for a shared place, for and in the car):
        the move, left in force, drove or turned it again whenever its estimate moved past
        the tolerance (a few mm with a hand reaching in; a 3 degree turn every few seconds
        waiting for the car)."""
        self._instruct(ctx, MoveInstruction(action="stop", detail=where))

    async def _deliver(self, ctx: ModuleContext, dispatch: OrderDispatch) -> None:
        self._handled.add(dispatch.order_id)
        self._events = {}
        life = DeliveryLifecycle(dispatch.order_id, dispatch.room)
        self._life = life
        try:
            self.planner.door_place(dispatch.room)
        except KeyError:
            self._report(
                ctx,
                life.fail(
                    f"no room {dispatch.room!r} on the floor plan", DeliveryProblem.UNKNOWN_ROOM
                ),
            )
            return
        await self._carry_on(ctx, life)

    async def _carry_on(self, ctx: ModuleContext, life: DeliveryLifecycle) -> None:
        """Serve ``life`` to its end and bring the robot back (also after a restart of this
        module in the middle of it: the delivery goes on from where it was)."""
        self._task = asyncio.create_task(self._serve(ctx, life))
        try:
            await self._task
        except asyncio.CancelledError:
            if not life.final:  # this module is being cancelled, not the delivery
                raise
        except DeliveryAborted as exc:
            self._report(ctx, life.fail(str(exc), exc.problem))
        finally:
            self._task = None
        if life.left_base:
            await self._go_home(ctx)
        elif "loading_spot" in self._holding:  # a fleet's robot that got no cup
            await self._drive(ctx, self.planner.back_to_spot())
        for place in list(self._asked):  # a wait for a place that ended with the order
            if not (place == "loading_spot" and self._on_loading_spot):
                await self._lease(ctx, Lease(place, False))
        self._life = None

    async def _go_home(self, ctx: ModuleContext) -> None:
        """Back to the base room; a fleet's robot with its next order taken stays on the
        loading spot for that order's cup, one without parks at its spot."""
        try:
            await self._drive(ctx, self._route_to(ctx, None).steps)
            if self.fleet and self._order_waiting(ctx):
                await self._drive(ctx, self.planner.face_out())
                self._on_loading_spot = True
            elif self.fleet:
                await self._drive(ctx, self.planner.back_to_spot())
        except DeliveryAborted as exc:
            ctx.log.error("could not return to base: %s", exc)
        where = "on the loading spot, for the next cup" if self._on_loading_spot else "parked"
        self._hold_still(ctx, where)
        ctx.board.publish(ROUTE, PlannedRoute(to=self._home.door.room))

    def _order_waiting(self, ctx: ModuleContext) -> bool:
        """Whether an order was dispatched to this robot that it has not taken up yet."""
        pending = ctx.board.latest(ORDER_DISPATCH)
        return pending is not None and pending.msg.order_id not in self._handled

    async def run(self, ctx: ModuleContext) -> None:
        dispatches = ctx.board.subscribe(ORDER_DISPATCH)
        operator = ctx.board.subscribe(OPERATOR_EVENT)
        with dispatches, operator:
            self._instruct(ctx, MoveInstruction(action="stop", detail="waiting for an order"))
            async with asyncio.TaskGroup() as group:
                group.create_task(self._pump(ctx, operator))
                life = self._life
                if life is not None:  # restarted (after a crash) in the middle of a delivery
                    ctx.log.warning("restarted during the delivery of %s: going on", life.order_id)
                    self._progress(ctx, f"going on to {life.room} after a restart of navigation")
                    await self._carry_on(ctx, life)
                # A dispatch published before this module subscribed is only in ``latest``.
                pending = ctx.board.latest(ORDER_DISPATCH)
                if pending is not None and pending.msg.order_id not in self._handled:
                    await self._deliver(ctx, pending.msg)
                async for envelope in dispatches:
                    if envelope.msg.order_id not in self._handled:
                        await self._deliver(ctx, envelope.msg)
