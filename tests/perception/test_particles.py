"""The particle filter: its sensor model by hand, KLD bounds, and the filter in the world.

The world tests drive the simulated robot on ground truth (a lane follower standing in for
navigation) and feed the filter what the daemon would: odometry at 50 Hz, scans and UWB fixes
at 10 Hz. Every generator is seeded, so each run is the same run.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from pathlib import Path

import numpy as np
import pytest

from coffeebot.config import ParticleFilterConfig, StateConfig, TofSensorConfig, load_robot_config
from coffeebot.floorplan import FloorPlan, load_floorplan, parse_floorplan
from coffeebot.messages import (
    ElevatorState,
    Odometry,
    RangeReading,
    RangeScan,
    ReadingStatus,
    UwbFix,
)
from coffeebot.perception.fusion import OdometryStep
from coffeebot.perception.likelihood_field import LikelihoodField
from coffeebot.perception.particles import ParticlePoseFusion
from coffeebot.perception.range_model import RangeModel
from coffeebot.perception.recovery import RecoveryMonitor
from coffeebot.perception.resampling import (
    adaptive_count,
    effective_sample_size,
    kld_count,
    low_variance_indices,
)
from coffeebot.perception.state import StateEstimator, make_fusion
from coffeebot.sim.world import Pose, RobotSpec, World
from coffeebot.sim.world.tof import as_range_reading, robot_setup
from coffeebot.sim.world.trace import hallway_pose, lane_wheel_speeds

ROOT = Path(__file__).resolve().parents[2]
CONFIG = load_robot_config(ROOT / "boards" / "coffeebot-v1.toml")
PARTICLE_CONFIG = CONFIG.model_copy(
    update={"state": CONFIG.state.model_copy(update={"fusion": "particles"})}
)
PLAN = load_floorplan(ROOT / "floorplans" / "cs-building.toml")
SETUP = robot_setup(CONFIG.tof)
"""The chips set up as the ToF poller sets them up."""
AHEAD = TofSensorConfig(id=0, channel=0, face="front", x_mm=0, y_mm=0, yaw_deg=0)
"""One sensor at the body centre looking forward: the hand-computed cases' geometry."""


def box_floor(width_mm: float = 2000.0) -> FloorPlan:
    """A closed 10 m hallway along +x, walls at y = +/- width / 2, and nothing else."""
    return parse_floorplan(
        {
            "floors": [
                {
                    "level": 1,
                    "hallways": [
                        {"id": "main", "start": [0, 0], "end": [10000, 0], "width_mm": width_mm}
                    ],
                    "doors": [{"room": "T", "kind": "tea_room", "side": "left", "at_mm": 500}],
                }
            ]
        }
    )


def scan(*readings: RangeReading) -> RangeScan:
    return RangeScan(cycle_start_s=0.0, cycle_time_s=0.1, readings=list(readings))


def valid(distance_mm: int, sensor: int = 0) -> RangeReading:
    return RangeReading(sensor=sensor, status=ReadingStatus.VALID, distance_mm=distance_mm)


# --- the sensor model by hand -------------------------------------------------------------


@pytest.fixture(scope="module")
def box() -> tuple[LikelihoodField, RangeModel]:
    floor = box_floor().floor(1)
    cfg = ParticleFilterConfig()
    return LikelihoodField(floor, cfg.grid_mm, 1000.0), RangeModel([AHEAD], 4000, cfg)


def test_the_field_is_the_exact_distance_to_the_walls(box) -> None:
    field, _ = box
    x = np.array([5000.0, 5000.0, 5013.0, 3000.0])
    y = np.array([0.0, 987.0, -640.0, 1200.0])
    # Walls at y = +/-1000 (the tea-room door leaves the left wall at 500 +/- 450 only).
    assert field(x, y) == pytest.approx([1000.0, 13.0, 360.0, 200.0], abs=0.5)


