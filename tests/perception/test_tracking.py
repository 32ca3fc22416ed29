"""Returns followed over scans: a person stepping in diagonally ahead is seen coming."""

from __future__ import annotations

import math

from perception_helpers import robot

from coffeebot.config import TofSensorConfig
from coffeebot.messages import RangeReading, RangeScan, ReadingStatus, SafetyState
from coffeebot.perception.collision import CollisionMonitor, stop_distance_mm
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


def test_someone_who_went_out_of_view_beside_the_path_is_passed_slowly() -> None:
    """A person crossing 800 mm ahead walks out of the cones to the left: they may turn back
    out of the blind spot, so the robot goes at ``lost_speed_mm_s`` for ``lost_mover_s``."""
    tracking = CONFIG.tracking
    monitor = CollisionMonitor(TOED_OUT, CONFIG.collision, max_speed_mm_s=1000, tracking=tracking)
    t, k = 0.0, 0
    verdicts = []
    while t < 3.0 + tracking.lost_mover_s:
        k += 1
        t = k * DT
        y = -600.0 + 700.0 * t  # out of every cone from about 1.3 m to the left
        points = [(305.0 + 800.0, y)] if y < 1500.0 else []
        verdicts.append((t, y, monitor.update(scan_of(points, t), 0.0, k)))
    lost = [t for t, _y, v in verdicts if "out of view" in v.reason]
    assert lost, "the walker is remembered once no cone sees them"
    careful = [v for t, _y, v in verdicts if lost[0] <= t < lost[0] + tracking.lost_mover_s - DT]
    assert all(v.state is SafetyState.SLOW for v in careful)
    assert all(v.speed_limit_mm_s == tracking.lost_speed_mm_s for v in careful)
    assert verdicts[-1][2].state is SafetyState.GO


def test_someone_walking_towards_the_robot_has_it_standing_before_they_meet() -> None:
    """They keep coming while it brakes: the robot slows from far off, as the verdicts say
    (braking at the rate it relies on), and stands before they reach it."""
    cfg = CONFIG.collision
    monitor = CollisionMonitor(TOED_OUT, cfg, max_speed_mm_s=1000, tracking=CONFIG.tracking)
    speed, walk, gap = 500.0, 1200.0, 3000.0
    reasons, first_slowed_at = [], None
    for k in range(1, 200):
        t = k * DT
        status = monitor.update(scan_of([(305.0 + gap, 0.0)], t), speed, k)
        reasons.append(status.reason)
        if first_slowed_at is None and status.state is not SafetyState.GO:
            first_slowed_at = gap
        limit = 0.0 if status.state is SafetyState.STOP else status.speed_limit_mm_s
        speed = max(min(speed, limit), speed - cfg.braking_mm_s2 * DT)
        gap -= (speed + walk) * DT
        if speed == 0.0:
            break
    assert speed == 0.0 and gap > 0, f"still at {speed:.0f} mm/s {gap:.0f} mm from them"
    assert any("coming towards" in reason for reason in reasons)
    stopping_s = cfg.reaction_latency_s + 500.0 / cfg.braking_mm_s2
    assert first_slowed_at is not None
    assert first_slowed_at > stop_distance_mm(cfg, 500.0) + walk * stopping_s


def test_blends_and_impossible_speeds_are_no_movers() -> None:
    """A reading with a large sigma (near and far returns averaged) is not tracked, and a
    return that jumps faster than anyone runs indoors is no one."""
    tracker = ReturnTracker(TOED_OUT, CONFIG.tracking)
    blended = scan_of([(1500.0, 0.0)], 0.0, walls=False)
    blended = blended.model_copy(
        update={
            "readings": [
                r.model_copy(update={"sigma_mm": CONFIG.tracking.max_sigma_mm + 1})
                for r in blended.readings
            ]
        }
    )
    assert tracker.sightings(blended) == []
    for k in range(12):  # a return sliding sideways at 4 m/s in front of a standing robot
        t = k * DT
        tracker.update(scan_of([(1500.0, -400.0 + 4000.0 * t)], t, walls=False), 0.0, 0.0)
    assert any(t.speed_mm_s > CONFIG.tracking.max_mover_speed_mm_s for t in tracker.tracks)
    assert tracker.movers() == []


