"""The ceiling cameras' layer on the inspector's live map, in Debian's Chromium.

The whole daemon drives the simulated robot on the building's real floor plan, standing in
the hallway at the tea room's door; a probe stands in for the cameras: the lobby's camera
works and sees a cart standing in the hallway ahead of the robot, the tea room's has
stopped sending frames. The map draws both fields and the cart where the plan says they are,
on desktop and on a phone, and the robot stays on top of them.
"""

from __future__ import annotations

import os
import re
from collections.abc import AsyncIterator, Sequence
from typing import Any

import numpy as np
import playwright.async_api as playwright
import pytest
import pytest_asyncio

from coffeebot.cameras.geometry import nominal_homography, to_plane
from coffeebot.config import load_robot_config
from coffeebot.floorplan import Camera
from coffeebot.messages import CAMERA_LAYER, CameraLayer, CameraObject, CameraView
from coffeebot.modules.base import Module, ModuleContext
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
    no_sideways_scroll,
)

pytestmark = pytest.mark.asyncio(loop_scope="module")

FLOOR = PLAN.floor(2)
CAMERAS = {camera.id: camera for camera in FLOOR.cameras}
CART = (40_200.0, 450.0)
"""In the hallway 1.8 m ahead of the robot (it stands at x 42 000 facing -x), off its lane."""


def field_of_view(camera: Camera) -> list[tuple[float, float]]:
    """The floor a camera of the plan sees: its image's corners through its homography."""
    w, h = camera.width_px, camera.height_px
    corners = to_plane(nominal_homography(camera), np.array([[0, 0], [w, 0], [w, h], [0, h]]))
    return [(float(x), float(y)) for x, y in corners]


class CameraProbe(Module):
    """Publishes the cameras' layer once a board second, as the cameras' module would."""

    name = "camera-probe"
    outputs = (CAMERA_LAYER,)

    async def run(self, ctx: ModuleContext) -> None:
        since = ctx.clock.now()
        views = [
            CameraView(
                camera_id="lobby-2",
                floor=2,
                corners_mm=field_of_view(CAMERAS["lobby-2"]),
                working=True,
            ),
            CameraView(
                camera_id="tea-room",
                floor=2,
                corners_mm=field_of_view(CAMERAS["tea-room"]),
                working=False,
                problem="no frames for 3 s",
            ),
        ]
        while True:
            cart = CameraObject(
                id="track-7",
                camera_id="lobby-2",
                floor=2,
                x_mm=CART[0],
                y_mm=CART[1],
                length_mm=900,
                width_mm=500,
                axis_deg=0,
                standing_since_s=since,
                seen_s=ctx.clock.now(),
            )
            ctx.board.publish(CAMERA_LAYER, CameraLayer(objects=[cart], cameras=views, expiry_s=30))
            await ctx.clock.sleep(1.0)


@pytest_asyncio.fixture(scope="module", loop_scope="module")
async def demo() -> AsyncIterator[SimInBrowser]:
    config = load_robot_config(BOARD_FILE)
    setup = demo_setup(PLAN, speed=2.0)
    async with sim_in_browser(config, PLAN, setup, lambda *_: [CameraProbe()]) as demo:
        yield demo


BOXES = """() => {
    const box = (e) => { const r = e.getBoundingClientRect();
        return {x: r.x + r.width / 2, y: r.y + r.height / 2, left: r.x, top: r.y,
                right: r.right, bottom: r.bottom}; };
    const all = (selector) => [...document.querySelectorAll(selector)].map(box);
    const overlay = [...document.querySelectorAll("#overlay > *")];
    const robot = document.querySelector("#map g.robot[data-label=estimated]");
    return {
        cart: box(document.querySelector("#map polygon.camera-object")),
        lobby: box(document.querySelector('#map polygon.camera-field[data-camera="lobby-2"]')),
        tea: box(document.querySelector('#map polygon.camera-field[data-camera="tea-room"]')),
        robot: box(robot.querySelector("rect")),
        robot_on_top: overlay.indexOf(robot) > Math.max(
            ...overlay.filter((e) => e.matches("[class^=camera]")).map((e) => overlay.indexOf(e))),
        map: box(document.querySelector("#map")),
    };
}"""