def test_a_reading_on_the_wall_gets_the_hit_density(box) -> None:
    field, model = box
    # Facing the left wall from the centre line: 1000 mm, sigma = 25 + 25 * 1.0 = 50 mm.
    facing_wall = np.array([[5000.0, 0.0, math.pi / 2]])
    result = model.evaluate(field, scan(valid(1000)), facing_wall)
    hit = 1.0 / (math.sqrt(2 * math.pi) * 50.0)
    short = 0.001 * math.exp(-1.0)
    expected = 0.7 * hit + 0.15 * short + 0.15 / 4000.0
    assert result.readings == 1
    assert result.log_likelihood[0] == pytest.approx(0.5 * math.log(expected), rel=1e-4)
    assert result.log_fit[0] == pytest.approx(0.0, abs=1e-4)


def test_a_reading_behind_the_wall_is_judged_by_the_nearest_point_of_its_arc(box) -> None:
    field, model = box
    facing_wall = np.array([[5000.0, 0.0, math.pi / 2]])
    # 1100 mm: the arc's edge points (8 degrees off the axis) end 1100 cos 8 - 1000 =
    # 89.3 mm behind the wall, the nearest of the five; sigma = 25 + 25 * 1.1 = 52.5 mm.
    result = model.evaluate(field, scan(valid(1100)), facing_wall)
    miss = 1100 * math.cos(math.radians(8.0)) - 1000
    sigma = 52.5
    hit = math.exp(-0.5 * (miss / sigma) ** 2) / (math.sqrt(2 * math.pi) * sigma)
    rest = 0.15 * 0.001 * math.exp(-1.1) + 0.15 / 4000.0
    best = 0.7 / (math.sqrt(2 * math.pi) * sigma) + rest
    assert result.log_likelihood[0] == pytest.approx(0.5 * math.log(0.7 * hit + rest), rel=1e-3)
    assert result.log_fit[0] == pytest.approx(math.log((0.7 * hit + rest) / best), rel=1e-3)


def test_the_chips_sigma_widens_the_hit_term(box) -> None:
    field, model = box
    facing_wall = np.array([[5000.0, 0.0, math.pi / 2]])
    # 1100 mm again, the chip reporting a 70 mm sigma (a blend of depths): the hit term's
    # sigma is hypot(52.5, 70) = 87.5 mm, so the 89.3 mm miss costs far less.
    blended = RangeReading(sensor=0, status=ReadingStatus.VALID, distance_mm=1100, sigma_mm=70.0)
    result = model.evaluate(field, scan(blended), facing_wall)
    miss = 1100 * math.cos(math.radians(8.0)) - 1000
    sigma = math.hypot(52.5, 70.0)
    hit = math.exp(-0.5 * (miss / sigma) ** 2) / (math.sqrt(2 * math.pi) * sigma)
    rest = 0.15 * 0.001 * math.exp(-1.1) + 0.15 / 4000.0
    assert result.log_likelihood[0] == pytest.approx(0.5 * math.log(0.7 * hit + rest), rel=1e-3)


@pytest.mark.parametrize("status", [ReadingStatus.SIGNAL_FAIL, ReadingStatus.OUT_OF_BOUNDS])
def test_nothing_ranged_is_likely_where_the_plan_has_no_surface_in_reach(
    box, status: ReadingStatus
) -> None:
    field, model = box
    nothing = RangeReading(sensor=0, status=status)
    # Along the hallway the checked cone (4 degrees either side of the axis) meets a wall
    # 1000 / tan 4 = 14.3 m away from the centre line, 200 / tan 4 = 2860 mm away from 200 mm
    # off the wall: both beyond the 2500 mm a painted wall is surely ranged from, "clear"
    # (0.9). From 100 mm off the wall it meets it at 1430 mm, and facing the wall 1 m away
    # at once: 0.3.
    poses = np.array(
        [[3000.0, 0.0, 0.0], [3000.0, 800.0, 0.0], [3000.0, 900.0, 0.0], [5000.0, 0.0, 1.57]]
    )
    result = model.evaluate(field, scan(nothing), poses)
    assert result.log_likelihood == pytest.approx(0.5 * np.log([0.9, 0.9, 0.3, 0.3]))


