"""The dispatcher's inspector, in Chromium: every robot of the fleet on the map with its name,
and a robot that stops reporting turns grey where it was last heard of and says for how
long, rather than vanishing. Desktop and phone size; screenshots next to the others."""

from __future__ import annotations

import asyncio
import re
from collections.abc import AsyncIterator
from pathlib import Path

import playwright.async_api as playwright
import pytest

from coffeebot.fleet.mosquitto import Mosquitto
from coffeebot.store import OrderStore
from coffeebot.web import WebModule
from web.test_browser import CHROMIUM, CHROMIUM_ARGS, DESKTOP, PHONE, SCREENSHOTS

from .conftest import ROBOTS
from .test_fleet_broker import Fleet

WAIT_MS = 15_000


@pytest.fixture
async def fleet(broker: Mosquitto, tmp_path: Path) -> AsyncIterator[Fleet]:
    store = OrderStore(tmp_path / "orders.sqlite3")
    fleet = Fleet(broker, store, web=True)
    await fleet.start()
    yield fleet
    await fleet.stop()
    store.close()


async def web_url(fleet: Fleet) -> str:
    [web] = [m for m in fleet.dispatcher.daemon.modules if isinstance(m, WebModule)]
    await asyncio.wait_for(web.started.wait(), 10)
    assert web.url is not None
    return web.url


@pytest.mark.parametrize("size", ["desktop", "phone"])
async def test_every_robot_is_on_the_map_and_a_silent_one_turns_grey(
    fleet: Fleet, size: str
) -> None:
    async with playwright.async_playwright() as p:
        browser = await p.chromium.launch(executable_path=str(CHROMIUM), args=CHROMIUM_ARGS)
        context = await browser.new_context(viewport=DESKTOP if size == "desktop" else PHONE)  # type: ignore[arg-type]
        page = await context.new_page()
        page.set_default_timeout(WAIT_MS)
        await page.goto(await web_url(fleet) + "/inspect")
        await page.click("text=Whole floor")
        shapes = {robot: page.locator(f'#map g.robot[data-label="{robot}"]') for robot in ROBOTS}
        for shape in shapes.values():
            await playwright.expect(shape).to_have_count(1)
        silent = page.locator("#map g.robot.silent")
        await playwright.expect(silent).to_have_count(0)

        gone = ROBOTS[1]
        await fleet.robots.pop(gone).shutdown()
        shape = shapes[gone]
        await playwright.expect(shape).to_have_class("robot robot-2 silent")
        await playwright.expect(page.locator("#map text.robot-label.silent")).to_have_text(
            re.compile(rf"{gone}: silent for \d+ s")
        )
        await playwright.expect(
            page.locator(f'#map g.robot[data-label="{ROBOTS[0]}"]')
        ).not_to_have_class(re.compile("silent"))
        await playwright.expect(shape.locator("rect")).to_have_css("fill", "rgb(170, 170, 170)")
        SCREENSHOTS.mkdir(parents=True, exist_ok=True)
        await page.screenshot(path=str(SCREENSHOTS / f"fleet-map-{size}.png"), full_page=True)
        await browser.close()
