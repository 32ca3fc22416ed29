"""The robot description: hardware wiring, geometry and every threshold, loaded from TOML.

Each threshold defaults to the value in the seed paper it comes from (seed 000 unless noted),
so an empty section means "as the paper built it". A broken file fails fast with
:class:`ConfigError`, which names the file, the field and what is wrong.
"""

from __future__ import annotations

import tomllib
from collections.abc import Callable
from pathlib import Path
from typing import Annotated, Any, Literal

from pydantic import BaseModel, ConfigDict, Field, ValidationError, model_validator

from coffeebot.errors import ConfigError
from coffeebot.hardware.vl53l1x import field_of_view_deg

# Sane ranges for the physical quantities: generous for any indoor robot, but a typo (an extra
# zero, a sign) or an impossible value fails at start instead of in the hallway.
MOUNT_MM = 1000.0
"""Anything mounted on the body sits this close to its centre."""
BODY_MM = 2000.0
DISTANCE_MM = 5000.0
"""Radii, margins, clearances, door widths: what the sensors can see and a bit more."""
RANGE_MM = 10_000
LENGTH_MM = 50_000.0
"""Along a hallway: look-aheads, approach distances, windows."""
SPEED_MM_S = 3000.0
ACCEL_MM_S2 = 10_000.0
"""About 1 g: no wheeled robot brakes harder."""
WAIT_S = 86_400.0
"""Timeouts: nothing waits longer than a day."""
DRINK_NAME_CHARS = 40


class Section(BaseModel):
    """A table of the board file: unknown keys, ``nan`` and ``inf`` are refused (a NaN
    threshold makes every comparison false, so a check built on it never fires)."""

    model_config = ConfigDict(extra="forbid", frozen=True, allow_inf_nan=False)


class I2CConfig(Section):
    bus: int = Field(1, ge=0, le=255, description="Linux I2C bus number (/dev/i2c-N)")
    mux_address: int = Field(0x70, ge=0x70, le=0x77, description="TCA9548A address")
    sensor_address: int = Field(0x29, ge=0x08, le=0x77, description="VL53L1X address")
    frequency_hz: int = Field(
        400_000,
        gt=0,
        le=3_400_000,
        description="the bus clock the sensors need: at 100 kHz eight sensors' transfers take "
        "longer than a scan (bench/tof.py); the self-check warns when the kernel runs it slower",
    )


class TofSensorConfig(Section):
    """One VL53L1X: its mux channel and where it sits on the body (robot frame)."""

    id: int = Field(ge=0, le=7)
    channel: int = Field(ge=0, le=7)
    face: Literal["front", "left", "right", "rear"]
    x_mm: float = Field(ge=-MOUNT_MM, le=MOUNT_MM)
    y_mm: float = Field(ge=-MOUNT_MM, le=MOUNT_MM)
    yaw_deg: float = Field(ge=-180, le=180)
    height_mm: float = Field(250.0, gt=0, le=2000)
    roi_spads: int = Field(
        16,
        ge=4,
        le=16,
        description="square region of interest: 16 = the full 27 degree cone, "
        "4 = the narrowest, 15 degrees (and a tenth of the light)",
    )

    @property
    def fov_deg(self) -> float:
        """The nominal field of view of the configured region of interest."""
        return field_of_view_deg(self.roi_spads)


class TofConfig(Section):
    distance_mode: Literal["short", "long"] = "long"
    timing_budget_ms: int = Field(20, ge=15, le=1000)
    scan_rate_hz: float | None = Field(
        None, gt=0, le=100, description="None: as fast as the timing budget allows"
    )
    max_range_mm: int = Field(4000, gt=0, le=RANGE_MM)
    min_signal_mcps: float = Field(
        1.0, ge=0, lt=512, description="the chip's minimum signal rate for a valid ranging"
    )
    sigma_limit_mm: float = Field(
        90.0, gt=0, lt=16384, description="the chip's sigma limit for a valid ranging"
    )
    effective_half_fov_deg: float = Field(
        0.0,
        ge=0,
        le=20,
        description="ranging model for wall geometry (angle correction): a reading is the "
        "nearest return within this many degrees of the optical axis; 0 = along the axis, "
        "which is what the VL53L1X's signal-weighted mean gives on a flat wall",
    )
    sensors: list[TofSensorConfig] = Field(min_length=1)

    @property
    def cone_half_deg(self) -> float:
        """Half the widest sensor's nominal field of view: where a return may come from."""
        return max((s.fov_deg for s in self.sensors), default=0.0) / 2.0

    @model_validator(mode="after")
    def _unique(self) -> TofConfig:
        if not any(s.face == "front" for s in self.sensors):
            raise ValueError("no sensor faces front: the robot would drive blind")
        for attr in ("id", "channel"):
            values = [getattr(s, attr) for s in self.sensors]
            dupes = sorted({v for v in values if values.count(v) > 1})
            if dupes:
                raise ValueError(f"duplicate sensor {attr} {dupes}")
        return self


class SerialPortConfig(Section):
    port: str = Field(min_length=1, description="device path or pyserial URL")
    baudrate: int = Field(115_200, gt=0, le=4_000_000)


class MotorConfig(SerialPortConfig):
    wheel_diameter_mm: float = Field(100.0, gt=0, le=1000)
    ticks_per_rev: int = Field(360, gt=0, le=1_000_000)
    wheel_base_mm: float = Field(
        450.0, gt=0, le=BODY_MM, description="distance between wheel contacts"
    )
    axle_x_mm: float = Field(
        150.0,
        ge=-MOUNT_MM,
        le=MOUNT_MM,
        description="driven axle ahead of the body centre (the seed's front wheels)",
    )
    max_speed_mm_s: float = Field(1000.0, gt=0, le=SPEED_MM_S)
    max_accel_mm_s2: float = Field(
        500.0, gt=0, le=ACCEL_MM_S2, description="the controller's ramp towards a set-point"
    )
    brake_mm_s2: float = Field(
        1000.0,
        gt=0,
        le=ACCEL_MM_S2,
        description="the controller's active braking on a stop line (0.1 g: a lidded cup rides it)",
    )
    watchdog_ms: int = Field(200, gt=0, le=1000, description="controller stops without a command")
    telemetry_timeout_s: float = Field(
        0.5,
        gt=0,
        le=5,
        description="no telemetry for this long: the controller is silent, the driver reports "
        "it failed and motion holds the robot (telemetry comes at 50 Hz)",
    )


