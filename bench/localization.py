"""Localization: the Kalman filter vs the particle filter vs UWB alone, on the simulated world.

    python bench/localization.py            # tables, for docs/benchmarks.md
    python bench/localization.py --json     # one JSON object
    python bench/localization.py --trials 20  # fewer kidnap and global trials (quicker)

Everything runs on the simulated world (``coffeebot.sim.world``) with its standard noise: the
seed robot's eight VL53L1X cones, unequal motors, wheel slip, a biased gyro and ~0.1 m UWB
fixes. The robot is driven on ground truth (a lane follower standing in for navigation), so
every filter sees the same readings; each filter has its own angle and door modules, closed
over its own estimate, as in the daemon. Odometry at 50 Hz, scans and UWB at 10 Hz.

* tracking: a pass along each floor's whole hallway, where every delivery route runs,
  keeping right at 500 mm/s, from a known start.
* uwb_outage_30s: the same pass on floor 2 with no UWB fix for 30 s from s = 10 m: the
  largest error during the outage and the 5 s after it.
* kidnap: while tracking, the robot is lifted 3 m along the hallway and turned by 90 degrees
  (random sides and directions), turns back to the hallway on the spot and drives on;
  recovered once the error stays within 200 mm and 5 degrees for the rest of the trial.
* global: the filter starts with no prior, the robot anywhere in either hallway facing
  anywhere; it turns to the hallway and drives on; localized as above.
* update_ms: CPU time of the fusion per 100 ms cycle (five odometry steps, a fix, a scan, the
  angle and door events) while tracking, and the median particle count it ran at (the
  floors' likelihood fields are built with the filter, before).
"""

from __future__ import annotations

import argparse
import functools
import json
import math
import sys
import time
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from coffeebot.config import RobotConfig, load_robot_config
from coffeebot.floorplan import Floor, FloorPlan, load_floorplan
from coffeebot.messages import AngleEstimate, Odometry, RangeScan, UwbFix
from coffeebot.perception.angle import AngleEstimator
from coffeebot.perception.door import DoorDetector
from coffeebot.perception.geometry import wrap_deg
from coffeebot.perception.state import StateEstimator, make_fusion
from coffeebot.sim.world import Pose, RobotSpec, World
from coffeebot.sim.world.tof import RangingSetup, as_range_reading, robot_setup
from coffeebot.sim.world.trace import hallway_pose

ROOT = Path(__file__).resolve().parents[1]
DT_S = 0.02
SCAN_EVERY = 5
SPEED_MM_S = 500.0
LANE_D_MM = -295.0
RECOVERED_MM = 200.0
RECOVERED_DEG = 5.0


def to_scan(world: World, setup: RangingSetup, t: float) -> RangeScan:
    """One ranging of every sensor, set up and published as the ToF poller does it."""
    return RangeScan(
        cycle_start_s=t,
        cycle_time_s=DT_S * SCAN_EVERY,
        readings=[as_range_reading(i, r) for i, r in enumerate(world.robot.scan(setup))],
    )


@dataclass
class Filter:
    """One fusion method with its own angle and door modules, and what it cost."""

    name: str
    state: StateEstimator
    angle: AngleEstimator
    doors: DoorDetector
    cpu_s: list[float] = field(default_factory=list)
    counts: list[int] = field(default_factory=list)

    @classmethod
    def make(cls, name: str, config: RobotConfig, plan: FloorPlan) -> Filter:
        fusion_config = config.model_copy(
            update={"state": config.state.model_copy(update={"fusion": name})}
        )
        cfg = fusion_config.state
        fusion = make_fusion(fusion_config, plan)
        return cls(
            name,
            StateEstimator(plan, config.motor, cfg, fusion),
            AngleEstimator(config.tof.sensors, config.angle, config.tof.effective_half_fov_deg),
            DoorDetector(config.tof.sensors, config.door, config.tof.cone_half_deg),
        )

    def error(self, truth: Pose) -> tuple[float, float]:
        e = self.state.pose()
        return (
            math.hypot(e.x_mm - truth.x_mm, e.y_mm - truth.y_mm),
            abs(wrap_deg(e.heading_deg - truth.heading_deg)),
        )


