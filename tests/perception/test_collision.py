"""Collision rules: the seed's private sphere and each extension of it."""

from __future__ import annotations

import math
from collections.abc import Sequence

import numpy as np
import pytest
from perception_helpers import robot, scan

from coffeebot.config import CollisionConfig, TofSensorConfig
from coffeebot.messages import RangeReading, ReadingStatus, SafetyState
from coffeebot.perception.collision import CollisionMonitor, safe_speed_mm_s, stop_distance_mm

CLEAR = {0: 300, 1: 300, 6: 900, 7: 900}  # keeping right, as the seed's robot did


def by_sensor(distances: dict[int, int | None]) -> dict[int, RangeReading]:
    return {r.sensor: r for r in scan(distances).readings}


def ahead(distance: int) -> dict[int, int]:
    """A wide obstacle: all four front sensors read it (a narrow one gets extra clearance)."""
    return dict.fromkeys((2, 3, 4, 5), distance)


STRAIGHT = [
    s.model_copy(update={"yaw_deg": 0.0}) if s.face == "front" else s for s in robot().tof.sensors
]
"""The seed's layout, every front sensor looking straight ahead: distances ahead of the
front face are a reading times cos(half the cone), easy to reason on."""


def monitor(**overrides: float) -> CollisionMonitor:
    cfg = robot()
    return CollisionMonitor(
        STRAIGHT, cfg.collision.model_copy(update=overrides), max_speed_mm_s=1000
    )


def test_starts_in_stop_before_any_scan() -> None:
    assert monitor().state is SafetyState.STOP


def test_go_only_when_every_face_is_clear() -> None:
    m = monitor()
    status = m.update(scan(CLEAR), speed_mm_s=0, scan_seq=1)
    assert status.state is SafetyState.GO
    assert status.reason == "clear again"
    assert m.update(scan(CLEAR), speed_mm_s=0, scan_seq=2).reason == "clear"


def test_seed_radii_front_200_sides_50_at_standstill() -> None:
    m = monitor()
    front = m.update(scan({**CLEAR, 3: 190}), speed_mm_s=0, scan_seq=1)
    assert (front.state, front.face, front.sensor, front.distance_mm) == (
        SafetyState.STOP,
        "front",
        3,
        190,
    )
    side = monitor().update(scan({**CLEAR, 0: 45}), speed_mm_s=0, scan_seq=1)
    assert (side.state, side.face, side.sensor) == (SafetyState.STOP, "right", 0)
    # 90 mm from the right wall is inside the seed's first 100 mm radius, which never let the
    # robot start; 50 mm plus the hysteresis does.
    assert monitor().update(scan({**CLEAR, 0: 90, 1: 90}), 0, 1).state is SafetyState.GO


def test_stop_distance_grows_with_speed_and_never_below_seed_radius() -> None:
    cfg = CollisionConfig()
    assert stop_distance_mm(cfg, 0) == cfg.front_radius_mm
    assert stop_distance_mm(cfg, 50) == cfg.front_radius_mm
    fast = stop_distance_mm(cfg, 1000)
    assert fast == pytest.approx(1000 * 0.1 + 1000**2 / 900 + 50)
    assert safe_speed_mm_s(cfg, fast - cfg.margin_mm) == pytest.approx(1000)
    # 500 mm ahead is fine when creeping, a stop at 1 m/s.
    assert monitor().update(scan({**CLEAR, 3: 500}), 1000, 1).state is SafetyState.STOP


def test_slowdown_zone_before_stop_zone_limits_speed() -> None:
    m = monitor()
    m.update(scan(CLEAR), 0, 1)
    status = m.update(scan({**CLEAR, 4: 470}), speed_mm_s=300, scan_seq=2)
    assert status.state is SafetyState.SLOW
    assert status.face == "front" and status.sensor == 4
    assert 0 < status.speed_limit_mm_s < 1000
    nearer = m.update(scan({**CLEAR, 4: 350}), speed_mm_s=200, scan_seq=3)
    assert nearer.speed_limit_mm_s < status.speed_limit_mm_s


