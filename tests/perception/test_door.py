"""Door detection: the seed's sliding window, its size from speed, and plan matching."""

from __future__ import annotations

import math

import numpy as np
import pytest
from perception_helpers import hallway_floor, pose, robot, scan, scan_at

from coffeebot.config import DoorConfig
from coffeebot.floorplan import Floor, parse_floorplan
from coffeebot.messages import DoorEvent
from coffeebot.perception.door import DoorDetector, readings_per_door, window_size

RATE_HZ = 10.0


def drive(
    floor: Floor,
    *,
    start: float,
    end: float,
    speed: float,
    y: float = -300.0,
    pose_offset: float = 0.0,
    pose_sigma_mm: float = 30.0,
    noise_mm: float = 0.0,
    target: str | None = None,
    seed: int = 1,
) -> list[DoorEvent]:
    """Drive straight along the hallway from ``start`` to ``end`` and collect door events."""
    detector = DoorDetector(robot().tof.sensors, DoorConfig(), target_door=target)
    rng = np.random.default_rng(seed)
    heading = 0.0 if end > start else 180.0
    step = speed / RATE_HZ * (1 if end > start else -1)
    events: list[DoorEvent] = []
    for k, x in enumerate(np.arange(start, end, step)):
        s = scan_at(floor, float(x), y, heading, noise_mm=noise_mm, rng=rng)
        believed = pose(float(x) + pose_offset, y, heading, sigma_mm=pose_sigma_mm)
        events += detector.update(s, k, believed, floor, speed, RATE_HZ)
    return events


def test_window_is_twice_the_readings_per_door_and_shrinks_with_speed() -> None:
    cfg = DoorConfig()
    # The seed's example: readings 0.25 s apart at ~0.9 m/s give 4 per door, a window of 8.
    assert readings_per_door(cfg, 900, 4.0) == 4
    assert window_size(cfg, 900, 4.0) == 8
    sizes = [window_size(cfg, v, RATE_HZ) for v in (100, 200, 500, 1000)]
    assert sizes == sorted(sizes, reverse=True)
    assert sizes[-1] == 18
    assert window_size(cfg, 0, RATE_HZ) == 2 * cfg.max_readings_per_door
    assert window_size(cfg, 100_000, RATE_HZ) == 2 * cfg.min_readings_per_door


@pytest.mark.parametrize("speed", [100, 300, 600, 1000])
def test_passing_a_door_names_the_room_at_any_speed(speed: float) -> None:
    floor = hallway_floor()
    events = drive(floor, start=4500, end=7500, speed=speed, noise_mm=5.0)
    assert [(e.room, e.side, e.kind) for e in events] == [("102", "right", "door")]
    event = events[0]
    assert event.jump_mm == pytest.approx(100, abs=25)
    assert abs(event.x_mm - 6000) <= speed / RATE_HZ / 2 + 10
    assert abs(event.along_correction_mm or 0) <= speed / RATE_HZ / 2 + 10


def test_below_the_80_mm_threshold_is_no_door() -> None:
    def floor_with_recess(recess: float) -> Floor:
        door = {"room": "9", "side": "right", "at_mm": 3000, "recess_mm": recess}
        tea = {"room": "t", "side": "left", "at_mm": 500, "kind": "tea_room"}
        hallway = {"id": "main", "start": [0, 0], "end": [6000, 0]}
        return parse_floorplan(
            {"floors": [{"level": 1, "hallways": [hallway], "doors": [door, tea]}]}
        ).floors[0]

    assert drive(floor_with_recess(70), start=1500, end=4500, speed=300) == []
    assert len(drive(floor_with_recess(100), start=1500, end=4500, speed=300)) == 1


def test_plain_wall_with_noise_gives_no_false_alarms() -> None:
    floor = hallway_floor()
    assert drive(floor, start=6600, end=8000, speed=200, noise_mm=5.0, seed=3) == []


def test_along_hallway_correction_from_the_matched_door() -> None:
    floor = hallway_floor()
    # The pose believes the robot is 300 mm further along than it is, and says it may be.
    events = drive(floor, start=4500, end=7500, speed=300, pose_offset=300.0, pose_sigma_mm=150)
    assert len(events) == 1 and events[0].room == "102"
    assert events[0].along_correction_mm == pytest.approx(-300, abs=20)
    assert (events[0].plan_x_mm, events[0].plan_y_mm) == (6000, -850)


def test_a_door_many_sigmas_from_where_the_pose_puts_it_is_not_matched() -> None:
    floor = hallway_floor()
    # A pose 1173 mm off that claims 30 mm: the recess it passes is not taken for door 102
    # (a fixed 1200 mm gate took a false door for one 1173 mm away).
    events = drive(floor, start=4500, end=7500, speed=300, pose_offset=1173.0)
    assert [(e.kind, e.room, e.along_correction_mm) for e in events] == [("door", None, None)]
    detector = DoorDetector(robot().tof.sensors, DoorConfig())
    assert detector.gate_mm(pose(6000, -300, 0.0, sigma_mm=30), floor) == pytest.approx(
        4 * math.hypot(30, 50)
    )
    assert detector.gate_mm(pose(6000, -300, 0.0, sigma_mm=2000), floor) == 1200
    # Along a diagonal hallway, the pose's x-y covariance is part of its sigma along it.
    diagonal = floor.model_copy(
        update={"hallways": [floor.hallway.model_copy(update={"end": (20000.0, 20000.0)})]}
    )
    assert diagonal.hallway.heading_deg == pytest.approx(45.0)
    correlated = pose(6000, -300, 45.0, sigma_mm=100).model_copy(update={"cov_xy_mm2": 8000.0})
    along = math.sqrt(0.5 * 100**2 + 0.5 * 100**2 + 8000.0)
    assert detector.gate_mm(correlated, diagonal) == pytest.approx(4 * math.hypot(along, 50))


