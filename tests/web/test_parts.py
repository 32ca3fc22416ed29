"""The pure parts of the web app: live-map geometry, the module graph, the rate limiter."""

from __future__ import annotations

import pytest

from coffeebot.board import Board
from coffeebot.config import TofSensorConfig
from coffeebot.messages import ALL_TOPICS, RANGE_SCAN, RangeReading, RangeScan, ReadingStatus
from coffeebot.modules.orders import OrdersModule
from coffeebot.store import OrderStore
from coffeebot.web import WebModule
from coffeebot.web.context import RateLimiter
from coffeebot.web.graph import module_graph
from coffeebot.web.livemap import NO_TARGET_RAY_MM, MapPose, RayShape, RobotShape, map_frame

from .conftest import web_deps

FRONT = TofSensorConfig(id=3, channel=3, face="front", x_mm=300, y_mm=0, yaw_deg=0)
LEFT = TofSensorConfig(id=6, channel=6, face="left", x_mm=0, y_mm=250, yaw_deg=90)


class ManualClock:
    def __init__(self) -> None:
        self.t = 0.0

    def now(self) -> float:
        return self.t

    async def sleep(self, seconds: float) -> None:
        self.t += seconds


def test_rays_start_at_the_mount_and_turn_with_the_robot() -> None:
    board = Board(ALL_TOPICS)
    readings = [
        RangeReading(sensor=3, status=ReadingStatus.VALID, distance_mm=1000),
        RangeReading(sensor=6, status=ReadingStatus.NO_TARGET),
    ]
    board.publish(RANGE_SCAN, RangeScan(cycle_start_s=0, cycle_time_s=0.02, readings=readings))
    pose = MapPose(x_mm=5000, y_mm=800, heading_deg=90, floor=3)
    frame = map_frame(board, lambda: {"estimated": pose}, [FRONT, LEFT])
    assert frame.floor == 3
    front, left, robot = frame.shapes
    assert isinstance(front, RayShape) and isinstance(left, RayShape)
    # Heading 90: the robot's forward is +y on the floor, its left is -x.
    assert (front.x1_mm, front.y1_mm) == pytest.approx((5000, 1100))
    assert (front.x2_mm, front.y2_mm) == pytest.approx((5000, 2100))
    assert (left.x1_mm, left.y1_mm) == pytest.approx((4750, 800))
    assert (left.x2_mm, left.y2_mm) == pytest.approx((4750 - NO_TARGET_RAY_MM, 800))
    assert left.status == "no_target"
    assert robot == RobotShape(label="estimated", x_mm=5000, y_mm=800, heading_deg=90)


def test_no_pose_draws_nothing() -> None:
    assert map_frame(Board(ALL_TOPICS), None, [FRONT]).shapes == []


async def test_graph_edges_follow_declarations(store: OrderStore, board: Board) -> None:
    orders = OrdersModule(store)
    graph = module_graph([orders, WebModule(web_deps(board, orders))])
    labels = {(b.kind, b.label) for b in graph.boxes}
    assert ("writer", "web") in labels
    assert ("topic", "operator/estop") in labels
    assert ("reader", "orders") in labels
    declared = sum(len(m.inputs) + len(m.outputs) for m in (orders, WebModule))
    assert len(graph.edges) == declared


def test_rate_limiter_burst_then_refill() -> None:
    clock = ManualClock()
    limiter = RateLimiter(burst=2, refill_s=10.0, clock=clock)
    assert limiter.take("a") == limiter.take("a") == 0.0
    assert limiter.take("a") == pytest.approx(10.0)
    assert limiter.take("b") == 0.0  # per client
    clock.t = 9.0
    assert limiter.take("a") == pytest.approx(1.0)
    clock.t = 10.5
    assert limiter.take("a") == 0.0
