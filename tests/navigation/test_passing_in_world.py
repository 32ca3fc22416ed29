"""Two robots meeting head-on in the floor-2 hallway, each in its keep-right lane, on the
simulated world: with each other's poses as traffic they pass in their passing lanes;
without, only by going round each other, later. And a
robot passes one that stands waiting beside its passing lane, as it waits for the elevator,
the standing robot marked as its outline from the traffic (``test_others.py``)."""

from __future__ import annotations

import math
from dataclasses import dataclass

from helpers import CONFIG, DT, PLAN, PLANNER, SETUP, reported, true_pose

from coffeebot.messages import (
    MotionState,
    MoveInstruction,
    RangeScan,
    SafetyState,
    Traffic,
)
from coffeebot.modules.motion import MotionModule
from coffeebot.navigation.control import wheel_speeds
from coffeebot.perception.collision import CollisionMonitor
from coffeebot.perception.walls import explainer
from coffeebot.sim.world import Pose, RobotSpec, World
from coffeebot.sim.world.tof import as_range_reading
from coffeebot.sim.world.world import WorldRobot

FLOOR = PLAN.floor(2)


@dataclass
class Meeting:
    done: list[bool]
    contacts: int
    t_s: float
    """Simulated time when both were done (or the time ran out)."""


def seen_as_traffic(name: str, robot: WorldRobot, moving: bool) -> Traffic:
    """What the dispatcher would tell the other robot of this one."""
    pose = true_pose(robot)
    other = reported(
        pose.x_mm, pose.y_mm, pose.heading_deg, name=name, floor=pose.floor, moving=moving
    )
    return Traffic(robots=[other])


STANDING_D_MM = 361.0
"""Where a robot that drove across the hallway to its waiting lane short of the elevator
(445 mm off the axis) stood, squared up, in the fleet's simulation."""