def test_invalid_readings_say_nothing(box) -> None:
    field, model = box
    unusable = [
        RangeReading(sensor=0, status=ReadingStatus.SIGMA_FAIL, distance_mm=500),
        RangeReading(sensor=0, status=ReadingStatus.VALID, distance_mm=500, healthy=False),
        RangeReading(sensor=0, status=ReadingStatus.VALID, distance_mm=None),
        RangeReading(sensor=0, status=ReadingStatus.VALID, distance_mm=9000),
        RangeReading(sensor=0, status=ReadingStatus.VALID, distance_mm=0),
        RangeReading(sensor=5, status=ReadingStatus.VALID, distance_mm=500),  # no such sensor
        RangeReading(sensor=0, status=ReadingStatus.TOO_CLOSE, distance_mm=20),
        RangeReading(sensor=0, status=ReadingStatus.VALID, distance_mm=500, sigma_mm=math.nan),
    ]
    result = model.evaluate(field, scan(*unusable), np.array([[5000.0, 0.0, 0.0]]))
    assert result.readings == 0 and result.log_likelihood[0] == 0.0


def test_weak_signals_are_skipped_when_a_floor_is_set(box) -> None:
    field, _ = box
    model = RangeModel([AHEAD], 4000, ParticleFilterConfig(min_signal_rate_mcps=1.0))
    weak = RangeReading(sensor=0, status=ReadingStatus.VALID, distance_mm=900, signal_rate_mcps=0.4)
    strong = weak.model_copy(update={"signal_rate_mcps": 5.0})
    pose = np.array([[5000.0, 0.0, math.pi / 2]])
    assert model.evaluate(field, scan(weak), pose).readings == 0
    assert model.evaluate(field, scan(strong), pose).readings == 1


# --- resampling and KLD ---------------------------------------------------------------------


def test_kld_bound_by_hand() -> None:
    # k = 2, error 0.05, z(0.99) = 2.3263: 1 / 0.1 * (1 - 2/9 + sqrt(2/9) * 2.3263)^3 = 65.85
    assert kld_count(2, 0.05, 0.99) == 66
    assert kld_count(1, 0.05, 0.99) == 1
    counts = kld_count(np.arange(2, 200), 0.05, 0.99)
    assert (np.diff(counts) > 0).all()
    # Larger error or lower confidence: fewer particles.
    assert kld_count(50, 0.1, 0.99) < kld_count(50, 0.05, 0.99)
    assert kld_count(50, 0.05, 0.9) < kld_count(50, 0.05, 0.99)


def test_adaptive_count_stays_within_its_bounds() -> None:
    rng = np.random.default_rng(1)
    bins = {"bin_mm": 100.0, "bin_rad": math.radians(5), "error": 0.05, "quantile": 0.99}
    tight = np.column_stack([rng.normal(0, 5, 2000), rng.normal(0, 5, 2000), np.zeros(2000)])
    spread = np.column_stack(
        [rng.uniform(0, 40000, 2000), rng.uniform(-800, 800, 2000), rng.uniform(-3, 3, 2000)]
    )
    w = np.ones(2000)
    assert adaptive_count(tight, w, minimum=300, maximum=3000, rng=rng, **bins) == 300
    assert adaptive_count(spread, w, minimum=300, maximum=3000, rng=rng, **bins) == 3000
    # In between: the count Fox's bound gives for the bins the cloud occupies.
    middle = np.column_stack([rng.normal(0, 300, 2000), rng.normal(0, 300, 2000), np.zeros(2000)])
    n = adaptive_count(middle, w, minimum=10, maximum=3000, rng=rng, **bins)
    assert 300 < n < 3000