class GeometryConfig(Section):
    width_mm: float = Field(510.0, gt=0, le=BODY_MM)
    length_mm: float = Field(610.0, gt=0, le=BODY_MM)
    height_mm: float = Field(
        900.0, gt=0, le=BODY_MM, description="its top: where the ceiling cameras read it"
    )


class CollisionConfig(Section):
    """The seed's "private sphere", plus a speed-dependent stop distance and a slowdown zone."""

    front_radius_mm: float = Field(
        200.0, gt=0, le=DISTANCE_MM, description="seed 000 private sphere, front"
    )
    side_radius_mm: float = Field(
        50.0, gt=0, le=DISTANCE_MM, description="seed 000 private sphere, sides"
    )
    reaction_latency_s: float = Field(
        0.1, ge=0, le=2, description="scan-to-brake latency: one scan period plus command transport"
    )
    braking_mm_s2: float = Field(
        450.0,
        gt=0,
        le=ACCEL_MM_S2,
        description="deceleration it can rely on: below the motor ramp (500)",
    )
    margin_mm: float = Field(
        50.0, ge=0, le=DISTANCE_MM, description="added to the kinematic stop distance"
    )
    slowdown_extra_mm: float = Field(
        400.0, ge=0, le=DISTANCE_MM, description="slowdown zone depth in front of the stop distance"
    )
    min_slow_speed_mm_s: float = Field(
        50.0,
        gt=0,
        le=SPEED_MM_S,
        description="slowest crawl the slowdown zone asks for before stopping",
    )
    hysteresis_mm: float = Field(
        30.0, ge=0, le=DISTANCE_MM, description="extra clearance needed to relax"
    )
    corridor_margin_mm: float = Field(
        100.0,
        ge=0,
        le=DISTANCE_MM,
        description="a front return this far beside the body's width is in the way",
    )
    creep_ahead_mm_s: float = Field(
        100.0, gt=0, le=SPEED_MM_S, description="the straight creep out of a side hold"
    )
    stale_cycles: int = Field(5, ge=1, le=100, description="scans without a valid reading -> stop")
    unknown_speed_mm_s: float | None = Field(
        None,
        gt=0,
        le=SPEED_MM_S,
        description="speed assumed without fresh odometry; None: motor max speed",
    )
    memory_s: float = Field(
        1.5,
        ge=0,
        le=10,
        description="a front return inside the body's corridor keeps blocking this long after "
        "it drops out of view (0: no memory): a chair's pole leaves the cones as the robot "
        "nears it, its seat does not; returns the plan's walls explain are not remembered",
    )
    memory_max_turn_deg: float = Field(
        10.0,
        gt=0,
        le=180,
        description="a remembered return is forgotten once the body has turned this much since: "
        "it is no longer ahead (turning on the spot in the elevator car, round a corner)",
    )
    narrow_margin_mm: float = Field(
        250.0,
        ge=0,
        le=DISTANCE_MM,
        description="extra front clearance for a narrow return: a pole can carry a seat or "
        "table top above the cones (a swivel chair's seat reaches ~240 mm beyond its pole)",
    )
    narrow_max_sensors: int = Field(
        2,
        ge=1,
        le=8,
        description="a return seen by at most this many adjacent front sensors is narrow",
    )
    narrow_depth_mm: float = Field(
        300.0,
        gt=0,
        le=RANGE_MM,
        description="the other front sensors read at least this much further",
    )
    narrow_max_range_mm: float = Field(
        1200.0,
        gt=0,
        le=RANGE_MM,
        description="narrow returns further than this are not judged (glances off side walls)",
    )


class TrackingConfig(Section):
    """Returns followed over scans (perception/tracking.py): people walking into the way."""

    max_range_mm: float = Field(
        4000.0,
        gt=0,
        le=RANGE_MM,
        description="readings further are not tracked: someone walking towards a robot at "
        "cruise speed must be tracked from 2.5 m for it to stop before they meet",
    )
    range_sigma_mm: float = Field(
        30.0, gt=0, le=DISTANCE_MM, description="a reading's error along its axis"
    )
    accel_sigma_mm_s2: float = Field(
        1500.0, gt=0, le=ACCEL_MM_S2, description="how hard a tracked person may change pace"
    )
    initial_speed_sigma_mm_s: float = Field(
        1600.0,
        gt=0,
        le=SPEED_MM_S,
        description="a new track may move as fast as a brisk walk (ISO 13855)",
    )
    gate_sigmas: float = Field(
        3.0, gt=0, le=100, description="association gate, in standard deviations"
    )
    confirm_hits: int = Field(
        3, ge=2, le=100, description="points before a track's velocity counts"
    )
    forget_s: float = Field(0.4, gt=0, le=60, description="a track not seen this long is dropped")
    mover_speed_mm_s: float = Field(
        250.0,
        gt=0,
        le=SPEED_MM_S,
        description="slower over the ground is standing (noise, a sliding glance)",
    )
    max_mover_speed_mm_s: float = Field(
        3000.0,
        gt=0,
        le=SPEED_MM_S,
        description="faster over the ground is no one: readings jumping between things",
    )
    turn_in_place_dps: float = Field(
        10.0,
        gt=0,
        le=360,
        description="turning on the spot at least this fast (and driving slower than "
        "turn_in_place_speed_mm_s), the cones sweep along the walls and their returns slide "
        "along them at up to 3 m/s, as nobody walks: nothing is tracked then, and what was "
        "is dropped (its velocity is the sweep's). Turning on the spot, the robot drives "
        "into nobody's way; the distance rules still stop it for what is near",
    )
    turn_in_place_speed_mm_s: float = Field(
        100.0,
        ge=0,
        le=SPEED_MM_S,
        description="slower than this while turning is turning on the spot (a DWA arc "
        "drives faster and keeps its tracks)",
    )
    max_sigma_mm: float = Field(
        150.0,
        gt=0,
        le=DISTANCE_MM,
        description="readings reporting a larger sigma (blends of near and far) are not "
        "tracked; below it the sigma weighs the reading (a person 2 m ahead reports ~140)",
    )
    closing_sigmas: float = Field(
        2.0,
        ge=0,
        le=10,
        description="an oncoming mover's closing speed is taken this many sigmas above its "
        "estimate: a new track's speed is still uncertain when the robot must act on it",
    )
    corridor_margin_mm: float = Field(
        100.0,
        ge=0,
        le=DISTANCE_MM,
        description="a mover this close to the body's corridor is in it",
    )
    horizon_s: float = Field(
        0.8, gt=0, le=10, description="prediction beyond the time to stop: how far ahead to look"
    )
    lost_mover_s: float = Field(
        2.0,
        ge=0,
        le=60,
        description="a mover that left every cone near the path is remembered this long: "
        "someone who just crossed may turn back out of a blind spot (0: forget at once)",
    )
    lost_reach_mm: float = Field(
        1000.0,
        ge=0,
        le=DISTANCE_MM,
        description="lost this close beside or ahead of the body: go carefully",
    )
    lost_speed_mm_s: float = Field(
        150.0, gt=0, le=SPEED_MM_S, description="the speed past where someone went out of view"
    )


