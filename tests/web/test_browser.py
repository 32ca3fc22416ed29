"""The pages in a real browser (Debian's Chromium through Playwright) against a live daemon.

The daemon runs the orders and web modules on a real port; a small stand-in robot moves
along the hallway publishing scans, and the tests play navigation by publishing delivery
updates (``test_browser_sim.py`` runs the whole simulated robot instead).
"""

from __future__ import annotations

import asyncio
import contextlib
import os
import re
from collections.abc import AsyncIterator, Mapping
from dataclasses import dataclass
from pathlib import Path

import playwright.async_api as playwright
import pytest

from coffeebot.board import Board
from coffeebot.config import WebConfig, load_robot_config
from coffeebot.daemon import Daemon
from coffeebot.messages import (
    ALL_TOPICS,
    DELIVERY_STATUS,
    OPERATOR_EVENT,
    RANGE_SCAN,
    DeliveryUpdate,
    OrderStatus,
    RangeReading,
    RangeScan,
    ReadingStatus,
)
from coffeebot.modules.orders import OrdersModule
from coffeebot.store import OrderStore
from coffeebot.web import WebDeps, WebModule
from coffeebot.web.livemap import MapPose

from .conftest import ROOMS, RULES, TOKEN

CHROMIUM = Path("/usr/bin/chromium")
CHROMIUM_ARGS = [
    "--no-sandbox",
    "--disable-gpu",
    "--disable-background-networking",
    "--disable-component-update",
    "--disable-sync",
    "--no-first-run",
]
REPO = Path(__file__).resolve().parents[2]
BOARD_FILE = REPO / "boards" / "coffeebot-v1.toml"
# The browser tests on the simulated robot save screenshots here (ignored by git);
# `make screenshots` refreshes the README's copies in docs/screenshots/ by pointing it there.
SCREENSHOTS = Path(os.environ.get("COFFEEBOT_SCREENSHOTS", REPO / "test-artifacts" / "screenshots"))


# Floor 2: the hallway runs along +x, offices above it; the #frame group is floor-plan mm, y up.
FLOOR_2 = """<svg xmlns="http://www.w3.org/2000/svg" viewBox="-500 -4500 17000 5000">
<g id="frame" transform="scale(1,-1)">
<rect x="0" y="0" width="16000" height="1700" fill="#f4f1ea" stroke="#555" stroke-width="40"/>
<rect x="0" y="1700" width="3000" height="2500" fill="#eef" stroke="#555" stroke-width="40"/>
<rect x="3000" y="1700" width="3000" height="2500" fill="#fff" stroke="#555" stroke-width="40"/>
<rect x="6000" y="1700" width="3000" height="2500" fill="#fff" stroke="#555" stroke-width="40"/>
</g></svg>"""


class StandInRobot:
    """Drives along the hallway and publishes a scan per step: enough to watch the inspector."""

    def __init__(self, board: Board) -> None:
        self.board = board
        self.pose = MapPose(x_mm=1500, y_mm=850, heading_deg=0, floor=2)

    def poses(self) -> Mapping[str, MapPose]:
        true = self.pose.model_copy(update={"y_mm": self.pose.y_mm + 60})
        return {"estimated": self.pose, "true": true}

    async def run(self) -> None:
        while True:
            x = self.pose.x_mm + 20
            self.pose = self.pose.model_copy(update={"x_mm": x if x < 14000 else 1500})
            readings = [
                RangeReading(sensor=i, status=ReadingStatus.VALID, distance_mm=600 + 40 * i)
                for i in range(7)
            ] + [RangeReading(sensor=7, status=ReadingStatus.NO_TARGET)]
            self.board.publish(
                RANGE_SCAN, RangeScan(cycle_start_s=0.0, cycle_time_s=0.02, readings=readings)
            )
            await asyncio.sleep(0.02)


@dataclass
class Served:
    url: str
    board: Board


@pytest.fixture
async def served(tmp_path: Path) -> AsyncIterator[Served]:
    board = Board(ALL_TOPICS)
    robot_config = load_robot_config(BOARD_FILE)
    store = OrderStore(tmp_path / "orders.sqlite3")
    orders = OrdersModule(store)
    robot = StandInRobot(board)
    web = WebModule(
        WebDeps(
            board=board,
            orders=orders,
            rooms=ROOMS,
            config=WebConfig(port=0, drinks=sorted(RULES.drinks), stream_period_s=0.2),
            operator_token=TOKEN,
            modules=lambda: daemon.modules,
            floor_svg=lambda floor: FLOOR_2 if floor == 2 else None,
            poses=robot.poses,
            sensors=robot_config.tof.sensors,
            geometry=robot_config.geometry,
            health=lambda: daemon.health(),
        )
    )
    daemon = Daemon(board, [orders, web])
    await daemon.start()
    driving = asyncio.create_task(robot.run())
    await web.started.wait()
    assert web.url is not None
    yield Served(web.url, board)
    driving.cancel()
    with contextlib.suppress(asyncio.CancelledError):
        await driving
    await daemon.shutdown()
    store.close()


