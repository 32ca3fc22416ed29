"""The pages in a real browser (Debian's Chromium through Playwright) against a live daemon.

The daemon runs the orders and web modules on a real port with the building's real floor
plan; a small stand-in robot stands in the hallway publishing scans and its pose, and the
tests play navigation and the other modules by publishing what they would
(``test_browser_sim.py`` runs the whole simulated robot instead). One daemon and one browser
serve the whole module; each test has its own page.
"""

from __future__ import annotations

import asyncio
import contextlib
import os
import re
from collections.abc import AsyncIterator
from dataclasses import dataclass, field
from pathlib import Path

import playwright.async_api as playwright
import pytest
import pytest_asyncio

from coffeebot.board import Board
from coffeebot.config import WebConfig, load_robot_config
from coffeebot.daemon import Daemon
from coffeebot.floorplan import load_floorplan
from coffeebot.messages import (
    ALL_TOPICS,
    CURRENT_STATE,
    DELIVERY_STATUS,
    HEALTH,
    MOTION_STATUS,
    OPERATOR_EVENT,
    PARTICLES,
    RANGE_SCAN,
    ROUTE,
    CurrentState,
    DeliveryUpdate,
    Health,
    HealthStatus,
    MotionState,
    MotionStatus,
    OrderStatus,
    ParticleCloud,
    PlannedRoute,
    PoseEstimate,
    RangeReading,
    RangeScan,
    ReadingStatus,
    RouteLeg,
    StopCause,
)
from coffeebot.modules.orders import OrdersModule
from coffeebot.runtime.web import floor_svgs, office_choices, pose_source
from coffeebot.store import OrderStore
from coffeebot.web import WebDeps, WebModule
from coffeebot.web.livemap import MapPose

pytestmark = [pytest.mark.asyncio(loop_scope="module"), pytest.mark.xdist_group("test_browser")]

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
PLAN = load_floorplan(REPO / "floorplans" / "cs-building.toml")
TOKEN = "operator-secret"
DESKTOP = {"width": 1280, "height": 900}
PHONE = {"width": 390, "height": 844}
# The browser tests on the simulated robot save screenshots here (ignored by git);
# `make screenshots` refreshes the README's copies in docs/screenshots/ by pointing it there.
SCREENSHOTS = Path(os.environ.get("COFFEEBOT_SCREENSHOTS", REPO / "test-artifacts" / "screenshots"))


class StandInRobot:
    """Stands in floor 2's hallway (or wherever a test puts it), publishing a scan and its
    estimated pose every step; its "true" pose sits 60 mm to the left of the estimate."""

    def __init__(self, board: Board) -> None:
        self.board = board
        self.pose = MapPose(x_mm=12_000, y_mm=-300, heading_deg=0, floor=2)
        self.faulty_sensor: int | None = None

    def true_pose(self) -> MapPose:
        return self.pose.model_copy(update={"y_mm": self.pose.y_mm + 60})

    async def run(self) -> None:
        while True:
            p = self.pose
            estimate = PoseEstimate(
                x_mm=p.x_mm,
                y_mm=p.y_mm,
                heading_deg=p.heading_deg,
                floor=p.floor,
                sigma_x_mm=120,
                sigma_y_mm=60,
                sigma_heading_deg=2,
            )
            self.board.publish(CURRENT_STATE, CurrentState(pose=estimate))
            readings = [
                RangeReading(sensor=i, status=ReadingStatus.VALID, distance_mm=600 + 40 * i)
                for i in range(7)
            ] + [RangeReading(sensor=7, status=ReadingStatus.OUT_OF_BOUNDS)]
            if self.faulty_sensor is not None:
                readings[self.faulty_sensor] = RangeReading(
                    sensor=self.faulty_sensor, status=ReadingStatus.BUS_ERROR, healthy=False
                )
            self.board.publish(
                RANGE_SCAN, RangeScan(cycle_start_s=0.0, cycle_time_s=0.02, readings=readings)
            )
            await asyncio.sleep(0.05)


