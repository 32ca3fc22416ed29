"""A scenario run's report: what the daemon did, with what only the simulator knows.

Written as JSON by ``coffeebot sim --scenario`` (``docs/scenarios.md`` shows one) and read by
the delivery tests and benchmarks as these models.
"""

from __future__ import annotations

import math

from pydantic import BaseModel, ConfigDict, Field

from coffeebot.sim.faults import FaultRecord
from coffeebot.sim.simulation import Simulation
from coffeebot.sim.world.contact import judge_contact
from coffeebot.sim.world.robot import RobotSpec
from coffeebot.sim.world.world import Collision


class _Report(BaseModel):
    model_config = ConfigDict(frozen=True, populate_by_name=True, serialize_by_alias=True)


class OrderOutcome(_Report):
    """One order the scenario placed, as last seen on the board."""

    id: str | None
    room: str
    status: str
    """An order status, or ``not placed`` / ``refused`` when it never got into the queue."""
    detail: str
    placed_at_s: float | None
    arrived_at_s: float | None
    delivered_at_s: float | None
    stop_error_mm: float | None
    """How far along the hallway the robot truly stood from the door's centre at ``arrived``."""


class Contact(_Report):
    """The robot's footprint touched something (ground truth, not what the robot saw)."""

    t: float
    with_: str = Field(alias="with")
    speed_mm_s: float
    """The body's signed forward speed."""
    towards_mm_s: float
    """The touched point of the body moving towards what it touched: a robot turning on the
    spot strikes with a corner while its centre barely moves."""
    floor: int
    x_mm: int
    y_mm: int

    @classmethod
    def of(cls, c: Collision, robot: RobotSpec) -> Contact:
        towards = c.speed_mm_s  # without the body's state, the centre's
        if c.body is not None:
            towards = judge_contact(c.element, (c.x_mm, c.y_mm), c.body, robot).robot_towards_mm_s
        return cls(
            t=round(c.t_s, 3),
            with_=c.element,
            speed_mm_s=round(c.speed_mm_s, 1),
            towards_mm_s=round(towards, 1),
            floor=c.floor,
            x_mm=round(c.x_mm),
            y_mm=round(c.y_mm),
        )


class SafetyStopEntry(_Report):
    """The collision verdict turned to "stop", or the motor driver stopped the motors because
    no command came in time while they were moving (``sensor`` is None then)."""

    t: float
    reason: str
    sensor: int | None


class InjectedFault(_Report):
    t: float
    fault: str
    detail: str
    cleared_t: float | None

    @classmethod
    def of(cls, f: FaultRecord) -> InjectedFault:
        return cls(
            t=round(f.t_s, 3),
            fault=f.fault,
            detail=f.detail,
            cleared_t=None if f.cleared_s is None else round(f.cleared_s, 3),
        )


class FinalPose(_Report):
    floor: int
    x_mm: int
    y_mm: int
    heading_deg: float


class ScenarioReport(_Report):
    scenario: str
    seed: int
    sim_time_s: float
    ended: str
    """Why the run ended: ``every order ended`` or ``time limit``."""
    orders: list[OrderOutcome]
    collisions: list[Contact]
    travelled_mm: int
    """Ground-truth distance driven, counting only while faster than a crawl."""
    moving_s: float
    min_clearance_mm: int | None
    """Smallest gap between the body and anything within its height (0 while touching)."""
    safety_stops: int
    safety_stop_log: list[SafetyStopEntry]
    faults_injected: list[InjectedFault]
    final_pose: FinalPose
    real_time_factor: float | None = None
    """Simulated seconds per wall second the machine kept up with (below the requested
    speed, the clock was paced down)."""

    @property
    def mean_speed_mm_s(self) -> float | None:
        return self.travelled_mm / self.moving_s if self.moving_s else None


def world_facts(
    sim: Simulation,
) -> tuple[list[Contact], FinalPose, int | None, list[InjectedFault]]:
    """What only the simulator knows: contacts, where the robot ended, the least clearance
    and the faults it injected."""
    with sim.lock:
        robot = sim.robot
        contacts = [Contact.of(c, robot.spec) for c in robot.collisions]
        pose = robot.pose
        final = FinalPose(
            floor=robot.floor_level,
            x_mm=round(pose.x_mm),
            y_mm=round(pose.y_mm),
            heading_deg=round(pose.heading_deg, 1),
        )
    clearance = sim.truth.min_clearance_mm
    least = round(clearance) if math.isfinite(clearance) else None
    return contacts, final, least, [InjectedFault.of(f) for f in sim.truth.faults]
