"""The motion module's safety gate: every command follows the freshest safety state."""

from __future__ import annotations

import logging

import numpy as np
import pytest
from helpers import CONFIG, PLAN, estimate_at

from coffeebot.board import Board
from coffeebot.daemon import Daemon
from coffeebot.messages import (
    ALL_TOPICS,
    COLLISION,
    CURRENT_STATE,
    ESTOP,
    HEALTH,
    MOTION_STATUS,
    MOTOR_COMMAND,
    MOVE_INSTRUCTION,
    ODOMETRY,
    CollisionStatus,
    CurrentState,
    EStop,
    Health,
    HealthStatus,
    MotionState,
    MotionStatus,
    MoveInstruction,
    Odometry,
    RangeReading,
    RangeScan,
    ReadingStatus,
    SafetyState,
    StopCause,
)
from coffeebot.modules.motion import MotionModule, safety_gate
from manual_clock import ManualClock

FLOOR = PLAN.floor(2)
X, Y = FLOOR.from_hallway(10000, -295)
POSE = estimate_at(2, X, Y)
GO = CollisionStatus(state=SafetyState.GO, scan_seq=1, speed_limit_mm_s=1000.0)
TELEMETRY = Odometry(
    controller_time_ms=0, left_ticks=0, right_ticks=0, gyro_z_dps=0.0, left_mm_s=0.0, right_mm_s=0.0
)


class Rig:
    def __init__(self, clock: ManualClock) -> None:
        self.clock = clock
        self.board = Board(ALL_TOPICS, clock=clock)
        self.module = MotionModule(CONFIG, PLAN)
        self.daemon = Daemon(self.board, [self.module])

    def feed(self, collision: CollisionStatus | None = GO, telemetry: bool = True) -> None:
        self.board.publish(CURRENT_STATE, CurrentState(pose=POSE))
        if telemetry:
            self.board.publish(ODOMETRY, TELEMETRY)
        if collision is not None:
            self.board.publish(COLLISION, collision)

    async def run_for(
        self, seconds: float, collision: CollisionStatus | None = GO, telemetry: bool = True
    ) -> None:
        """Advance time in control periods with fresh pose and motor telemetry (unless told
        otherwise), and verdicts (unless None)."""
        for _ in range(round(seconds / CONFIG.motion.period_s)):
            self.feed(collision, telemetry)
            await self.clock.advance(CONFIG.motion.period_s)

    def speed(self) -> float:
        command = self.board.latest(MOTOR_COMMAND)
        assert command is not None
        return (command.msg.left_mm_s + command.msg.right_mm_s) / 2


@pytest.fixture
async def rig() -> Rig:
    rig = Rig(ManualClock(100.0))
    await rig.daemon.start()
    rig.board.publish(
        MOVE_INSTRUCTION,
        MoveInstruction(id=1, action="follow_lane", floor=2, target_s_mm=30000, lane_mm=-295),
    )
    yield rig
    await rig.daemon.shutdown()


async def test_moves_with_fresh_go(rig: Rig) -> None:
    await rig.run_for(1.0)
    assert rig.speed() > 100


async def test_stale_collision_verdict_stops(rig: Rig) -> None:
    await rig.run_for(1.0)
    await rig.run_for(CONFIG.motion.stale_safety_s * 2, collision=None)
    assert rig.speed() == 0
    assert motion_status(rig).stopped_by is StopCause.STALE_VERDICT


async def test_no_verdict_at_all_stops(rig: Rig) -> None:
    await rig.run_for(0.5, collision=None)
    assert rig.speed() == 0


async def test_collision_stop_stops_at_once(rig: Rig) -> None:
    await rig.run_for(1.0)
    stop = CollisionStatus(state=SafetyState.STOP, scan_seq=2, reason="front obstacle")
    rig.feed(stop)
    await rig.clock.advance(0.0)
    assert rig.speed() == 0
    command = rig.board.latest(MOTOR_COMMAND)
    assert command is not None and command.msg.brake  # the controller's stop line, not its ramp


async def test_a_change_of_motion_state_is_logged_with_its_reason_and_place(
    rig: Rig, caplog: pytest.LogCaptureFixture
) -> None:
    caplog.set_level(logging.INFO, logger="coffeebot.module.motion")
    await rig.run_for(1.0)
    stop = CollisionStatus(state=SafetyState.STOP, scan_seq=2, reason="front obstacle at 300 mm")
    await rig.run_for(0.2, stop)
    await rig.run_for(0.2, stop)  # held: no new line while the state stays
    records = [r for r in caplog.records if r.name == "coffeebot.module.motion"]
    said = [r.getMessage() for r in records]
    assert said[-1] == "motion moving -> safety_stop: collision stop: front obstacle at 300 mm"
    assert sum("-> safety_stop" in line for line in said) == 1
    where = vars(records[-1])  # and where it happened: a fleet's log is read by positions
    assert (where["floor"], where["x_mm"], where["y_mm"]) == (
        POSE.floor,
        round(POSE.x_mm),
        round(POSE.y_mm),
    )