def test_low_variance_resampling_follows_the_weights_exactly() -> None:
    rng = np.random.default_rng(3)
    indices = low_variance_indices(np.array([0.5, 0.25, 0.25]), 400, rng)
    assert np.bincount(indices).tolist() == [200, 100, 100]
    assert effective_sample_size(np.array([1.0, 1.0, 1.0, 1.0])) == pytest.approx(4.0)
    assert effective_sample_size(np.array([1.0, 0.0, 0.0])) == pytest.approx(1.0)


def test_config_refuses_inverted_bounds() -> None:
    with pytest.raises(ValueError, match="min_particles"):
        ParticleFilterConfig(min_particles=500, max_particles=100)
    with pytest.raises(ValueError, match="alpha_slow"):
        ParticleFilterConfig(recovery_alpha_slow=0.2, recovery_alpha_fast=0.1)


# --- the filter in the world ----------------------------------------------------------------


class Run:
    """The world and a state estimator with the particle filter, stepped like the daemon."""

    def __init__(self, world: World, *, uwb: bool = True) -> None:
        self.world = world
        self.state = StateEstimator(
            PLAN, CONFIG.motor, PARTICLE_CONFIG.state, make_fusion(PARTICLE_CONFIG, PLAN)
        )
        self.uwb = uwb
        self.tick = 0
        self.travel_mm = 0.0

    @property
    def fusion(self) -> ParticlePoseFusion:
        assert isinstance(self.state.fusion, ParticlePoseFusion)
        return self.state.fusion

    def step(self, left: float, right: float) -> None:
        w, now = self.world, self.world.t_s
        self.tick += 1
        lt, rt = w.robot.encoder_ticks
        self.state.on_odometry(
            Odometry(
                controller_time_ms=round(now * 1000),
                left_ticks=lt,
                right_ticks=rt,
                gyro_z_dps=w.robot.gyro_z_dps(),
                left_mm_s=0.0,
                right_mm_s=0.0,
            ),
            now,
        )
        if self.tick % 5 == 0:
            fix = w.robot.uwb_fix() if self.uwb else None
            if fix is not None:
                self.state.on_uwb(fix, now)
            readings = [as_range_reading(i, r) for i, r in enumerate(w.robot.scan(SETUP))]
            self.state.on_scan(scan(*readings), now)
        before = w.robot.pose
        w.robot.command_wheels(left, right)
        w.step(0.02)
        self.travel_mm += math.dist(before[:2], w.robot.pose[:2])

    def rest(self, seconds: float) -> None:
        for _ in range(round(seconds / 0.02)):
            self.step(0.0, 0.0)

    def drive(self, mm: float, lane_mm: float = -295.0, each: Callable[[], None] | None = None):
        goal = self.travel_mm + mm
        while self.travel_mm < goal:
            self.step(*lane_wheel_speeds(self.world, 500.0, lane_mm))
            if each is not None:
                each()

    def turn_to(self, heading_deg: float, each: Callable[[], None] | None = None) -> None:
        robot = self.world.robot
        while abs(error := math.remainder(heading_deg - robot.pose.heading_deg, 360)) > 3:
            rate = max(-150.0, min(150.0, 4.0 * error))
            self.step(-rate, rate)
            if each is not None:
                each()

    def error(self) -> tuple[float, float]:
        e, t = self.state.pose(), self.world.robot.pose
        return (
            math.hypot(e.x_mm - t.x_mm, e.y_mm - t.y_mm),
            abs(math.remainder(e.heading_deg - t.heading_deg, 360)),
        )


SPEC = RobotSpec.from_config(CONFIG)


def start_run(s_mm: float, seed: int, *, uwb: bool = True, placed: bool = True) -> Run:
    floor = PLAN.floor(2)
    start = hallway_pose(floor, s_mm, -295.0)
    run = Run(World(PLAN, SPEC, floor=2, pose=start, seed=seed), uwb=uwb)
    if placed:
        run.state.place(start.x_mm, start.y_mm, start.heading_deg, 2)
    run.rest(1.0)
    return run


