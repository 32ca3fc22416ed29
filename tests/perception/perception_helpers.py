"""Synthetic inputs for the perception tests: scans from plain distances, the seed robot."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np

from coffeebot.config import RobotConfig, load_robot_config
from coffeebot.floorplan import Floor, parse_floorplan
from coffeebot.messages import PoseEstimate, RangeReading, RangeScan, ReadingStatus
from coffeebot.perception.geometry import sensor_origin

BOARD_FILE = Path(__file__).resolve().parents[2] / "boards" / "coffeebot-v1.toml"


def robot() -> RobotConfig:
    return load_robot_config(BOARD_FILE)


def scan(
    distances: dict[int, int | None] | None = None,
    *,
    default: int | None = None,
    status: dict[int, ReadingStatus] | None = None,
    unhealthy: frozenset[int] = frozenset(),
    t: float = 0.0,
) -> RangeScan:
    """A scan of sensors 0..7: a distance per sensor, None = no target, ``default`` otherwise."""
    distances = distances or {}
    status = status or {}
    readings = []
    for sensor in range(8):
        distance = distances.get(sensor, default)
        st = status.get(
            sensor, ReadingStatus.VALID if distance is not None else ReadingStatus.NO_TARGET
        )
        readings.append(
            RangeReading(
                sensor=sensor,
                status=st,
                distance_mm=distance if st is ReadingStatus.VALID else None,
                healthy=sensor not in unhealthy,
            )
        )
    return RangeScan(cycle_start_s=t, cycle_time_s=0.05, readings=readings)


# --- a small test building and a centre-ray caster over it --------------------------------


def hallway_floor(angle_zones: list[dict] | None = None, doors: list[dict] | None = None) -> Floor:
    """A 20 m hallway along +x: doors on both sides, an opening, two angle zones; or the
    given ``doors`` (the tea room among them) and ``angle_zones`` instead."""
    plan = parse_floorplan(
        {
            "name": "test",
            "floors": [
                {
                    "level": 1,
                    "hallways": [
                        {"id": "main", "start": [0, 0], "end": [20000, 0], "width_mm": 1700}
                    ],
                    "doors": doors
                    if doors is not None
                    else [
                        {"room": "101", "side": "left", "at_mm": 3000},
                        {"room": "102", "side": "right", "at_mm": 6000},
                        {"room": "104", "side": "right", "at_mm": 12000},
                        {"room": "tea", "side": "left", "at_mm": 15000, "kind": "tea_room"},
                    ],
                    "openings": [{"id": "side hall", "side": "right", "at_mm": 9000}],
                    "angle_zones": angle_zones
                    if angle_zones is not None
                    else [
                        {"id": "Za", "from_mm": 3900, "to_mm": 5100},
                        {"id": "Zb", "from_mm": 6000, "to_mm": 8000},
                    ],
                }
            ],
        }
    )
    return plan.floors[0]


def cast(
    floor: Floor, x: float, y: float, heading_deg: float, max_mm: float = 4000
) -> float | None:
    """Distance along a ray to the nearest wall segment of ``floor``, None beyond ``max_mm``."""
    a = floor.segment_array
    h = math.radians(heading_deg)
    dx, dy = math.cos(h), math.sin(h)
    ex, ey = a[:, 2] - a[:, 0], a[:, 3] - a[:, 1]
    denom = dx * ey - dy * ex
    with np.errstate(divide="ignore", invalid="ignore"):
        t = ((a[:, 0] - x) * ey - (a[:, 1] - y) * ex) / denom
        u = ((a[:, 0] - x) * dy - (a[:, 1] - y) * dx) / denom
    ok = (np.abs(denom) > 1e-12) & (t > 0) & (u >= 0) & (u <= 1)
    if not ok.any():
        return None
    best = float(t[ok].min())
    return best if best <= max_mm else None


def scan_at(
    floor: Floor,
    x: float,
    y: float,
    heading_deg: float,
    *,
    noise_mm: float = 0.0,
    rng: np.random.Generator | None = None,
    t: float = 0.0,
) -> RangeScan:
    """The scan the seed robot would take at a pose, by casting each sensor's optical axis."""
    distances: dict[int, int | None] = {}
    for sensor in robot().tof.sensors:
        sx, sy, look = sensor_origin(x, y, heading_deg, sensor)
        d = cast(floor, sx, sy, look)
        if d is not None and noise_mm and rng is not None:
            d += rng.normal(0.0, noise_mm)
        distances[sensor.id] = None if d is None else round(d)
    return scan(distances, t=t)


def pose(
    x: float, y: float, heading_deg: float, sigma_mm: float = 30.0, sigma_deg: float = 3.0
) -> PoseEstimate:
    return PoseEstimate(
        x_mm=x,
        y_mm=y,
        heading_deg=heading_deg,
        floor=1,
        sigma_x_mm=sigma_mm,
        sigma_y_mm=sigma_mm,
        sigma_heading_deg=sigma_deg,
    )
