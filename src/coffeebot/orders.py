"""What a front end asks of whoever keeps the orders, and what can go wrong.

The web app talks to orders only through :class:`Orders`: on one robot the orders module
(:class:`~coffeebot.modules.orders.OrdersModule`) implements it over its SQLite queue; in a
fleet the dispatcher implements the same four calls. The errors say what went wrong in the
orders' own terms; the web maps them to HTTP answers in one place (``web/app.py``).
"""

from __future__ import annotations

from typing import Protocol

from coffeebot.errors import OrderError
from coffeebot.store import NewOrder, Order


class OrderNotFound(OrderError):
    """No order has that id."""


class OrdersUnavailable(OrderError):
    """The orders cannot be reached now (starting up, or restarting after a crash)."""


class Orders(Protocol):
    async def place(self, new: NewOrder, client: str) -> Order:
        """Queue a validated order from ``client`` (who the rate limit and the log name)."""
        ...

    async def get(self, order_id: str) -> Order:
        """The order as it stands; :class:`OrderNotFound` if there is none."""
        ...

    async def cancel(self, order_id: str, detail: str = "cancelled by the customer") -> Order:
        """Cancel an order still waiting in the queue; :class:`OrderError` once it is out."""
        ...

    async def active(self) -> list[Order]:
        """Every order that has not ended, in order of arrival, with its place in the queue."""
        ...
