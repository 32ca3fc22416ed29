"""The customer's order as a timeline: the steps it goes through, where it is now, what is
happening in plain words, when it should arrive and how long the robot waits at the door.

Navigation's details are written for staff and logs ("at the door of 207 (-7 mm)"); here
each status is said to the person who ordered, from the stored order and what the board
says about the delivery that is out (navigation's report, the elevator, the route).
"""

from __future__ import annotations

import time
from collections.abc import Callable
from enum import Enum
from typing import Literal

from pydantic import BaseModel

from coffeebot.board import BoardView
from coffeebot.messages import (
    CURRENT_STATE,
    DELIVERY_STATUS,
    ELEVATOR_REQUEST,
    ELEVATOR_STATE,
    ROUTE,
    DeliveryProblem,
    DeliveryUpdate,
    OrderStatus,
)
from coffeebot.store import Order
from coffeebot.web.eta import Pace, arrival_in_s
from coffeebot.web.wording import STATUS_TEXT, orders_ahead

StepState = Literal["done", "current", "todo", "ended"]


class Ride(Enum):
    """Whether an order's way includes the elevator, and whether the ride is behind it."""

    NONE = "none"
    AHEAD = "ahead"
    DONE = "done"


class Step(BaseModel):
    key: str
    label: str
    state: StepState


class Timeline(BaseModel):
    """Everything the status page shows of an order at one moment."""

    order_id: str
    status: OrderStatus
    headline: str
    detail: str
    steps: list[Step]
    arrival_in_s: float | None = None
    """The estimate of arrival while the robot carries the order; None otherwise."""
    pickup_left_s: float | None = None
    """While at the door: how long the robot still waits for the customer."""
    final: bool = False


PROBLEM_TEXT: dict[DeliveryProblem, str] = {
    DeliveryProblem.CUP_NOT_LOADED: "The tea room could not put your cup on the robot in time.",
    DeliveryProblem.NOT_PICKED_UP: (
        "Nobody took the cup in time, so the robot took it back to the tea room."
    ),
    DeliveryProblem.UNKNOWN_ROOM: "The robot does not know the way to this office.",
    DeliveryProblem.LOST: "The robot lost track of where it is; staff will check on it.",
    DeliveryProblem.BLOCKED: "The robot could not get past something in its way.",
    DeliveryProblem.ELEVATOR: "The elevator did not answer the robot.",
    DeliveryProblem.MOTION_SILENT: "The robot stopped answering; staff will check on it.",
    DeliveryProblem.MOTOR_CONTROLLER: "The robot's motors stopped answering; staff will check.",
}


def _sentence(text: str) -> str:
    text = text.strip()
    if not text:
        return ""
    text = text[0].upper() + text[1:]
    return text if text.endswith((".", "!", "?")) else text + "."


def _steps(status: OrderStatus, room_floor: int | None, ride: Ride) -> list[Step]:
    """The steps of this order with where it stands; an order to another floor than the tea
    room's has the elevator and the other floor's hallway as steps of their own. A robot
    waiting for the elevator has that step even when the floors are not known here."""
    keys = [("queued", "Ordered"), ("preparing", "In the tea room"), ("on_the_way", "On the way")]
    if ride is not Ride.NONE or status is OrderStatus.WAITING_FOR_ELEVATOR:
        keys.append(("elevator", "In the elevator"))
    if ride is not Ride.NONE:
        keys.append(("on_floor", f"On floor {room_floor}"))
    keys += [("arrived", "At your door"), ("delivered", "Delivered")]
    if status in (OrderStatus.CANCELLED, OrderStatus.FAILED):
        # How far it got before it ended is not kept: say that it was ordered and ended.
        end = "Cancelled" if status is OrderStatus.CANCELLED else "Not delivered"
        return [
            Step(key="queued", label="Ordered", state="done"),
            Step(key=status.value, label=end, state="ended"),
        ]
    current = {
        OrderStatus.WAITING_FOR_ELEVATOR: "elevator",
        OrderStatus.ON_THE_WAY: "on_floor" if ride is Ride.DONE else "on_the_way",
    }.get(status, status.value)
    at = [k for k, _ in keys].index(current)
    steps = []
    for i, (key, label) in enumerate(keys):
        state: StepState = "done" if i < at else "current" if i == at else "todo"
        if key == "delivered" and status is OrderStatus.DELIVERED:
            state = "done"
        steps.append(Step(key=key, label=label, state=state))
    return steps