async def camera_layer_drawn(page: playwright.Page) -> dict[str, Any]:
    """Waits for the layer the probe publishes, checks what each shape says, and returns
    where the shapes and the robot are drawn on screen."""
    expect = playwright.expect
    await expect(page.locator("#map g.robot[data-label=estimated]")).to_have_count(1)
    await expect(page.locator("#map polygon.camera-field")).to_have_count(2)
    down = page.locator("#map polygon.camera-field.down")
    await expect(down).to_have_attribute("data-camera", "tea-room")
    await expect(down.locator("title")).to_have_text(
        "camera tea-room: not working (no frames for 3 s)"
    )
    lobby = page.locator('#map polygon.camera-field[data-camera="lobby-2"]:not(.down)')
    await expect(lobby.locator("title")).to_have_text("camera lobby-2")
    cart = page.locator("#map polygon.camera-object")
    await expect(cart).to_have_attribute("data-object", "track-7")
    await expect(cart.locator("title")).to_have_text(
        re.compile(r"^seen standing by camera lobby-2 for \d+ s$")
    )
    await expect(page.locator("#camera-legend")).to_be_visible()
    return await page.evaluate(BOXES)


def centre(corners: Sequence[tuple[float, float]]) -> MapPose:
    return MapPose(
        x_mm=sum(x for x, _ in corners) / len(corners),
        y_mm=sum(y for _, y in corners) / len(corners),
        heading_deg=0,
        floor=FLOOR.level,
    )


async def test_the_cameras_fields_and_what_they_see_standing_are_on_the_map(
    demo: SimInBrowser,
) -> None:
    page = await demo.page(DESKTOP)
    await page.goto(demo.url + "/inspect")
    at = await camera_layer_drawn(page)
    cart, robot = at["cart"], at["robot"]
    # Following the robot: the cart ahead of it (to its left on screen, x decreasing), clear
    # of it, and the robot drawn over the camera layer.
    assert cart["right"] < robot["left"], at
    assert at["robot_on_top"], at
    os.makedirs(SCREENSHOTS, exist_ok=True)
    await page.screenshot(path=SCREENSHOTS / "inspector-cameras.png")
    await page.locator("#map").screenshot(path=SCREENSHOTS / "inspector-cameras-map.png")

    # The whole floor: each shape where the plan's own hallway says it is.
    await page.click("#view-toggle")
    await expect_whole_floor(page)
    at = await page.evaluate(BOXES)
    cart_x, cart_y = CART
    for shape, where in (
        ("cart", MapPose(x_mm=cart_x, y_mm=cart_y, heading_deg=0, floor=FLOOR.level)),
        ("lobby", centre(field_of_view(CAMERAS["lobby-2"]))),
        ("tea", centre(field_of_view(CAMERAS["tea-room"]))),
    ):
        want = await drawn(page, "estimated", where)
        got = at[shape]
        assert abs(got["x"] - want["want_x"]) < 3 and abs(got["y"] - want["want_y"]) < 3, (
            shape,
            got,
            want,
        )
    assert want["hall_top"] < at["cart"]["top"] and at["cart"]["bottom"] < want["hall_bottom"]
    await page.locator("#map").screenshot(path=SCREENSHOTS / "inspector-cameras-floor.png")
    await page.context.close()


async def expect_whole_floor(page: playwright.Page) -> None:
    await playwright.expect(page.locator("#view-toggle")).to_have_text("Follow robot")
    small = "document.querySelector('#map g.robot rect').getBoundingClientRect().width < 20"
    await page.wait_for_function(f"() => {small}")


async def test_on_a_phone_the_camera_layer_is_legible_and_leaves_the_robot_visible(
    demo: SimInBrowser,
) -> None:
    page = await demo.page(PHONE)
    await page.goto(demo.url + "/inspect")
    at = await camera_layer_drawn(page)
    cart, robot, screen = at["cart"], at["robot"], at["map"]
    assert cart["right"] < robot["left"] and at["robot_on_top"], at
    assert cart["right"] - cart["left"] > 20, "big enough to see on a phone"
    assert screen["left"] <= cart["left"] and cart["right"] <= screen["right"]
    await no_sideways_scroll(page)
    os.makedirs(SCREENSHOTS, exist_ok=True)
    await page.screenshot(path=SCREENSHOTS / "inspector-cameras-phone.png")
    await page.locator("#map").screenshot(path=SCREENSHOTS / "inspector-cameras-phone-map.png")
    await page.context.close()