async def test_never_faster_than_the_rated_speed(rig: Rig) -> None:
    """An instruction asking for the motors' maximum gets the robot's rated speed."""
    rig.board.publish(
        MOVE_INSTRUCTION,
        MoveInstruction(
            id=3,
            action="follow_lane",
            floor=2,
            target_s_mm=40000,
            lane_mm=-295,
            speed_mm_s=CONFIG.motor.max_speed_mm_s,
        ),
    )
    await rig.run_for(6.0)
    assert CONFIG.motion.max_speed_mm_s < CONFIG.motor.max_speed_mm_s
    assert rig.speed() == pytest.approx(CONFIG.motion.max_speed_mm_s)


async def test_slow_verdict_caps_the_speed(rig: Rig) -> None:
    slow = CollisionStatus(state=SafetyState.SLOW, scan_seq=2, speed_limit_mm_s=80.0)
    await rig.run_for(3.0, collision=slow)
    assert 0 < rig.speed() <= 80.0


async def test_failed_collision_module_stops(rig: Rig) -> None:
    await rig.run_for(1.0)
    failed = Health(module="perception", status=HealthStatus.FAILED, publishes=(COLLISION.name,))
    rig.board.publish(HEALTH, failed)
    await rig.run_for(0.2)
    assert rig.speed() == 0
    assert motion_status(rig).stopped_by is StopCause.COLLISION_MODULE_DOWN


async def test_another_module_failing_does_not_hold_the_robot(rig: Rig) -> None:
    await rig.run_for(1.0)
    rig.board.publish(HEALTH, Health(module="door", status=HealthStatus.FAILED))
    await rig.run_for(0.2)
    assert rig.speed() > 0


async def test_silent_motor_controller_stops_until_telemetry_resumes(rig: Rig) -> None:
    await rig.run_for(1.0)
    assert rig.speed() > 100
    await rig.run_for(CONFIG.motor.telemetry_timeout_s * 2, telemetry=False)
    assert rig.speed() == 0
    status = motion_status(rig)
    assert (status.state, status.stopped_by) == (MotionState.SAFETY_STOP, StopCause.MOTOR_SILENT)
    assert status.detail.startswith("no telemetry from the motor controller for ")
    await rig.run_for(1.0)
    assert rig.speed() > 0


async def test_no_telemetry_yet_means_no_motion(rig: Rig) -> None:
    await rig.run_for(1.0, telemetry=False)
    assert rig.speed() == 0
    assert motion_status(rig).stopped_by is StopCause.MOTOR_SILENT


async def test_estop_stops_and_release_resumes(rig: Rig) -> None:
    await rig.run_for(1.0)
    rig.board.publish(ESTOP, EStop(engaged=True, source="operator"))
    await rig.run_for(0.1)
    assert rig.speed() == 0
    rig.board.publish(ESTOP, EStop(engaged=False, source="operator"))
    await rig.run_for(1.0)
    assert rig.speed() > 0


async def test_shutdown_sends_a_stop_last(rig: Rig) -> None:
    await rig.run_for(1.0)
    assert rig.speed() > 0
    await rig.daemon.shutdown()
    assert rig.speed() == 0


def test_gate_prefers_stop_on_any_doubt() -> None:
    assert safety_gate(None, None, None, None, 0.2).stop
    assert safety_gate(None, None, EStop(engaged=True, source="x"), HealthStatus.RUNNING, 0.2).stop
    assert safety_gate(None, None, None, HealthStatus.RESTARTING, 0.2).stop


def motion_status(rig: Rig) -> MotionStatus:
    status = rig.board.latest(MOTION_STATUS)
    assert status is not None
    return status.msg


def wheels(rig: Rig) -> tuple[float, float]:
    command = rig.board.latest(MOTOR_COMMAND)
    assert command is not None
    return command.msg.left_mm_s, command.msg.right_mm_s


async def test_front_stop_that_allows_rotating_turns_on_the_spot_only(rig: Rig) -> None:
    """Held by a jamb half-way through a turn into a door: the turn may go on (the wheels
    turn in opposite directions, no forward speed); without ``may_rotate`` nothing moves."""
    rig.board.publish(
        MOVE_INSTRUCTION, MoveInstruction(id=2, action="turn", floor=2, heading_deg=-60.0)
    )
    held = CollisionStatus(
        state=SafetyState.STOP,
        scan_seq=2,
        face="front",
        reason="front narrow obstacle at 440 mm",
        blocked_faces=("front",),
        may_rotate=True,
    )
    await rig.run_for(0.5, held)
    left, right = wheels(rig)
    assert left > 0 > right  # turning right, towards -60 degrees
    assert left + right == pytest.approx(0.0, abs=1e-6)
    frozen = held.model_copy(update={"may_rotate": False})
    await rig.run_for(0.2, frozen)
    assert wheels(rig) == (0.0, 0.0)


