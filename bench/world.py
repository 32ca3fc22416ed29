"""Simulation cost: ToF scans per second of wall time, the robot's sensors, the CS building.

Prints a table for docs/benchmarks.md. Target: >= 1000 scans/s (20x real time at 50 Hz).
The baseline is a naive per-direction Python loop over every surface of the floor, measured
in the same run on the same poses; its paths are checked against the compiled ones
(``sim/world/cast.py``).

    .venv/bin/python bench/world.py [--scans N] [--robots N]

With ``--robots N`` (a fleet in one building) the last rows step the world with N robots
driving down the hallway, each one's sensors seeing the others, and scan every robot's
sensors each 20 ms: the world's speed against real time, and per robot.
"""

from __future__ import annotations

import argparse
import math
import time
from collections.abc import Callable
from pathlib import Path

import numpy as np

from coffeebot.config import load_robot_config
from coffeebot.floorplan import load_floorplan
from coffeebot.sim.world import ObstacleSpec, Pose, RobotSpec, World, tof
from coffeebot.sim.world.trace import hallway_pose

ROOT = Path(__file__).resolve().parents[1]
SCAN_RATE_HZ = 50.0

OBSTACLES = [
    ObstacleSpec(id="cart", kind="mail_cart", floor=2, x_mm=7000, y_mm=-550, heading_deg=0),
    ObstacleSpec(id="swivel", kind="swivel_chair", floor=2, x_mm=12000, y_mm=500),
    ObstacleSpec(id="sofa", kind="sofa", floor=2, x_mm=18000, y_mm=380),
    ObstacleSpec(id="chair", kind="wooden_chair", floor=2, x_mm=28000, y_mm=-550),
    ObstacleSpec(id="box", kind="cardboard_box", floor=2, x_mm=31000, y_mm=0),
    ObstacleSpec(
        id="walker",
        kind="person",
        floor=2,
        x_mm=1000,
        y_mm=300,
        path=[(40000, 300)],
        speed_mm_s=1200,
    ),
]


def _poses(world: World, n: int) -> list[Pose]:
    floor = world.robot.floor
    rng = np.random.default_rng(0)
    poses = []
    for _ in range(n):
        pose = hallway_pose(floor, rng.uniform(1000, 43000), rng.uniform(-500, 500))
        poses.append(pose._replace(heading_deg=pose.heading_deg + rng.uniform(-20, 20)))
    return poses


def _naive_background(world: World) -> np.ndarray:
    """Per direction, per surface, in plain Python: the path along each sampled direction of
    every cone to the first wall, face or floor (the layer the compiled optics compute
    first; poles are left out here, since they only share that direction's light)."""
    s = world.robot.body.state
    surfaces = world.robot.surfaces()
    az_deg, el_deg, _mask = tof._grid(world.optics)
    out = []
    for mount in world.robot.sensors.mounts:
        ox = s.x + math.cos(s.theta) * mount.x_mm - math.sin(s.theta) * mount.y_mm
        oy = s.y + math.sin(s.theta) * mount.x_mm + math.cos(s.theta) * mount.y_mm
        rows = []
        for a in az_deg.tolist():
            az = s.theta + math.radians(mount.yaw_deg + a)
            dx, dy = math.cos(az), math.sin(az)
            hits = []
            for x0, y0, x1, y1, zb, zt in surfaces.segments.tolist():
                ex, ey = x1 - x0, y1 - y0
                denom = dx * ey - dy * ex
                if denom == 0:
                    continue
                wx, wy = x0 - ox, y0 - oy
                t = (wx * ey - wy * ex) / denom
                u = (wx * dy - wy * dx) / denom
                if t > 1e-6 and 0 <= u <= 1:
                    hits.append((t, zb, zt))
            column = []
            for e in el_deg.tolist():
                tan_e = math.tan(math.radians(e))
                best = mount.height_mm / -tan_e if tan_e < 0 else math.inf
                for t, zb, zt in hits:
                    if t < best and zb <= mount.height_mm + t * tan_e <= zt:
                        best = t
                column.append(best / math.cos(math.radians(e)))
            rows.append(column)
        out.append(rows)
    return np.array(out)


def _layers(world: World) -> tof.Layers:
    """Every cone's optics at the world's pose, as the chips' first question each step."""
    s = world.robot.body.state
    surfaces = world.robot.surfaces()
    near = surfaces.take(*surfaces.near(s.x, s.y, world.optics.max_path_mm + 400.0))
    return world.robot.sensors.layers(s.x, s.y, s.theta, near)


