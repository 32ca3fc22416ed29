"""The motion controller in a loop with the simulated world, without buses or the daemon.

Ground-truth pose in, world scans into the costmap and the collision monitor, the gated
command out to the wheels: what the motion module does each period, minus the board.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from pathlib import Path

from coffeebot.config import CollisionConfig, RobotConfig, load_robot_config
from coffeebot.floorplan import FloorPlan, load_floorplan
from coffeebot.messages import (
    MotionState,
    MoveInstruction,
    OtherRobot,
    PoseEstimate,
    RangeScan,
    SafetyState,
)
from coffeebot.modules.motion import MotionModule
from coffeebot.navigation.control import wheel_speeds
from coffeebot.navigation.route import RoutePlanner
from coffeebot.perception.collision import CollisionMonitor
from coffeebot.perception.walls import explainer
from coffeebot.sim.world import World
from coffeebot.sim.world.tof import as_range_reading, robot_setup
from coffeebot.sim.world.world import WorldRobot

ROOT = Path(__file__).resolve().parents[2]
CONFIG: RobotConfig = load_robot_config(ROOT / "boards" / "coffeebot-v1.toml")
PLAN: FloorPlan = load_floorplan(ROOT / "floorplans" / "cs-building.toml")
PLANNER = RoutePlanner(
    PLAN,
    CONFIG.motion,
    CONFIG.navigation,
    CONFIG.geometry.width_mm,
    body_length_mm=CONFIG.geometry.length_mm,
)
"""Routes of a single robot turning about its body's centre (no axle offset)."""
DT = 0.05
SETUP = robot_setup(CONFIG.tof)
"""The chips set up as the ToF poller sets them up."""


def reported(
    x_mm: float,
    y_mm: float,
    heading_deg: float,
    *,
    name: str = "robot-2",
    floor: int = 2,
    moving: bool = False,
    age_s: float = 0.0,
) -> OtherRobot:
    """Another robot of the fleet as the dispatcher's traffic reports it."""
    return OtherRobot(
        robot=name,
        floor=floor,
        x_mm=x_mm,
        y_mm=y_mm,
        heading_deg=heading_deg,
        moving=moving,
        reported_at_s=0.0,
        age_s=age_s,
    )


def to_scan(world: World) -> RangeScan:
    readings = [as_range_reading(k, r) for k, r in enumerate(world.robot.scan(SETUP))]
    return RangeScan(cycle_start_s=world.t_s, cycle_time_s=DT, readings=readings)


def estimate_at(floor: int, x: float, y: float, heading: float = 0.0) -> PoseEstimate:
    """A pose estimate at rest, as the state module gives it with good fixes (10 mm, 1 deg)."""
    return PoseEstimate(
        x_mm=x,
        y_mm=y,
        heading_deg=heading,
        floor=floor,
        sigma_x_mm=10,
        sigma_y_mm=10,
        sigma_heading_deg=1,
    )


def true_pose(robot: WorldRobot) -> PoseEstimate:
    """The robot's ground truth as a pose estimate without uncertainty."""
    body = robot.body.state
    return PoseEstimate(
        x_mm=robot.pose.x_mm,
        y_mm=robot.pose.y_mm,
        heading_deg=robot.pose.heading_deg,
        floor=robot.floor_level,
        sigma_x_mm=0.0,
        sigma_y_mm=0.0,
        sigma_heading_deg=0.0,
        speed_mm_s=body.speed_mm_s,
    )


@dataclass
class Run:
    states: list[MotionState] = field(default_factory=list)
    min_speed_after_start: float = 0.0
    done: bool = False
    path: list[tuple[float, float, float]] = field(default_factory=list)
    """True (x, y, heading) each period."""


def drive(
    world: World,
    instruction: MoveInstruction,
    max_time_s: float,
    collision: CollisionConfig = CONFIG.collision,
) -> Run:
    """Run one instruction until motion reports done (or time runs out)."""
    module = MotionModule(CONFIG, PLAN)
    monitor = CollisionMonitor(
        CONFIG.tof.sensors, collision, max_speed_mm_s=CONFIG.motor.max_speed_mm_s
    )
    run = Run()
    seq = 0
    while world.t_s < max_time_s:
        seq += 1
        scan = to_scan(world)
        pose = true_pose(world.robot)
        run.path.append((pose.x_mm, pose.y_mm, pose.heading_deg))
        module.costmap.update(
            scan, PLAN.floor(pose.floor), pose.x_mm, pose.y_mm, pose.heading_deg, world.t_s
        )
        # As the collision module with a good pose: the plan's walls place what they explain.
        explain = explainer(PLAN.floor(pose.floor), pose, CONFIG.motion.wall_margin_mm)
        yaw_rate = math.degrees(world.robot.body.state.yaw_rate_rad_s)
        verdict = monitor.update(scan, pose.speed_mm_s, seq, yaw_rate, explain)
        limit = 0.0 if verdict.state is SafetyState.STOP else verdict.speed_limit_mm_s
        if limit <= 0 and verdict.may_rotate:
            # As the motion module: held by something ahead, it may still turn on the spot.
            command = module.controller.step(instruction, pose, world.t_s, DT, 0.0)
            run.states.append(command.status.state)
            turn = wheel_speeds(0.0, command.yaw_rate_dps, CONFIG.motor.wheel_base_mm)
            world.robot.command_wheels(*turn)
        elif limit <= 0 and verdict.may_creep_ahead:
            # As the motion module: held beside something, it may creep straight ahead.
            creep = CONFIG.collision.creep_ahead_mm_s
            command = module.controller.step(instruction, pose, world.t_s, DT, creep)
            run.states.append(command.status.state)
            world.robot.command_wheels(command.speed_mm_s, command.speed_mm_s)
        elif limit <= 0:
            module.controller.halt()
            world.robot.command_wheels(0.0, 0.0)
        else:
            command = module.controller.step(instruction, pose, world.t_s, DT, limit)
            run.states.append(command.status.state)
            if command.status.state is MotionState.DONE:
                run.done = True
                world.robot.command_wheels(0.0, 0.0)
                world.step(1.0)
                return run
            world.robot.command_wheels(
                *wheel_speeds(command.speed_mm_s, command.yaw_rate_dps, CONFIG.motor.wheel_base_mm)
            )
        world.step(DT)
    return run
