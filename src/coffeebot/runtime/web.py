"""The web UI wired to one daemon: the order form for the plan's offices, the floor maps, the
pose the live map draws and the inspector's view of the modules."""

from __future__ import annotations

import functools
import os
from collections.abc import Callable, Mapping, Sequence

from coffeebot.board import Board
from coffeebot.config import RobotConfig
from coffeebot.cpu import CpuLedger
from coffeebot.floorplan import FloorPlan
from coffeebot.floorplan_svg import render_svg
from coffeebot.messages import CURRENT_STATE, Health
from coffeebot.modules.base import Module
from coffeebot.orders import Orders
from coffeebot.web import RoomChoice, WebDeps, WebModule
from coffeebot.web.livemap import MapPose, PoseSource

TruePose = Callable[[], MapPose]
"""Where the robot really is (the simulator's ground truth), for the live map."""


def floor_svgs(plan: FloorPlan) -> Callable[[int], str | None]:
    """One floor's drawing for the web map, rendered once per floor."""
    levels = {f.level for f in plan.floors}

    @functools.cache
    def svg(level: int) -> str | None:
        return render_svg(plan, [level]) if level in levels else None

    return svg


def office_choices(plan: FloorPlan) -> list[RoomChoice]:
    """Every office of the plan, floor by floor in door order, for the order form."""
    return [
        RoomChoice(id=room, floor=plan.find_room(room).floor.level, label=f"Office {room}")
        for room in plan.rooms
    ]


def pose_source(board: Board, true_pose: TruePose | None) -> Callable[[], Mapping[str, MapPose]]:
    """The estimate first (the map draws scans from it), then the true pose if there is one."""

    def poses() -> Mapping[str, MapPose]:
        found: dict[str, MapPose] = {}
        state = board.latest(CURRENT_STATE)
        if state is not None and state.msg.pose.initialised:
            p = state.msg.pose
            found["estimated"] = MapPose(
                x_mm=p.x_mm, y_mm=p.y_mm, heading_deg=p.heading_deg, floor=p.floor
            )
        if true_pose is not None:
            found["true"] = true_pose()
        return found

    return poses


def web_module(
    config: RobotConfig,
    plan: FloorPlan,
    board: Board,
    orders: Orders,
    modules: Callable[[], Sequence[Module]],
    health: Callable[[], Sequence[Health]],
    cpu: Callable[[], CpuLedger] | None = None,
    true_pose: TruePose | None = None,
    poses: PoseSource | None = None,
) -> WebModule:
    """The web UI: order form for the plan's offices, floor maps, the inspector. The map
    draws ``poses`` (a fleet's robots), by default this robot's estimate and ``true_pose``."""
    return WebModule(
        WebDeps(
            board=board,
            orders=orders,
            rooms=office_choices(plan),
            config=config.web,
            operator_token=os.environ.get(config.web.operator_token_env),
            modules=modules,
            floor_svg=floor_svgs(plan),
            poses=poses or pose_source(board, true_pose),
            sensors=config.tof.sensors,
            geometry=config.geometry,
            health=health,
            cpu=cpu,
            plan=plan,
            max_range_mm=config.tof.max_range_mm,
            pickup_timeout_s=config.navigation.pickup_timeout_s,
        )
    )
