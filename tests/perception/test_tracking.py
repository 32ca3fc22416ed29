"""Returns followed over scans: a person stepping in diagonally ahead is seen coming."""

from __future__ import annotations

import math

from perception_helpers import robot

from coffeebot.config import TofSensorConfig
from coffeebot.messages import RangeReading, RangeScan, ReadingStatus, SafetyState
from coffeebot.perception.collision import CollisionMonitor
from coffeebot.perception.tracking import ReturnTracker

DT = 0.02
CONFIG = robot()
TOED_OUT = CONFIG.tof.sensors
"""The robot's layout: the front sensors toed out (inner 5 degrees, outer 20)."""
STRAIGHT = [s.model_copy(update={"yaw_deg": 0.0}) if s.face == "front" else s for s in TOED_OUT]
"""Every front sensor looking straight ahead, as the seed's robot had them."""


def scan_of(
    points: list[tuple[float, float]],
    t: float,
    sensors: list[TofSensorConfig] = TOED_OUT,
    walls: bool = True,
) -> RangeScan:
    """What each sensor reads of small targets at robot-frame points (the nearest one in its
    cone), or nothing; with ``walls`` the side sensors see walls 300 mm (right) and 900 mm
    (left) away."""
    readings = []
    for s in sensors:
        best = None
        for x, y in points:
            dx, dy = x - s.x_mm, y - s.y_mm
            off = abs((math.degrees(math.atan2(dy, dx)) - s.yaw_deg + 180) % 360 - 180)
            if off <= s.fov_deg / 2 and (best is None or math.hypot(dx, dy) < best):
                best = math.hypot(dx, dy)
        if walls and s.face in ("left", "right"):
            best = 300.0 if s.face == "right" else 900.0
        status = ReadingStatus.VALID if best is not None else ReadingStatus.SIGNAL_FAIL
        readings.append(
            RangeReading(
                sensor=s.id, status=status, distance_mm=None if best is None else round(best)
            )
        )
    return RangeScan(cycle_start_s=t, cycle_time_s=DT, readings=readings)


def crossing(
    sensors: list[TofSensorConfig], speed: float, ahead: float, walk: float, start_y: float
) -> list[tuple[float, SafetyState, str]]:
    """A person (a point) walking across at ``walk`` mm/s, ``ahead`` of the robot's front
    face when it starts (the ground frame), the robot driving at ``speed``: the verdicts."""
    monitor = CollisionMonitor(
        sensors, CONFIG.collision, max_speed_mm_s=1000, tracking=CONFIG.tracking
    )
    out = []
    x_person = 305.0 + ahead
    for k in range(60):
        t = k * DT
        robot_x = speed * t
        y = start_y - math.copysign(walk * t, start_y)
        status = monitor.update(scan_of([(x_person - robot_x, y)], t, sensors), speed, k + 1)
        out.append((y, status.state, status.reason))
    return out


def test_a_static_return_is_no_mover() -> None:
    tracker = ReturnTracker(TOED_OUT, CONFIG.tracking)
    for k in range(40):
        t = k * DT
        # A box 1.5 m ahead of the front face in the ground frame, the robot at 400 mm/s.
        tracker.update(scan_of([(305 + 1500 - 400 * t, 0.0)], t, walls=False), 400, 0.0)
    assert {3, 4} <= {s for t in tracker.tracks for s in t.sensors}
    assert not tracker.movers()


def test_a_person_crossing_diagonally_ahead_stops_the_robot_before_the_corridor() -> None:
    verdicts = crossing(TOED_OUT, speed=500, ahead=900, walk=1000, start_y=900)
    first = next(i for i, (_, state, _) in enumerate(verdicts) if state is not SafetyState.GO)
    assert verdicts[first][0] > 255 + 100  # still outside the body's corridor and its margin
    stop = next(y for y, state, _ in verdicts if state is SafetyState.STOP)
    assert stop > 255  # stopped before the person is in front of the body
    assert any("moving into the way" in reason for _, _, reason in verdicts)


def test_straight_cones_see_the_crossing_too_late() -> None:
    """Why the front sensors are toed out: looking straight ahead, the same crossing is first
    judged much later, nearer the corridor."""
    verdicts = crossing(STRAIGHT, speed=500, ahead=900, walk=1000, start_y=900)
    toed = crossing(TOED_OUT, speed=500, ahead=900, walk=1000, start_y=900)

    def first_y(runs: list[tuple[float, SafetyState, str]]) -> float:
        return next(y for y, state, _reason in runs if state is not SafetyState.GO)

    assert first_y(toed) > first_y(verdicts) + 100


def test_a_wall_glance_sliding_along_with_the_robot_is_no_intrusion() -> None:
    tracker = ReturnTracker(TOED_OUT, CONFIG.tracking)
    for k in range(50):
        # The outer right sensor reads the side wall at the same distance as the robot drives.
        tracker.update(scan_of([(900.0, -800.0)], k * DT), 400, 0.0)
    assert tracker.intrusion(400, 305, 255, 1.5) is None


def test_a_person_walking_away_across_the_corridor_is_no_intrusion() -> None:
    verdicts = crossing(TOED_OUT, speed=300, ahead=1200, walk=800, start_y=-400)
    # Starting beside the corridor and walking outwards: nothing ever slows the robot.
    assert all(state is SafetyState.GO for y, state, _ in verdicts if y < -355)


def test_a_side_hold_allows_creeping_straight_ahead_until_the_gap_shrinks() -> None:
    monitor = CollisionMonitor(TOED_OUT, CONFIG.collision, max_speed_mm_s=1000)
    clear = scan_of([], 0.0)
    monitor.update(clear, 0, 1)

    def side(gap: int, t: float) -> RangeScan:
        readings = [
            r.model_copy(update={"distance_mm": gap}) if r.sensor == 1 else r
            for r in clear.readings
        ]
        return clear.model_copy(update={"readings": readings, "cycle_start_s": t})

    held = monitor.update(side(40, 0.02), 0, 2)
    assert held.state is SafetyState.STOP and held.may_creep_ahead and not held.may_rotate
    assert monitor.update(side(42, 0.04), 50, 3).may_creep_ahead
    closing = monitor.update(side(20, 0.06), 50, 4)
    assert closing.state is SafetyState.STOP and not closing.may_creep_ahead