class TimelineMaker:
    """Builds timelines from the stored order and the board; one per web app."""

    def __init__(
        self,
        board: BoardView,
        room_floor: Callable[[str], int | None],
        base_floor: int | None,
        pace: Pace,
        wall_clock: Callable[[], float] = time.time,
    ) -> None:
        self.board = board
        self.room_floor = room_floor
        self.base_floor = base_floor
        self.pace = pace
        self.wall_clock = wall_clock

    def _report(self, order: Order) -> DeliveryUpdate | None:
        """Navigation's latest word on this order, if it is about this one."""
        latest = self.board.latest(DELIVERY_STATUS)
        if latest is None or latest.msg.order_id != order.id:
            return None
        return latest.msg

    def timeline(self, order: Order) -> Timeline:
        floor = self.room_floor(order.room)
        report = self._report(order)
        problem = None if report is None else report.problem
        detail, arrival, pickup_left = "", None, None
        status = order.status
        if status is OrderStatus.QUEUED:
            detail = orders_ahead(order.ahead or 0)
        elif status is OrderStatus.PREPARING:
            if report is not None and report.ready_for_cup:
                detail = (
                    f"The robot is in the tea room; staff are putting your {order.drink} on it."
                )
            else:
                detail = "The robot is getting ready in the tea room."
        elif status is OrderStatus.ON_THE_WAY:
            if problem is DeliveryProblem.BLOCKED:
                detail = "Something is in the robot's way; it waits for the way to clear."
            elif problem is DeliveryProblem.MOTOR_CONTROLLER:
                detail = "The robot has stopped: its motors do not answer; staff have been told."
            else:
                detail = f"The robot is carrying your {order.drink} to {order.room}."
            arrival = self._arrival(order)
        elif status is OrderStatus.WAITING_FOR_ELEVATOR:
            detail = self._elevator(problem, floor)
            arrival = self._arrival(order)
        elif status is OrderStatus.ARRIVED:
            detail = f"Please take your {order.drink} from the robot, then press the button."
            deadline = order.updated_at + self.pace.pickup_timeout_s
            pickup_left = max(0.0, deadline - self.wall_clock())
        elif status is OrderStatus.DELIVERED:
            detail = f"Enjoy your {order.drink}."
        elif status is OrderStatus.CANCELLED:
            detail = (
                "You cancelled this order."
                if order.detail == "cancelled by the customer"
                else "Staff cancelled this order."
            )
        elif status is OrderStatus.FAILED:
            detail = PROBLEM_TEXT.get(problem, "") if problem else _sentence(order.detail)
        return Timeline(
            order_id=order.id,
            status=status,
            headline=STATUS_TEXT[status],
            detail=detail,
            steps=_steps(status, floor, self._ride(floor)),
            arrival_in_s=arrival,
            pickup_left_s=pickup_left,
            final=status.final,
        )

    def _ride(self, room_floor: int | None) -> Ride:
        if room_floor is None or self.base_floor is None or room_floor == self.base_floor:
            return Ride.NONE
        state = self.board.latest(CURRENT_STATE)
        here = None if state is None else state.msg.pose.floor
        return Ride.DONE if here == room_floor else Ride.AHEAD

    def _elevator(self, problem: DeliveryProblem | None, room_floor: int | None) -> str:
        if problem is DeliveryProblem.ELEVATOR:
            return "The elevator does not answer; staff have been asked to help."
        state, request = self.board.latest(ELEVATOR_STATE), self.board.latest(ELEVATOR_REQUEST)
        moving = state is not None and state.msg.moving
        if moving and request is not None and request.msg.action == "send":
            return f"Riding the elevator to floor {request.msg.floor}."
        pose = self.board.latest(CURRENT_STATE)
        here = None if pose is None else pose.msg.pose.floor
        if here is not None and here != room_floor:
            return f"Waiting for the elevator on floor {here}."
        return f"Getting out of the elevator on floor {here}."

    def _arrival(self, order: Order) -> float | None:
        route, state = self.board.latest(ROUTE), self.board.latest(CURRENT_STATE)
        if route is None or state is None or route.msg.order_id != order.id:
            return None
        if not state.msg.pose.initialised:
            return None
        return arrival_in_s(route.msg, state.msg.pose, self.pace)
