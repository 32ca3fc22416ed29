"""The web server as a board task: serves the app from the daemon's event loop.

It declares what it really does on the board: it publishes the operator's e-stop and events,
and reads order updates for the live order pages and health reports for the alerts; that
traffic goes through the module's restricted board view, handed to the app factory. The
inspector's view of every topic's statistics and latest value comes from the read-only board
view in its deps.
"""

from __future__ import annotations

import asyncio

from aiohttp import web

from coffeebot.messages import ESTOP, HEALTH, OPERATOR_EVENT, ORDER_UPDATE
from coffeebot.modules.base import Module, ModuleContext
from coffeebot.web.app import create_app
from coffeebot.web.deps import WebDeps


class WebModule(Module):
    """Serves ``create_app`` on ``deps.config.host``/``port``."""

    name = "web"
    inputs = (ORDER_UPDATE, HEALTH)
    outputs = (ESTOP, OPERATOR_EVENT)

    def __init__(self, deps: WebDeps) -> None:
        self.deps = deps
        self.url: str | None = None
        self.started = asyncio.Event()

    async def run(self, ctx: ModuleContext) -> None:
        runner = web.AppRunner(
            create_app(self.deps, ctx.board), access_log=None, shutdown_timeout=2.0
        )
        await runner.setup()
        try:
            site = web.TCPSite(runner, self.deps.config.host, self.deps.config.port)
            await site.start()
            host, port = runner.addresses[0][:2]
            self.url = f"http://{host}:{port}"
            ctx.log.info("serving", extra={"url": self.url})
            self._say_operator_token(ctx)
            self.started.set()
            await asyncio.Event().wait()
        finally:
            self.started.clear()
            await runner.cleanup()

    def _say_operator_token(self, ctx: ModuleContext) -> None:
        """The first thing an operator needs to know in the terminal: can they act at all."""
        env = self.deps.config.operator_token_env
        if self.deps.operator_token:
            ctx.log.info("operator actions on: the inspector asks for the token in $%s", env)
        else:
            ctx.log.warning(
                "operator actions off: no operator token; set one with "
                "`export %s=<a secret>` before starting, then enter it on %s/inspect",
                env,
                self.url,
            )
