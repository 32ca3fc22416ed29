"""What the web app is built from: plain data and narrow interfaces, no daemon internals.

The orders come in as the orders protocol (the robot's orders module, or a fleet's
dispatcher), the board as a read-only view for the inspector, and the floor plan, the poses
and the module list as data or callables, so the app runs the same under the daemon, in API
tests on a bare board and in the benchmark. The board traffic the web itself makes goes
through the ``bus`` handed to :func:`~coffeebot.web.app.create_app`.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from typing import Protocol, TypeVar

from pydantic import BaseModel

from coffeebot.board import BoardView, Envelope, Subscription, Topic
from coffeebot.config import GeometryConfig, TofSensorConfig, WebConfig
from coffeebot.cpu import CpuLedger
from coffeebot.floorplan import FloorPlan
from coffeebot.messages import Health
from coffeebot.modules.base import Module
from coffeebot.orders import Orders
from coffeebot.web.livemap import PoseSource

M = TypeVar("M", bound=BaseModel)


class BoardIO(Protocol):
    """The web's own board traffic (a ``ModuleBoard`` under the daemon, a ``Board`` in tests)."""

    def publish(self, topic: Topic[M], msg: M) -> Envelope[M]: ...

    def subscribe(self, topic: Topic[M]) -> Subscription[M]: ...


class RoomChoice(BaseModel):
    """An office a customer can order to, from the floor plan."""

    id: str
    floor: int
    label: str = ""


@dataclass(frozen=True)
class WebDeps:
    """Everything ``create_app`` needs besides the bus."""

    board: BoardView
    """Read only, for the inspector: statistics and latest values of every topic."""
    orders: Orders
    rooms: Sequence[RoomChoice]
    config: WebConfig = field(default_factory=WebConfig)
    operator_token: str | None = None
    modules: Callable[[], Sequence[Module]] = tuple
    """The modules the inspector draws as a graph (``Daemon.modules``)."""
    floor_svg: Callable[[int], str | None] | None = None
    poses: PoseSource | None = None
    sensors: Sequence[TofSensorConfig] = ()
    geometry: GeometryConfig = field(default_factory=GeometryConfig)
    health: Callable[[], Sequence[Health]] | None = None
    """Module health as the supervisor sees it now (``Daemon.health``)."""
    cpu: Callable[[], CpuLedger] | None = None
    """CPU per module, the board's and the process's (``Daemon.cpu``)."""
    plan: FloorPlan | None = None
    """The building: hallway coordinates for the map, the tea room's floor for timelines."""
    max_range_mm: float = 4000.0
    """How far the sensors see: a clear cone is drawn this long."""
    pickup_timeout_s: float = 180.0
    """How long the robot waits at a door (the customer's countdown)."""