def test_hysteresis_keeps_stop_until_clearance_exceeds_radius_plus_margin() -> None:
    m = monitor(hysteresis_mm=30, memory_s=0)
    m.update(scan(CLEAR), 0, 1)
    assert m.update(scan({**CLEAR, **ahead(199)}), 0, 2).state is SafetyState.STOP
    # Jitter just above the radius does not release the stop...
    assert m.update(scan({**CLEAR, **ahead(210)}), 0, 3).state is SafetyState.STOP
    assert m.update(scan({**CLEAR, **ahead(205)}), 0, 4).state is SafetyState.STOP
    # ...clearing the radius plus the hysteresis does, and says so.
    released = m.update(scan({**CLEAR, **ahead(240)}), 0, 5)
    assert released.state is not SafetyState.STOP


def test_a_side_stop_holds_until_the_gap_clears_the_side_radius_plus_the_hysteresis() -> None:
    m = monitor(hysteresis_mm=30, memory_s=0)
    m.update(scan(CLEAR), 0, 1)
    beside = {**CLEAR, 0: 45, 1: 45}
    assert m.update(scan(beside), 0, 2).state is SafetyState.STOP
    assert m.update(scan({**beside, 0: 70, 1: 70}), 0, 3).state is SafetyState.STOP
    assert m.update(scan({**beside, 0: 85, 1: 85}), 0, 4).state is SafetyState.GO


def test_a_stop_ahead_leaves_the_sides_thresholds_alone() -> None:
    """Held by something ahead, 65 mm from the wall beside it (outside the seed's 50 mm side
    radius): once the front clears it drives on. With one hysteresis for the whole verdict
    the side's threshold grew to 80 mm with the front's stop, and the gap, which standing
    never widens, held the robot for good."""
    m = monitor(hysteresis_mm=30, memory_s=0)
    m.update(scan(CLEAR), 0, 1)  # it starts held: the first scan sees the wall 300 mm away
    near_wall = {**CLEAR, 0: 65, 1: 65}
    assert m.update(scan(near_wall), 0, 1).state is SafetyState.GO
    held = m.update(scan({**near_wall, **ahead(150)}), 0, 2)
    assert (held.state, held.face) == (SafetyState.STOP, "front")
    assert m.update(scan(near_wall), 0, 3).state is SafetyState.GO


def test_obstacle_leaving_gives_clear_again() -> None:
    m = monitor(memory_s=0)
    m.update(scan(CLEAR, t=0.0), 0, 1)
    assert m.update(scan({**CLEAR, 2: 100}, t=0.1), 0, 2).state is SafetyState.STOP
    status = m.update(scan(CLEAR, t=0.2), 0, 3)
    assert status.state is SafetyState.GO and status.reason == "clear again"


def test_a_reading_counts_the_near_end_of_its_reported_spread() -> None:
    """A blend (a pole before a far wall) reads beyond the pole with a large sigma: the
    monitor assumes the near end, a clean reading at the same distance keeps its value."""
    gap_at_400 = 400 * math.cos(math.radians(13.5))  # beyond the 200 mm radius at rest

    def with_sigma(sigma_mm: float) -> SafetyState:
        readings = scan({**CLEAR, **ahead(400)}).readings
        blended = [
            r.model_copy(update={"sigma_mm": sigma_mm}) if r.sensor in (2, 3, 4, 5) else r
            for r in readings
        ]
        m = monitor(slowdown_extra_mm=0, memory_s=0)
        return m.update(scan(CLEAR).model_copy(update={"readings": blended}), 0, 1).state

    assert gap_at_400 - 1.5 * 5 > 200 and with_sigma(5) is SafetyState.GO
    assert (400 - 1.5 * 140) * math.cos(math.radians(13.5)) < 200
    assert with_sigma(140) is SafetyState.STOP