class OpeningsConfig(Section):
    """Slow zones at the floor plan's openings (navigation/openings.py).

    The cones see along the hallway, not round the corner of a side hallway: someone walking
    out of one is seen only once past the wall line, and the wedge between the outer front
    cone and the side cone (33.5 to 76.5 degrees off the axis) leaves part of the mouth
    unseen even then. So near an opening the robot goes no faster than it can stand from
    before someone who steps out where the cones first see the wall line, and walks straight
    at its front at ``walking_speed_mm_s``, reaches it: ``v t + v^2/2a + K (t + v/a) <= D -
    margin``, with the collision config's reaction latency ``t``, braking ``a`` and margin.
    ``D`` is from the front face's corner to the nearest point of the mouth the outer front
    cone on that side sees (where its edge meets the wall line: 0.58 m ahead for a mouth 300
    mm beside the body, 1.47 m for one across the hallway). Keeping right, the cap is
    117 mm/s beside an opening on the right and 371 mm/s across from one on the left; it
    rises with the distance to the mouth ahead and ends once the front is past it."""

    slow_zones: bool = Field(
        True, description="cap the speed near openings (off: only the collision rules slow)"
    )
    walking_speed_mm_s: float = Field(
        1600.0,
        gt=0,
        le=SPEED_MM_S,
        description="how fast someone may come out of an opening at the robot: ISO 13855's "
        "walking approach speed for separation distances",
    )


class AngleConfig(Section):
    """Seed 000 angle correction from a side's sensor pair, with the door-straddle checks."""

    max_side_distance_mm: float = Field(
        850.0, gt=0, le=RANGE_MM, description="both side sensors below"
    )
    max_sigma_mm: float = Field(
        20.0,
        gt=0,
        le=DISTANCE_MM,
        description="readings the sensor reports a larger sigma for are not used",
    )
    min_angle_deg: float = Field(5.0, ge=0, le=45, description="smaller angles are no correction")
    scans_per_estimate: int = Field(
        8,
        ge=1,
        le=100,
        description="accepted scans averaged (heading changes compensated) per angle",
    )
    max_window_s: float = Field(3.0, gt=0, le=60, description="older accepted scans are dropped")
    side_agreement_deg: float = Field(
        3.0, gt=0, le=45, description="both walls in range must agree within this, per scan"
    )
    prior_gate_deg: float = Field(
        8.0, gt=0, le=180, description="reject angles this far from the pose's heading (or 3 sigma)"
    )
    scan_outlier_deg: float = Field(
        4.0, gt=0, le=45, description="a scan this far from the window's median is dropped"
    )
    footprint_margin_mm: float = Field(
        50.0,
        ge=0,
        le=DISTANCE_MM,
        description="added to the cone's footprint when checking doors/openings",
    )


class DoorConfig(Section):
    """Seed 000 door detection by a sliding window over one side sensor."""

    jump_mm: float = Field(
        80.0, gt=0, le=DISTANCE_MM, description="newer-half mean minus older-half mean"
    )
    door_width_mm: float = Field(900.0, gt=0, le=DISTANCE_MM)
    max_door_jump_mm: float = Field(
        350.0,
        gt=0,
        le=DISTANCE_MM,
        description="larger jumps are an opening or an open door, not a recess",
    )
    min_readings_per_door: int = Field(2, ge=1, le=1000)
    max_readings_per_door: int = Field(60, ge=1, le=1000)
    min_speed_mm_s: float = Field(
        20.0,
        ge=0,
        le=SPEED_MM_S,
        description="readings taken slower than this are not added to the window",
    )
    max_side_distance_mm: float = Field(
        1500.0,
        gt=0,
        le=RANGE_MM,
        description="walls further than this are not used (noisy readings)",
    )
    match_gate_mm: float = Field(
        1200.0,
        gt=0,
        le=LENGTH_MM,
        description="a detection further than this from a plan door is unmatched, however "
        "uncertain the pose",
    )
    match_sigmas: float = Field(
        4.0,
        gt=0,
        le=100,
        description="a detection is matched to a plan door within this many sigmas of the "
        "pose along the hallway and of the detection itself",
    )
    centre_sigma_mm: float = Field(
        50.0,
        gt=0,
        le=DISTANCE_MM,
        description="1-sigma of a detected door centre along the hallway (bench/accuracy.py: "
        "p95 ~40 mm)",
    )
    max_feature_mm: float = Field(
        2500.0,
        gt=0,
        le=LENGTH_MM,
        description="travel after a rising edge without the wall coming back: report the door "
        "from its near edge alone (wider than the 1700 mm openings)",
    )

    @model_validator(mode="after")
    def _window_fits(self) -> DoorConfig:
        if self.max_readings_per_door < self.min_readings_per_door:
            raise ValueError("max_readings_per_door must not be below min_readings_per_door")
        return self