@dataclass
class Served:
    url: str
    board: Board
    orders: OrdersModule
    robot: StandInRobot
    browser: playwright.Browser
    failed_responses: list[str] = field(default_factory=list)

    async def page(self, viewport: dict[str, int] = DESKTOP) -> playwright.Page:
        context = await self.browser.new_context(viewport=viewport)  # type: ignore[arg-type]
        page = await context.new_page()
        page.set_default_timeout(15_000)
        page.on("dialog", lambda d: pytest.fail(f"a script injected through an order ran: {d}"))
        page.on(
            "response",
            lambda r: (
                self.failed_responses.append(f"{r.status} {r.url}") if r.status >= 400 else None
            ),
        )
        return page


@pytest_asyncio.fixture(scope="module", loop_scope="module")
async def served(tmp_path_factory: pytest.TempPathFactory) -> AsyncIterator[Served]:
    board = Board(ALL_TOPICS)
    robot_config = load_robot_config(BOARD_FILE)
    store = OrderStore(tmp_path_factory.mktemp("web") / "orders.sqlite3")
    orders = OrdersModule(store)
    robot = StandInRobot(board)
    web = WebModule(
        WebDeps(
            board=board,
            orders=orders,
            rooms=office_choices(PLAN),
            config=WebConfig(
                port=0,
                stream_period_s=0.2,
                progress_period_s=0.3,
                order_burst=100,  # every test here orders from 127.0.0.1, at the test's pace
            ),
            operator_token=TOKEN,
            modules=lambda: daemon.modules,
            floor_svg=floor_svgs(PLAN),
            poses=pose_source(board, robot.true_pose),
            sensors=robot_config.tof.sensors,
            geometry=robot_config.geometry,
            health=lambda: daemon.health(),
            plan=PLAN,
        )
    )
    daemon = Daemon(board, [orders, web])
    await daemon.start()
    standing = asyncio.create_task(robot.run())
    await web.started.wait()
    assert web.url is not None
    async with playwright.async_playwright() as p:
        browser = await p.chromium.launch(executable_path=str(CHROMIUM), args=CHROMIUM_ARGS)
        yield Served(web.url, board, orders, robot, browser)
        await browser.close()
    standing.cancel()
    with contextlib.suppress(asyncio.CancelledError):
        await standing
    await daemon.shutdown()
    store.close()


@pytest_asyncio.fixture(loop_scope="module")
async def page(served: Served) -> AsyncIterator[playwright.Page]:
    page = await served.page()
    yield page
    await page.context.close()


async def idle(served: Served) -> None:
    """End every order, so each test starts with an idle robot and an empty queue: the one out
    as navigation would (cancelled), the queued ones as their customers would."""
    for order in await served.orders.active():
        if order.status is OrderStatus.QUEUED:
            await served.orders.cancel(order.id)
        else:
            cancelled = DeliveryUpdate(order_id=order.id, status=OrderStatus.CANCELLED)
            served.board.publish(DELIVERY_STATUS, cancelled)
    for _ in range(100):
        if not await served.orders.active():
            return
        await asyncio.sleep(0.02)
    raise AssertionError("orders still active")


@pytest_asyncio.fixture(autouse=True, loop_scope="module")
async def each_test_starts_idle(served: Served) -> AsyncIterator[None]:
    await idle(served)
    served.robot.pose = MapPose(x_mm=12_000, y_mm=-300, heading_deg=0, floor=2)
    served.robot.faulty_sensor = None
    yield
    await idle(served)


async def order_through_the_form(page: playwright.Page, url: str, name: str, room: str) -> str:
    await page.goto(url + "/")
    await page.select_option("select[name=drink]", "latte")
    await page.fill("input[name=name]", name)
    await page.select_option("select[name=room]", room)
    await page.click("button[type=submit]")
    status_page = re.compile(r"/orders/[A-Za-z0-9_-]+\?key=[A-Za-z0-9_-]+$")
    await playwright.expect(page).to_have_url(status_page)
    order_id = await page.locator("#order").get_attribute("data-order-id")
    assert order_id
    return order_id


def steps(page: playwright.Page) -> playwright.Locator:
    return page.locator("#steps li")