def test_tracks_a_hallway_pass() -> None:
    run = start_run(3000.0, seed=21)
    errors: list[tuple[float, float]] = []
    run.drive(5000.0, each=lambda: errors.append(run.error()))
    position = np.array([e[0] for e in errors[100:]])
    heading = np.array([e[1] for e in errors[100:]])
    assert np.sqrt(np.mean(position**2)) < 40.0
    assert np.sqrt(np.mean(heading**2)) < 1.5
    estimate = run.state.pose()
    assert estimate.particles is not None and estimate.particles >= 300
    assert estimate.effective_sample_size is not None and estimate.effective_sample_size > 1


def towards_the_start(world: World, lane_mm: float) -> tuple[float, float]:
    """Wheel speeds that bring the robot to ``lane_mm`` off the axis at up to 20 degrees,
    driving towards the hallway's start at 500 mm/s (ground truth, like ``lane_wheel_speeds``)."""
    floor, pose = world.robot.floor, world.robot.pose
    _, d = floor.to_hallway(pose.x_mm, pose.y_mm)
    wanted = floor.hallway.heading_deg + 180.0 - max(-20.0, min(20.0, 0.1 * (lane_mm - d)))
    error = math.radians(math.remainder(wanted - pose.heading_deg, 360.0))
    turn = 3.0 * error * SPEC.wheel_base_mm / 2
    return 500.0 - turn, 500.0 + turn


@pytest.mark.parametrize("seed", [21, 22])
def test_tracks_across_the_hallway_opposite_the_elevator(seed: int) -> None:
    # Out of the tea room's crossing towards the hallway's start, moving over to a passing
    # lane beside the elevator's wall: the scans that cannot have seen the car still count.
    # With every scan left out within 2 m of the door, the estimate ran up to 109 mm across.
    floor = PLAN.floor(2)
    x, y = floor.from_hallway(41700.0, 290.0)
    run = Run(World(PLAN, SPEC, floor=2, pose=Pose(x, y, 180.0), seed=seed))
    run.state.place(x, y, 180.0, 2)
    run.rest(1.0)
    across = []
    for step in range(300):
        run.step(*towards_the_start(run.world, 290.0 if step < 50 else 510.0))
        estimate, truth = run.state.pose(), run.world.robot.pose
        across.append(abs(estimate.y_mm - truth.y_mm))
    assert max(across) < 40.0


def test_only_the_doors_the_elevator_reports_shut_are_taken_as_shut() -> None:
    state = StateEstimator(PLAN, CONFIG.motor, PARTICLE_CONFIG.state)
    door = PLAN.floor(2).elevator
    assert door is not None and state.floor == 2

    def told(now: float, **fields: object) -> frozenset[str]:
        state.on_elevator(ElevatorState.model_validate({"source": "sim", **fields}), 10.0)
        return state.shut_elevator_doors(now)

    assert state.shut_elevator_doors(10.0) == frozenset()  # nothing heard yet
    assert told(10.1, car_floor=2, doors="closed") == {door.id}
    assert told(10.1, car_floor=3, doors="open") == {door.id}
    assert told(10.1, car_floor=None, doors="closed", moving=True) == {door.id}
    assert told(10.1, car_floor=2, doors="open") == frozenset()
    assert told(10.1, car_floor=2, doors="moving") == frozenset()
    # Too old to say the doors have not opened since; an interface without a car says nothing.
    assert told(11.0, car_floor=3, doors="closed") == frozenset()
    assert told(10.1, car_floor=None, doors="closed", source="none") == frozenset()


