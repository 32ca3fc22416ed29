"""Synthetic inputs for the perception tests: scans from plain distances, the seed robot."""

from __future__ import annotations

from pathlib import Path

from coffeebot.config import RobotConfig, load_robot_config
from coffeebot.messages import RangeReading, RangeScan, ReadingStatus

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