class ParticleFilterConfig(Section):
    """The particle filter (seed 003's AMCL) on the floor plan: ``[state.particles]``.

    docs/localization.md explains each group; the defaults are what bench/localization.py
    measured (docs/benchmarks.md).
    """

    # Particle count: KLD sampling (Fox 2003) between these bounds.
    min_particles: int = Field(300, ge=10, description="fewest particles, however converged")
    max_particles: int = Field(
        3000, ge=10, description="most particles: global localization and recovery start here"
    )
    kld_error: float = Field(
        0.05, gt=0, le=1, description="KLD bound between the sample and the true posterior"
    )
    kld_quantile: float = Field(
        0.99, gt=0.5, lt=1, description="probability that the sample stays within that bound"
    )
    kld_bin_mm: float = Field(100.0, gt=0, description="histogram bin size in x and y")
    kld_bin_deg: float = Field(5.0, gt=0, description="histogram bin size in heading")
    resample_ess_fraction: float = Field(
        0.5,
        gt=0,
        le=1,
        description="resample when the effective sample size falls below this share of the count",
    )
    roughening: float = Field(
        0.2,
        ge=0,
        description="resampled particles are jittered by this times the cloud's spread times "
        "count^(-1/3) (Gordon 1993), so copies of one particle do not stay identical at rest",
    )
    # Motion model: seed 004 odometry steps with random-walk noise.
    along_sigma_mm: float = Field(
        20.0, ge=0, description="1-sigma of the distance after 1 m (grows with its square root)"
    )
    lateral_sigma_mm: float = Field(
        10.0, ge=0, description="1-sigma sideways slip after 1 m (grows with its square root)"
    )
    heading_sigma_deg: float = Field(
        1.0, ge=0, description="heading 1-sigma after 1 m of travel (square-root growth)"
    )
    turn_sigma_deg: float = Field(
        2.0, ge=0, description="heading 1-sigma after turning one radian (square-root growth)"
    )
    update_min_mm: float = Field(
        40.0, ge=0, description="range scans update the filter after this much travel ..."
    )
    update_min_deg: float = Field(2.0, ge=0, description="... or this much turning")
    # Range sensor model (docs/localization.md, "Sensor model").
    grid_mm: float = Field(20.0, gt=0, description="likelihood field cell size")
    cone_points: int = Field(
        5, ge=1, description="points across each cone's arc where a reading may have come from"
    )
    arc_half_deg: float = Field(
        8.0,
        ge=0,
        le=13.5,
        description="half-angle of that arc: a blend of what the cone sees lands near its axis "
        "on a flat wall, nearer the cone's edge where one side of it is much closer",
    )
    sigma_hit_mm: float = Field(25.0, gt=0, description="reading error near the sensor")
    sigma_hit_per_m: float = Field(
        25.0, ge=0, description="added to sigma_hit_mm per metre of reading (mm)"
    )
    z_hit: float = Field(0.7, ge=0, description="weight of readings explained by the plan")
    z_short: float = Field(
        0.15, ge=0, description="weight of readings cut short by something not in the plan"
    )
    short_decay_per_m: float = Field(
        1.0, gt=0, description="how fast the short component falls with range (per metre)"
    )
    z_random: float = Field(0.15, ge=0, description="weight of unexplained readings")
    no_target_when_clear: float = Field(
        0.9,
        gt=0,
        le=1,
        description="P(nothing ranged: signal fail, out of bounds) when the plan has no surface "
        "within reach of the checked cone",
    )
    no_target_when_wall: float = Field(
        0.3,
        gt=0,
        le=1,
        description="P(nothing ranged) when the plan has one (the simulated chip: ~0.01; kept "
        "soft for what the plan does not know, a door left open, a dark coat)",
    )
    no_target_range_mm: float = Field(
        2500.0,
        gt=0,
        description="a plan surface this close inside the checked cone returns enough light to "
        "be ranged; beyond, or at a grazing angle, it may not",
    )
    no_target_half_deg: float = Field(
        4.0, ge=0, le=13.5, description="half-angle of the cone checked for a plan surface"
    )
    no_target_step_mm: float = Field(
        200.0, gt=0, description="spacing of the points along the cone checked for walls"
    )
    reading_weight: float = Field(
        0.5,
        gt=0,
        le=1,
        description="exponent on each reading's likelihood: readings of one wall by neighbouring "
        "cones are not independent, and counting each fully makes the filter overconfident",
    )
    min_signal_rate_mcps: float = Field(
        0.0, ge=0, description="readings reporting a weaker signal than this are skipped"
    )
    elevator_blind_mm: float = Field(
        2000.0,
        ge=0,
        description="scans are not weighed while the estimate is this close to an elevator "
        "door and its heading more than 45 degrees off the hallway's (facing the car, driving "
        "into it or out): the car behind the door is not in the floor plan, and its walls seen "
        "through the open doors pulled the cloud sideways into the jamb; odometry and UWB "
        "carry it there (perception/elevator_mask.py)",
    )
    elevator_margin_mm: float = Field(
        300.0,
        ge=0,
        description="along the hallway, readings whose cone may have crossed an elevator's "
        "doorway, widened by this each side, are not weighed; nor is any reading with the "
        "estimate this close to the doorway's wall line",
    )
    robot_margin_mm: float = Field(
        150.0,
        ge=0,
        le=DISTANCE_MM,
        description="readings whose cone may have met another robot of the fleet standing "
        "still, its outline grown by this each side, are not weighed: the plan has no robots "
        "(perception/robot_mask.py)",
    )
    # Other sources as likelihoods.
    uwb_outlier_probability: float = Field(
        0.05, ge=0, lt=1, description="share of UWB fixes that are multipath outliers"
    )
    use_wall_angle: bool = Field(
        False,
        description="also weigh the angle module's heading and wall distances (they come from "
        "the same ToF readings the filter already uses)",
    )
    use_doors: bool = Field(
        False, description="also weigh the door module's along-hallway corrections"
    )
    # Recovery (augmented MCL) and global localization.
    recovery_alpha_slow: float = Field(
        0.001, gt=0, lt=1, description="long-term average of the measurement fit"
    )
    recovery_alpha_fast: float = Field(
        0.1, gt=0, lt=1, description="short-term average; below the long one, inject particles"
    )
    injection_sigma_mm: float = Field(
        400.0, gt=0, description="injected particles spread this much around the last UWB fix"
    )
    global_sigma_mm: float = Field(
        500.0, gt=0, description="without a prior, particles start this close to the first fix"
    )
    relocalize_sigma_mm: float = Field(
        300.0, gt=0, description="on arriving at another floor, the cloud is widened to this"
    )
    relocalize_sigma_deg: float = Field(10.0, gt=0, description="... and its headings to this")
    # What goes on the board for the live map.
    cloud_points: int = Field(
        150, ge=0, description="particles published on state/particles for the map (0: none)"
    )
    cloud_period_s: float = Field(0.5, gt=0, description="how often they are published")

    @model_validator(mode="after")
    def _bounds(self) -> ParticleFilterConfig:
        if self.min_particles > self.max_particles:
            raise ValueError(
                f"min_particles ({self.min_particles}) exceeds max_particles ({self.max_particles})"
            )
        if self.recovery_alpha_slow >= self.recovery_alpha_fast:
            raise ValueError("recovery_alpha_slow must be below recovery_alpha_fast")
        if self.z_hit + self.z_short + self.z_random <= 0:
            raise ValueError("z_hit + z_short + z_random must be positive")
        return self


