"""The dispatcher's pure rules: leases of shared places, who takes which order, and what a
message on the broker may look like."""

from __future__ import annotations

from pathlib import Path

import pytest

from coffeebot.config import load_robot_config
from coffeebot.fleet.assignment import FreeRobot, WaitingOrder, completion_s, greedy, joint
from coffeebot.fleet.estimates import TravelTimes
from coffeebot.fleet.leases import LeaseBook
from coffeebot.fleet.protocol import (
    Assignment,
    BadMessage,
    InstantAction,
    decode,
    encode,
    parse_robot_topic,
    robot_topic,
)
from coffeebot.floorplan import load_floorplan
from coffeebot.web.eta import Pace

ROOT = Path(__file__).resolve().parents[2]


def test_a_place_is_one_robots_and_goes_to_the_first_who_asked_when_it_frees() -> None:
    book = LeaseBook(duration_s=30.0)
    assert book.request("r1", "elevator", 0.0).granted
    assert not book.request("r2", "elevator", 1.0).granted
    assert not book.request("r3", "elevator", 2.0).granted
    refused = book.request("r3", "elevator", 3.0)
    assert not refused.granted and refused.holder == "r1"
    book.release("r1", "elevator")
    assert not book.request("r3", "elevator", 4.0).granted, "r2 asked first"
    assert book.request("r2", "elevator", 5.0).granted
    assert book.holder("elevator", 5.0) == "r2"
    assert book.request("r1", "loading_spot", 5.0).granted, "places are independent"


def test_a_lease_not_renewed_expires_and_a_renewed_one_does_not() -> None:
    book = LeaseBook(duration_s=10.0)
    assert book.request("r1", "elevator", 0.0).granted
    assert book.request("r1", "elevator", 8.0).granted  # renewed until 18
    assert not book.request("r2", "elevator", 15.0).granted
    assert book.holder("elevator", 17.9) == "r1"
    assert book.holder("elevator", 18.0) is None, "a holder that stops asking loses it"
    assert book.request("r2", "elevator", 18.0).granted


def test_a_robot_that_is_gone_frees_what_it_held_and_leaves_the_queue() -> None:
    book = LeaseBook(duration_s=60.0)
    book.request("r1", "loading_spot", 0.0)
    book.request("r2", "loading_spot", 0.0)
    book.request("r3", "loading_spot", 0.0)
    book.forget("r1")
    book.forget("r2")
    assert book.request("r3", "loading_spot", 1.0).granted


def test_joint_assignment_spares_the_longest_wait_where_first_come_does_not() -> None:
    # "b" has waited long and goes far; "a" is new and near. First come gives the robot at
    # home to the first in the list, "a"; the joint assignment gives it to "b".
    orders = [WaitingOrder("a", "near", waited_s=0.0), WaitingOrder("b", "far", waited_s=300.0)]
    robots = [FreeRobot("home", 0.0), FreeRobot("returning", 100.0)]
    to_room = {"near": 10.0, "far": 200.0}
    cost = completion_s(20.0, to_room.__getitem__)

    def longest_wait(pairs: list[tuple[WaitingOrder, FreeRobot]]) -> float:
        return max(o.waited_s + cost(o, r) for o, r in pairs)

    first_come = greedy(orders, robots, cost)
    assert [(o.order_id, r.robot) for o, r in first_come] == [("a", "home"), ("b", "returning")]
    best = joint(orders, robots, cost)
    assert {(o.order_id, r.robot) for o, r in best} == {("a", "returning"), ("b", "home")}
    assert longest_wait(best) < longest_wait(first_come)


def test_with_more_orders_than_robots_the_oldest_are_served() -> None:
    orders = [WaitingOrder(str(i), "near") for i in range(5)]
    robots = [FreeRobot("r1", 0.0), FreeRobot("r2", 5.0)]
    cost = completion_s(20.0, lambda room: 10.0)
    assert {o.order_id for o, _ in joint(orders, robots, cost)} == {"0", "1"}
    assert {o.order_id for o, _ in greedy(orders, robots, cost)} == {"0", "1"}


def test_travel_times_grow_with_the_route_and_the_elevator() -> None:
    plan = load_floorplan(ROOT / "floorplans" / "cs-building.toml")
    times = TravelTimes(plan, load_robot_config(ROOT / "boards" / "coffeebot-v1.toml"), Pace())
    near, far, upstairs = times.base_to("212"), times.base_to("201"), times.base_to("308")
    assert 0 < near < far
    assert upstairs > Pace().elevator_ride_s


def test_messages_round_trip_and_bad_ones_name_the_field() -> None:
    assignment = Assignment(assignment_id="x1", order_id="o1", room="205", drink="latte")
    topic = robot_topic("robot-1", "assignment")
    assert decode(Assignment, topic, encode(assignment)) == assignment
    with pytest.raises(BadMessage, match="kind"):
        decode(InstantAction, topic, b'{"action_id": "a", "kind": "explode"}')
    with pytest.raises(BadMessage, match="payload"):
        decode(InstantAction, topic, b"not json")
    with pytest.raises(BadMessage, match="unexpected"):
        decode(
            Assignment,
            topic,
            b'{"assignment_id":"x","order_id":"o","room":"1","drink":"d","unexpected":1}',
        )
    assert parse_robot_topic(topic) == ("robot-1", "assignment")
    for foreign in ("coffeebot/v2/robots/r/state", "coffeebot/v1/robots/R#/state", "other"):
        with pytest.raises(BadMessage):
            parse_robot_topic(foreign)
