"""The whole daemon on the simulated robot with its web UI up, and Debian's Chromium to look
at it: what every browser test on the simulated robot starts from."""

from __future__ import annotations

import asyncio
import contextlib
from collections.abc import AsyncIterator
from dataclasses import dataclass

import playwright.async_api as playwright

from coffeebot.config import RobotConfig
from coffeebot.floorplan import FloorPlan
from coffeebot.runtime.assemble import Runtime
from coffeebot.runtime.service import serve
from coffeebot.runtime.sim import SimExtraModules, build_sim
from coffeebot.sim.simulation import SimSetup, Simulation
from coffeebot.web import WebModule
from coffeebot.web.livemap import MapPose

from .test_browser import CHROMIUM, CHROMIUM_ARGS


@dataclass
class SimInBrowser:
    url: str
    runtime: Runtime
    sim: Simulation
    browser: playwright.Browser

    async def page(self, viewport: dict[str, int], timeout_ms: float = 30_000) -> playwright.Page:
        context = await self.browser.new_context(viewport=viewport)  # type: ignore[arg-type]
        page = await context.new_page()
        page.set_default_timeout(timeout_ms)
        return page

    def true_pose(self) -> MapPose:
        """Where the simulator has the robot now."""
        with self.sim.lock:
            pose, floor = self.sim.robot.pose, self.sim.robot.floor_level
        return MapPose(x_mm=pose.x_mm, y_mm=pose.y_mm, heading_deg=pose.heading_deg, floor=floor)


@contextlib.asynccontextmanager
async def sim_in_browser(
    config: RobotConfig, plan: FloorPlan, setup: SimSetup, extra: SimExtraModules | None = None
) -> AsyncIterator[SimInBrowser]:
    """The daemon served on a free local port, Chromium launched; both stopped after."""
    config = config.model_copy(
        update={"web": config.web.model_copy(update={"host": "127.0.0.1", "port": 0})}
    )
    async with build_sim(config, plan, setup, extra) as (runtime, sim):
        serving = asyncio.create_task(serve(runtime))
        web = runtime.module("web")
        assert isinstance(web, WebModule)
        await asyncio.wait_for(web.started.wait(), 30)
        assert web.url is not None
        async with playwright.async_playwright() as p:
            browser = await p.chromium.launch(executable_path=str(CHROMIUM), args=CHROMIUM_ARGS)
            yield SimInBrowser(web.url, runtime, sim, browser)
            await browser.close()
        runtime.request_stop("test over")
        with contextlib.suppress(asyncio.CancelledError):
            await asyncio.wait_for(serving, 30)