def hallway_scan(
    heading_rad: float, t: float, person: tuple[float, float] | None = None
) -> RangeScan:
    """What each sensor reads (the nearest of five rays across its cone) of a 1700 mm hallway's
    walls, the robot's centre 300 mm right of the axis, and of a person (a 200 mm disc) at a
    robot-frame point."""
    readings = []
    for s in TOED_OUT:
        sy = -300.0 + s.x_mm * math.sin(heading_rad) + s.y_mm * math.cos(heading_rad)
        best: float | None = None
        for k in range(5):
            ray = math.radians(s.yaw_deg + (k - 2) * s.fov_deg / 4)  # in the robot's frame
            dy = math.sin(heading_rad + ray)
            for wall in (850.0, -850.0):
                if abs(dy) > 1e-9 and (d := (wall - sy) / dy) > 0 and (best is None or d < best):
                    best = d
            if person is not None:
                px, py = person[0] - s.x_mm, person[1] - s.y_mm
                along = px * math.cos(ray) + py * math.sin(ray)
                across = abs(-px * math.sin(ray) + py * math.cos(ray))
                if along > 0 and across <= 100.0 and (best is None or along < best):
                    best = along
        valid = best is not None and best <= 4000.0
        readings.append(
            RangeReading(
                sensor=s.id,
                status=ReadingStatus.VALID if valid else ReadingStatus.SIGNAL_FAIL,
                distance_mm=round(best) if valid and best is not None else None,
            )
        )
    return RangeScan(cycle_start_s=t, cycle_time_s=DT, readings=readings)


def half_turn_rates() -> list[float]:
    """A half turn on the spot at 45 deg/s, half a second up to speed and down again."""
    ramp = [45.0 * min(1.0, (i + 1) * DT / 0.5) for i in range(25)]
    turned = 2 * sum(r * DT for r in ramp)
    return ramp + [45.0] * round((180.0 - turned) / 45.0 / DT) + ramp[::-1]


def test_a_half_turn_on_the_spot_sees_nobody_moving_in_an_empty_hallway() -> None:
    """Issue 21's phantom: turning on the spot, the side cones sweep along the walls and
    their returns slide along them at up to 3 m/s; tracked, they were "someone moving into
    the way" during the turn and 1-3 m after it. Now nothing is tracked while the robot
    turns on the spot, and the empty hallway stays empty as it drives off."""
    monitor = CollisionMonitor(
        TOED_OUT, CONFIG.collision, max_speed_mm_s=1000, tracking=CONFIG.tracking
    )
    heading, t, reasons = 0.0, 0.0, []
    steps = [(rate, 0.0) for rate in half_turn_rates()]
    steps += [(0.0, min(300.0, 600.0 * k * DT)) for k in range(150)]  # then 0.8 m at 300 mm/s
    for seq, (rate, speed) in enumerate(steps, start=1):
        status = monitor.update(hallway_scan(heading, t), speed, seq, yaw_rate_dps=rate)
        reasons.append(status.reason)
        heading += math.radians(rate) * DT
        t += DT
    assert not [r for r in reasons if "moving" in r]


def test_someone_stepping_in_ahead_right_after_a_turn_is_seen_coming() -> None:
    """The tracks dropped during the turn are no blindness after it: a person walking across
    1.5 m ahead at 1.2 m/s as the robot drives off is a mover within a few scans."""
    monitor = CollisionMonitor(
        TOED_OUT, CONFIG.collision, max_speed_mm_s=1000, tracking=CONFIG.tracking
    )
    heading, t, seq = 0.0, 0.0, 0
    for rate in half_turn_rates():
        seq += 1
        monitor.update(hallway_scan(heading, t), 0.0, seq, yaw_rate_dps=rate)
        heading += math.radians(rate) * DT
        t += DT
    heading = math.pi  # where the turn's controller leaves it
    seen_at = None
    for k in range(40):
        seq += 1
        person = (305.0 + 1500.0 - 200.0 * k * DT, 700.0 - 1200.0 * k * DT)
        monitor.update(hallway_scan(heading, t, person), 200.0, seq)
        t += DT
        movers = [m for m in monitor.tracker.movers() if m.speed_mm_s > 800.0]
        if movers:
            seen_at = k
            break
    assert seen_at is not None and seen_at <= 10, seen_at
