"""The web pages on the whole daemon driving the simulated robot, in Debian's Chromium.

An order is placed through the form, staff load the cup with the operator token, and the
status page follows the robot live; the inspector shows the board moving and the robot on
the building's map. The screenshots are the README's (``make screenshots``).
"""

from __future__ import annotations

import asyncio
import contextlib
import os
import re
from collections.abc import AsyncIterator
from pathlib import Path

import playwright.async_api as playwright
import pytest

from coffeebot.config import load_robot_config
from coffeebot.floorplan import load_floorplan
from coffeebot.runtime.assemble import Runtime
from coffeebot.runtime.service import serve
from coffeebot.runtime.sim import build_sim
from coffeebot.sim.simulation import demo_setup
from coffeebot.web import WebModule

from .test_browser import CHROMIUM, CHROMIUM_ARGS, REPO, SCREENSHOTS

TOKEN = "sim-operator-token"


@pytest.fixture
async def robot(monkeypatch: pytest.MonkeyPatch) -> AsyncIterator[Runtime]:
    config = load_robot_config(REPO / "boards" / "coffeebot-v1.toml")
    config = config.model_copy(
        update={"web": config.web.model_copy(update={"host": "127.0.0.1", "port": 0})}
    )
    monkeypatch.setenv(config.web.operator_token_env, TOKEN)
    plan = load_floorplan(REPO / "floorplans" / "cs-building.toml")
    async with build_sim(config, plan, demo_setup(plan, speed=2.0), web=True) as (runtime, _):
        serving = asyncio.create_task(serve(runtime))
        web = runtime.module("web")
        assert isinstance(web, WebModule)
        await asyncio.wait_for(web.started.wait(), 30)
        yield runtime
        runtime.request_stop("test over")
        with contextlib.suppress(asyncio.CancelledError):
            await asyncio.wait_for(serving, 30)


@pytest.fixture
async def browser() -> AsyncIterator[playwright.Browser]:
    async with playwright.async_playwright() as p:
        launched = await p.chromium.launch(executable_path=str(CHROMIUM), args=CHROMIUM_ARGS)
        yield launched
        await launched.close()


async def test_order_on_the_simulated_robot_and_watch_it_drive(
    robot: Runtime, browser: playwright.Browser
) -> None:
    expect = playwright.expect
    web = robot.module("web")
    assert isinstance(web, WebModule) and web.url
    context = await browser.new_context(viewport={"width": 1100, "height": 800})
    page = await context.new_page()
    await page.goto(web.url + "/")
    await page.select_option("select[name=drink]", "cappuccino")
    await page.fill("input[name=name]", "Grace")
    await page.select_option("select[name=room]", "207")
    await page.click("button[type=submit]")
    await expect(page.locator("#status-text")).to_have_text("Being prepared in the tea room")
    order_id = await page.locator("#order").get_attribute("data-order-id")

    loaded = await page.request.post(
        f"{web.url}/api/orders/{order_id}/cup-loaded",
        headers={"Authorization": f"Bearer {TOKEN}"},
    )
    assert loaded.status == 202
    await expect(page.locator("#status-text")).to_have_text("On the way", timeout=30_000)
    os.makedirs(SCREENSHOTS, exist_ok=True)
    await page.screenshot(path=SCREENSHOTS / "order-status.png")

    inspector = await context.new_page()
    await inspector.goto(web.url + "/inspect")
    scans = inspector.locator('tr[data-topic="tof/scan"] td').nth(4)
    await expect(scans).to_have_text(re.compile(r"^\d+$"))
    first = int(await scans.text_content() or 0)
    await expect(scans).not_to_have_text(str(first))
    await expect(inspector.locator("#map g.robot[data-label=estimated]")).to_have_count(1)
    await expect(inspector.locator("#map g.robot[data-label=true]")).to_have_count(1)
    await expect(inspector.locator("#map line.ray")).to_have_count(8)
    await expect(inspector.locator("#map ellipse.uncertainty")).to_have_count(1)
    await expect(inspector.locator("#map g.particles")).to_have_count(1)  # the default fusion
    await expect(inspector.locator('tr[data-topic="motor/command"] td').nth(4)).not_to_have_text(
        "0"
    )
    # The robot is moving down the hallway: its true pose on the map changes.
    robot_mark = inspector.locator("#map g.robot[data-label=true]")
    before = await robot_mark.get_attribute("transform")
    await expect(robot_mark).not_to_have_attribute("transform", before or "", timeout=15_000)
    await inspector.screenshot(path=Path(SCREENSHOTS) / "inspector.png", full_page=True)
    await context.close()