async def test_order_through_the_form_and_follow_its_timeline(
    page: playwright.Page, served: Served
) -> None:
    expect = playwright.expect
    await page.goto(served.url + "/")
    await page.select_option("select[name=drink]", "latte")
    await page.fill("input[name=name]", "Ada <img src=x onerror=alert(1)>")
    await page.select_option("select[name=room]", "307")
    await page.fill("textarea[name=notes]", "oat milk <script>alert(2)</script>")
    await page.click("button[type=submit]")

    await expect(page).to_have_url(re.compile(r"/orders/[A-Za-z0-9_-]+\?key=[A-Za-z0-9_-]+$"))
    await expect(page.locator("#order-name")).to_have_text("Ada <img src=x onerror=alert(1)>")
    await expect(page.locator("#status-text")).to_have_text("Being prepared in the tea room")
    await expect(page.locator("#live")).to_have_text("live")
    # Floor 3 from the tea room on floor 2: the elevator and floor 3 are steps of their own.
    await expect(steps(page)).to_have_text(
        [
            "Ordered",
            "In the tea room",
            "On the way",
            "In the elevator",
            "On floor 3",
            "At your door",
            "Delivered",
        ]
    )
    await expect(page.locator("#steps li.current")).to_have_text("In the tea room")
    order_id = await page.locator("#order").get_attribute("data-order-id")
    assert order_id

    def report(status: OrderStatus, detail: str = "", ready: bool = False) -> None:
        update = DeliveryUpdate(
            order_id=order_id, status=status, detail=detail, ready_for_cup=ready
        )
        served.board.publish(DELIVERY_STATUS, update)

    report(OrderStatus.PREPARING, "the robot is in the tea room, waiting for the cup", True)
    await expect(page.locator("#detail")).to_have_text(
        "The robot is in the tea room; staff are putting your latte on it."
    )
    # On the way along a route 20 m on floor 2 and 10 m on floor 3: an estimate that moves.
    legs = [
        RouteLeg(floor=2, points=[(2_000, -300), (40_000, -300)]),
        RouteLeg(floor=3, points=[(40_000, -300), (50_000, -300)]),
    ]
    served.board.publish(ROUTE, PlannedRoute(order_id=order_id, to="307", legs=legs))
    served.robot.pose = served.robot.pose.model_copy(update={"x_mm": 2_000})
    report(OrderStatus.ON_THE_WAY, "leaving the tea room for 307")
    await expect(page.locator("#status-text")).to_have_text("On the way")
    await expect(page.locator("#detail")).to_have_text("The robot is carrying your latte to 307.")
    # 48 m at 0.3 m/s and one ride: about 4 min; nearer the elevator, about 2 min.
    await expect(page.locator("#eta")).to_have_text(re.compile(r"^Arriving in about 4 min"))
    served.robot.pose = served.robot.pose.model_copy(update={"x_mm": 30_000})
    await expect(page.locator("#eta")).to_have_text(re.compile(r"^Arriving in about 2 min"))
    await expect(page.locator("#pickup")).to_be_hidden()
    report(OrderStatus.ARRIVED, "at the door of 307 (-7 mm)")
    await expect(page.locator("#status-text")).to_have_text("At your door")
    await expect(page.locator("#detail")).to_have_text(
        "Please take your latte from the robot, then press the button."
    )
    await expect(page.locator("#countdown")).to_have_text(
        re.compile(r"^The robot waits [23]:\d\d more, then takes the cup back to the tea room\.$")
    )
    await expect(page.locator("#eta")).to_be_hidden()
    assert "mm" not in (await page.locator("#order").inner_text())
    async with page.expect_response(lambda r: "/pickup?key=" in r.url) as answer:
        await page.click("#pickup")
    assert (await answer.value).status == 202
    await expect(page.locator("#action-error")).to_be_hidden()
    event = served.board.latest(OPERATOR_EVENT)
    assert event is not None
    assert (event.msg.kind, event.msg.order_id) == ("pickup_confirmed", order_id)
    report(OrderStatus.DELIVERED, "picked up at 307")
    await expect(page.locator("#status-text")).to_have_text("Delivered, enjoy!")
    await expect(page.locator("#detail")).to_have_text("Enjoy your latte.")
    await expect(page.locator("#steps li.done")).to_have_count(7)
    await expect(page.locator("#keep-link")).to_be_hidden()
    await expect(page.locator("#countdown")).to_be_hidden()
    assert served.failed_responses == [], "no 404 for the favicon or anything else"