class StateConfig(Section):
    """Pose fusion: seed 004 odometry and complementary filter, plus UWB, walls and doors."""

    fusion: Literal["ekf", "particles"] = Field(
        "particles",
        description="the particle filter on the floor plan ([state.particles]), or the "
        "extended Kalman filter; docs/localization.md compares them",
    )
    particles: ParticleFilterConfig = ParticleFilterConfig()
    initial_floor: int = 2
    turn_rate_dps: float = Field(
        5.0, ge=0, le=360, description="gyro yaw rate above which the robot counts as turning"
    )
    gyro_weight: float = Field(
        0.98, ge=0, le=1, description="seed 004 complementary filter weight of the gyro in turns"
    )
    gyro_calibration_samples: int = Field(
        25,
        ge=1,
        le=10_000,
        description="at-rest gyro samples for the seed 004 offset and noise band",
    )
    encoder_sigma_fraction: float = Field(
        0.02, ge=0, le=1, description="odometry distance 1-sigma as a fraction of distance"
    )
    heading_sigma_deg_per_m: float = Field(
        0.5, ge=0, le=90, description="heading random walk per metre travelled"
    )
    heading_sigma_deg_per_rad_turned: float = Field(
        3.0,
        ge=0,
        le=90,
        description="heading 1-sigma a turn of one radian adds (gyro scale, slip in turns); a "
        "random walk, so it grows with the square root of the angle turned",
    )
    uwb_sigma_mm: float = Field(
        100.0, gt=0, le=DISTANCE_MM, description="1-sigma of a quality-100 UWB fix"
    )
    uwb_gate_sigma: float = Field(
        4.0, gt=0, le=100, description="fixes further than this (Mahalanobis) are outliers"
    )
    uwb_max_rejected: int = Field(
        20,
        ge=1,
        le=10_000,
        description="after this many rejected fixes in a row the filter re-seeds",
    )
    door_sigma_mm: float = Field(
        40.0, gt=0, le=DISTANCE_MM, description="1-sigma of a matched door landmark"
    )
    wall_sigma_mm: float = Field(
        30.0, gt=0, le=DISTANCE_MM, description="1-sigma of a wall-distance fix"
    )
    speed_window_s: float = Field(
        0.1,
        gt=0,
        le=10,
        description="speed and yaw rate are averaged over this much odometry: one telemetry "
        "step is a few ticks and a jittery time stamp, too coarse to size the door window",
    )
    camera_gate_sigma: float = Field(
        5.0,
        gt=0,
        le=100,
        description="a ceiling camera's fix further than this from the particle cloud (in "
        "sigmas of the fix and the cloud together) is not used, as the Kalman filter's gate "
        "refuses one: a single fix cannot tell a kidnapped robot from a wrong match, and a "
        "wrong one would carry a robot that knows where it is metres off (the filter's own "
        "recovery finds a kidnapped robot)",
    )