def test_with_memory_an_obstacle_leaving_view_clears_only_after_memory_s() -> None:
    m = monitor(memory_s=1.5)
    m.update(scan(CLEAR, t=0.0), 0, 1)
    m.update(scan({**CLEAR, 2: 100}, t=0.1), 0, 2)
    # Out of view it is remembered for memory_s (it may only have left the cone), then clear.
    assert m.update(scan(CLEAR, t=0.2), 0, 3).state is SafetyState.STOP
    status = m.update(scan(CLEAR, t=0.2 + m.cfg.memory_s), 0, 4)
    assert status.state is SafetyState.GO and status.reason == "clear again"


def test_stale_sensor_stops_after_n_cycles() -> None:
    m = monitor(stale_cycles=3)
    m.update(scan(CLEAR), 0, 1)
    bad = {5: ReadingStatus.NOT_READY}
    assert m.update(scan(CLEAR, status=bad), 0, 2).state is SafetyState.GO
    assert m.update(scan(CLEAR, status=bad), 0, 3).state is SafetyState.GO
    status = m.update(scan(CLEAR, status=bad), 0, 4)
    assert (status.state, status.sensor) == (SafetyState.STOP, 5)
    assert "stale" in status.reason
    assert m.update(scan(CLEAR), 0, 5).state is SafetyState.GO


def test_missing_sensor_counts_as_stale() -> None:
    m = monitor(stale_cycles=2)
    m.update(scan(CLEAR), 0, 1)
    partial = scan(CLEAR)
    partial = partial.model_copy(update={"readings": partial.readings[:7]})
    m.update(partial, 0, 2)
    status = m.update(partial, 0, 3)
    assert (status.state, status.sensor) == (SafetyState.STOP, 7)


@pytest.mark.parametrize(
    ("kind", "kwargs"),
    [
        ("unhealthy", {"unhealthy": frozenset({6})}),
        ("hardware", {"status": {6: ReadingStatus.HARDWARE_FAIL}}),
        ("bus", {"status": {6: ReadingStatus.BUS_ERROR}}),
    ],
)
def test_failed_sensor_stops_at_once(kind: str, kwargs: dict) -> None:
    m = monitor()
    m.update(scan(CLEAR), 0, 1)
    status = m.update(scan(CLEAR, **kwargs), 0, 2)
    assert (status.state, status.sensor) == (SafetyState.STOP, 6), kind


def test_target_below_minimum_range_stops_at_once() -> None:
    m = monitor()
    m.update(scan(CLEAR), 0, 1)
    status = m.update(scan(CLEAR, status={3: ReadingStatus.TOO_CLOSE}), 0, 2)
    assert (status.state, status.sensor, status.distance_mm) == (SafetyState.STOP, 3, 0)


def test_nothing_within_range_is_clear_not_stop() -> None:
    m = monitor()
    for seq in range(1, 20):  # far longer than stale_cycles
        status = m.update(scan({0: 300, 1: 300}), 0, seq)  # every other sensor: no target
        assert status.state is SafetyState.GO
    beyond = m.update(scan({**CLEAR, 3: 4200}), 0, 20)
    assert beyond.state is SafetyState.GO
    out = m.update(scan(CLEAR, status={2: ReadingStatus.OUT_OF_BOUNDS}), 0, 21)
    assert out.state is SafetyState.GO


def test_a_sensor_that_finds_nothing_it_can_range_is_clear_however_long() -> None:
    """Down an empty hallway (or at an idle robot's far wall) the VL53L1X answers "signal
    fail" or "sigma fail": the sensor works and nothing is near. Only no answer is stale."""
    m = monitor(stale_cycles=3)
    far = {s: ReadingStatus.SIGNAL_FAIL for s in (2, 3)} | {4: ReadingStatus.SIGMA_FAIL}
    for seq in range(1, 50):
        assert m.update(scan(CLEAR, status=far), 0, seq).state is SafetyState.GO


