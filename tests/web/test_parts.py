"""The pure parts of the web app: live-map geometry, the module graph, the rate limiter."""

from __future__ import annotations

from pathlib import Path

import pytest

from coffeebot.board import Board
from coffeebot.config import TofSensorConfig
from coffeebot.floorplan import load_floorplan
from coffeebot.messages import (
    ALL_TOPICS,
    CURRENT_STATE,
    ELEVATOR_REQUEST,
    ELEVATOR_STATE,
    MOTION_STATUS,
    MOVE_INSTRUCTION,
    PARTICLES,
    RANGE_SCAN,
    ROUTE,
    CurrentState,
    ElevatorRequest,
    ElevatorState,
    MotionState,
    MotionStatus,
    MoveInstruction,
    ParticleCloud,
    PlannedRoute,
    PoseEstimate,
    RangeReading,
    RangeScan,
    ReadingStatus,
    RouteLeg,
)
from coffeebot.modules.orders import OrdersModule
from coffeebot.sensor_view import ConeShape
from coffeebot.store import OrderStore
from coffeebot.web import WebModule
from coffeebot.web.context import RateLimiter
from coffeebot.web.graph import module_graph
from coffeebot.web.livemap import (
    CloudShape,
    EllipseShape,
    GoalShape,
    MapPose,
    PathShape,
    RobotShape,
    map_frame,
)

from .conftest import web_deps

FRONT = TofSensorConfig(id=3, channel=3, face="front", x_mm=300, y_mm=0, yaw_deg=0)
LEFT = TofSensorConfig(id=6, channel=6, face="left", x_mm=0, y_mm=250, yaw_deg=90, roi_spads=4)
RIGHT = TofSensorConfig(id=0, channel=0, face="right", x_mm=0, y_mm=-250, yaw_deg=-90)
PLAN = load_floorplan(Path(__file__).resolve().parents[2] / "floorplans" / "cs-building.toml")


class ManualClock:
    def __init__(self) -> None:
        self.t = 0.0

    def now(self) -> float:
        return self.t

    async def sleep(self, seconds: float) -> None:
        self.t += seconds


def test_cones_start_at_the_mount_turn_with_the_robot_and_say_the_reading() -> None:
    board = Board(ALL_TOPICS)
    readings = [
        RangeReading(sensor=3, status=ReadingStatus.VALID, distance_mm=1000),
        RangeReading(sensor=6, status=ReadingStatus.NO_TARGET),
        RangeReading(sensor=0, status=ReadingStatus.BUS_ERROR, healthy=False),
    ]
    board.publish(RANGE_SCAN, RangeScan(cycle_start_s=0, cycle_time_s=0.02, readings=readings))
    pose = MapPose(x_mm=5000, y_mm=800, heading_deg=90, floor=3)
    frame = map_frame(board, lambda: {"estimated": pose}, [FRONT, LEFT, RIGHT], 4000.0)
    assert frame.floor == 3
    front, left, right, robot = frame.shapes
    assert isinstance(front, ConeShape) and isinstance(left, ConeShape)
    assert isinstance(right, ConeShape)
    # Heading 90: the robot's forward is +y on the floor, its left is -x.
    assert (front.x_mm, front.y_mm, front.heading_deg) == pytest.approx((5000, 1100, 90))
    assert (front.reach, front.range_mm, front.text) == ("hit", 1000, "tof3: 1000 mm")
    # The cone is as wide as the sensor's configured field of view.
    # The narrowest region of interest draws the narrowest cone: 15 degrees.
    assert front.half_fov_deg == 13.5 and left.half_fov_deg == 7.5
    assert (left.x_mm, left.y_mm, left.heading_deg) == pytest.approx((4750, 800, 180))
    # Nothing in range: clear as far as the sensor sees, not a fault.
    assert (left.reach, left.range_mm, left.text) == ("clear", 4000, "tof6: nothing in range")
    assert (right.reach, right.text) == ("fault", "tof0: no reading (bus error)")
    assert robot == RobotShape(label="estimated", x_mm=5000, y_mm=800, heading_deg=90, floor=3)


def test_the_estimate_is_drawn_with_its_95_percent_ellipse() -> None:
    board = Board(ALL_TOPICS)
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
    here = MapPose(x_mm=5000, y_mm=0, heading_deg=0, floor=2)
    [ellipse] = [
        s for s in map_frame(board, lambda: {"e": here}, []).shapes if isinstance(s, EllipseShape)
    ]
    assert (ellipse.rx_mm, ellipse.ry_mm) == pytest.approx((244.8, 122.4), abs=0.1)
    # On another floor than the one shown: not drawn.
    elsewhere = here.model_copy(update={"floor": 3})
    assert not any(
        isinstance(s, EllipseShape) for s in map_frame(board, lambda: {"e": elsewhere}, []).shapes
    )


def test_the_route_is_drawn_from_the_robot_on_and_ends_at_the_goal() -> None:
    board = Board(ALL_TOPICS)
    legs = [
        RouteLeg(floor=2, points=[(0, 0), (10_000, -300), (20_000, -300)]),
        RouteLeg(floor=3, points=[(20_000, -300), (30_000, 300)]),
    ]
    board.publish(ROUTE, PlannedRoute(order_id="a", to="307", legs=legs))
    here = MapPose(x_mm=12_000, y_mm=-250, heading_deg=0, floor=2)
    [path] = map_frame(board, lambda: {"e": here}, []).shapes[:-1]
    assert isinstance(path, PathShape) and path.role == "route"
    assert path.points == [(12_000, -250), (20_000, -300)]
    # On floor 3 the last leg is shown, with the door it ends at.
    there = MapPose(x_mm=20_000, y_mm=-300, heading_deg=0, floor=3)
    path, goal, _ = map_frame(board, lambda: {"e": there}, []).shapes
    assert isinstance(path, PathShape) and path.points[-1] == (30_000, 300)
    assert goal == GoalShape(label="307", x_mm=30_000, y_mm=300)


def test_a_detour_is_drawn_out_to_its_lane_past_the_obstacle_and_back() -> None:
    board = Board(ALL_TOPICS)
    board.publish(
        MOVE_INSTRUCTION,
        MoveInstruction(action="follow_lane", floor=2, target_s_mm=20_000, lane_mm=-300),
    )
    board.publish(
        MOTION_STATUS,
        MotionStatus(
            instruction_id=1,
            state=MotionState.AVOIDING,
            detour_phase="going_round",
            detour_lane_mm=350,
            detour_until_s_mm=9_000,
        ),
    )
    here = MapPose(x_mm=8_000, y_mm=-300, heading_deg=0, floor=2)
    [detour] = [
        s
        for s in map_frame(board, lambda: {"e": here}, [], plan=PLAN).shapes
        if isinstance(s, PathShape)
    ]
    assert detour.role == "detour"
    assert detour.points == [(8_000, -300), (8_600, 350), (9_600, 350), (10_800, -300)]


def test_the_map_says_when_the_robot_rides_the_elevator() -> None:
    board = Board(ALL_TOPICS)
    board.publish(ELEVATOR_REQUEST, ElevatorRequest(action="send", floor=3))
    board.publish(ELEVATOR_STATE, ElevatorState(car_floor=2, doors="closed", moving=True))
    here = MapPose(x_mm=0, y_mm=0, heading_deg=0, floor=2)
    assert map_frame(board, lambda: {"e": here}, []).caption == "riding the elevator to floor 3"


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