class Drive:
    """The world, its filters and a ground-truth driver, stepped in 20 ms ticks."""

    def __init__(self, world: World, filters: list[Filter], setup: RangingSetup) -> None:
        self.world = world
        self.setup = setup
        self.filters = filters
        self.tick = 0
        self.travel_mm = 0.0
        self.uwb_blocked: Callable[[float], bool] = lambda t: False
        self.uwb_errors: list[float] = []
        self._cycle_cpu = {f.name: 0.0 for f in filters}

    def _timed(self, f: Filter, call: Callable[[], object]) -> None:
        started = time.process_time()
        call()
        self._cycle_cpu[f.name] += time.process_time() - started

    def step(self, left: float, right: float) -> None:
        world = self.world
        self.tick += 1
        now = world.t_s
        lt, rt = world.robot.encoder_ticks
        wl, wr = world.robot.wheel_speeds_mm_s
        odo = Odometry(
            controller_time_ms=round(now * 1000),
            left_ticks=lt,
            right_ticks=rt,
            gyro_z_dps=world.robot.gyro_z_dps(),
            left_mm_s=wl,
            right_mm_s=wr,
        )
        for f in self.filters:
            self._timed(f, functools.partial(f.state.on_odometry, odo, now))
        if self.tick % SCAN_EVERY == 0:
            fix = None if self.uwb_blocked(now) else world.robot.uwb_fix()
            if fix is not None:
                truth = world.robot.pose
                self.uwb_errors.append(math.hypot(fix.x_mm - truth.x_mm, fix.y_mm - truth.y_mm))
            scan = to_scan(world, self.setup, now)
            floor = world.robot.floor
            for f in self.filters:
                self._timed(f, functools.partial(self._measure, f, fix, scan, floor, now))
                f.cpu_s.append(self._cycle_cpu[f.name])
                self._cycle_cpu[f.name] = 0.0
                summary = f.state.fusion.summary()
                if summary is not None:
                    f.counts.append(summary.count)
        before = world.robot.pose
        world.robot.command_wheels(left, right)
        world.step(DT_S)
        self.travel_mm += math.dist(before[:2], world.robot.pose[:2])

    def _measure(
        self, f: Filter, fix: UwbFix | None, scan: RangeScan, floor: Floor, now: float
    ) -> None:
        state = f.state
        if fix is not None:
            state.on_uwb(fix, now)
        state.on_scan(scan, now)
        estimate = state.pose()
        if not estimate.initialised:
            return
        result = f.angle.update(scan, self.tick, estimate, floor, False, now)
        if isinstance(result, AngleEstimate):
            state.on_angle(result, now)
        for event in f.doors.update(scan, self.tick, estimate, floor, estimate.speed_mm_s, 10.0):
            state.on_door(event, now)

    # --- ground-truth driving ------------------------------------------------------------

    def lane_speeds(self, direction_deg: float, lane_mm: float) -> tuple[float, float]:
        floor, pose = self.world.robot.floor, self.world.robot.pose
        _, d = floor.to_hallway(pose.x_mm, pose.y_mm)
        sign = 1.0 if abs(wrap_deg(direction_deg - floor.hallway.heading_deg)) < 90 else -1.0
        heading_error = math.radians(wrap_deg(pose.heading_deg - direction_deg))
        turn = 2.0 * (-0.004 * sign * (d - lane_mm) - heading_error) * 225.0
        return SPEED_MM_S - turn, SPEED_MM_S + turn

    def turn_to(self, heading_deg: float, on_each: Callable[[], None] | None = None) -> None:
        """On the spot until within 3 degrees."""
        for _ in range(2000):
            error = wrap_deg(heading_deg - self.world.robot.pose.heading_deg)
            if abs(error) < 3.0:
                return
            rate = max(-150.0, min(150.0, 4.0 * error))
            self.step(-rate, rate)
            if on_each is not None:
                on_each()

    def drive(
        self,
        distance_mm: float,
        direction_deg: float,
        lane_mm: float,
        on_each: Callable[[], None] | None = None,
    ) -> None:
        """Along the hallway for ``distance_mm`` of travel (or until 2 m from its end)."""
        floor = self.world.robot.floor
        goal = self.travel_mm + distance_mm
        forward = abs(wrap_deg(direction_deg - floor.hallway.heading_deg)) < 90
        deadline = self.world.t_s + min(distance_mm, 50_000.0) / SPEED_MM_S * 2 + 10.0
        while self.travel_mm < goal and self.world.t_s < deadline:
            s, _ = floor.to_hallway(self.world.robot.pose.x_mm, self.world.robot.pose.y_mm)
            if (forward and s > floor.hallway.length_mm - 2000) or (not forward and s < 2000):
                break
            self.step(*self.lane_speeds(direction_deg, lane_mm))
            if on_each is not None:
                on_each()

    def rest(self, seconds: float) -> None:
        for _ in range(round(seconds / DT_S)):
            self.step(0.0, 0.0)


