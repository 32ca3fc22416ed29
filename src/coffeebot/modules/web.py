"""The web server as a board task: serves the app from the daemon's event loop.

It declares what it really does on the board: it publishes the operator's e-stop and events,
and reads order updates for the live order pages. The inspector's view of every
topic's statistics and latest value comes from the board it is given, read only.
"""

from __future__ import annotations

import asyncio
import dataclasses

from aiohttp import web

from coffeebot.messages import ESTOP, OPERATOR_EVENT, ORDER_UPDATE
from coffeebot.modules.base import Module, ModuleContext
from coffeebot.web import WebDeps, create_app


class WebModule(Module):
    """Serves ``create_app`` on ``deps.config.host``/``port``; the real ``bus`` comes from ctx.

    Build it with ``WebDeps(board=board, bus=board, ...)``: ``bus`` is replaced by the
    module's restricted board view when it runs. ``modules`` should list the other modules;
    the web module adds itself for the graph.
    """

    name = "web"
    inputs = (ORDER_UPDATE,)
    outputs = (ESTOP, OPERATOR_EVENT)

    def __init__(self, deps: WebDeps) -> None:
        self.deps = deps
        self.url: str | None = None
        self.started = asyncio.Event()

    async def run(self, ctx: ModuleContext) -> None:
        deps = dataclasses.replace(self.deps, bus=ctx.board, modules=[*self.deps.modules, self])
        runner = web.AppRunner(create_app(deps), access_log=None, shutdown_timeout=2.0)
        await runner.setup()
        try:
            site = web.TCPSite(runner, deps.config.host, deps.config.port)
            await site.start()
            host, port = runner.addresses[0][:2]
            self.url = f"http://{host}:{port}"
            ctx.log.info("serving", extra={"url": self.url})
            self.started.set()
            await asyncio.Event().wait()
        finally:
            self.started.clear()
            await runner.cleanup()
