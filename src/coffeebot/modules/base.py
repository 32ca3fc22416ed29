"""The shape every board task has, and the restricted board view it runs with.

A module declares the topics it reads (``inputs``) and writes (``outputs``). The daemon hands
it a :class:`ModuleBoard` that refuses anything else, so the declarations the inspector draws
as the module graph are also what the code can actually do ("motion is the only writer to the
motors" is enforced, not hoped for).
"""

from __future__ import annotations

import logging
from abc import ABC, abstractmethod
from dataclasses import dataclass
from typing import Any, ClassVar, TypeVar

from pydantic import BaseModel

from coffeebot.board import Board, BoardError, Envelope, Subscription, Topic
from coffeebot.clock import Clock

M = TypeVar("M", bound=BaseModel)


class ModuleBoard:
    """A module's window on the board: only its declared inputs and outputs."""

    def __init__(self, board: Board, module: Module) -> None:
        self._board = board
        self._module = module
        self._inputs = {t.name for t in module.inputs}
        self._outputs = {t.name for t in module.outputs}
        self._readable = self._inputs | self._outputs

    @property
    def clock(self) -> Clock:
        return self._board.clock

    def _check(self, topic: Topic[Any], allowed: set[str], verb: str) -> None:
        if topic.name not in allowed:
            raise BoardError(
                f"module {self._module.name!r} may not {verb} {topic.name!r}: "
                f"not among its declared {'outputs' if verb == 'publish' else 'inputs'}"
            )

    def publish(self, topic: Topic[M], msg: M) -> Envelope[M]:
        self._check(topic, self._outputs, "publish")
        return self._board.publish(topic, msg)

    def subscribe(self, topic: Topic[M]) -> Subscription[M]:
        self._check(topic, self._inputs, "read")
        return self._board.subscribe(topic, name=self._module.name)

    def latest(self, topic: Topic[M]) -> Envelope[M] | None:
        self._check(topic, self._readable, "read")
        return self._board.latest(topic)

    def age(self, topic: Topic[M]) -> float | None:
        self._check(topic, self._readable, "read")
        return self._board.age(topic)

    async def next(self, topic: Topic[M], timeout: float | None = None) -> Envelope[M]:
        self._check(topic, self._inputs, "read")
        return await self._board.next(topic, timeout)


@dataclass
class ModuleContext:
    """What a running module gets from the daemon."""

    board: ModuleBoard
    clock: Clock
    log: logging.Logger


class Module(ABC):
    """A board task. Subclasses set ``name``, ``inputs``, ``outputs`` and implement ``run``.

    ``run`` is restarted by the supervisor if it raises. ``shutdown`` is called once when the
    daemon stops, in ascending ``shutdown_order`` *before* any task is cancelled, which is
    where the motor driver sends its stop.
    """

    name: ClassVar[str]
    inputs: ClassVar[tuple[Topic[Any], ...]] = ()
    outputs: ClassVar[tuple[Topic[Any], ...]] = ()
    shutdown_order: ClassVar[int] = 100
    critical: ClassVar[bool] = False
    """A critical module that is marked failed makes the robot stop for good."""

    @abstractmethod
    async def run(self, ctx: ModuleContext) -> None:
        """The module's loop. Returning ends the module; raising gets it restarted."""

    async def shutdown(self) -> None:  # noqa: B027 - an optional hook, empty by default
        """Bring hardware to a safe state. Must be quick and must not raise."""
