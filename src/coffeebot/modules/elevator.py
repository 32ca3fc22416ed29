"""Elevator module: navigation's elevator requests to a building interface, its state back.

The interface is small on purpose (call the car to a floor, send it to a floor, release it;
report the car's floor and its doors) so a building's lift API, a relay board on the call
buttons, or the simulated elevator can serve it. Without one, this module is not assembled
and navigation falls back to an operator confirming each step.
"""

from __future__ import annotations

import asyncio
from typing import Protocol

from coffeebot.messages import ELEVATOR_REQUEST, ELEVATOR_STATE, ElevatorRequest, ElevatorState
from coffeebot.modules.base import Module, ModuleContext

STATE_PERIOD_S = 0.2


class ElevatorInterface(Protocol):
    def request(self, request: ElevatorRequest) -> None: ...

    def state(self) -> ElevatorState: ...


class ElevatorModule(Module):
    name = "elevator"
    inputs = (ELEVATOR_REQUEST,)
    outputs = (ELEVATOR_STATE,)

    def __init__(self, elevator: ElevatorInterface) -> None:
        self.elevator = elevator

    async def _requests(self, ctx: ModuleContext) -> None:
        with ctx.board.subscribe(ELEVATOR_REQUEST) as requests:
            async for envelope in requests:
                self.elevator.request(envelope.msg)

    async def _states(self, ctx: ModuleContext) -> None:
        while True:
            ctx.board.publish(ELEVATOR_STATE, self.elevator.state())
            await ctx.clock.sleep(STATE_PERIOD_S)

    async def run(self, ctx: ModuleContext) -> None:
        async with asyncio.TaskGroup() as group:
            group.create_task(self._requests(ctx))
            group.create_task(self._states(ctx))
