"""The customer's timeline and arrival estimate, from a stored order and the board."""

from __future__ import annotations

import pytest

from coffeebot.board import Board
from coffeebot.messages import (
    ALL_TOPICS,
    CURRENT_STATE,
    DELIVERY_STATUS,
    ELEVATOR_REQUEST,
    ELEVATOR_STATE,
    ROUTE,
    CurrentState,
    DeliveryProblem,
    DeliveryUpdate,
    ElevatorRequest,
    ElevatorState,
    OrderStatus,
    PlannedRoute,
    PoseEstimate,
    RouteLeg,
)
from coffeebot.store import Order
from coffeebot.web.eta import Pace, arrival_in_s, remaining_on
from coffeebot.web.timeline import PROBLEM_TEXT, TimelineMaker

PACE = Pace(travel_mm_s=500.0, elevator_ride_s=60.0, pickup_timeout_s=180.0)
FLOORS = {"207": 2, "307": 3}


def order(status: OrderStatus, room: str = "307", detail: str = "", ahead: int = 0) -> Order:
    return Order(
        id="abc",
        seq=1,
        room=room,
        drink="tea",
        name="Ada",
        notes="",
        status=status,
        detail=detail,
        created_at=1000.0,
        updated_at=1000.0,
        ahead=ahead,
    )


def at(board: Board, x: float, floor: int) -> None:
    pose = PoseEstimate(
        x_mm=x,
        y_mm=0,
        heading_deg=0,
        floor=floor,
        sigma_x_mm=1,
        sigma_y_mm=1,
        sigma_heading_deg=1,
    )
    board.publish(CURRENT_STATE, CurrentState(pose=pose))


@pytest.fixture
def board() -> Board:
    return Board(ALL_TOPICS)


@pytest.fixture
def maker(board: Board) -> TimelineMaker:
    return TimelineMaker(board, FLOORS.get, base_floor=2, pace=PACE, wall_clock=lambda: 1030.0)


def test_the_remaining_route_is_measured_from_the_nearest_point() -> None:
    points = [(0.0, 0.0), (10_000.0, 0.0), (10_000.0, 5_000.0)]
    assert remaining_on(points, 4_000, 300) == pytest.approx(11_000)
    assert remaining_on(points, 10_200, 4_000) == pytest.approx(1_000)
    assert remaining_on(points[:1], 0, 0) == 0.0


def test_arrival_adds_what_is_left_and_each_ride_ahead() -> None:
    route = PlannedRoute(
        order_id="abc",
        to="307",
        legs=[
            RouteLeg(floor=2, points=[(0, 0), (20_000, 0)]),
            RouteLeg(floor=3, points=[(20_000, 0), (30_000, 0)]),
        ],
    )
    pose = PoseEstimate(
        x_mm=5_000,
        y_mm=0,
        heading_deg=0,
        floor=2,
        sigma_x_mm=1,
        sigma_y_mm=1,
        sigma_heading_deg=1,
    )
    # 15 m left on floor 2 and 10 m on floor 3 at 0.5 m/s, and one ride.
    assert arrival_in_s(route, pose, PACE) == pytest.approx(50 + 60)
    upstairs = pose.model_copy(update={"floor": 3, "x_mm": 25_000})
    assert arrival_in_s(route, upstairs, PACE) == pytest.approx(10)
    assert arrival_in_s(route, pose.model_copy(update={"floor": 4}), PACE) is None


def test_queued_says_how_many_are_ahead_in_words(maker: TimelineMaker) -> None:
    assert maker.timeline(order(OrderStatus.QUEUED, ahead=1)).detail == "1 order ahead of yours."
    assert maker.timeline(order(OrderStatus.QUEUED, ahead=2)).detail == "2 orders ahead of yours."
    assert maker.timeline(order(OrderStatus.QUEUED, ahead=0)).detail == "Yours is next."


def test_an_order_upstairs_has_the_elevator_as_steps(board: Board, maker: TimelineMaker) -> None:
    at(board, 10_000, 2)
    steps = maker.timeline(order(OrderStatus.ON_THE_WAY)).steps
    assert [s.key for s in steps] == [
        "queued",
        "preparing",
        "on_the_way",
        "elevator",
        "on_floor",
        "arrived",
        "delivered",
    ]
    assert [s.state for s in steps][:4] == ["done", "done", "current", "todo"]
    assert steps[4].label == "On floor 3"
    # Riding: the customer is told, with the floor.
    board.publish(ELEVATOR_REQUEST, ElevatorRequest(action="send", floor=3))
    board.publish(ELEVATOR_STATE, ElevatorState(car_floor=2, doors="closed", moving=True))
    riding = maker.timeline(order(OrderStatus.WAITING_FOR_ELEVATOR))
    assert riding.headline == "Taking the elevator"
    assert riding.detail == "Riding the elevator to floor 3."
    # Out on floor 3 and on the way again: the ride is behind.
    at(board, 21_000, 3)
    states = [s.state for s in maker.timeline(order(OrderStatus.ON_THE_WAY)).steps]
    assert states[3:5] == ["done", "current"]
    # On the robot's floor: no elevator at all.
    assert "elevator" not in [s.key for s in maker.timeline(order(OrderStatus.QUEUED, "207")).steps]