def test_a_glance_outside_the_corridor_is_not_in_the_way() -> None:
    """A front sensor toed out 25 degrees sees the side wall of the hallway diagonally ahead;
    its arc at 1 m lies wholly beside the body's corridor."""
    cfg = robot()
    sensors = [s.model_copy(update={"yaw_deg": -25.0}) if s.id == 2 else s for s in STRAIGHT]
    m = CollisionMonitor(sensors, cfg.collision, max_speed_mm_s=1000)
    m.update(scan(CLEAR), 0, 1)
    assert m.ahead_mm(sensors[2], 1000) is None
    assert m.update(scan({**CLEAR, 2: 1000}), 900, 2).state is SafetyState.GO
    assert m.update(scan({**CLEAR, 3: 1000}), 900, 3).state is SafetyState.STOP


def test_unknown_speed_assumes_max() -> None:
    m = monitor()
    m.update(scan(CLEAR), 0, 1)
    assert m.update(scan({**CLEAR, **ahead(700)}), None, 2).state is SafetyState.STOP
    assert m.update(scan({**CLEAR, **ahead(700)}), 0, 3).state is SafetyState.GO


def test_narrow_return_gets_the_overhang_margin() -> None:
    # One front sensor sees a pole the others do not: a seat may overhang it above the cones.
    m = monitor(narrow_margin_mm=250)
    m.update(scan(CLEAR), 0, 1)
    status = m.update(scan({**CLEAR, 3: 400}), 0, 2)
    assert (status.state, status.sensor) == (SafetyState.STOP, 3)
    assert "narrow" in status.reason
    # The same distance across the whole front is a wide obstacle: the seed radius applies.
    assert monitor().update(scan({**CLEAR, **ahead(400)}), 0, 1).state is SafetyState.SLOW


def test_a_plan_wall_that_reads_narrow_gets_no_overhang_margin() -> None:
    """Turning out beside a side wall, one toed-out cone sees the wall ahead while the
    others look along the hallway: as narrow as a pole, but nothing overhangs a wall."""

    def wall_at(readings: Sequence[tuple[TofSensorConfig, float]]) -> dict[int, np.ndarray]:
        return {
            sensor.id: np.array([[sensor.x_mm + distance, sensor.y_mm]])
            for sensor, distance in readings
            if sensor.id == 3
        }

    readings = scan({**CLEAR, 3: 400})
    m = monitor(narrow_margin_mm=250)
    m.update(scan(CLEAR), 0, 1)
    assert m.update(readings, 0, 2).state is SafetyState.STOP
    m = monitor(narrow_margin_mm=250)
    m.update(scan(CLEAR), 0, 1)
    status = m.update(readings, 0, 2, explain=wall_at)
    assert status.state is SafetyState.SLOW and "narrow" not in status.reason


def test_narrow_means_at_most_two_adjacent_sensors_with_the_rest_further() -> None:
    m = monitor()
    # Two adjacent sensors on one pole; two separate legs; a wall glimpsed by three sensors.
    assert m.narrow(by_sensor({**CLEAR, 3: 500, 4: 520})) == {3, 4}
    assert m.narrow(by_sensor({**CLEAR, 2: 500, 5: 520})) == {2, 5}
    assert m.narrow(by_sensor({**CLEAR, 2: 500, 3: 520, 4: 700})) == set()
    # Neighbours within the depth count as the same object, even if a little further.
    assert m.narrow(by_sensor({**CLEAR, 3: 500, 4: 760, 5: 790})) == set()
    # Beyond the range limit nothing is judged narrow (a glance off a side wall).
    assert m.narrow(by_sensor({**CLEAR, 2: 1500})) == set()


def test_narrow_margin_slows_earlier_so_the_robot_can_still_stop() -> None:
    cfg = robot().collision
    m = monitor()
    m.update(scan(CLEAR), 0, 1)
    wide = m.update(scan({**CLEAR, **ahead(700)}), 400, 2)
    m = monitor()
    m.update(scan(CLEAR), 0, 1)
    narrow = m.update(scan({**CLEAR, 4: 700}), 400, 2)
    assert narrow.state is SafetyState.SLOW
    gap = m.ahead_mm(STRAIGHT[4], 700)
    assert gap is not None and gap == pytest.approx(700 * math.cos(math.radians(13.5)))
    room = gap - cfg.front_radius_mm - cfg.hysteresis_mm - cfg.narrow_margin_mm
    assert narrow.speed_limit_mm_s == pytest.approx(safe_speed_mm_s(cfg, room))
    assert narrow.speed_limit_mm_s < wide.speed_limit_mm_s


