"""Scenario files: a reproducible run of the whole daemon on the simulated world.

A scenario (TOML, ``docs/scenarios.md``) names the floor plan, where the robot starts, the
orders customers place and when, the obstacles, the faults, speed limits, the random seed and
a time limit.
"""

from __future__ import annotations

from pathlib import Path

from pydantic import BaseModel, ConfigDict, Field, ValidationError

from coffeebot.config import SPEED_MM_S, WAIT_S, RobotConfig, describe_validation_error, read_toml
from coffeebot.errors import ConfigError
from coffeebot.floorplan import Coordinate, FloorPlan, load_floorplan
from coffeebot.sim.faults import Fault
from coffeebot.sim.simulation import SimSetup
from coffeebot.sim.world import ObstacleSpec, Pose


class _Model(BaseModel):
    """Unknown keys, ``nan`` and ``inf`` are refused, as in the board file."""

    model_config = ConfigDict(extra="forbid", frozen=True, allow_inf_nan=False)


class StartPose(_Model):
    """Where the robot stands when the run begins (floor frame)."""

    floor: int
    x_mm: Coordinate
    y_mm: Coordinate
    heading_deg: float = Field(0.0, ge=-360, le=360)


class OrderSpec(_Model):
    """A customer placing an order ``at_s`` simulated seconds into the run."""

    room: str
    at_s: float = Field(0.0, ge=0, le=WAIT_S)
    drink: str = "espresso"
    name: str = "scenario"


class Limits(_Model):
    """Speed limits for the run; unset keeps the board file's values."""

    max_speed_mm_s: float | None = Field(None, gt=0, le=SPEED_MM_S, description="the motors' limit")
    cruise_speed_mm_s: float | None = Field(
        None, gt=0, le=SPEED_MM_S, description="navigation's cruise"
    )


class Staff(_Model):
    """The people around a delivery: staff loading the cup, the customer taking it."""

    load_after_s: float = Field(
        3.0, ge=0, le=WAIT_S, description="after the robot stands ready in the tea room for the cup"
    )
    pickup_after_s: float | None = Field(
        5.0, ge=0, le=WAIT_S, description="after the robot arrived; unset: nobody comes"
    )


class Scenario(_Model):
    name: str
    description: str = ""
    floorplan: Path = Field(description="relative to the scenario file")
    seed: int = 0
    time_limit_s: float = Field(
        gt=0, le=WAIT_S, description="simulated seconds before the run ends"
    )
    start: StartPose
    orders: list[OrderSpec] = []
    obstacles: list[ObstacleSpec] = []
    faults: list[Fault] = []
    limits: Limits = Limits()
    staff: Staff = Staff()
    cameras: bool | None = Field(
        None,
        description="the building's ceiling cameras watch (rendered by the simulator) and "
        "the robot uses them; unset keeps the board file's ``[cameras] enabled``",
    )

    def configure(self, config: RobotConfig) -> RobotConfig:
        """The board's config with this scenario's speed limits and cameras."""
        motor, motion = config.motor, config.motion
        if self.limits.max_speed_mm_s is not None:
            motor = motor.model_copy(update={"max_speed_mm_s": self.limits.max_speed_mm_s})
        if self.limits.cruise_speed_mm_s is not None:
            motion = motion.model_copy(update={"cruise_speed_mm_s": self.limits.cruise_speed_mm_s})
        cameras = config.cameras
        if self.cameras is not None:
            cameras = cameras.model_copy(update={"enabled": self.cameras})
        return config.model_copy(update={"motor": motor, "motion": motion, "cameras": cameras})

    def setup(self, speed: float = 1.0) -> SimSetup:
        """The simulated world this scenario starts from."""
        start = self.start
        return SimSetup(
            floor=start.floor,
            pose=Pose(start.x_mm, start.y_mm, start.heading_deg),
            obstacles=self.obstacles,
            faults=self.faults,
            seed=self.seed,
            speed=speed,
        )


def load_scenario(path: str | Path) -> tuple[Scenario, FloorPlan]:
    """Read and check a scenario and its floor plan; problems raise :class:`ConfigError`
    naming the file and the field (``orders.1.room: unknown room '299'``)."""
    path = Path(path)
    try:
        scenario = Scenario.model_validate(read_toml(path))
    except ValidationError as exc:
        raise ConfigError(describe_validation_error(path, exc)) from None
    plan_path = path.parent / scenario.floorplan
    scenario = scenario.model_copy(update={"floorplan": plan_path})
    plan = load_floorplan(plan_path)
    levels = {f.level for f in plan.floors}
    problems = []
    if scenario.start.floor not in levels:
        problems.append(f"start.floor: no floor {scenario.start.floor} in {plan_path}")
    rooms = set(plan.rooms)
    problems += [
        f"orders.{i}.room: unknown room {o.room!r}"
        for i, o in enumerate(scenario.orders)
        if o.room not in rooms
    ]
    problems += [
        f"obstacles.{i}.floor: no floor {o.floor} in {plan_path}"
        for i, o in enumerate(scenario.obstacles)
        if o.floor not in levels
    ]
    if problems:
        raise ConfigError("\n".join(f"{path}: {p}" for p in problems))
    return scenario, plan