def test_a_detection_two_doors_could_explain_is_refused() -> None:
    # Doors 2000 mm apart; the pose 900 mm off and unsure enough (400 mm) that both doors
    # lie within its gate of the first one it passes: neither is guessed. The second door,
    # passed 900 mm off too, has only itself within the gate and is matched.
    close = hallway_floor(
        angle_zones=[],
        doors=[
            {"room": "102", "side": "right", "at_mm": 6000},
            {"room": "102a", "side": "right", "at_mm": 4000},
            {"room": "tea", "side": "left", "at_mm": 15000, "kind": "tea_room"},
        ],
    )
    events = drive(close, start=2500, end=7500, speed=300, pose_offset=900.0, pose_sigma_mm=400)
    assert [e.room for e in events] == [None, "102"]


def test_opening_is_not_a_door() -> None:
    floor = hallway_floor()
    events = drive(floor, start=7600, end=10500, speed=500)
    assert [(e.kind, e.room) for e in events] == [("opening", None)]


def test_travelling_back_sees_the_door_on_its_left() -> None:
    floor = hallway_floor()
    events = drive(floor, start=7500, end=4500, speed=500, y=300.0)
    assert [(e.room, e.side) for e in events] == [("102", "right")]
    assert abs(events[0].along_correction_mm or 0) <= 30


def test_arrived_at_target_door() -> None:
    floor = hallway_floor()
    events = drive(floor, start=4500, end=13000, speed=500, target="104")
    arrived = [e.room for e in events if e.arrived_at_target]
    assert arrived == ["104"]
    assert "102" in [e.room for e in events]


def test_of_a_room_with_two_doors_only_the_target_door_is_arrived_at() -> None:
    """Room 104 has a second door ("104b", across the hallway 3 m before the first):
    passing it is not arriving."""
    doors = [
        {"room": "102", "side": "right", "at_mm": 6000},
        {"id": "104b", "room": "104", "side": "left", "at_mm": 9000},
        {"room": "104", "side": "right", "at_mm": 12000},
        {"room": "tea", "side": "left", "at_mm": 15000, "kind": "tea_room"},
    ]
    floor = hallway_floor(doors=doors)
    events = drive(floor, start=4500, end=13000, speed=500, target="104")
    assert [(e.room, e.arrived_at_target) for e in events if e.room == "104"] == [
        ("104", False),
        ("104", True),
    ]


def test_no_readings_while_standing_still() -> None:
    floor = hallway_floor()
    detector = DoorDetector(robot().tof.sensors, DoorConfig())
    s = scan_at(floor, 5900, -300, 0.0)
    for k in range(50):
        assert detector.update(s, k, pose(5900, -300, 0.0), floor, 0.0, RATE_HZ) == []
    assert all(not t.samples for t in detector.tracks.values())


def drive_synthetic(
    door_along: dict[int, tuple[float, float]],
    *,
    speed: float = 300.0,
    half_fov_deg: float = 13.5,
    start: float = 4000.0,
    end: float = 8000.0,
) -> list[tuple[float, DoorEvent]]:
    """Drive along ``hallway_floor`` with the right sensors reading the recess (395 mm instead
    of the wall's 295 mm) while their own along position is inside ``door_along[sensor]``.

    Returns each event with the front right sensor's along position when it came.
    """
    floor = hallway_floor()
    sensors = robot().tof.sensors
    detector = DoorDetector(sensors, DoorConfig(), half_fov_deg)
    events: list[tuple[float, DoorEvent]] = []
    for k, x in enumerate(np.arange(start, end, speed / RATE_HZ)):
        distances: dict[int, int | None] = {}
        for s in sensors:
            if s.face == "right":
                lo, hi = door_along[s.id]
                distances[s.id] = 395 if lo <= x + s.x_mm <= hi else 295
            elif s.face == "left":
                distances[s.id] = 1195
        found = detector.update(scan(distances), k, pose(float(x), -300, 0.0), floor, speed, 10)
        events += [(float(x) + sensors[1].x_mm, e) for e in found]
    return events


@pytest.mark.parametrize("blur", [0.0, 70.0, 140.0])
def test_door_centre_from_both_edges_is_free_of_the_cone_blur(blur: float) -> None:
    # A wide cone reporting the nearest return sees the recess only between the edges moved
    # inwards by its footprint (71 mm for 13.5 degrees at 295 mm), whatever it turns out to be.
    seen = (5550.0 + blur, 6450.0 - blur)
    events = drive_synthetic({0: seen, 1: seen})
    assert len(events) == 1
    sensor_at, event = events[0]
    assert event.room == "102"
    assert event.x_mm == pytest.approx(6000, abs=30 / 2 + 1)
    assert sensor_at > seen[1], "reported once the wall has come back"


def test_the_two_sensors_on_a_side_are_averaged() -> None:
    events = drive_synthetic({1: (5610.0, 6510.0), 0: (5530.0, 6430.0)})
    assert len(events) == 1
    assert events[0][1].x_mm == pytest.approx(6020, abs=16)


def test_wall_not_coming_back_falls_back_to_the_near_edge_and_the_plan_width() -> None:
    cfg = DoorConfig()
    events = drive_synthetic({0: (5550.0, 1e9), 1: (5550.0, 1e9)}, half_fov_deg=0.0, end=9000)
    assert len(events) == 1
    sensor_at, event = events[0]
    assert event.room == "102"
    assert event.x_mm == pytest.approx(6000, abs=16)
    assert sensor_at >= 5550 + cfg.max_feature_mm
