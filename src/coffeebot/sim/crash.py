"""Module crashes on demand: an exception raised inside a running module, wherever it is.

The ``module_crash`` fault (:mod:`coffeebot.sim.faults`) needs a module to fail as a bug
would make it fail: at an arbitrary await point, in the middle of whatever it was doing. A
:class:`CrashSwitch` runs the module's own ``run`` as a task of its own and, when tripped,
cancels it there (its ``finally`` blocks run, as they would for an exception) and raises
:class:`SimulatedCrash` to the daemon's supervisor, which logs it, reports it and restarts
the module as it does any crash. Only modules a run's faults name get a switch.
"""

from __future__ import annotations

import asyncio
from collections.abc import Iterable

from coffeebot.modules.base import Module, ModuleContext


class SimulatedCrash(RuntimeError):
    """What a crashed module raises to its supervisor."""


class CrashSwitch:
    """Wraps one module's ``run`` so that :meth:`trip` makes it raise."""

    def __init__(self, module: Module) -> None:
        self.module = module
        self._run = module.run
        self._why: str | None = None
        self._tripped: asyncio.Event | None = None
        module.run = self.run  # type: ignore[method-assign]

    def trip(self, why: str) -> None:
        """Crash the module now (or, between runs, as soon as it starts again)."""
        self._why = why
        if self._tripped is not None:
            self._tripped.set()

    async def run(self, ctx: ModuleContext) -> None:
        self._tripped = tripped = asyncio.Event()
        if self._why is not None:
            tripped.set()
        inner = asyncio.create_task(self._run(ctx), name=f"module:{self.module.name}:run")
        trip = asyncio.create_task(tripped.wait(), name=f"module:{self.module.name}:crash")
        crashed = False
        try:
            await asyncio.wait({inner, trip}, return_when=asyncio.FIRST_COMPLETED)
            crashed = not inner.done()
        finally:
            self._tripped = None
            trip.cancel()
            inner.cancel()
            await asyncio.gather(inner, trip, return_exceptions=True)
        if crashed:
            why, self._why = self._why, None
            raise SimulatedCrash(why)
        inner.result()  # returned: return; raised: raise the module's own error


def crash_switches(modules: Iterable[Module], names: Iterable[str]) -> dict[str, CrashSwitch]:
    """Switches for the modules named ``names``; an unknown name is a ValueError."""
    by_name = {m.name: m for m in modules}
    unknown = sorted(set(names) - set(by_name))
    if unknown:
        raise ValueError(f"no module named {', '.join(unknown)} to crash")
    return {name: CrashSwitch(by_name[name]) for name in set(names)}