def rms(values: list[float]) -> float:
    return float(np.sqrt(np.mean(np.square(values)))) if values else float("nan")


def stats(errors: list[tuple[float, float]]) -> dict[str, float]:
    position = [e[0] for e in errors]
    return {
        "rms_mm": round(rms(position), 1),
        "p95_mm": round(float(np.percentile(position, 95)), 1),
        "heading_rms_deg": round(rms([e[1] for e in errors]), 2),
    }


# --- tracking and outage --------------------------------------------------------------------


def bench_tracking(plan: FloorPlan, config: RobotConfig, spec: RobotSpec) -> dict[str, Any]:
    errors: dict[str, list[tuple[float, float]]] = {"ekf": [], "particles": []}
    uwb: list[float] = []
    cpu: dict[str, list[float]] = {"ekf": [], "particles": []}
    counts: list[int] = []
    for level in (2, 3):
        floor = plan.floor(level)
        start = hallway_pose(floor, 600, LANE_D_MM)
        world = World(plan, spec, floor=level, pose=start, seed=100 + level)
        filters = [Filter.make(name, config, plan) for name in ("ekf", "particles")]
        for f in filters:
            f.state.place(start.x_mm, start.y_mm, start.heading_deg, level)
        drive = Drive(world, filters, robot_setup(config.tof))
        drive.rest(1.0)  # the gyro calibration at rest (seed 004)

        def record(drive: Drive = drive, filters: list[Filter] = filters) -> None:
            if drive.tick % SCAN_EVERY == 0:
                for f in filters:
                    errors[f.name].append(f.error(drive.world.robot.pose))

        drive.drive(1e9, floor.hallway.heading_deg, LANE_D_MM, record)
        uwb += drive.uwb_errors
        for f in filters:
            cpu[f.name] += f.cpu_s
        counts += filters[1].counts
    return {
        "tracking": {
            "ekf": stats(errors["ekf"]),
            "particles": stats(errors["particles"]),
            "uwb_only": {
                "rms_mm": round(rms(uwb), 1),
                "p95_mm": round(float(np.percentile(uwb, 95)), 1),
                "heading_rms_deg": None,
            },
        },
        "update_ms": {
            "ekf": round(1000 * float(np.mean(cpu["ekf"])), 3),
            "particles": round(1000 * float(np.mean(cpu["particles"])), 3),
            "particles_count": int(np.median(counts)),
        },
    }


