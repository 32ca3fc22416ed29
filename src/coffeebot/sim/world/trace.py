"""Offline traces: drive the world down a hallway without the daemon and record every scan.

A trace is what the door and angle modules see on a pass, with ground truth alongside, so
they can be developed and tested against the simulator without buses or asyncio. By default
a ground-truth line follower holds the robot on its lane (the daemon's job on the robot);
``steer=False`` drives open loop, showing the drift of unequal motors.
"""

from __future__ import annotations

import csv
import math
from collections.abc import Sequence
from typing import NamedTuple, TextIO

from coffeebot.floorplan import Floor
from coffeebot.sim.world.robot import Pose
from coffeebot.sim.world.tof import DEFAULT_SETUP, RangingSetup, ToFReading
from coffeebot.sim.world.world import World

_LANE_GAIN = 0.004  # rad of heading correction per mm of lateral error
_HEADING_GAIN = 2.0  # rad/s of turn per rad of heading error


class TraceRow(NamedTuple):
    t_s: float
    pose: Pose
    s_mm: float
    d_mm: float
    readings: tuple[ToFReading, ...]


def hallway_pose(floor: Floor, s_mm: float, d_mm: float) -> Pose:
    """A pose in a floor's hallway, facing from its start towards its end."""
    x, y = floor.from_hallway(s_mm, d_mm)
    return Pose(x, y, floor.hallway.heading_deg)


def lane_wheel_speeds(world: World, speed_mm_s: float, lane_mm: float) -> tuple[float, float]:
    """Wheel speeds that hold the robot ``lane_mm`` off the hallway axis, travelling towards
    the hallway's end: a ground-truth line follower standing in for navigation and motion."""
    floor, pose = world.robot.floor, world.robot.pose
    _, d = floor.to_hallway(pose.x_mm, pose.y_mm)
    heading_error = math.radians(
        math.remainder(pose.heading_deg - floor.hallway.heading_deg, 360.0)
    )
    wanted = -_LANE_GAIN * (d - lane_mm)
    turn = _HEADING_GAIN * (wanted - heading_error) * world.robot.spec.wheel_base_mm / 2
    return speed_mm_s - turn, speed_mm_s + turn


def hallway_pass(
    world: World,
    *,
    speed_mm_s: float,
    to_s_mm: float,
    rate_hz: float = 10.0,
    steer: bool = True,
    max_time_s: float | None = None,
    setup: RangingSetup = DEFAULT_SETUP,
) -> list[TraceRow]:
    """Drive along the hallway axis until ``to_s_mm``, scanning at ``rate_hz``.

    Stops early on a collision or after ``max_time_s`` (default: twice the nominal travel
    time plus the time to reach speed).
    """
    floor = world.robot.floor
    start_s, lane = floor.to_hallway(world.robot.pose.x_mm, world.robot.pose.y_mm)
    if max_time_s is None:
        travel = abs(to_s_mm - start_s) / speed_mm_s
        max_time_s = 2 * travel + speed_mm_s / world.robot.spec.max_accel_mm_s2 + 1.0
    dt = 1.0 / rate_hz
    collisions = len(world.robot.collisions)
    rows: list[TraceRow] = []
    while world.t_s < max_time_s:
        pose = world.robot.pose
        s, d = floor.to_hallway(pose.x_mm, pose.y_mm)
        rows.append(TraceRow(world.t_s, pose, s, d, tuple(world.robot.scan(setup))))
        if s >= to_s_mm or len(world.robot.collisions) > collisions:
            break
        if steer:
            world.robot.command_wheels(*lane_wheel_speeds(world, speed_mm_s, lane))
        else:
            world.robot.command_wheels(speed_mm_s, speed_mm_s)
        world.step(dt)
    world.robot.command_wheels(0.0, 0.0)
    return rows


def write_trace_csv(rows: Sequence[TraceRow], out: TextIO) -> None:
    """One line per scan: time, ground truth, then status and distance of each sensor."""
    n = len(rows[0].readings) if rows else 0
    writer = csv.writer(out)
    header = ["t_s", "x_mm", "y_mm", "heading_deg", "s_mm", "d_mm"]
    for k in range(n):
        header += [f"status_{k}", f"distance_{k}_mm"]
    writer.writerow(header)
    for row in rows:
        line: list[object] = [
            f"{row.t_s:.3f}",
            f"{row.pose.x_mm:.1f}",
            f"{row.pose.y_mm:.1f}",
            f"{row.pose.heading_deg:.2f}",
            f"{row.s_mm:.1f}",
            f"{row.d_mm:.1f}",
        ]
        for reading in row.readings:
            line += [reading.status.value, reading.distance_mm]
        writer.writerow(line)