def _rate(world: World, poses: list[Pose], work: Callable[[], object]) -> tuple[int, float]:
    """Time ``work`` alone at each pose (placing the robot is not part of a scan)."""
    elapsed = 0.0
    for pose in poses:
        world.robot.place(pose)
        start = time.perf_counter()
        work()
        elapsed += time.perf_counter() - start
    return len(poses), elapsed


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--scans", type=int, default=3000)
    parser.add_argument("--naive-scans", type=int, default=30)
    parser.add_argument("--robots", type=int, default=1, help="robots in the fleet rows")
    args = parser.parse_args()

    plan = load_floorplan(ROOT / "floorplans" / "cs-building.toml")
    robot = RobotSpec.from_config(load_robot_config(ROOT / "boards" / "coffeebot-v1.toml"))
    bare = World(plan, robot, floor=2, pose=Pose(2000, 0, 0))
    furnished = World(plan, robot, floor=2, pose=Pose(2000, 0, 0), obstacles=OBSTACLES)
    poses = _poses(bare, args.scans)

    # The compiled optics skip surfaces beyond their reach; within it both must agree, on
    # every direction of the cone (the grid's corners outside it weigh nothing: there a wall
    # tall enough for the cone's edge may be taken for one reaching higher).
    _az, _el, cone = tof._grid(furnished.optics)
    reach = furnished.optics.max_path_mm
    check = _poses(furnished, args.naive_scans)
    for pose in check:
        furnished.robot.place(pose)
        fast = _layers(furnished).path_mm[..., 0]
        slow = _naive_background(furnished)
        in_reach = (slow <= reach) & (fast > 0) & cone[None, :, :]
        assert np.allclose(fast[in_reach], slow[in_reach], rtol=1e-9)

    rows: list[tuple[str, int, float]] = []
    rows.append(
        (
            "naive per-direction loop, obstacles",
            *_rate(furnished, check, lambda: _naive_background(furnished)),
        )
    )
    rows.append(("compiled optics, bare floor", *_rate(bare, poses, lambda: _layers(bare))))
    rows.append(
        ("compiled optics, obstacles", *_rate(furnished, poses, lambda: _layers(furnished)))
    )
    ranging = _rate(furnished, poses, furnished.robot.scan)
    rows.append(("optics + ranging (scan), obstacles", *ranging))

    def live() -> None:
        furnished.robot.command_wheels(400, 400)
        furnished.step(1 / SCAN_RATE_HZ)
        furnished.robot.scan()

    furnished.robot.place(hallway_pose(furnished.robot.floor, 2000, -400))
    start = time.perf_counter()
    for _ in range(args.scans):
        live()
    rows.append(("step 20 ms + scan, obstacles", args.scans, time.perf_counter() - start))

    fleet = World(plan, robot, floor=2, pose=Pose(2000, 0, 0), obstacles=OBSTACLES)
    fleet.robot.place(hallway_pose(fleet.robot.floor, 2000, -400))
    for k in range(1, args.robots):
        # Spread along the hallway, alternate lanes, half of them coming the other way.
        pose = hallway_pose(fleet.robot.floor, 2000 + 9000 * k, 400 if k % 2 else -400)
        if k % 2:
            pose = pose._replace(heading_deg=pose.heading_deg + 180.0)
        fleet.add_robot(robot, 2, pose, f"robot{k + 1}")
    steps = max(1, args.scans // args.robots)
    start = time.perf_counter()
    for _ in range(steps):
        for r in fleet.robots:
            r.command_wheels(400, 400)
        fleet.step(1 / SCAN_RATE_HZ)
        for r in fleet.robots:
            r.scan()
    fleet_s = time.perf_counter() - start
    if args.robots > 1:
        rows.append(
            (f"step 20 ms + scan, {args.robots} robots (per robot)", steps * args.robots, fleet_s)
        )

    naive_rate = rows[0][1] / rows[0][2]
    az, el, mask = tof._grid(furnished.optics)
    segments = len(furnished.robot.surfaces().segments)
    cylinders = len(furnished.robot.surfaces().cylinders)
    print(
        f"{len(furnished.robot.sensors.mounts)} sensors x {int(mask.sum())} directions "
        f"({len(az)} x {len(el)} grid), CS building floor 2: {segments} segments, "
        f"{cylinders} cylinders with obstacles; target >= 1000 scans/s"
    )
    print()
    print("| case | scans | wall s | scans/s | x real time @ 50 Hz | vs naive |")
    print("|---|---:|---:|---:|---:|---:|")
    for name, n, seconds in rows:
        rate = n / seconds
        print(
            f"| {name} | {n} | {seconds:.3f} | {rate:,.0f} | {rate / SCAN_RATE_HZ:,.1f} "
            f"| {rate / naive_rate:,.0f}x |"
        )
    if args.robots > 1:
        world_x = steps / fleet_s / SCAN_RATE_HZ
        print(
            f"\nThe world with {args.robots} robots: {world_x:.1f}x real time "
            f"({world_x * args.robots:.1f} robot-seconds simulated per second)"
        )


if __name__ == "__main__":
    main()
