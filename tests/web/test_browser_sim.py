"""The web pages on the whole daemon driving the simulated robot, in Debian's Chromium.

A customer orders through the form, staff load the cup from the inspector's orders table,
the status page follows the robot with its timeline and arrival estimate, and the inspector
shows it on the building's real floor plan: in the hallway, where the simulator says it
is. The screenshots are the README's (``make screenshots``).
"""

from __future__ import annotations

import asyncio
import math
import os
import re
from collections.abc import AsyncIterator

import playwright.async_api as playwright
import pytest
import pytest_asyncio

from coffeebot.config import load_robot_config
from coffeebot.sim.simulation import demo_setup
from coffeebot.web.livemap import MapPose

from .sim_browser import SimInBrowser, sim_in_browser
from .test_browser import (
    BOARD_FILE,
    DESKTOP,
    PHONE,
    PLAN,
    SCREENSHOTS,
    drawn,
)

pytestmark = pytest.mark.asyncio(loop_scope="module")

TOKEN = "sim-operator-token"


@pytest_asyncio.fixture(scope="module", loop_scope="module")
async def demo() -> AsyncIterator[SimInBrowser]:
    config = load_robot_config(BOARD_FILE)
    with pytest.MonkeyPatch.context() as env:
        env.setenv(config.web.operator_token_env, TOKEN)
        async with sim_in_browser(config, PLAN, demo_setup(PLAN, speed=2.0)) as demo:
            yield demo


async def until(check: object, what: str, timeout_s: float = 60.0) -> None:
    """Poll ``check()`` (wall time: the simulation runs at its own pace) until it holds."""
    assert callable(check)
    for _ in range(int(timeout_s / 0.1)):
        if check():
            return
        await asyncio.sleep(0.1)
    raise AssertionError(f"timed out waiting for {what}")


def in_the_hallway(pose: MapPose, past_s_mm: float) -> bool:
    """On floor 2's hallway, well clear of the tea room's door, on the way down it."""
    floor = PLAN.floor(pose.floor)
    s, d = floor.to_hallway(pose.x_mm, pose.y_mm)
    return pose.floor == 2 and s < past_s_mm and abs(d) < floor.hallway.width_mm / 2 - 300


async def test_order_load_the_cup_and_watch_the_robot_drive_in_the_hallway(
    demo: SimInBrowser,
) -> None:
    expect = playwright.expect
    customer = await demo.page(DESKTOP)
    await customer.goto(demo.url + "/")
    await customer.select_option("select[name=drink]", "cappuccino")
    await customer.fill("input[name=name]", "Grace")
    await customer.select_option("select[name=room]", "211")
    await customer.click("button[type=submit]")
    await expect(customer.locator("#status-text")).to_have_text("Being prepared in the tea room")
    await expect(customer.locator("#detail")).to_have_text(
        "The robot is in the tea room; staff are putting your cappuccino on it.", timeout=60_000
    )

    # Staff load the cup from the inspector's live orders table.
    inspector = await demo.page(DESKTOP)
    await inspector.goto(demo.url + "/inspect")
    await inspector.fill("#token", TOKEN)
    await inspector.dispatch_event("#token", "change")
    row = inspector.locator("#orders-table tbody tr").filter(has_text="Grace")
    await row.locator("button", has_text="Cup loaded").click()
    await expect(inspector.locator("#operator-message")).to_have_text(
        "Cup loaded: Grace's cappuccino to 211 is on its way."
    )
    await expect(row.locator("td.status")).to_have_text("On the way")
    await expect(customer.locator("#status-text")).to_have_text("On the way")
    await expect(customer.locator("#eta")).to_have_text(re.compile(r"^Arriving in about "))
    await expect(customer.locator("#steps li.current")).to_have_text("On the way")

    # Out of the tea room and down the hallway: what the README shows.
    tea_room = PLAN.tea_room.door.at_mm
    await until(lambda: in_the_hallway(demo.true_pose(), tea_room - 2_500), "the hallway")
    await expect(inspector.locator("#map polyline.path.route")).to_have_count(1)
    await expect(inspector.locator("#map polygon.cone")).to_have_count(8)
    await expect(inspector.locator("#map ellipse.uncertainty")).to_have_count(1)
    await expect(inspector.locator("#map g.particles")).to_have_count(1)  # the default fusion
    # CPU per module once its first 5 s window is in: the ToF poller's share of a core.
    tof = inspector.locator("#health-table tbody tr").filter(has_text="tof").first
    await expect(tof.locator("td").nth(3)).to_have_text(re.compile(r"^\d+\.\d$"))
    await expect(inspector.locator("#cpu-note")).to_contain_text("the whole process")
    os.makedirs(SCREENSHOTS, exist_ok=True)
    await customer.screenshot(path=SCREENSHOTS / "order-status.png")
    await inspector.screenshot(path=SCREENSHOTS / "inspector.png")

    # Held by the e-stop, the robot stands still: drawn where the simulator says it is.
    await inspector.click("#estop")
    await expect(inspector.locator("#alerts li.critical")).to_contain_text("Emergency stop engaged")
    still = demo.true_pose()
    for _ in range(50):
        await asyncio.sleep(0.2)
        now = demo.true_pose()
        if math.dist((now.x_mm, now.y_mm), (still.x_mm, still.y_mm)) < 1:
            break
        still = now
    await asyncio.sleep(1.0)  # a frame or two drawn since it stopped
    at = await drawn(inspector, "true", demo.true_pose())
    assert abs(at["x"] - at["want_x"]) < 3 and abs(at["y"] - at["want_y"]) < 3, at
    assert at["hall_top"] < at["y"] < at["hall_bottom"]
    assert in_the_hallway(demo.true_pose(), tea_room)
    await inspector.click("#resume")
    await expect(inspector.locator("#estop-state")).to_have_text("released")

    # At the door: the countdown, on a phone too; then the customer takes the cup.
    await expect(customer.locator("#status-text")).to_have_text("At your door", timeout=90_000)
    await expect(customer.locator("#countdown")).to_have_text(re.compile(r"^The robot waits"))
    phone = await demo.page(PHONE)
    await phone.goto(customer.url)
    await expect(phone.locator("#countdown")).to_be_visible()
    await phone.screenshot(path=SCREENSHOTS / "order-phone.png")
    await customer.click("#pickup")
    await expect(customer.locator("#status-text")).to_have_text("Delivered, enjoy!")
    await expect(row).to_have_count(0)
    for page in (customer, inspector, phone):
        await page.context.close()
