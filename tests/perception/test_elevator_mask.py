"""Which readings the particle filter leaves out near an elevator: those whose cone may have
crossed its doorway (the car behind it is not in the plan), and the whole scan in the
doorway or facing the car."""

from __future__ import annotations

from pathlib import Path

from coffeebot.config import TofSensorConfig, load_robot_config
from coffeebot.floorplan import load_floorplan
from coffeebot.messages import RangeReading, RangeScan, ReadingStatus
from coffeebot.perception.elevator_mask import ElevatorMask

ROOT = Path(__file__).resolve().parents[2]
CONFIG = load_robot_config(ROOT / "boards" / "coffeebot-v1.toml")
FLOOR = load_floorplan(ROOT / "floorplans" / "cs-building.toml").floor(2)
ELEVATOR_S_MM = 42000.0
"""Floor 2's elevator door, on the hallway's left (+d), opposite the tea room's."""
MASK = ElevatorMask(CONFIG.tof.sensors, margin_mm=300.0, blind_mm=2000.0, reach_mm=4000.0)


def every_sensor_reads(distance_mm: int | None) -> RangeScan:
    status = ReadingStatus.VALID if distance_mm is not None else ReadingStatus.NO_TARGET
    readings = [
        RangeReading(sensor=s.id, status=status, distance_mm=distance_mm)
        for s in CONFIG.tof.sensors
    ]
    return RangeScan(cycle_start_s=0.0, cycle_time_s=0.1, readings=readings)


def faces(ids: frozenset[int]) -> set[str]:
    return {s.face for s in CONFIG.tof.sensors if s.id in ids}


def test_facing_the_doorway_the_front_sensors_are_left_out_and_the_sides_kept() -> None:
    x, y = FLOOR.from_hallway(ELEVATOR_S_MM, -300.0)
    heading = FLOOR.hallway.heading_deg + 90.0  # towards the elevator
    masked = MASK.masked(FLOOR, every_sensor_reads(1500), (x, y, heading), 5.0)
    assert faces(masked) == {"front"}
    assert len(masked) == sum(s.face == "front" for s in CONFIG.tof.sensors)
    # Nothing ranged through the doorway is left out too: the car may have swallowed it.
    assert faces(MASK.masked(FLOOR, every_sensor_reads(None), (x, y, heading), 5.0)) == {"front"}


def test_a_reading_short_of_the_doorway_is_kept() -> None:
    # Facing the elevator from 1.1 m off its wall line: a reading of 300 mm ends (with the
    # margin) before the cone reaches the wall line.
    x, y = FLOOR.from_hallway(ELEVATOR_S_MM, -300.0)
    heading = FLOOR.hallway.heading_deg + 90.0
    assert not MASK.masked(FLOOR, every_sensor_reads(300), (x, y, heading), 5.0)


def test_driving_away_along_the_hallway_nothing_is_left_out() -> None:
    # Just past the tea room crossing, heading away from it in the lane beside the
    # elevator's wall: no cone crosses the doorway behind.
    x, y = FLOOR.from_hallway(ELEVATOR_S_MM - 1200.0, 450.0)
    heading = FLOOR.hallway.heading_deg + 180.0
    assert not MASK.masked(FLOOR, every_sensor_reads(1500), (x, y, heading), 5.0)


def test_the_heading_uncertainty_widens_the_cones() -> None:
    # One sensor at the body centre, looking ahead along the axis 1.5 m short of the
    # doorway: its cone (13.5 degrees each side) meets the wall line only beyond the reading,
    # unless the heading may be 30 degrees off.
    ahead = TofSensorConfig(id=0, channel=0, face="front", x_mm=0, y_mm=0, yaw_deg=0)
    mask = ElevatorMask([ahead], margin_mm=300.0, blind_mm=2000.0, reach_mm=4000.0)
    reading = RangeReading(sensor=0, status=ReadingStatus.VALID, distance_mm=1500)
    scan = RangeScan(cycle_start_s=0.0, cycle_time_s=0.1, readings=[reading])
    x, y = FLOOR.from_hallway(ELEVATOR_S_MM - 1500.0, 0.0)
    assert not mask.masked(FLOOR, scan, (x, y, FLOOR.hallway.heading_deg), 0.0)
    assert mask.masked(FLOOR, scan, (x, y, FLOOR.hallway.heading_deg), 30.0) == {0}


def test_far_from_any_elevator_nothing_is_left_out() -> None:
    x, y = FLOOR.from_hallway(20000.0, -300.0)
    assert not MASK.masked(FLOOR, every_sensor_reads(1500), (x, y, 90.0), 30.0)


def test_the_whole_scan_is_left_out_in_the_doorway_and_facing_the_car() -> None:
    half, along = FLOOR.hallway.width_mm / 2, FLOOR.hallway.heading_deg
    in_car = FLOOR.from_hallway(ELEVATOR_S_MM, half + 400.0)
    at_the_jamb = FLOOR.from_hallway(ELEVATOR_S_MM + 700.0, half - 250.0)
    in_the_lane = FLOOR.from_hallway(ELEVATOR_S_MM, half - 400.0)
    assert MASK.blind(FLOOR, *in_car, along)
    assert MASK.blind(FLOOR, *at_the_jamb, along + 180.0)
    # In the lane in front of the door: looking along the hallway either way the scan
    # counts (less what the mask leaves out); facing the car, or turning there, it does not.
    assert not MASK.blind(FLOOR, *in_the_lane, along)
    assert not MASK.blind(FLOOR, *in_the_lane, along + 180.0 - 40.0)
    assert MASK.blind(FLOOR, *in_the_lane, along + 90.0)
    assert MASK.blind(FLOOR, *in_the_lane, along - 50.0)
    # Far from the door, any heading counts.
    assert not MASK.blind(FLOOR, *FLOOR.from_hallway(ELEVATOR_S_MM - 2500.0, 0.0), along + 90.0)


def test_a_shut_door_is_weighed_like_a_wall_but_not_from_in_the_doorway() -> None:
    door = FLOOR.elevator
    assert door is not None
    shut = frozenset({door.id})
    half, along = FLOOR.hallway.width_mm / 2, FLOOR.hallway.heading_deg
    in_the_lane = FLOOR.from_hallway(ELEVATOR_S_MM, half - 400.0)
    assert MASK.blind(FLOOR, *in_the_lane, along + 90.0)
    assert not MASK.blind(FLOOR, *in_the_lane, along + 90.0, shut)
    # In the car the plan has no walls for what the sensors see, shut or not.
    assert MASK.blind(FLOOR, *FLOOR.from_hallway(ELEVATOR_S_MM, half + 400.0), along, shut)
    facing = (*FLOOR.from_hallway(ELEVATOR_S_MM, -300.0), along + 90.0)
    assert MASK.masked(FLOOR, every_sensor_reads(1500), facing, 5.0)
    assert not MASK.masked(FLOOR, every_sensor_reads(1500), facing, 5.0, shut)
    assert MASK.masked(FLOOR, every_sensor_reads(1500), facing, 5.0, frozenset({"another"}))
