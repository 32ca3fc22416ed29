"""The pure parts of the web app: live-map geometry, the module graph, the rate limiter."""

from __future__ import annotations

import pytest

from coffeebot.board import Board
from coffeebot.config import TofSensorConfig
from coffeebot.messages import (
    ALL_TOPICS,
    CURRENT_STATE,
    PARTICLES,
    RANGE_SCAN,
    CurrentState,
    ParticleCloud,
    PoseEstimate,
    RangeReading,
    RangeScan,
    ReadingStatus,
)
from coffeebot.modules.orders import OrdersModule
from coffeebot.store import OrderStore
from coffeebot.web import WebModule
from coffeebot.web.context import RateLimiter
from coffeebot.web.graph import module_graph
from coffeebot.web.livemap import (
    NO_TARGET_RAY_MM,
    CloudShape,
    EllipseShape,
    MapPose,
    RayShape,
    RobotShape,
    map_frame,
)

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


def test_the_particle_cloud_and_the_uncertainty_ellipse_are_drawn() -> None:
    board = Board(ALL_TOPICS)
    # sigma_x 100, sigma_y 50, no correlation: a 95 % ellipse of 2.45 x those, along x.
    pose = PoseEstimate(
        x_mm=5000,
        y_mm=0,
        heading_deg=0,
        floor=2,
        sigma_x_mm=100,
        sigma_y_mm=50,
        sigma_heading_deg=1,
    )
    board.publish(CURRENT_STATE, CurrentState(pose=pose))
    board.publish(
        PARTICLES,
        ParticleCloud(floor=2, x_mm=[4900, 5100], y_mm=[10, -10], heading_deg=[0, 1]),
    )
    here = MapPose(x_mm=5000, y_mm=0, heading_deg=0, floor=2)
    shapes = map_frame(board, lambda: {"estimated": here}, [FRONT]).shapes
    cloud = next(s for s in shapes if isinstance(s, CloudShape))
    ellipse = next(s for s in shapes if isinstance(s, EllipseShape))
    assert cloud.points == [(4900, 10), (5100, -10)]
    assert (ellipse.rx_mm, ellipse.ry_mm) == pytest.approx((244.8, 122.4), abs=0.1)
    assert ellipse.angle_deg == pytest.approx(0.0)
    # A cloud from another floor (the robot just left the elevator) is not drawn.
    board.publish(PARTICLES, ParticleCloud(floor=3, x_mm=[1], y_mm=[1], heading_deg=[0]))
    shapes = map_frame(board, lambda: {"estimated": here}, [FRONT]).shapes
    assert not any(isinstance(s, CloudShape) for s in shapes)


def test_a_correlated_covariance_tilts_the_ellipse() -> None:
    board = Board(ALL_TOPICS)
    pose = PoseEstimate(
        x_mm=0,
        y_mm=0,
        heading_deg=0,
        floor=2,
        sigma_x_mm=100,
        sigma_y_mm=100,
        sigma_heading_deg=1,
        cov_xy_mm2=5000,
    )
    board.publish(CURRENT_STATE, CurrentState(pose=pose))
    here = MapPose(x_mm=0, y_mm=0, heading_deg=0, floor=2)
    (ellipse,) = [
        s for s in map_frame(board, lambda: {"e": here}, []).shapes if isinstance(s, EllipseShape)
    ]
    # Eigenvalues 15000 and 5000 mm^2, the long axis along the diagonal.
    assert ellipse.angle_deg == pytest.approx(45.0)
    assert ellipse.rx_mm == pytest.approx(2.448 * 15000**0.5, rel=1e-3)
    assert ellipse.ry_mm == pytest.approx(2.448 * 5000**0.5, rel=1e-3)
