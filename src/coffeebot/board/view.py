"""The board read only: what a reader of everything (the inspector, the live map) may do.

:class:`~coffeebot.board.Board` satisfies it; code typed against it cannot publish.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any, Protocol, TypeVar

from pydantic import BaseModel

from coffeebot.board.stats import BoardSnapshot
from coffeebot.board.topic import Envelope, Topic
from coffeebot.clock import Clock

M = TypeVar("M", bound=BaseModel)


class BoardView(Protocol):
    @property
    def clock(self) -> Clock: ...

    @property
    def topics(self) -> Sequence[Topic[Any]]: ...

    def latest(self, topic: Topic[M] | str) -> Envelope[M] | None: ...

    def snapshot(self) -> BoardSnapshot: ...
