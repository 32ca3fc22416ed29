"""Who caused a contact, where on the body, how fast: the safety benchmark's judgement and
the run report's."""

from __future__ import annotations

import math

import numpy as np
import pytest

from coffeebot.scenario.report import Contact
from coffeebot.sim.world import RobotSpec, Surfaces
from coffeebot.sim.world.contact import MOVING_MM_S, body_region, contact_normal, judge_contact
from coffeebot.sim.world.robot import BodyState
from coffeebot.sim.world.world import Collision

ROBOT = RobotSpec()  # 610 x 510 mm, driven axle 150 mm ahead of the centre
FRONT_X = ROBOT.length_mm / 2
LEFT_Y = ROBOT.width_mm / 2


def body(speed: float = 0.0, yaw_rate: float = 0.0, theta: float = 0.0) -> BodyState:
    return BodyState(0.0, 0.0, theta, speed_mm_s=speed, yaw_rate_rad_s=yaw_rate)


def test_driving_into_a_standing_obstacle_is_robot_caused() -> None:
    j = judge_contact("box", (FRONT_X, 0.0), body(speed=600.0), ROBOT)
    assert j.region == "front"
    assert j.cause == "robot_caused" and j.robot_moving_towards
    assert j.closing_mm_s == pytest.approx(600.0)


def test_a_person_walking_into_a_standing_robot_is_counted_apart() -> None:
    j = judge_contact("person torso", (FRONT_X, 0.0), body(), ROBOT, (-1200.0, 0.0))
    assert j.cause == "walked_into_robot" and not j.robot_moving_towards
    assert j.object_towards_mm_s == pytest.approx(1200.0)


def test_a_person_walking_into_a_retreating_robot_is_counted_apart() -> None:
    j = judge_contact("person leg", (FRONT_X, 0.0), body(speed=-200.0), ROBOT, (-1000.0, 0.0))
    assert j.cause == "walked_into_robot"
    assert j.robot_towards_mm_s == pytest.approx(-200.0)
    assert j.closing_mm_s == pytest.approx(800.0)


def test_braking_but_still_moving_towards_the_person_is_robot_caused() -> None:
    """A slow robot still moving into someone who walks into it too: the robot's share is
    what the standard blames."""
    j = judge_contact("person torso", (FRONT_X, 0.0), body(speed=80.0), ROBOT, (-1600.0, 0.0))
    assert j.cause == "robot_caused"


def test_the_corner_of_a_robot_turning_on_the_spot_moves_into_what_it_touches() -> None:
    """Turning left about the axle, the rear-right corner swings right and back: a pole there
    is struck although the body's forward speed is zero."""
    corner = (-FRONT_X, -LEFT_Y)
    j = judge_contact("pole", corner, body(yaw_rate=math.radians(45.0)), ROBOT)
    assert j.region == "rear-right corner"
    assert j.cause == "robot_caused" and j.robot_towards_mm_s > 100.0


def test_someone_walking_into_the_side_of_a_robot_driving_past_is_counted_apart() -> None:
    """The robot moves along its side, not towards the person: it is the person who closes."""
    j = judge_contact("person leg", (0.0, LEFT_Y), body(speed=800.0), ROBOT, (0.0, -1000.0))
    assert j.region == "left side"
    assert j.robot_towards_mm_s == pytest.approx(0.0, abs=1e-9)
    assert j.cause == "walked_into_robot"


def test_a_contact_nobody_walked_into_is_the_robots() -> None:
    """Neither moving towards the other (a standing robot, a standing box): the robot's."""
    assert judge_contact("box", (FRONT_X, 0.0), body(), ROBOT).cause == "robot_caused"


def test_the_judgement_follows_the_heading() -> None:
    """Facing +y, the body's front is at y = +305 and its left side at x = -255."""
    heading = body(speed=500.0, theta=math.pi / 2)
    assert judge_contact("box", (0.0, FRONT_X), heading, ROBOT).region == "front"
    left = judge_contact("box", (-LEFT_Y, 0.0), heading, ROBOT)
    assert left.region == "left side" and left.robot_towards_mm_s == pytest.approx(0.0, abs=1e-6)


def test_the_normal_comes_from_the_touched_shape_where_there_is_one() -> None:
    """A person beside the rear-right corner, stepping towards it: the body turning left
    swings that corner into them. The corner's diagonal would say the corner moves away (the
    body drives on); the torso's axis, straight to the right, says it moves into them."""
    torso_at = (-FRONT_X + 20.0, -LEFT_Y - 180.0)
    torso = Surfaces(np.zeros((0, 6)), (), np.array([[*torso_at, 180.0, 850.0, 1750.0]]), ("t",))
    point = (-FRONT_X + 20.0, -LEFT_Y)
    turning = body(speed=500.0, yaw_rate=0.1)
    assert contact_normal(torso, point, turning) == pytest.approx((0.0, -1.0))
    guessed = judge_contact("person torso", point, turning, ROBOT, (0.0, 100.0))
    judged = judge_contact("person torso", point, turning, ROBOT, (0.0, 100.0), torso)
    assert guessed.cause == "walked_into_robot"
    assert judged.cause == "robot_caused" and judged.robot_towards_mm_s > 20.0


def test_a_touched_wall_faces_away_from_the_body() -> None:
    wall = Surfaces(
        np.array([[-1000.0, LEFT_Y, 1000.0, LEFT_Y, 0.0, 2700.0]]), ("w",), np.zeros((0, 5)), ()
    )
    assert contact_normal(wall, (0.0, LEFT_Y), body()) == pytest.approx((0.0, 1.0))


@pytest.mark.parametrize(
    ("x", "y", "region"),
    [
        (FRONT_X, 0.0, "front"),
        (-FRONT_X, 10.0, "rear"),
        (0.0, LEFT_Y, "left side"),
        (100.0, -LEFT_Y, "right side"),
        (FRONT_X - 10.0, LEFT_Y - 10.0, "front-left corner"),
        (-FRONT_X, -LEFT_Y + 30.0, "rear-right corner"),
    ],
)
def test_body_regions(x: float, y: float, region: str) -> None:
    assert body_region(x, y, ROBOT)[0] == region


def test_a_report_counts_a_corner_struck_turning_on_the_spot_as_moving() -> None:
    """A robot turning on the spot at 22 deg/s strikes the wall with its rear corner while
    its centre moves at under 1 mm/s: the run's report says how fast the corner came, which
    is what the delivery benchmark counts a contact "with the robot moving" by."""
    turning = BodyState(24998.2, -537.0, 2.934, speed_mm_s=0.6, yaw_rate_rad_s=-0.385)
    struck = Collision(2.33, 2, "hallway right wall", 25243.2, -850.0, 0.6, turning)
    contact = Contact.of(struck, ROBOT)
    assert contact.speed_mm_s < MOVING_MM_S
    assert contact.towards_mm_s > MOVING_MM_S