@pytest.mark.parametrize("seed", [2, 3])
def test_turns_round_in_front_of_the_shut_car_on_its_scans(seed: int) -> None:
    # Up to the car's door along the hallway, a turn to face it, round, back and on: with the
    # doors reported shut the plan's leaf explains what the front sensors see. Left without
    # the scans there (the doors may be open), the heading ran 8.5 and 10.9 degrees off.
    floor = PLAN.floor(2)
    along = floor.hallway.heading_deg
    x, y = floor.from_hallway(41000.0, 0.0)
    run = Run(World(PLAN, SPEC, floor=2, pose=Pose(x, y, along), seed=seed))
    run.state.place(x, y, along, 2)
    errors: list[tuple[float, float]] = []

    def each() -> None:
        if run.tick % 10 == 0:
            shut = ElevatorState(car_floor=2, doors="closed", source="sim")
            run.state.on_elevator(shut, run.world.t_s)
        errors.append(run.error())

    run.rest(1.0)
    run.drive(900.0, lane_mm=0.0, each=each)
    for heading in (along + 90.0, along + 180.0, along + 90.0, along):
        run.turn_to(heading, each=each)
        for _ in range(100):
            run.step(0.0, 0.0)
            each()
    run.drive(1500.0, lane_mm=0.0, each=each)
    assert max(position for position, _ in errors) < 80.0
    assert max(heading for _, heading in errors) < 4.0


def test_recovers_from_a_kidnap() -> None:
    run = start_run(12000.0, seed=22)
    run.drive(1500.0)
    assert run.error()[0] < 100
    # Lifted 3 m further down the hallway and turned by 90 degrees: odometry knows nothing.
    floor, pose = PLAN.floor(2), run.world.robot.pose
    s, d = floor.to_hallway(pose.x_mm, pose.y_mm)
    x, y = floor.from_hallway(s + 3000.0, d)
    run.world.robot.place(Pose(x, y, pose.heading_deg + 90.0), 2)
    assert run.error()[0] > 2500
    run.turn_to(floor.hallway.heading_deg)
    run.drive(3000.0)
    position, heading = run.error()
    assert position < 200.0 and heading < 5.0
    assert run.fusion.injected > 0


def test_finds_itself_from_no_prior_around_the_first_fix() -> None:
    run = start_run(20000.0, seed=23, placed=False)
    assert run.state.pose().initialised  # the first fix seeded the cloud
    run.drive(5000.0)
    position, heading = run.error()
    assert position < 200.0 and heading < 5.0


def test_global_localization_over_the_whole_floor_is_honest_about_it() -> None:
    fusion = ParticlePoseFusion(PLAN, CONFIG.tof, PARTICLE_CONFIG.state, clearance_mm=255)
    fusion.change_floor(2)
    fusion.localize_globally()
    cloud = fusion.particles
    assert len(cloud) == PARTICLE_CONFIG.state.particles.max_particles
    # In free space (nothing nearer a wall than the body allows), over the whole floor.
    assert (fusion.field.nearest(cloud[:, 0], cloud[:, 1]) >= 255 - 20).all()
    assert np.ptp(cloud[:, 0]) > 35000
    sx, _, sh = fusion.sigmas()
    assert sx > 5000 and sh > 60


def test_a_new_floor_widens_the_cloud_and_relocalizes_on_its_plan() -> None:
    run = start_run(30000.0, seed=24)
    run.drive(1000.0)
    before = run.state.pose()
    # The same spot on floor 3 (the elevator's way of moving a robot), fixes from floor 3.
    run.world.robot.place(run.world.robot.pose, 3)
    run.drive(400.0)
    assert run.state.floor == 3 and run.fusion.level == 3
    assert run.fusion.field.level == 3
    run.drive(3000.0)
    position, heading = run.error()
    assert position < 150.0 and heading < 5.0
    assert before.floor == 2


def test_change_floor_widens_the_cloud() -> None:
    fusion = ParticlePoseFusion(PLAN, CONFIG.tof, PARTICLE_CONFIG.state)
    fusion.change_floor(2)
    fusion.reset(20000, -295, 0, 20, 1)
    fusion.change_floor(3)
    assert fusion.level == 3
    sx, _, sh = fusion.sigmas()
    assert sx == pytest.approx(300, rel=0.15) and sh == pytest.approx(10, rel=0.15)
    fusion.change_floor(9)  # not in the plan: ignored
    assert fusion.level == 3