def test_an_elevator_wait_without_known_floors_still_has_its_step(board: Board) -> None:
    unplanned = TimelineMaker(board, {}.get, base_floor=None, pace=PACE)
    steps = unplanned.timeline(order(OrderStatus.WAITING_FOR_ELEVATOR)).steps
    assert [(s.key, s.state) for s in steps] == [
        ("queued", "done"),
        ("preparing", "done"),
        ("on_the_way", "done"),
        ("elevator", "current"),
        ("arrived", "todo"),
        ("delivered", "todo"),
    ]


def test_on_the_way_estimates_arrival_from_the_route(board: Board, maker: TimelineMaker) -> None:
    at(board, 10_000, 3)
    legs = [RouteLeg(floor=3, points=[(0, 0), (40_000, 0)])]
    board.publish(ROUTE, PlannedRoute(order_id="abc", to="307", legs=legs))
    timeline = maker.timeline(order(OrderStatus.ON_THE_WAY))
    assert timeline.arrival_in_s == pytest.approx(60)
    assert timeline.detail == "The robot is carrying your tea to 307."
    # Another order's route says nothing about this one.
    board.publish(ROUTE, PlannedRoute(order_id="xyz", to="207", legs=legs))
    assert maker.timeline(order(OrderStatus.ON_THE_WAY)).arrival_in_s is None


def test_at_the_door_the_countdown_runs_from_arrival(maker: TimelineMaker) -> None:
    timeline = maker.timeline(order(OrderStatus.ARRIVED, detail="at the door of 307 (-7 mm)"))
    assert timeline.pickup_left_s == pytest.approx(150)  # 180 s from 1000, now 1030
    assert "mm" not in timeline.detail and timeline.headline == "At your door"


def test_problems_are_said_in_plain_words(board: Board, maker: TimelineMaker) -> None:
    blocked = DeliveryUpdate(
        order_id="abc",
        status=OrderStatus.ON_THE_WAY,
        detail="blocked: no progress for 31 s (obstacle 420 mm ahead)",
        problem=DeliveryProblem.BLOCKED,
    )
    board.publish(DELIVERY_STATUS, blocked)
    timeline = maker.timeline(order(OrderStatus.ON_THE_WAY))
    assert timeline.detail == "Something is in the robot's way; it waits for the way to clear."
    failed = blocked.model_copy(
        update={"status": OrderStatus.FAILED, "problem": DeliveryProblem.NOT_PICKED_UP}
    )
    board.publish(DELIVERY_STATUS, failed)
    ended = maker.timeline(
        order(OrderStatus.FAILED, detail="nobody picked the cup up within 180 s")
    )
    assert ended.detail.startswith("Nobody took the cup in time")
    assert [(s.label, s.state) for s in ended.steps] == [
        ("Ordered", "done"),
        ("Not delivered", "ended"),
    ]
    assert ended.final


def test_a_silent_motor_controller_is_said_as_such(board: Board, maker: TimelineMaker) -> None:
    held = DeliveryUpdate(
        order_id="abc",
        status=OrderStatus.ON_THE_WAY,
        detail="stopped: no telemetry from the motor controller",
        problem=DeliveryProblem.MOTOR_CONTROLLER,
    )
    board.publish(DELIVERY_STATUS, held)
    timeline = maker.timeline(order(OrderStatus.ON_THE_WAY))
    assert timeline.detail.startswith("The robot has stopped: its motors do not answer")
    board.publish(DELIVERY_STATUS, held.model_copy(update={"status": OrderStatus.FAILED}))
    ended = maker.timeline(order(OrderStatus.FAILED, detail="stopped for 60 s"))
    assert ended.detail == "The robot's motors stopped answering; staff will check."


def test_every_delivery_problem_has_plain_words() -> None:
    assert set(PROBLEM_TEXT) == set(DeliveryProblem)


def test_a_failure_after_a_restart_keeps_the_stored_reason(maker: TimelineMaker) -> None:
    detail = "the robot restarted while the order was on the way; staff will check on the cup"
    assert maker.timeline(order(OrderStatus.FAILED, detail=detail)).detail == (
        "The robot restarted while the order was on the way; staff will check on the cup."
    )


def test_who_cancelled_is_said(maker: TimelineMaker) -> None:
    mine = maker.timeline(order(OrderStatus.CANCELLED, detail="cancelled by the customer"))
    assert mine.detail == "You cancelled this order."
    staff = maker.timeline(order(OrderStatus.CANCELLED, detail="cancelled by an operator"))
    assert staff.detail == "Staff cancelled this order."