def bench_outage(plan: FloorPlan, config: RobotConfig, spec: RobotSpec) -> dict[str, Any]:
    floor = plan.floor(2)
    start = hallway_pose(floor, 600, LANE_D_MM)
    world = World(plan, spec, floor=2, pose=start, seed=7)
    filters = [Filter.make(name, config, plan) for name in ("ekf", "particles")]
    for f in filters:
        f.state.place(start.x_mm, start.y_mm, start.heading_deg, 2)
    drive = Drive(world, filters, robot_setup(config.tof))
    drive.rest(1.0)
    window: dict[str, float] = {}

    def blocked(t: float) -> bool:
        s, _ = floor.to_hallway(world.robot.pose.x_mm, world.robot.pose.y_mm)
        if "start" not in window and s >= 10_000:
            window["start"] = t
        return "start" in window and t < window["start"] + 30.0

    drive.uwb_blocked = blocked
    worst = {f.name: 0.0 for f in filters}

    def record() -> None:
        t = world.t_s
        if "start" in window and t < window["start"] + 35.0 and drive.tick % SCAN_EVERY == 0:
            for f in filters:
                worst[f.name] = max(worst[f.name], f.error(world.robot.pose)[0])

    drive.drive(1e9, floor.hallway.heading_deg, LANE_D_MM, record)
    return {name: {"max_error_mm": round(value, 1)} for name, value in worst.items()}


# --- kidnap and global localization ---------------------------------------------------------


def _until_settled(
    drive: Drive, f: Filter, travel_mm: float, direction: float, lane: float
) -> float | None:
    """Drive on; the travel after which the error stayed within bounds (None: never)."""
    start = drive.travel_mm
    settled: list[float | None] = [None]

    def check() -> None:
        if drive.tick % SCAN_EVERY:
            return
        position, heading = f.error(drive.world.robot.pose)
        if position <= RECOVERED_MM and heading <= RECOVERED_DEG:
            if settled[0] is None:
                settled[0] = drive.travel_mm - start
        else:
            settled[0] = None

    drive.drive(travel_mm, direction, lane, check)
    return settled[0]


def _trial_pose(rng: np.random.Generator, floor: Floor, margin_mm: float) -> tuple[float, float]:
    s = float(rng.uniform(margin_mm, floor.hallway.length_mm - margin_mm))
    d = float(rng.uniform(-350.0, 350.0))
    return s, d


def bench_kidnap(
    plan: FloorPlan, config: RobotConfig, spec: RobotSpec, trials: int
) -> dict[str, Any]:
    rng = np.random.default_rng(2024)
    travels: list[float] = []
    recovered = 0
    for trial in range(trials):
        level = 2 + trial % 2
        floor = plan.floor(level)
        s, d = _trial_pose(rng, floor, 8000)
        forward = rng.random() < 0.5
        direction = floor.hallway.heading_deg + (0.0 if forward else 180.0)
        lane = -295.0 if forward else 295.0
        x, y = floor.from_hallway(s, d)
        world = World(plan, spec, floor=level, pose=Pose(x, y, direction), seed=1000 + trial)
        f = Filter.make("particles", config, plan)
        f.state.place(x, y, direction, level)
        drive = Drive(world, [f], robot_setup(config.tof))
        drive.rest(1.0)
        drive.drive(1500, direction, lane)
        # Lifted 3 m along the hallway (either way) and turned by 90 degrees (either way).
        pose = world.robot.pose
        ps, pd = floor.to_hallway(pose.x_mm, pose.y_mm)
        ks = ps + (3000.0 if rng.random() < 0.5 else -3000.0)
        kx, ky = floor.from_hallway(ks, float(np.clip(pd, -350, 350)))
        turned = pose.heading_deg + (90.0 if rng.random() < 0.5 else -90.0)
        world.robot.place(Pose(kx, ky, turned), level)
        drive.turn_to(direction)
        travel = _until_settled(drive, f, 6000.0, direction, lane)
        if travel is not None:
            recovered += 1
            travels.append(travel)
    return {
        "trials": trials,
        "recovered": recovered,
        "travel_to_recover_mm_p95": round(float(np.percentile(travels, 95)), 0)
        if travels
        else None,
    }