async def test_a_robot_still_rolling_brakes_before_it_turns_on_the_spot(rig: Rig) -> None:
    """A turn command would only ramp the wheels down from cruising speed: brake first."""
    rig.board.publish(
        MOVE_INSTRUCTION, MoveInstruction(id=2, action="turn", floor=2, heading_deg=-60.0)
    )
    held = CollisionStatus(
        state=SafetyState.STOP, scan_seq=2, face="front", blocked_faces=("front",), may_rotate=True
    )
    rolling = POSE.model_copy(update={"speed_mm_s": 400.0})
    for _ in range(3):
        rig.board.publish(CURRENT_STATE, CurrentState(pose=rolling))
        rig.board.publish(ODOMETRY, TELEMETRY)
        rig.board.publish(COLLISION, held)
        await rig.clock.advance(CONFIG.motion.period_s)
    command = rig.board.latest(MOTOR_COMMAND)
    assert command is not None and command.msg.brake
    await rig.run_for(0.3, held)  # standing (the rig's pose has speed 0): the turn goes on
    left, right = wheels(rig)
    assert left > 0 > right


async def test_a_stale_pose_stops_even_a_turn_the_front_stop_allows(rig: Rig) -> None:
    rig.board.publish(
        MOVE_INSTRUCTION, MoveInstruction(id=2, action="turn", floor=2, heading_deg=-60.0)
    )
    held = CollisionStatus(
        state=SafetyState.STOP, scan_seq=2, face="front", blocked_faces=("front",), may_rotate=True
    )
    rig.board.publish(CURRENT_STATE, CurrentState(pose=POSE))  # and then no more
    for _ in range(round(1.0 / CONFIG.motion.period_s)):
        rig.board.publish(COLLISION, held)  # fresh verdicts, but the pose goes stale
        await rig.clock.advance(CONFIG.motion.period_s)
    assert wheels(rig) == (0.0, 0.0)


async def test_held_with_no_way_past_reports_blocked_with_the_reason(rig: Rig) -> None:
    """A front stop in front of something that fills the hallway: no turn and no lane gets
    past, so motion says "blocked" (navigation acts on that) instead of an endless stop."""
    readings = [
        RangeReading(sensor=s.id, status=ReadingStatus.VALID, distance_mm=450)
        if s.face == "front"
        else RangeReading(sensor=s.id, status=ReadingStatus.OUT_OF_BOUNDS)
        for s in CONFIG.tof.sensors
    ]
    scan = RangeScan(cycle_start_s=0.0, cycle_time_s=0.05, readings=readings)
    s, _ = FLOOR.to_hallway(X, Y)
    half = FLOOR.hallway.width_mm / 2
    for d in np.arange(-half + 200, half - 199, 100.0):  # the same wall-to-wall thing
        x, y = FLOOR.from_hallway(s, float(d))
        rig.module.costmap.update(scan, FLOOR, x, y, FLOOR.hallway.heading_deg, rig.clock.now())
    held = CollisionStatus(
        state=SafetyState.STOP,
        scan_seq=2,
        face="front",
        reason="front obstacle at 450 mm, stop distance 480 mm",
        blocked_faces=("front",),
        may_rotate=True,
    )
    await rig.run_for(CONFIG.motion.static_confirm_s + 1.0, held)
    status = rig.board.latest(MOTION_STATUS)
    assert status is not None and status.msg.state is MotionState.BLOCKED
    assert "front obstacle at 450 mm" in status.msg.detail
    assert wheels(rig) == (0.0, 0.0)


async def test_a_slow_zone_at_an_opening_caps_the_command(rig: Rig) -> None:
    """Driving back down the hallway with the side hallway's mouth beside the lane, the
    command stays at the zone's cap, and says why; past the mouth the cap is gone."""
    hall = next(o for o in FLOOR.openings if o.id == "north hall")
    front = CONFIG.geometry.length_mm / 2

    async def drive_at(s: float) -> None:
        x, y = FLOOR.from_hallway(s, 295)
        pose = estimate_at(2, x, y, 180.0)
        for _ in range(round(4.0 / CONFIG.motion.period_s)):
            rig.board.publish(CURRENT_STATE, CurrentState(pose=pose))
            rig.board.publish(ODOMETRY, TELEMETRY)
            rig.board.publish(COLLISION, GO)
            await rig.clock.advance(CONFIG.motion.period_s)

    rig.board.publish(
        MOVE_INSTRUCTION,
        MoveInstruction(id=4, action="follow_lane", floor=2, target_s_mm=1000, lane_mm=295),
    )
    beside = hall.at_mm + front
    await drive_at(beside)
    x, y = FLOOR.from_hallway(beside, 295)
    zone = rig.module.zone(estimate_at(2, x, y, 180.0), CONFIG.motion.max_speed_mm_s)
    assert zone is not None and zone.opening == "north hall"
    assert 0 < rig.speed() <= zone.speed_mm_s + 1e-6
    command = rig.board.latest(MOTOR_COMMAND)
    assert command is not None and "opening north hall" in command.msg.reason
    await drive_at(hall.span[0] - 100.0)  # the front past the mouth's far edge
    assert rig.speed() > zone.speed_mm_s + 100.0