async def test_a_queued_order_says_its_place_in_words_and_can_be_cancelled(
    page: playwright.Page, served: Served
) -> None:
    expect = playwright.expect
    await order_through_the_form(page, served.url, "First", "207")
    await order_through_the_form(page, served.url, "Second", "207")
    await expect(page.locator("#detail")).to_have_text("1 order ahead of yours.")
    await expect(page.locator("#keep-link")).to_contain_text("and cancel")
    await page.click("#cancel")
    await expect(page.locator("#status-text")).to_have_text("Cancelled")
    await expect(page.locator("#detail")).to_have_text("You cancelled this order.")
    await expect(page.locator("#cancel")).to_be_hidden()
    await expect(page.locator("#keep-link")).to_be_hidden()


async def test_the_form_asks_for_an_office_and_says_what_to_fix(
    page: playwright.Page, served: Served
) -> None:
    expect = playwright.expect
    await page.goto(served.url + "/")
    # Nothing is chosen for the customer, and the browser will not send the form without it.
    await expect(page.locator("select[name=room]")).to_have_value("")
    await page.fill("input[name=name]", "Ada")
    await page.click("button[type=submit]")
    await expect(page).to_have_url(served.url + "/")
    assert await page.eval_on_selector("select[name=room]", "e => !e.checkValidity()")
    # Sent anyway (a script, an old browser): the page says it in words.
    answer = await page.request.post(served.url + "/orders", form={"drink": "latte", "name": ""})
    assert answer.status == 422
    await page.set_content(await answer.text())
    await expect(page.locator('.error[data-field="name"]')).to_have_text(
        "Please tell us your name, so the robot knows whose cup it carries."
    )
    await expect(page.locator('.error[data-field="room"]')).to_have_text("Please pick your office.")


BOXES = """label => {
    const box = (e) => { const r = e.getBoundingClientRect();
        return {x: r.x, y: r.y, width: r.width, height: r.height}; };
    const robot = document.querySelector(`#map g.robot[data-label=${label}] rect`);
    const hallway = document.querySelector("#map polygon.hallway");
    return {robot: robot && box(robot), hallway: box(hallway),
            map: box(document.querySelector("#map"))};
}"""


async def drawn(page: playwright.Page, label: str, pose: MapPose) -> dict[str, float]:
    """Where the robot ``label`` is drawn on screen and where the plan's own hallway says the
    pose should be: the hallway polygon's box on screen against the hallway's extent in the
    plan (read at one moment, as the overlay is redrawn with every frame)."""
    boxes = await page.evaluate(BOXES, label)
    robot, hallway = boxes["robot"], boxes["hallway"]
    assert robot is not None
    floor = PLAN.floor(pose.floor)
    half = floor.hallway.width_mm / 2
    corners = [
        floor.from_hallway(s, d) for s in (0, floor.hallway.length_mm) for d in (-half, half)
    ]
    xs, ys = [c[0] for c in corners], [c[1] for c in corners]
    return {
        "x": robot["x"] + robot["width"] / 2,
        "y": robot["y"] + robot["height"] / 2,
        "size": robot["width"],
        "want_x": hallway["x"] + (pose.x_mm - min(xs)) / (max(xs) - min(xs)) * hallway["width"],
        "want_y": hallway["y"] + (max(ys) - pose.y_mm) / (max(ys) - min(ys)) * hallway["height"],
        "hall_top": hallway["y"],
        "hall_bottom": hallway["y"] + hallway["height"],
        "map_centre_x": boxes["map"]["x"] + boxes["map"]["width"] / 2,
    }


async def test_the_robot_is_drawn_in_the_hallway_where_its_pose_says(
    page: playwright.Page, served: Served
) -> None:
    expect = playwright.expect
    await page.goto(served.url + "/inspect")
    await expect(page.locator("#map g.robot[data-label=true]")).to_have_count(1)
    true = served.robot.true_pose()
    for view in ("follow", "whole floor"):
        at = await drawn(page, "true", true)
        assert abs(at["x"] - at["want_x"]) < 3 and abs(at["y"] - at["want_y"]) < 3, (view, at)
        assert at["hall_top"] < at["y"] < at["hall_bottom"], view
        if view == "follow":
            # Zoomed to the robot: big enough to see, in the middle of the map.
            assert at["size"] > 40 and abs(at["x"] - at["map_centre_x"]) < 80
            await page.click("#view-toggle")
            await expect(page.locator("#view-toggle")).to_have_text("Follow robot")
            small = "document.querySelector('#map g.robot rect').getBoundingClientRect().width < 20"
            await page.wait_for_function(f"() => {small}")