def bench_global(
    plan: FloorPlan, config: RobotConfig, spec: RobotSpec, trials: int
) -> dict[str, Any]:
    rng = np.random.default_rng(4048)
    travels: list[float] = []
    localized = 0
    for trial in range(trials):
        level = 2 + trial % 2
        floor = plan.floor(level)
        s, d = _trial_pose(rng, floor, 2500)
        x, y = floor.from_hallway(s, d)
        heading = float(rng.uniform(-180.0, 180.0))
        world = World(plan, spec, floor=level, pose=Pose(x, y, heading), seed=5000 + trial)
        f = Filter.make("particles", config, plan)  # no prior: the first fix names the floor
        drive = Drive(world, [f], robot_setup(config.tof))
        drive.rest(1.0)
        forward = s < floor.hallway.length_mm / 2
        direction = floor.hallway.heading_deg + (0.0 if forward else 180.0)
        drive.turn_to(direction)
        travel = _until_settled(drive, f, 8000.0, direction, -295.0 if forward else 295.0)
        if travel is not None:
            localized += 1
            travels.append(travel)
    return {
        "trials": trials,
        "localized": localized,
        "travel_mm_p95": round(float(np.percentile(travels, 95)), 0) if travels else None,
    }


# --- output ---------------------------------------------------------------------------------


def table(result: dict[str, Any]) -> str:
    t, o, k, g, u = (
        result[key] for key in ("tracking", "uwb_outage_30s", "kidnap", "global", "update_ms")
    )
    lines = [
        "| tracking | RMS | p95 | heading RMS | target (particles) |",
        "|---|---|---|---|---|",
    ]
    for name in ("ekf", "particles", "uwb_only"):
        row = t[name]
        heading = "-" if row["heading_rms_deg"] is None else f"{row['heading_rms_deg']} deg"
        target = "<= 30 mm, <= 1 deg" if name == "particles" else ""
        lines.append(f"| {name} | {row['rms_mm']} mm | {row['p95_mm']} mm | {heading} | {target} |")
    lines += [
        "",
        "| measure | EKF | particles | target (particles) |",
        "|---|---|---|---|",
        f"| 30 s UWB outage, max error | {o['ekf']['max_error_mm']} mm "
        f"| {o['particles']['max_error_mm']} mm | <= 100 mm |",
        f"| kidnap recovered | - | {k['recovered']} of {k['trials']} | >= 99 % |",
        f"| kidnap travel to recover p95 | - | {k['travel_to_recover_mm_p95']} mm | <= 3000 mm |",
        f"| global localized | - | {g['localized']} of {g['trials']} | >= 99 % |",
        f"| global travel p95 | - | {g['travel_mm_p95']} mm | <= 5000 mm |",
        f"| CPU per 100 ms cycle | {u['ekf']} ms | {u['particles']} ms at "
        f"{u['particles_count']} particles | <= 5 ms |",
    ]
    return "\n".join(lines)


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--json", action="store_true", help="print one JSON object")
    parser.add_argument("--trials", type=int, default=100, help="kidnap and global trials each")
    parser.add_argument("--board", type=Path, default=ROOT / "boards" / "coffeebot-v1.toml")
    parser.add_argument("--floorplan", type=Path, default=ROOT / "floorplans" / "cs-building.toml")
    parser.add_argument(
        "--only", choices=["tracking", "outage", "kidnap", "global"], help="one part only"
    )
    args = parser.parse_args(argv)
    config = load_robot_config(args.board)
    plan = load_floorplan(args.floorplan)
    spec = RobotSpec.from_config(config)
    started = time.monotonic()
    result: dict[str, Any] = {}
    if args.only in (None, "tracking"):
        result |= bench_tracking(plan, config, spec)
    if args.only in (None, "outage"):
        result["uwb_outage_30s"] = bench_outage(plan, config, spec)
    if args.only in (None, "kidnap"):
        result["kidnap"] = bench_kidnap(plan, config, spec, args.trials)
    if args.only in (None, "global"):
        result["global"] = bench_global(plan, config, spec, args.trials)
    if args.json or args.only is not None:
        json.dump(result, sys.stdout, indent=1)
        print()
    else:
        print(table(result))
        print(f"\n(elapsed {time.monotonic() - started:.0f} s)")
    return 0


if __name__ == "__main__":
    sys.exit(main())
