"""What the web app is built from: plain data and narrow interfaces, no daemon internals.

The floor plan, the pose estimate and the module list come in as data or callables, so the
app runs the same under the daemon, in API tests on a bare board and in the benchmark.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from typing import Protocol, TypeVar

from pydantic import BaseModel

from coffeebot.board import Board, Envelope, Subscription, Topic
from coffeebot.config import GeometryConfig, TofSensorConfig, WebConfig
from coffeebot.messages import Health
from coffeebot.modules.base import Module
from coffeebot.modules.orders import OrdersModule
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
    """Everything ``create_app`` needs.

    ``board`` is read only, for the inspector (statistics and latest values of every topic);
    all publishing and subscribing goes through ``bus``, which under the daemon is limited to
    the web module's declared topics.
    """

    board: Board
    bus: BoardIO
    orders: OrdersModule
    rooms: Sequence[RoomChoice]
    config: WebConfig = field(default_factory=WebConfig)
    operator_token: str | None = None
    modules: Sequence[Module] = ()
    floor_svg: Callable[[int], str | None] | None = None
    poses: PoseSource | None = None
    sensors: Sequence[TofSensorConfig] = ()
    geometry: GeometryConfig = field(default_factory=GeometryConfig)
    health: Callable[[], Sequence[Health]] | None = None
    """Module health as the supervisor sees it now (``Daemon.health``)."""