def test_a_return_that_drops_out_of_view_up_close_still_blocks() -> None:
    # A seat edge seen at 600 mm leaves the top of the cone; the pole behind reads 850 mm.
    m = monitor(memory_s=1.5)
    m.update(scan({**CLEAR, **ahead(2000)}, t=0.0), 0, 1)
    m.update(scan({**CLEAR, **ahead(600)}, t=0.1), 300, 2)
    # 0.6 s later at 300 mm/s the seat is 180 mm closer, though no sensor sees it any more.
    status = m.update(scan({**CLEAR, **ahead(850)}, t=0.7), 300, 3)
    assert status.distance_mm == pytest.approx(600 - 300 * 0.6, abs=1)
    assert "seen 0.6 s ago" in status.reason
    # Past the memory it no longer counts.
    later = m.update(scan({**CLEAR, **ahead(850)}, t=2.0), 0, 4)
    assert later.distance_mm is None or later.distance_mm >= 850


def test_only_returns_inside_the_body_corridor_are_remembered() -> None:
    # An outer sensor's cone leaves the body's width beyond ~340 mm: a return there may be a
    # glance off a side wall, so it is not remembered; an inner sensor's return at 700 mm is.
    m = monitor(memory_s=1.5)
    m.update(scan({**CLEAR, 2: 700}, t=0.0), 0, 1)
    assert m.update(scan(CLEAR, t=0.1), 0, 2).state is SafetyState.GO
    m.update(scan({**CLEAR, 3: 700}, t=0.2), 0, 3)
    assert m.update(scan(CLEAR, t=0.3), 0, 4).distance_mm == 700


def test_a_remembered_return_is_forgotten_once_the_body_turns_away() -> None:
    # In the elevator car the robot faces the back wall, then turns on the spot to drive out.
    m = monitor(memory_s=1.5, memory_max_turn_deg=10)
    m.update(scan({**CLEAR, 3: 250}, t=0.0), 0, 1)
    turning = m.update(scan(CLEAR, t=0.1), 0, 2, yaw_rate_dps=50)  # 5 deg turned: still ahead
    assert turning.distance_mm == 250
    turned = m.update(scan(CLEAR, t=0.3), 0, 3, yaw_rate_dps=50)  # 15 deg: no longer ahead
    assert turned.distance_mm is None


def test_memory_keeps_the_nearest_return_per_sensor() -> None:
    m = monitor(memory_s=1.5)
    m.update(scan({**CLEAR, **ahead(500)}, t=0.0), 0, 1)
    m.update(scan({**CLEAR, **ahead(650)}, t=0.1), 0, 2)
    assert m.update(scan(CLEAR, t=0.2), 0, 3).distance_mm == 500


def test_a_front_only_stop_allows_turning_on_the_spot() -> None:
    m = monitor()
    m.update(scan(CLEAR, t=0.0), 0, 1)
    status = m.update(scan({**CLEAR, 2: 400}, t=0.1), 0, 2)
    assert status.state is SafetyState.STOP
    assert (status.blocked_faces, status.front_clearance_mm, status.may_rotate) == (
        ("front",),
        400,
        True,
    )
    # Turning away opens the gap: still allowed while it is stopped.
    assert m.update(scan({**CLEAR, 2: 430}, t=0.2), 0, 3).may_rotate