def meet(
    traffic: bool, max_time_s: float, b_stands: bool = False, a_off_mm: float = 0.0
) -> Meeting:
    """Robot a from s=13 m going +s, robot b from s=21 m going -s, each in its lane, each
    with its own motion module and collision monitor fed ground truth (as ``drive`` does).
    ``b_stands``: b stands still on its side ``STANDING_D_MM`` off the axis instead.
    ``a_off_mm``: a's estimate that far off its truth towards the hallway's middle."""
    h = FLOOR.hallway.heading_deg
    lane_a, lane_b = PLANNER.lane_mm(FLOOR, 1.0), PLANNER.lane_mm(FLOOR, -1.0)
    xa, ya = FLOOR.from_hallway(13000, lane_a)
    xb, yb = FLOOR.from_hallway(21000 if not b_stands else 17000, lane_b)
    if b_stands:
        xb, yb = FLOOR.from_hallway(17000, STANDING_D_MM)
    world = World(
        PLAN, RobotSpec.from_config(CONFIG), floor=2, pose=Pose(xa, ya, h), obstacles=[], seed=3
    )
    other = world.add_robot(RobotSpec.from_config(CONFIG), 2, Pose(xb, yb, h + 180), "b")
    robots, names = [world.robot, other], ["robot-a", "robot-b"]
    instructions = [
        MoveInstruction(
            id=1, action="follow_lane", floor=2, target_s_mm=24000, lane_mm=lane_a, avoid=True
        ),
        MoveInstruction(
            id=1, action="follow_lane", floor=2, target_s_mm=10000, lane_mm=lane_b, avoid=True
        ),
    ]
    modules = [MotionModule(CONFIG, PLAN) for _ in robots]
    monitors = [
        CollisionMonitor(
            CONFIG.tof.sensors, CONFIG.collision, max_speed_mm_s=CONFIG.motor.max_speed_mm_s
        )
        for _ in robots
    ]
    done = [False, b_stands]
    seq = 0
    while world.t_s < max_time_s and not all(done):
        seq += 1
        if traffic and seq % 10 == 1:  # twice a second
            for i in (0, 1):
                modules[i].controller.note_traffic(
                    seen_as_traffic(names[1 - i], robots[1 - i], moving=not done[1 - i]),
                    world.t_s,
                )
        for i, robot in enumerate(robots):
            if done[i]:
                robot.command_wheels(0.0, 0.0)
                continue
            readings = [as_range_reading(k, r) for k, r in enumerate(robot.scan(SETUP))]
            scan = RangeScan(cycle_start_s=world.t_s, cycle_time_s=DT, readings=readings)
            pose = true_pose(robot)
            if i == 0 and a_off_mm:
                s, d = FLOOR.to_hallway(pose.x_mm, pose.y_mm)
                x, y = FLOOR.from_hallway(s, d - math.copysign(a_off_mm, d))
                pose = pose.model_copy(update={"x_mm": x, "y_mm": y})
            module, ins = modules[i], instructions[i]
            module.costmap.update(
                scan,
                FLOOR,
                pose.x_mm,
                pose.y_mm,
                pose.heading_deg,
                world.t_s,
                robots=module.controller.standing_robots(FLOOR.level, world.t_s),
            )
            explain = explainer(FLOOR, pose, CONFIG.motion.wall_margin_mm)
            yaw_rate = math.degrees(robot.body.state.yaw_rate_rad_s)
            verdict = monitors[i].update(scan, pose.speed_mm_s, seq, yaw_rate, explain)
            limit = 0.0 if verdict.state is SafetyState.STOP else verdict.speed_limit_mm_s
            if limit <= 0 and verdict.may_rotate:
                command = module.controller.step(ins, pose, world.t_s, DT, 0.0)
                robot.command_wheels(
                    *wheel_speeds(0.0, command.yaw_rate_dps, CONFIG.motor.wheel_base_mm)
                )
            elif limit <= 0 and verdict.may_creep_ahead:
                creep = CONFIG.collision.creep_ahead_mm_s
                command = module.controller.step(ins, pose, world.t_s, DT, creep)
                robot.command_wheels(command.speed_mm_s, command.speed_mm_s)
            elif limit <= 0:
                module.controller.halt()
                robot.command_wheels(0.0, 0.0)
            else:
                command = module.controller.step(ins, pose, world.t_s, DT, limit)
                if command.status.state is MotionState.DONE:
                    done[i] = True
                    robot.command_wheels(0.0, 0.0)
                    continue
                robot.command_wheels(
                    *wheel_speeds(
                        command.speed_mm_s, command.yaw_rate_dps, CONFIG.motor.wheel_base_mm
                    )
                )
        world.step(DT)
    return Meeting(done, sum(len(r.collisions) for r in robots), world.t_s)


def test_with_traffic_both_pass_in_their_passing_lanes() -> None:
    meeting = meet(traffic=True, max_time_s=60.0)
    assert meeting.done == [True, True]
    assert meeting.contacts == 0


def test_they_pass_with_one_estimate_50_mm_towards_the_middle() -> None:
    """a, 50 mm nearer its wall than it believes, reads that wall at a glancing angle
    where the plan puts no wall: the cells it marks there are not an obstacle in its passing
    lane (they were: its go-round, its rear's swing held by them, ended against the wall)."""
    meeting = meet(traffic=True, max_time_s=60.0, a_off_mm=50.0)
    assert meeting.done == [True, True]
    assert meeting.contacts == 0


def test_without_traffic_they_get_past_only_by_going_round_each_other_later() -> None:
    """Each takes the other for an obstacle in its keep-right lane and goes round it beside
    the wall (its rear may swing to the turn clearance there, ``test_local_planner.py``):
    both get past, 13 s after robots that know each other's way pass in their lanes."""
    without = meet(traffic=False, max_time_s=60.0)
    assert without.done == [True, True]
    assert without.contacts == 0
    assert without.t_s > meet(traffic=True, max_time_s=60.0).t_s + 5.0


def test_with_traffic_it_passes_a_robot_standing_by_its_passing_lane() -> None:
    meeting = meet(traffic=True, max_time_s=60.0, b_stands=True)
    assert meeting.done[0]
    assert meeting.contacts == 0