@pytest.fixture
async def page(served: Served) -> AsyncIterator[playwright.Page]:
    async with playwright.async_playwright() as p:
        browser = await p.chromium.launch(executable_path=str(CHROMIUM), args=CHROMIUM_ARGS)
        context = await browser.new_context(viewport={"width": 1100, "height": 800})
        page = await context.new_page()
        page.set_default_timeout(15_000)
        dialogs: list[str] = []
        page.on("dialog", lambda d: dialogs.append(d.message))
        yield page
        await browser.close()
        assert dialogs == [], "a script injected through an order ran in the page"


async def test_order_through_the_form_and_watch_it_live(
    page: playwright.Page, served: Served
) -> None:
    expect = playwright.expect
    await page.goto(served.url + "/")
    await page.select_option("select[name=drink]", "latte")
    await page.fill("input[name=name]", "Ada <img src=x onerror=alert(1)>")
    await page.select_option("select[name=room]", "302")
    await page.fill("textarea[name=notes]", "oat milk <script>alert(2)</script>")
    await page.click("button[type=submit]")

    await expect(page).to_have_url(re.compile(r"/orders/[A-Za-z0-9_-]+\?key=[A-Za-z0-9_-]+$"))
    await expect(page.locator("#order-name")).to_have_text("Ada <img src=x onerror=alert(1)>")
    await expect(page.locator("#status-text")).to_have_text("Being prepared in the tea room")
    await expect(page.locator("#live")).to_have_text("live")
    order_id = await page.locator("#order").get_attribute("data-order-id")
    assert order_id

    def report(status: OrderStatus) -> None:
        served.board.publish(DELIVERY_STATUS, DeliveryUpdate(order_id=order_id, status=status))

    report(OrderStatus.ON_THE_WAY)
    await expect(page.locator("#status-text")).to_have_text("On the way")
    await expect(page.locator("#pickup")).to_be_hidden()
    report(OrderStatus.ARRIVED)
    await expect(page.locator("#status-text")).to_have_text("At your door")
    async with page.expect_response(lambda r: "/pickup?key=" in r.url) as answer:
        await page.click("#pickup")
    assert (await answer.value).status == 202
    await expect(page.locator("#action-error")).to_be_hidden()
    event = served.board.latest(OPERATOR_EVENT)
    assert event is not None
    assert (event.msg.kind, event.msg.order_id) == ("pickup_confirmed", order_id)
    report(OrderStatus.DELIVERED)
    await expect(page.locator("#status-text")).to_have_text("Delivered, enjoy!")


async def test_queued_order_shows_its_place_and_can_be_cancelled(
    page: playwright.Page, served: Served
) -> None:
    expect = playwright.expect
    for name in ("First", "Second"):
        await page.goto(served.url + "/")
        await page.fill("input[name=name]", name)
        await page.click("button[type=submit]")
    await expect(page.locator("#queue")).to_have_text("1 order(s) ahead of yours")
    await page.click("#cancel")
    await expect(page.locator("#status-text")).to_have_text("Cancelled")
    await expect(page.locator("#cancel")).to_be_hidden()


async def test_form_shows_which_field_is_wrong(page: playwright.Page, served: Served) -> None:
    await page.goto(served.url + "/")
    await page.click("button[type=submit]")  # no name
    await playwright.expect(page.locator('.error[data-field="name"]')).to_be_visible()


async def test_inspector_shows_topics_updating_and_the_robot_on_the_map(
    page: playwright.Page, served: Served
) -> None:
    expect = playwright.expect
    await page.goto(served.url + "/inspect")
    published = page.locator('tr[data-topic="tof/scan"] td').nth(4)
    await expect(published).to_have_text(re.compile(r"^\d+$"))
    first = await published.text_content()
    await expect(published).not_to_have_text(first or "")
    await expect(page.locator("#map g.robot[data-label=estimated]")).to_have_count(1)
    await expect(page.locator("#map g.robot[data-label=true]")).to_have_count(1)
    await expect(page.locator("#map line.ray")).to_have_count(8)
    await expect(page.locator("#map line.ray.no_target")).to_have_count(1)
    await expect(page.locator("#map #frame rect").first).to_be_visible()
    await expect(page.locator('#health-table td:text-is("web")')).to_have_count(1)

    await page.fill("#token", "wrong")
    await page.dispatch_event("#token", "change")
    await page.click("#estop")
    await expect(page.locator("#operator-message")).to_have_text("operator token required")
    await page.fill("#token", TOKEN)
    await page.dispatch_event("#token", "change")
    await page.click("#estop")
    await expect(page.locator("#estop-state")).to_have_text(re.compile("ENGAGED"))
    await page.click("#resume")
    await expect(page.locator("#estop-state")).to_have_text("released")
