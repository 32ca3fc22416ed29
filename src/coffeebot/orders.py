"""What a front end asks of whoever keeps the orders, and what can go wrong.

The web app talks to orders only through :class:`Orders`: on one robot the orders module
(:class:`~coffeebot.modules.orders.OrdersModule`) implements it over its SQLite queue; in a
fleet the dispatcher implements the same calls. The errors say what went wrong in the
orders' own terms; the web maps them to HTTP answers in one place (``web/app.py``).

An order's id identifies it (operators, the board and the logs see it); its key, handed to
the customer once when the order is placed, is what authorizes the customer to follow,
cancel and confirm it (:meth:`Orders.authorize`).
"""

from __future__ import annotations

from typing import Protocol

from coffeebot.errors import OrderError
from coffeebot.store import NewOrder, Order, PlacedOrder


class OrderNotFound(OrderError):
    """No order has that id."""


class OrdersUnavailable(OrderError):
    """The orders cannot be reached now (starting up, restarting after a crash, or the order
    database cannot be used)."""


class WrongOrderKey(OrderError):
    """The key given for an order is missing or is not that order's key."""


class Orders(Protocol):
    async def place(self, new: NewOrder, client: str) -> PlacedOrder:
        """Queue a validated order from ``client`` (who the rate limit and the log name); the
        answer carries the order's key, the only time it is shown."""
        ...

    async def get(self, order_id: str) -> Order:
        """The order as it stands; :class:`OrderNotFound` if there is none."""
        ...

    async def authorize(self, order_id: str, key: str) -> Order:
        """The order if ``key`` is its key; :class:`WrongOrderKey` if not."""
        ...

    async def cancel(self, order_id: str, detail: str = "cancelled by the customer") -> Order:
        """Cancel an order still waiting in the queue; :class:`OrderError` once it is out."""
        ...

    async def active(self) -> list[Order]:
        """Every order that has not ended, in order of arrival, with its place in the queue."""
        ...