class MotionConfig(Section):
    """The motion module: lane keeping, the speed profile, the safety gate, going around."""

    cruise_speed_mm_s: float = Field(500.0, gt=0, le=SPEED_MM_S)
    max_speed_mm_s: float = Field(
        500.0,
        gt=0,
        le=SPEED_MM_S,
        description="the robot's rated speed, whatever an instruction asks: from 500 mm/s it "
        "and someone walking towards it at 1600 mm/s close 2.3 m while it stops, about as "
        "far as it tracks people; from 1 m/s it needs 1.2 m to stop for a chair's pole, "
        "beyond where it reliably sees one (docs/safety.md)",
    )
    approach_speed_mm_s: float = Field(
        150.0,
        gt=0,
        le=SPEED_MM_S,
        description="speed over the last approach_mm before a target door",
    )
    room_speed_mm_s: float = Field(
        300.0,
        gt=0,
        le=SPEED_MM_S,
        description="speed of a drive to a point through a doorway: into and out of a room "
        "or the elevator's car (at 150 mm/s a robot took 14 s to drive its 2 m into the car, "
        "holding the car the fleet shares); the profile still brakes to stop on the point",
    )
    approach_mm: float = Field(
        1200.0,
        ge=0,
        le=LENGTH_MM,
        description="slow down this far before a door so its detection can land",
    )
    creep_speed_mm_s: float = Field(
        30.0, gt=0, le=SPEED_MM_S, description="least speed while still short"
    )
    accel_mm_s2: float = Field(
        300.0, gt=0, le=ACCEL_MM_S2, description="profile limit, below the motor ramp"
    )
    wall_distance_mm: float = Field(
        300.0,
        gt=0,
        le=DISTANCE_MM,
        description="keep right: gap between the body's side and the wall",
    )
    passing_wall_distance_mm: float = Field(
        150.0,
        gt=0,
        le=DISTANCE_MM,
        description="the same gap while another robot of the fleet comes the other way in the "
        "hallway: two robots in their lanes at 300 mm stop face to face, at 150 mm they pass, "
        "at 100 mm a side passes 73 mm from the wall, 23 mm outside the side radius "
        "(navigation/passing.py)",
    )
    stale_safety_s: float = Field(0.2, gt=0, le=5, description="older collision verdicts mean stop")
    stale_pose_s: float = Field(0.5, gt=0, le=5, description="older pose estimates mean stop")
    stop_tolerance_mm: float = Field(50.0, gt=0, le=DISTANCE_MM)
    heading_tolerance_deg: float = Field(3.0, gt=0, le=45, description="a turn is done within this")
    period_s: float = Field(
        0.05,
        gt=0,
        le=1,
        description="control period; the motor driver's command timeout must be longer",
    )
    heading_gain: float = Field(
        2.0, gt=0, le=100, description="rad/s of turn per rad of heading error"
    )
    lane_lookahead_mm: float = Field(
        800.0,
        gt=0,
        le=LENGTH_MM,
        description="lane keeping aims at the lane this far ahead (pure pursuit); shorter "
        "weaves: with the heading hold's gain it sets the damping of the lateral loop",
    )
    max_lane_angle_deg: float = Field(
        20.0, gt=0, le=90, description="steepest angle to regain a lane"
    )
    max_turn_rate_dps: float = Field(45.0, gt=0, le=360)
    turn_accel_dps2: float = Field(90.0, gt=0, le=3600)
    # Local planning around obstacles (seed 003: costmap with inflation + DWA).
    costmap_resolution_mm: float = Field(50.0, gt=0, le=1000)
    costmap_size_mm: float = Field(
        6000.0, gt=0, le=LENGTH_MM, description="square window around the robot"
    )
    obstacle_memory_s: float = Field(8.0, gt=0, le=600, description="unseen obstacle cells expire")
    wall_margin_mm: float = Field(
        60.0,
        ge=0,
        le=DISTANCE_MM,
        description="a reading within this of the plan's walls is the wall",
    )
    wall_heading_tolerance_deg: float = Field(
        3.0,
        ge=0,
        le=45,
        description="the cone is widened by this when asking whether a wall explains a "
        "reading: at a grazing wall one degree of heading error moves the return ~100 mm",
    )
    clear_heading_sigmas: float = Field(
        2.0,
        ge=0,
        le=10,
        description="a cone clears only where it looks for certain: narrowed on each side by "
        "this many of the pose's heading sigmas, plus what the robot turns in pose_lag_s",
    )
    pose_lag_s: float = Field(
        0.1, ge=0, le=2, description="how far the pose may lag the sensors while turning"
    )
    side_clearance_mm: float = Field(
        100.0,
        ge=0,
        le=DISTANCE_MM,
        description="least gap the body's front and sides keep to a plan wall: above the "
        "collision module's side radius plus its hysteresis, so going round never trips it "
        "(the rear corners, which no sensor watches, keep turn_clearance_mm)",
    )
    obstacle_clearance_mm: float = Field(
        100.0,
        ge=0,
        le=DISTANCE_MM,
        description="least gap kept to an obstacle, for the same reason",
    )
    turn_clearance_mm: float = Field(
        50.0,
        ge=0,
        le=DISTANCE_MM,
        description="least gap a turn on the spot keeps to the plan's walls all the way round "
        "(the seed's side sphere; the rear corners swing out where no sensor looks): a turn "
        "with less is not begun. To what the sensors saw it keeps any gap: their cells already "
        "lie on the robot's side of it (a car's back wall 30-80 mm nearer than it stands)",
    )
    inflation_mm: float = Field(
        400.0, ge=0, le=DISTANCE_MM, description="cost decays to zero over this"
    )
    lookahead_mm: float = Field(
        2500.0, gt=0, le=LENGTH_MM, description="lane checked for obstacles this far"
    )
    static_confirm_s: float = Field(
        1.5, gt=0, le=60, description="an obstacle must stand still this long to be planned around"
    )
    static_tolerance_mm: float = Field(
        100.0, gt=0, le=DISTANCE_MM, description="'still': moved less than this"
    )
    dwa_horizon_s: float = Field(2.0, gt=0, le=10)
    dwa_speed_samples: int = Field(6, ge=2, le=100)
    dwa_turn_samples: int = Field(15, ge=3, le=100)


class ElevatorConfig(Section):
    """How long each elevator step may take before the robot reports, retries or aborts."""

    call_timeout_s: float = Field(60.0, gt=0, le=WAIT_S, description="car and open doors, per call")
    call_retries: int = Field(
        2, ge=0, le=10, description="calls repeated before asking the operator"
    )
    ride_timeout_s: float = Field(
        90.0, gt=0, le=WAIT_S, description="car at the other floor, doors open"
    )
    operator_timeout_s: float = Field(
        300.0, gt=0, le=WAIT_S, description="then the step is given up and the delivery fails"
    )
    car_depth_mm: float = Field(
        900.0,
        gt=0,
        le=DISTANCE_MM,
        description="how far past the door line the robot parks in the car",
    )