async def test_the_map_draws_cones_route_ellipse_particles_and_legend(
    page: playwright.Page, served: Served
) -> None:
    expect = playwright.expect
    legs = [RouteLeg(floor=2, points=[(12_000, -300), (20_500, -300), (21_000, 350)])]
    served.board.publish(ROUTE, PlannedRoute(order_id="x", to="207", legs=legs))
    cloud = ParticleCloud(floor=2, x_mm=[11_900, 12_100], y_mm=[-250, -350], heading_deg=[0, 1])
    served.board.publish(PARTICLES, cloud)
    await page.goto(served.url + "/inspect")
    cones = page.locator("#map polygon.cone")
    await expect(cones).to_have_count(8)
    await expect(page.locator("#map polygon.cone.hit")).to_have_count(7)
    await expect(page.locator("#map polygon.cone.clear")).to_have_count(1)
    await expect(page.locator("#map circle.hit-point")).to_have_count(7)
    readings = page.locator("#readings li")
    await expect(readings).to_have_text(
        [f"tof{i}: {600 + 40 * i} mm" for i in range(7)] + ["tof7: nothing in range"]
    )
    await expect(page.locator("#map ellipse.uncertainty")).to_have_count(1)
    await expect(page.locator("#map polyline.path.route")).to_have_count(1)
    await expect(page.locator("#map text.goal-label")).to_have_text("207")
    await expect(page.locator("#map g.particles circle")).to_have_count(2)
    await expect(page.locator("#legend li")).to_have_count(13)
    # A sensor that stops answering turns red and raises an alert.
    served.robot.faulty_sensor = 3
    await expect(page.locator("#map polygon.cone.fault")).to_have_count(1)
    await expect(page.locator("#readings li.fault")).to_have_text("tof3: no reading (bus error)")
    await expect(page.locator("#alerts li.warning")).to_contain_text(["Sensor tof3"])
    served.board.publish(ROUTE, PlannedRoute(to="tea room"))


async def test_the_map_switches_floor_with_the_robot(page: playwright.Page, served: Served) -> None:
    expect = playwright.expect
    await page.goto(served.url + "/inspect")
    await expect(page.locator("#map")).to_have_attribute("data-floor", "2")
    served.robot.pose = served.robot.pose.model_copy(update={"floor": 3, "x_mm": 41_000})
    await expect(page.locator("#map")).to_have_attribute("data-floor", "3")
    await expect(page.locator("#map #floor-3 text.title")).to_have_text("Floor 3")
    await expect(page.locator("#map g.robot[data-label=estimated]")).to_have_count(1)


async def test_the_operator_sees_alerts_by_severity_with_their_age(
    page: playwright.Page, served: Served
) -> None:
    expect = playwright.expect
    await page.goto(served.url + "/inspect")
    await expect(page.locator("#stream-state")).to_have_text("live")
    served.board.publish(
        MOTION_STATUS,
        MotionStatus(
            instruction_id=1,
            state=MotionState.SAFETY_STOP,
            since_s=4.0,
            detail="obstacle at 310 mm",
            stopped_by=StopCause.COLLISION_STOP,
        ),
    )
    served.board.publish(
        HEALTH, Health(module="collision", component="tof5", status=HealthStatus.DEGRADED)
    )
    alerts = page.locator("#alerts li")
    await expect(alerts.filter(has_text="Robot held by the safety gate")).to_contain_text(
        re.compile(r"obstacle at 310 mm.*for \d+(\.\d)? s · value \d+(\.\d)? s old · motion/status")
    )
    await expect(alerts.filter(has_text="tof5 (collision) degraded")).to_have_count(1)
    # Nothing publishes uwb/fix or the collision verdicts here: stale topics, and the age shows.
    await expect(alerts.filter(has_text="No uwb/fix yet")).to_have_count(1)
    severities = await alerts.evaluate_all("items => items.map(i => i.className)")
    ranks = ["critical", "warning", "info"]
    order = [next(r for r in ranks if r in c) for c in severities]
    assert order == sorted(order, key=ranks.index)
    await expect(page.locator('tr[data-topic="uwb/fix"] td.stale')).to_have_count(1)
    served.board.publish(
        HEALTH, Health(module="collision", component="tof5", status=HealthStatus.RUNNING)
    )
    served.board.publish(MOTION_STATUS, MotionStatus(instruction_id=1, state=MotionState.IDLE))
    await expect(alerts.filter(has_text="tof5")).to_have_count(0)


