"""The delivery lifecycle as navigation drives it, one dispatched order at a time.

The orders module owns ``queued`` and stores every status; navigation reports the rest, and
this machine decides which event means what in which status so each report is made once
and in order: the cup loaded in ``preparing`` means leaving; a pickup only counts once
``arrived``; a cancel or a failure ends the order from any status before the end. After the
end the robot still has to go back to base; :attr:`returning` says so.
"""

from __future__ import annotations

from coffeebot.messages import DeliveryProblem, DeliveryUpdate, OrderStatus

MOVING = (OrderStatus.ON_THE_WAY, OrderStatus.WAITING_FOR_ELEVATOR)


class DeliveryLifecycle:
    """Status of one delivery; every method returns the update to publish, or None."""

    def __init__(self, order_id: str, room: str) -> None:
        self.order_id = order_id
        self.room = room
        self.status = OrderStatus.PREPARING
        self.left_base = False

    def _to(
        self,
        status: OrderStatus,
        detail: str,
        problem: DeliveryProblem | None = None,
        ready_for_cup: bool = False,
    ) -> DeliveryUpdate:
        self.status = status
        return DeliveryUpdate(
            order_id=self.order_id,
            status=status,
            detail=detail,
            problem=problem,
            ready_for_cup=ready_for_cup,
        )

    @property
    def final(self) -> bool:
        return self.status.final

    @property
    def returning(self) -> bool:
        """The order has ended but the robot has left base: it must drive back."""
        return self.final and self.left_base

    def ready_for_cup(self) -> DeliveryUpdate | None:
        if self.status is not OrderStatus.PREPARING or self.left_base:
            return None
        return self._to(
            OrderStatus.PREPARING,
            "the robot is in the tea room, waiting for the cup",
            ready_for_cup=True,
        )

    def cup_loaded(self) -> DeliveryUpdate | None:
        if self.status is not OrderStatus.PREPARING:
            return None
        self.left_base = True
        return self._to(OrderStatus.ON_THE_WAY, f"leaving the tea room for {self.room}")

    def progress(
        self, detail: str, problem: DeliveryProblem | None = None
    ) -> DeliveryUpdate | None:
        """On the way again (after the elevator), or with news such as "blocked"."""
        if self.status not in MOVING:
            return None
        return self._to(OrderStatus.ON_THE_WAY, detail, problem)

    def waiting_for_elevator(
        self, detail: str, problem: DeliveryProblem | None = None
    ) -> DeliveryUpdate | None:
        if self.status not in MOVING:
            return None
        return self._to(OrderStatus.WAITING_FOR_ELEVATOR, detail, problem)

    def arrived(self, detail: str) -> DeliveryUpdate | None:
        if self.status not in MOVING:
            return None
        return self._to(OrderStatus.ARRIVED, detail)

    def pickup_confirmed(self) -> DeliveryUpdate | None:
        if self.status is not OrderStatus.ARRIVED:
            return None
        return self._to(OrderStatus.DELIVERED, f"picked up at {self.room}")

    def cancel(self, detail: str = "cancelled by an operator") -> DeliveryUpdate | None:
        if self.final:
            return None
        return self._to(OrderStatus.CANCELLED, detail)

    def fail(self, reason: str, problem: DeliveryProblem) -> DeliveryUpdate | None:
        if self.final:
            return None
        return self._to(OrderStatus.FAILED, reason, problem)
