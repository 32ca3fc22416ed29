"""Four robots, a mail cart and a walker in one building: where each robot ends up and what it
touched, to the last bit, as the world computed it before its surfaces were cached per step
(the figures below are from that code), and what their sensors read on the way, as the cones
were cast before they were cast only in the columns a pole or a low face crosses. A speed-up
of the world must not move anyone, nor change a reading."""

from __future__ import annotations

import math

from coffeebot.floorplan import FloorPlan
from coffeebot.sim.world import ObstacleSpec, RobotSpec, World
from coffeebot.sim.world.trace import hallway_pose

EXPECTED = {
    "robot": (
        (6265.372261717209, -174.91972777248924, -0.21899842182983822),
        [("cart lower shelf", 9.91), ("cart upper shelf", 9.91)],
    ),
    "robot2": (
        (4637.711589241365, 570.2010932845735, 3.0572112757473504),
        [("hallway left wall", 6.325), ("walker torso", 7.665), ("walker leg", 7.79)],
    ),
    "robot3": (
        (12165.060402652643, -588.3579648902873, -0.44611912562054096),
        [("door 204", 3.805)],
    ),
    "robot4": (
        (14224.669228208879, 495.41057417734334, 2.7363607304233604),
        [("hallway left wall", 2.625)],
    ),
}

READ = {"robot": 4696733, "robot2": 4884024, "robot3": 3132905, "robot4": 3454412}
"""Every reported distance of every scan, summed per robot (the noise included: its draws
follow the signals)."""


def test_four_robots_drive_where_they_always_did(
    cs_building: FloorPlan, board_robot: RobotSpec
) -> None:
    floor = cs_building.floor(2)
    obstacles = [
        ObstacleSpec(id="cart", kind="mail_cart", floor=2, x_mm=7000, y_mm=-550, heading_deg=0),
        ObstacleSpec(
            id="walker",
            kind="person",
            floor=2,
            x_mm=12000,
            y_mm=300,
            path=[(1000, 300)],
            speed_mm_s=900,
        ),
    ]
    world = World(
        cs_building,
        board_robot,
        floor=2,
        pose=hallway_pose(floor, 3000, -450),
        obstacles=obstacles,
        seed=7,
    )
    for k in range(1, 4):
        pose = hallway_pose(floor, 3000 + 4000 * k, 400 if k % 2 else -400)
        turned = pose._replace(heading_deg=pose.heading_deg + (180.0 if k % 2 else 0.0))
        world.add_robot(board_robot, 2, turned, f"robot{k + 1}")
    read: dict[str, int] = {robot.name: 0 for robot in world.robots}
    for step in range(500):
        for k, robot in enumerate(world.robots):
            turn = 60.0 * math.sin(step / 40.0 + k)
            robot.command_wheels(350 - turn, 350 + turn)
        world.step(0.02)
        for robot in world.robots:
            # Every robot's cones cast each step, as the daemons ask them.
            read[robot.name] += sum(reading.distance_mm for reading in robot.scan())
    for robot in world.robots:
        s = robot.body.state
        pose, touched = EXPECTED[robot.name]
        assert (s.x, s.y, s.theta) == pose
        assert [(c.element, round(c.t_s, 3)) for c in robot.collisions] == touched
    assert read == READ