async def test_the_orders_table_follows_the_orders_live(
    page: playwright.Page, served: Served
) -> None:
    expect = playwright.expect
    customer = await served.page()
    order_id = await order_through_the_form(customer, served.url, "Grace", "207")
    await order_through_the_form(customer, served.url, "Linus", "209")
    await page.goto(served.url + "/inspect")
    await expect(page.locator("#orders-note")).to_have_text(
        "Enter the operator token to see the orders."
    )
    await page.fill("#token", TOKEN)
    await page.dispatch_event("#token", "change")
    rows = page.locator("#orders-table tbody tr")
    await expect(rows).to_have_count(2)
    first = page.locator(f'#orders-table tr[data-order="{order_id}"]')
    await expect(first.locator("td").nth(0)).to_have_text("out now")
    await expect(rows.nth(1).locator("td").nth(0)).to_have_text("#1")
    await expect(first.locator("td.status")).to_have_text("Being prepared in the tea room")
    await first.locator("button", has_text="Cup loaded").click()
    await expect(page.locator("#operator-message")).to_have_text(
        "Cup loaded: Grace's latte to 207 is on its way."
    )
    event = served.board.latest(OPERATOR_EVENT)
    assert event is not None and event.msg.kind == "cup_loaded"
    # Navigation leaves; the table changes without anyone pressing anything.
    update = DeliveryUpdate(order_id=order_id, status=OrderStatus.ON_THE_WAY)
    served.board.publish(DELIVERY_STATUS, update)
    await expect(first.locator("td.status")).to_have_text("On the way")
    await expect(first.locator("button", has_text="Cup loaded")).to_have_count(0)
    for status in (OrderStatus.ARRIVED, OrderStatus.DELIVERED):
        served.board.publish(DELIVERY_STATUS, update.model_copy(update={"status": status}))
    await expect(first).to_have_count(0)
    await expect(rows).to_have_count(1)
    await expect(rows.first.locator("td.status")).to_have_text("Being prepared in the tea room")
    # Wrong token: said as it is.
    await page.fill("#token", "wrong")
    await page.dispatch_event("#token", "change")
    await page.click("#estop")
    await expect(page.locator("#operator-message")).to_have_text("operator token required")
    await page.fill("#token", TOKEN)
    await page.dispatch_event("#token", "change")
    await page.click("#estop")
    await expect(page.locator("#estop-state")).to_have_text(re.compile("ENGAGED"))
    await expect(page.locator("#alerts li.critical")).to_contain_text("Emergency stop engaged")
    await page.click("#resume")
    await expect(page.locator("#estop-state")).to_have_text("released")
    await expect(page.locator("#operator-message")).to_have_text("Emergency stop released.")
    await customer.context.close()


async def no_sideways_scroll(page: playwright.Page) -> None:
    width = await page.evaluate("() => document.documentElement.scrollWidth")
    assert width <= PHONE["width"], f"the page is {width} px wide on a {PHONE['width']} px phone"


async def test_phone_size_inspector_is_one_column_with_a_usable_map(served: Served) -> None:
    expect = playwright.expect
    page = await served.page(PHONE)
    await page.goto(served.url + "/inspect")
    await expect(page.locator("#map g.robot[data-label=estimated]")).to_have_count(1)
    await no_sideways_scroll(page)
    map_box = await page.locator("#map").bounding_box()
    assert map_box is not None and map_box["width"] > 340
    for button in ("#estop", "#resume"):
        box = await page.locator(button).bounding_box()
        assert box is not None and box["x"] >= 0 and box["x"] + box["width"] <= PHONE["width"]
    # One column: the alerts come below the map, not beside it.
    alerts = await page.locator("#alerts").bounding_box()
    assert alerts is not None and alerts["y"] > map_box["y"] + map_box["height"]
    await page.context.close()


async def test_phone_size_order_pages_fit(served: Served) -> None:
    page = await served.page(PHONE)
    await order_through_the_form(page, served.url, "Ada", "207")
    await playwright.expect(steps(page)).to_have_count(5)
    await no_sideways_scroll(page)
    await page.goto(served.url + "/")
    await no_sideways_scroll(page)
    await page.context.close()
