"""The product's errors: one family, so a caller can catch coffeebot's own errors apart from
Python's and the libraries'.

:class:`CoffeebotError` is the base of every error raised on purpose; its children name the
part that raised it. The specific errors live next to their code and derive from one of these
(``FloorPlanError`` from :class:`ConfigError`, ``DeviceError`` from :class:`HardwareError`,
``OrderNotFound`` from :class:`OrderError`, ...). Where a standard base was part of the
contract it is kept beside: a configuration error is still a ``ValueError``, and a device
that answers wrongly is still an ``OSError``, handled with the ones that do not answer.
"""

from __future__ import annotations


class CoffeebotError(Exception):
    """Base of every error coffeebot raises on purpose."""


class ConfigError(CoffeebotError, ValueError):
    """A configuration, floor-plan or scenario file that cannot be used, with the reason."""


class BoardError(CoffeebotError):
    """The board refused a publish or a read (an undeclared topic, the wrong model), or a
    recording of it cannot be used."""


class HardwareError(CoffeebotError):
    """A device that cannot be used: it answers wrongly, or fails its check."""


class StoreError(CoffeebotError):
    """The order database cannot be opened, read or written (locked by another process, read
    only, full, not a database), naming the file and what is wrong."""


class OrderError(CoffeebotError):
    """An order request that cannot be carried out as asked (the order is in a state that
    does not allow it)."""


class DeliveryError(CoffeebotError):
    """A delivery that cannot go on."""