class NavigationConfig(Section):
    """Delivery timing: nothing waits forever."""

    base_depth_mm: float = Field(
        700.0,
        gt=0,
        le=LENGTH_MM,
        description="parking spot: this far inside the base room's door line",
    )
    loading_timeout_s: float = Field(600.0, gt=0, le=WAIT_S, description="no cup by then: failed")
    pickup_timeout_s: float = Field(180.0, gt=0, le=WAIT_S, description="no pickup by then: return")
    blocked_report_s: float = Field(20.0, gt=0, le=WAIT_S, description="then 'blocked' is reported")
    on_blocked: Literal["wait", "return"] = "wait"
    blocked_give_up_s: float = Field(
        600.0,
        gt=0,
        le=WAIT_S,
        description="blocked this long: fail and return whatever on_blocked says",
    )
    door_side_lane: bool = Field(
        True, description="pull over to the target door's side for the last stretch"
    )
    pull_over_mm: float = Field(
        3000.0, ge=0, le=LENGTH_MM, description="how early to cross to the door side"
    )
    hold_short_mm: float = Field(
        1200.0,
        ge=0,
        le=LENGTH_MM,
        description="a fleet's robot coming back waits for the loading spot this far before "
        "the base room's door, clear of a robot driving out of it (out of the car across "
        "from it: this far from the car, at the holding point)",
    )
    camera_stop_short_mm: float = Field(
        1500.0,
        ge=0,
        le=LENGTH_MM,
        description="something a ceiling camera sees blocking the hallway ahead is waited "
        "for with the body's front this far before it (navigation/camera_blocks.py)",
    )
    camera_stale_s: float = Field(
        3.0,
        gt=0,
        le=60,
        description="a camera layer older than this (it comes at least once a second) is no "
        "camera information, not 'still blocked': navigation stops waiting for what it "
        "showed and motion's costmap drops its marks; the robot's own sensors still stop "
        "it for whatever is there",
    )
    elevator: ElevatorConfig = ElevatorConfig()


class WebConfig(Section):
    host: str = Field("127.0.0.1", min_length=1)
    port: int = Field(8080, ge=0, le=65535)
    allowed_hosts: list[str] = Field(
        [],
        description="names the web answers to (the Host header) besides IP addresses, "
        "localhost and this machine's own name: anything else is refused, so a web page "
        "elsewhere cannot reach the API by pointing its own name at the robot (DNS rebinding)",
    )
    operator_token_env: str = Field("COFFEEBOT_OPERATOR_TOKEN", min_length=1)
    drinks: list[Annotated[str, Field(min_length=1, max_length=DRINK_NAME_CHARS)]] = Field(
        ["espresso", "americano", "latte", "cappuccino", "tea"], min_length=1
    )
    max_body_bytes: int = Field(
        16_384, gt=0, le=1_048_576, description="larger request bodies get 413"
    )
    order_burst: int = Field(
        5, ge=1, le=1000, description="orders one client may place back to back"
    )
    order_refill_s: float = Field(
        12.0, gt=0, le=3600, description="one more order allowed per this"
    )
    stream_period_s: float = Field(0.5, gt=0, le=60, description="inspector stream frame interval")
    progress_period_s: float = Field(
        2.0, gt=0, le=60, description="a customer's page hears how its delivery goes this often"
    )
    eta_speed_mm_s: float = Field(
        300.0, gt=0, le=SPEED_MM_S, description="average delivery speed for the arrival estimate"
    )
    eta_elevator_ride_s: float = Field(
        60.0, ge=0, le=WAIT_S, description="one elevator ride (call, ride, exit) in the estimate"
    )
    stale_after_s: dict[str, Annotated[float, Field(gt=0, le=WAIT_S)]] = Field(
        {
            "tof/scan": 0.5,
            "safety/collision": 0.5,
            "state/current": 1.0,
            "motor/odometry": 1.0,
            "uwb/fix": 2.0,
        },
        description="topics that must keep coming: an operator alert when one is older",
    )

    @model_validator(mode="after")
    def _distinct_drinks(self) -> WebConfig:
        repeated = sorted({d for d in self.drinks if self.drinks.count(d) > 1})
        if repeated:
            raise ValueError(f"drinks listed twice: {repeated}")
        return self


class StoreConfig(Section):
    """The order database and what happens when it cannot be written (locked, read only,
    full): every change is kept and retried, and the operator is told."""

    path: Path = Path("var/orders.sqlite3")
    busy_timeout_s: float = Field(
        1.0,
        gt=0,
        le=60,
        description="a write waits this long for another process's lock before it is retried "
        "later; reads queue behind it, so keep it short",
    )
    retry_max_s: float = Field(
        2.0, gt=0, le=60, description="longest wait between two attempts at a failed write"
    )
    failed_after_s: float = Field(
        30.0,
        gt=0,
        le=WAIT_S,
        description="unwritable this long: the orders' health says failed (degraded before)",
    )


class LoggingConfig(Section):
    level: Literal["DEBUG", "INFO", "WARNING", "ERROR"] = "INFO"


class WatchdogConfig(Section):
    """When systemd's watchdog gets its pings: the control loop's topics keep arriving."""

    topics: list[str] = Field(
        ["safety/collision"], min_length=1, description="each must stay fresh"
    )
    max_age_s: float = Field(1.0, gt=0, le=60, description="older than this: control loop stalled")
    max_loop_lag_s: float = Field(1.0, gt=0, le=60, description="event loop this late: stalled")


class DispatchConfig(Section):
    """The fleet's dispatcher (``coffeebot fleet``): when it gives up on a robot, how long
    a shared place is lent, how it estimates and assigns (docs/fleet.md)."""

    stale_after_s: float = Field(
        5.0, gt=0, le=600, description="a robot not heard of this long is stale (grey on the map)"
    )
    lost_after_s: float = Field(
        30.0,
        gt=0,
        le=WAIT_S,
        description="stale this long while carrying an order out: the order fails with the reason",
    )
    ack_timeout_s: float = Field(
        3.0, gt=0, le=600, description="an assignment not acknowledged this long is sent again"
    )
    lease_s: float = Field(
        30.0, gt=0, le=3600, description="how long a grant of a shared place lasts unless renewed"
    )
    loading_s: float = Field(
        30.0, ge=0, le=WAIT_S, description="estimate: staff loading the cup at the tea room"
    )
    strategy: Literal["joint", "greedy"] = Field(
        "joint", description="several orders and robots at once: jointly, or first come"
    )