def test_a_featureless_stretch_without_uwb_leaves_the_cloud_long() -> None:
    # Floor 2 from 15.6 to 17.4 m: plain walls on both sides (doors 205 and 206 span up to
    # 15.45 and from 17.55 m), no UWB: only the walls constrain it, and only across.
    run = start_run(15600.0, seed=25, uwb=False)
    run.drive(1800.0)
    estimate = run.state.pose()
    assert estimate.sigma_x_mm > 3 * estimate.sigma_y_mm
    assert run.error()[0] < 200.0


def test_bad_input_is_ignored() -> None:
    fusion = ParticlePoseFusion(PLAN, CONFIG.tof, PARTICLE_CONFIG.state)
    fusion.change_floor(2)
    assert not fusion.update_position(math.nan, 0.0, 100.0)
    assert not fusion.initialised  # a NaN fix seeds nothing
    fusion.reset(20000, -295, 0, 50, 5)
    before = fusion.pose()
    assert not fusion.update_position(20000.0, math.inf, 100.0)
    assert not fusion.update_heading(math.nan, 1.0)
    assert not fusion.update_offset(0.0, math.nan, 40.0)
    fusion.predict(OdometryStep(math.nan, 0.0, 0.02))
    fusion.predict(OdometryStep(10.0, math.inf, 0.02))
    assert fusion.pose() == before
    nothing = scan(RangeReading(sensor=2, status=ReadingStatus.HARDWARE_FAIL))
    assert not fusion.update_ranges(nothing)
    assert np.isfinite(fusion.particles).all()


def test_an_empty_floor_gives_a_flat_answer_not_an_error() -> None:
    # A hallway narrower than the body: nowhere for it to stand, nothing to localize on.
    plan = box_floor(width_mm=300.0)
    cfg = StateConfig(initial_floor=1, fusion="particles")
    fusion = ParticlePoseFusion(plan, CONFIG.tof, cfg, clearance_mm=255)
    assert len(fusion.free_space()) == 0
    fusion.localize_globally()
    assert fusion.initialised and np.isfinite(fusion.particles).all()
    readings = [RangeReading(sensor=i, status=ReadingStatus.NO_TARGET) for i in range(8)]
    assert fusion.update_ranges(scan(*readings))
    assert all(math.isfinite(v) for v in fusion.pose())


def test_the_state_estimator_picks_the_fusion_from_the_config() -> None:
    ekf_config = CONFIG.model_copy(
        update={"state": CONFIG.state.model_copy(update={"fusion": "ekf"})}
    )
    ekf = StateEstimator(PLAN, CONFIG.motor, ekf_config.state, make_fusion(ekf_config, PLAN))
    assert ekf.pose().particles is None
    assert ekf.cloud(10) is None
    pf = StateEstimator(
        PLAN, CONFIG.motor, PARTICLE_CONFIG.state, make_fusion(PARTICLE_CONFIG, PLAN)
    )
    pf.place(20000, -295, 0, 2)
    cloud = pf.cloud(10)
    assert cloud is not None and len(cloud.x_mm) == 10 and cloud.floor == 2
    fix = UwbFix(x_mm=20000, y_mm=-295, z_mm=900, quality=80)
    assert pf.on_uwb(fix, 0.0)


def test_recovery_asks_for_particles_only_when_the_fit_falls() -> None:
    monitor = RecoveryMonitor(alpha_slow=0.001, alpha_fast=0.1)
    for _ in range(50):
        monitor.update(0.8)
    assert monitor.injection_probability == 0.0
    monitor.update(0.0)  # lost: the fast average drops by a tenth of the way
    assert monitor.injection_probability == pytest.approx(1 - 0.72 / 0.7992, rel=1e-3)
    monitor.update(math.nan)  # no evidence, no change
    assert monitor.injection_probability == pytest.approx(1 - 0.72 / 0.7992, rel=1e-3)
    monitor.reset()
    monitor.update(0.1)
    assert monitor.injection_probability == 0.0