def test_turning_that_brings_the_front_nearer_is_refused() -> None:
    """Within reach of the front corners a turn may only open the gap. The clearance is
    smoothed over scans, so a noisy reading alone does not end the turn."""
    m = monitor()
    m.update(scan(CLEAR, t=0.0), 0, 1)
    assert m.update(scan({**CLEAR, 2: 200}, t=0.1), 0, 2).may_rotate
    assert not m.beyond_front_sweep(STRAIGHT[2], 200)
    assert m.update(scan({**CLEAR, 2: 185}, t=0.2), 0, 3).may_rotate  # noise
    nearer = m.update(scan({**CLEAR, 2: 120}, t=0.3), 0, 4)
    assert nearer.state is SafetyState.STOP and not nearer.may_rotate


def test_anything_out_of_the_front_corners_reach_never_stops_a_turn() -> None:
    m = monitor()
    m.update(scan(CLEAR, t=0.0), 0, 1)
    assert m.beyond_front_sweep(STRAIGHT[3], 400)
    assert m.update(scan({**CLEAR, 3: 400}, t=0.1), 0, 2).may_rotate
    assert m.update(scan({**CLEAR, 3: 300}, t=0.2), 0, 3).may_rotate


def test_a_side_stop_or_a_sensor_fault_never_allows_turning() -> None:
    m = monitor()
    m.update(scan(CLEAR, t=0.0), 0, 1)
    both = m.update(scan({**CLEAR, 2: 400, 0: 40}, t=0.1), 0, 2)
    assert set(both.blocked_faces) == {"front", "right"} and not both.may_rotate
    m = monitor()
    m.update(scan(CLEAR, t=0.0), 0, 1)
    faulty = scan({**CLEAR, 2: 400}, t=0.1)
    readings = [
        r.model_copy(update={"healthy": False}) if r.sensor == 5 else r for r in faulty.readings
    ]
    status = m.update(faulty.model_copy(update={"readings": readings}), 0, 2)
    assert status.state is SafetyState.STOP and not status.may_rotate


def test_the_body_is_swept_along_the_arc_it_drives() -> None:
    """Something 900 mm ahead and just inside the corridor on the right: driving straight the
    body meets it after 900 mm; arcing left, round it, never; arcing gently right, still
    (it turns onto it), arcing sharply right, never (it turns inside it)."""
    m = monitor()
    corner = np.array([[305.0 + 900.0, -300.0]])
    right = STRAIGHT[2]

    def gap(radius_mm: float | None) -> float | None:
        curve = 0.0 if radius_mm is None else 1.0 / radius_mm
        return m.ahead_mm(right, 900, corner, curvature_per_mm=curve)

    assert gap(None) == pytest.approx(900, abs=1)
    assert gap(760) is None
    assert gap(-2000) is not None
    assert gap(-500) is None


def test_a_turn_stopped_as_it_braked_may_turn_again_not_nearer_than_where_it_came_to_rest() -> None:
    """Turning towards a wall, the front stop fires at 224 mm; the turn brakes for two scans
    and the robot comes to rest at 186 mm. Turning is refused while it still turns, then
    allowed from where it stands: away (the gap opens), not nearer. Measured from the first
    scan, the braking alone had forbidden any turn for good."""
    m = monitor()
    m.update(scan(CLEAR, t=0.0), 0, 1, 30.0)
    fired = m.update(scan({**CLEAR, 2: 224}, t=0.1), 0, 2, 30.0)
    assert fired.state is SafetyState.STOP and not fired.may_rotate
    assert not m.update(scan({**CLEAR, 2: 205}, t=0.2), 0, 3, 12.0).may_rotate
    assert m.update(scan({**CLEAR, 2: 186}, t=0.3), 0, 4, 0.0).may_rotate
    assert m.update(scan({**CLEAR, 2: 186}, t=0.4), 0, 5, 0.0).may_rotate
    assert m.update(scan({**CLEAR, 2: 196}, t=0.5), 0, 6, -20.0).may_rotate
    m.update(scan({**CLEAR, 2: 120}, t=0.6), 0, 7, 20.0)
    nearer = m.update(scan({**CLEAR, 2: 120}, t=0.7), 0, 8, 20.0)
    assert nearer.state is SafetyState.STOP and not nearer.may_rotate