class FleetConfig(Section):
    """One robot of a fleet: the MQTT broker it reports to and takes its orders from
    (docs/fleet.md). Without a broker the robot keeps its own orders, as a single robot
    does. The broker's user name is the robot id; the password comes from the environment
    (``COFFEEBOT_MQTT_PASSWORD``), never from this file."""

    broker: str = Field(
        "",
        pattern=r"^(mqtt://[A-Za-z0-9.\-]+(:[0-9]{1,5})?)?$",
        description="mqtt://host[:port]; empty: a single robot, no fleet",
    )
    robot_id: str = Field(
        "",
        pattern=r"^([a-z0-9][a-z0-9-]{0,31})?$",
        description="its name on the broker (empty: the board's name)",
    )
    parking_spot: int = Field(
        0, ge=0, le=63, description="which of the floor plan's parking spots is this robot's"
    )
    state_hz: float = Field(2.0, gt=0, le=20, description="state reports per second")
    lease_renew_s: float = Field(
        5.0, gt=0, le=600, description="a held place is asked for again this often"
    )
    lease_wait_s: float = Field(
        120.0,
        gt=0,
        le=WAIT_S,
        description="without the broker for this long, the robot goes into a shared place on "
        "its own sensors' word (a robot that lost the broker finishes what it carries)",
    )
    reconnect_max_s: float = Field(10.0, gt=0, le=600, description="longest wait between tries")
    dispatch: DispatchConfig = DispatchConfig()

    @property
    def enabled(self) -> bool:
        return bool(self.broker)


class SupervisionConfig(Section):
    restart_backoff_s: float = Field(0.5, gt=0, le=60)
    restart_backoff_max_s: float = Field(10.0, gt=0, le=3600)
    max_restarts: int = Field(5, ge=0, le=1000, description="within failure_window_s, then failed")
    failure_window_s: float = Field(60.0, gt=0, le=WAIT_S)

    @model_validator(mode="after")
    def _backoff_grows(self) -> SupervisionConfig:
        if self.restart_backoff_max_s < self.restart_backoff_s:
            raise ValueError("restart_backoff_max_s must not be below restart_backoff_s")
        return self


class CamerasConfig(Section):
    """The building's ceiling cameras (seed 003), when the robot uses them. A robot alone
    runs their pipeline itself (the ``cameras`` module); the rules of identification and of
    the map layer are :mod:`coffeebot.cameras`' defaults."""

    enabled: bool = Field(
        False,
        description="watch the floor plan's ceiling cameras: they fix the robot's pose and "
        "put what stands in the hallway on the map",
    )
    streams: dict[str, str] = Field(
        {},
        description="each camera's stream by its id in the floor plan: a URL or device "
        "OpenCV opens (rtsp://..., /dev/video0); the simulated robot renders every camera "
        "of the plan instead",
    )
    windows_s: tuple[float, ...] = Field(
        (2.0, 4.0, 8.0),
        min_length=1,
        description="the stretches of track and odometry identification compares, each "
        "frame: a robot is named on the shortest that names it (a fast robot soon after it "
        "drives into view, one crawling through a crossing at 115 mm/s only over 8 s)",
    )
    fix_period_s: float = Field(
        0.5, gt=0, le=60, description="at most one fix per camera this often"
    )
    out_after_s: float = Field(
        3.0,
        gt=0,
        le=WAIT_S,
        description="a camera with no frame for this long is reported out, and what it saw "
        "stays on the map only until it expires",
    )


class RobotConfig(Section):
    name: str = "coffeebot"
    i2c: I2CConfig = I2CConfig()
    tof: TofConfig
    uwb: SerialPortConfig
    motor: MotorConfig
    geometry: GeometryConfig = GeometryConfig()
    collision: CollisionConfig = CollisionConfig()
    tracking: TrackingConfig = TrackingConfig()
    openings: OpeningsConfig = OpeningsConfig()
    angle: AngleConfig = AngleConfig()
    door: DoorConfig = DoorConfig()
    state: StateConfig = StateConfig()
    motion: MotionConfig = MotionConfig()
    navigation: NavigationConfig = NavigationConfig()
    web: WebConfig = WebConfig()
    store: StoreConfig = StoreConfig()
    logging: LoggingConfig = LoggingConfig()
    supervision: SupervisionConfig = SupervisionConfig()
    watchdog: WatchdogConfig = WatchdogConfig()
    fleet: FleetConfig = FleetConfig()
    cameras: CamerasConfig = CamerasConfig()

    @property
    def robot_id(self) -> str:
        """The robot's name in a fleet: ``[fleet] robot_id``, else the board's name."""
        return self.fleet.robot_id or self.name

    def sensor(self, sensor_id: int) -> TofSensorConfig:
        return next(s for s in self.tof.sensors if s.id == sensor_id)


def describe_validation_error(path: Path, error: ValidationError) -> str:
    """One line per problem: ``file: field.path: message``."""
    lines = []
    for item in error.errors():
        where = ".".join(str(part) for part in item["loc"]) or "(top level)"
        lines.append(f"{path}: {where}: {item['msg']}")
    return "\n".join(lines)


def read_toml(path: Path, fail: Callable[[str], ConfigError] | None = None) -> dict[str, Any]:
    """The document in a TOML file; a file that cannot be read or parsed raises
    ``fail(problem)`` (by default a :class:`ConfigError` "<path>: <problem>"), one line."""
    try:
        return tomllib.loads(path.read_bytes().decode("utf-8"))
    except FileNotFoundError:
        problem = "file not found"
    except IsADirectoryError:
        problem = "is a directory, not a file"
    except OSError as exc:
        problem = f"cannot be read: {exc.strerror or exc}"
    except UnicodeDecodeError as exc:
        problem = f"not UTF-8 text (byte {exc.start} is {exc.object[exc.start]:#04x})"
    except tomllib.TOMLDecodeError as exc:
        problem = f"not valid TOML: {exc}"
    raise ConfigError(f"{path}: {problem}") if fail is None else fail(problem)


def load_robot_config(path: str | Path) -> RobotConfig:
    path = Path(path)
    data = read_toml(path)
    try:
        return RobotConfig.model_validate(data)
    except ValidationError as exc:
        raise ConfigError(describe_validation_error(path, exc)) from None
