"""A cart across the hallway under a ceiling camera, as the people see it, in Debian's
Chromium: the whole daemon drives the simulated robot with the building's cameras on
(scenario ``floor2-cart-seen-by-camera``'s world). A customer orders to 207 through the
form, staff load the cup from the inspector; the camera sees the cart stand, the robot holds
short of it; the customer's page says why it waits, and the inspector's map shows the
cameras' fields, the cart and the robot held short of it. The screenshots are the README's
(``make screenshots``)."""

from __future__ import annotations

import asyncio
import os
import re
from collections.abc import AsyncIterator
from pathlib import Path

import playwright.async_api as playwright
import pytest
import pytest_asyncio

from coffeebot.config import load_robot_config
from coffeebot.messages import DELIVERY_STATUS, DeliveryProblem
from coffeebot.scenario.spec import load_scenario

from .sim_browser import SimInBrowser, sim_in_browser
from .test_browser import BOARD_FILE, DESKTOP, PHONE, SCREENSHOTS

pytestmark = pytest.mark.asyncio(loop_scope="module")

ROOT = Path(__file__).resolve().parents[2]
SCENARIO, PLAN = load_scenario(ROOT / "scenarios" / "floor2-cart-seen-by-camera.toml")
TOKEN = "sim-operator-token"


def standing_at_x(demo: SimInBrowser) -> float | None:
    """Where along the hallway the robot stands still (None while it moves)."""
    with demo.sim.lock:
        robot = demo.sim.robot
        moving = abs(robot.body.state.speed_mm_s) > 1.0
        x_mm = robot.pose.x_mm
    return None if moving else x_mm


@pytest_asyncio.fixture(scope="module", loop_scope="module")
async def demo() -> AsyncIterator[SimInBrowser]:
    config = SCENARIO.configure(load_robot_config(BOARD_FILE))
    # The scenario's world (its start, the cart, the cameras); the orders come from the form.
    with pytest.MonkeyPatch.context() as env:
        env.setenv(config.web.operator_token_env, TOKEN)
        async with sim_in_browser(config, PLAN, SCENARIO.setup(speed=2.0)) as demo:
            yield demo


async def test_the_customer_and_the_inspector_see_the_robot_wait_for_a_cart_a_camera_saw(
    demo: SimInBrowser,
) -> None:
    expect = playwright.expect
    held = demo.runtime.board.subscribe(DELIVERY_STATUS)
    customer = await demo.page(PHONE, timeout_ms=60_000)
    await customer.goto(demo.url + "/")
    await customer.select_option("select[name=drink]", "latte")
    await customer.fill("input[name=name]", "Grace")
    await customer.select_option("select[name=room]", "207")
    await customer.click("button[type=submit]")
    await expect(customer.locator("#detail")).to_have_text(
        "The robot is in the tea room; staff are putting your latte on it."
    )
    inspector = await demo.page(DESKTOP, timeout_ms=60_000)
    await inspector.goto(demo.url + "/inspect")
    await inspector.fill("#token", TOKEN)
    await inspector.dispatch_event("#token", "change")
    row = inspector.locator("#orders-table tbody tr").filter(has_text="Grace")
    await row.locator("button", has_text="Cup loaded").click()

    # The robot holds for the cart the camera saw, far beyond its own sensors' reach.
    with held:
        async with asyncio.timeout(120):
            while (await held.get()).msg.problem is not DeliveryProblem.BLOCKED:
                pass
    await expect(customer.locator("#detail")).to_have_text(
        "Something is in the robot's way; it waits for the way to clear."
    )
    # It drives on to where it holds, short of the cart, and stands there.
    (cart_spec,) = SCENARIO.obstacles
    async with asyncio.timeout(120):
        while (at := standing_at_x(demo)) is None or at > 30_000:
            await asyncio.sleep(0.1)
    assert at - cart_spec.x_mm > 1500.0
    await expect(customer.locator("#status-text")).to_have_text("On the way")
    cart = inspector.locator('#map polygon.camera-object[data-camera="north-hall-2"]')
    await expect(cart).to_have_count(1)
    await expect(cart.locator("title")).to_have_text(
        re.compile(r"^seen standing by camera north-hall-2 for \d+ s$")
    )
    await expect(inspector.locator("#map polygon.camera-field")).to_have_count(3)
    await expect(inspector.locator("#map polygon.camera-field.down")).to_have_count(0)
    await expect(inspector.locator("#camera-legend")).to_be_visible()
    # Following the robot, which faces -x: the cart lies ahead, to its left on screen.
    # The map is drawn anew with each pose: both boxes are taken from one drawing, in one
    # script run, once the drawing has both.
    drawn = await inspector.wait_for_function(
        """() => {
            const cart = document.querySelector(
                '#map polygon.camera-object[data-camera="north-hall-2"]');
            const robot = document.querySelector('#map g.robot[data-label=estimated] rect');
            if (!cart || !robot) return null;
            return {cart_right: cart.getBoundingClientRect().right,
                    robot_left: robot.getBoundingClientRect().left};
        }"""
    )
    boxes = await drawn.json_value()
    assert boxes["cart_right"] < boxes["robot_left"], boxes
    os.makedirs(SCREENSHOTS, exist_ok=True)
    await inspector.locator("#map").screenshot(path=SCREENSHOTS / "inspector-camera-cart.png")
    await customer.screenshot(path=SCREENSHOTS / "order-status-camera-cart-phone.png")
