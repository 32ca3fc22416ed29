"""The go-around: what lane keeping does about an obstacle in its lane (no I/O).

A detour has three phases. **Confirming**: something is in the lane ahead; the robot stops
short of it until it has stood still for ``static_confirm_s`` (a person walking, or
something just seen, is waited for) and, if the instruction allows leaving the lane, a lane
past it is free. **Going round**: the dynamic window holds the detour lane until the body's
rear is beyond the obstacle's extent, the furthest along-hallway position seen of it (a long
cart is seen bit by bit, so the extent grows and the detour lane may move out). **Rejoining**:
past it with the lane ahead clear, the dynamic window steers back to the lane, checking the
rear's swing against the walls, until the robot is within ``REJOIN_MM`` of it; then the
detour ends and lane keeping takes over. Something new in the lane while rejoining is judged
afresh, from confirming.

A narrow return's cells (a pole, a leg: :mod:`coffeebot.navigation.costmap`) carry what may
stand on them, a seat overhanging by ~240 mm: each of the questions below widens them by
their margin, in the lane ahead, in the lane past it, where to wait and when the body is
past.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from enum import StrEnum

import numpy as np

from coffeebot.config import MotionConfig
from coffeebot.floorplan import Floor
from coffeebot.navigation.costmap import Footprint, LocalCostmap

REJOIN_MM = 100.0
"""After going round, the dynamic window steers back to the lane until the robot is this
close to it; lane keeping turns at up to ``max_lane_angle_deg`` without looking at the walls,
and from a detour lane beside the far wall that swings the rear corner into it."""

WAIT_ROOM_MM = 400.0
"""Room left beyond the planner's lethal zone where the robot waits in front of an obstacle,
so it can still turn out and the dynamic window find arcs away from it. A thin thing in front
of a far one reads up to ~150 mm beyond where it is (the sensor averages both returns), so
its costmap cell, and the wait, are that much nearer than planned."""


class Phase(StrEnum):
    CONFIRMING = "confirming"
    GOING_ROUND = "going_round"
    REJOINING = "rejoining"


@dataclass(frozen=True)
class Sighting:
    """The nearest obstacle cell in the lane ahead."""

    s_mm: float
    """Its along-hallway position."""
    static: bool
    """Whether it, and the cells just beyond it, have stood still for ``static_confirm_s``."""
    margin_mm: float = 0.0
    """How far beyond the cell what stands on it may reach (a narrow return's margin)."""

    def near_edge(self, direction: float) -> float:
        """Its along-hallway position, less its margin towards the robot."""
        return self.s_mm - direction * self.margin_mm

    def far_edge(self, direction: float) -> float:
        """Its along-hallway position, plus its margin away from the robot."""
        return self.s_mm + direction * self.margin_mm


@dataclass
class Detour:
    """One go-around, from the first sighting to being back in the lane."""

    phase: Phase = Phase.CONFIRMING
    lane_mm: float | None = None
    """The lane the dynamic window holds (going round: beside the obstacle; rejoining: the
    instruction's lane); None while confirming."""
    extent_s_mm: float | None = None
    """The furthest along-hallway position of the obstacle seen while going round, plus the
    static tolerance: the body's rear must be beyond it before the robot rejoins."""
    too_near_stop: bool = False
    """Confirming: a lane past it is free, but the robot would not be back in its own lane
    by where it must stop in it."""

    def go_round(self, lane_mm: float) -> None:
        self.phase, self.lane_mm = Phase.GOING_ROUND, lane_mm

    def extend(self, far_s_mm: float, direction: float) -> None:
        """More of the obstacle seen: the extent only ever grows in the direction of travel."""
        if self.extent_s_mm is None or (far_s_mm - self.extent_s_mm) * direction > 0:
            self.extent_s_mm = far_s_mm


class DetourPlanner:
    """Keeps the current instruction's detour and answers lane keeping's questions about the
    obstacles in its lane, from the local costmap."""

    def __init__(self, cfg: MotionConfig, costmap: LocalCostmap, footprint: Footprint) -> None:
        self.cfg = cfg
        self.costmap = costmap
        self.footprint = footprint
        self.detour: Detour | None = None
        """None: the lane ahead is clear and lane keeping drives on its own."""

    @property
    def phase(self) -> Phase | None:
        return None if self.detour is None else self.detour.phase

    @property
    def lane_mm(self) -> float | None:
        """The lane the dynamic window steers to while going round or rejoining."""
        return None if self.detour is None else self.detour.lane_mm

    def reset(self) -> None:
        """A new instruction: whatever was being gone round is judged afresh."""
        self.detour = None

    def keep_distance_mm(self) -> float:
        """Centre-to-obstacle distance ahead at the edge of the lethal zone: the body, the
        zone kept free ahead of it and the clearance."""
        fp = self.footprint
        return fp.length_mm / 2 + fp.front_extra_mm + self.cfg.obstacle_clearance_mm

    def wait_distance_mm(self) -> float:
        """Centre-to-obstacle distance at which the robot waits: outside the lethal zone."""
        return self.keep_distance_mm() + self.cfg.costmap_resolution_mm + WAIT_ROOM_MM

    def update(
        self,
        floor: Floor,
        s: float,
        d: float,
        lane: float,
        direction: float,
        avoid: bool,
        now: float,
        horizon_mm: float | None = None,
        in_lane_by_s_mm: float | None = None,
    ) -> Sighting | None:
        """One control period at hallway position ``s``, ``d`` keeping ``lane``: move the
        detour through its phases; the nearest obstacle in the lane ahead, if any, nearer
        than ``horizon_mm`` (default: the lookahead). With ``in_lane_by_s_mm`` (the move
        ends there, in its lane: a turn on the spot or a wait follows) a go-round that would
        not be back in the lane by then is not begun: the robot waits in its lane."""
        sighting = self.obstacle_ahead(floor, s, lane, direction, now, horizon_mm)
        detour = self.detour
        if sighting is not None:
            if detour is None or detour.phase is Phase.REJOINING:
                detour = self.detour = Detour()
            if sighting.static and avoid:
                # Chosen from what is seen of the obstacle, and moved out (to the nearest lane
                # still free) when more of it shows up while going round and stands still
                # (a long cart is seen bit by bit; a noisy reading comes and goes).
                settled = detour.phase is Phase.GOING_ROUND
                wanted = detour.lane_mm if settled and detour.lane_mm is not None else lane
                free = self.free_lane(floor, sighting.s_mm, wanted, direction, now, settled)
                detour.too_near_stop = (
                    free is not None
                    and not settled
                    and in_lane_by_s_mm is not None
                    and (in_lane_by_s_mm - self._back_in_lane_s(sighting, free, lane, direction))
                    * direction
                    < 0
                )
                if free is not None and not detour.too_near_stop:
                    detour.go_round(free)
            if detour.phase is Phase.GOING_ROUND:
                far = sighting.far_edge(direction) + direction * self.cfg.static_tolerance_mm
                detour.extend(far, direction)
        elif detour is not None:
            if detour.phase is Phase.CONFIRMING:
                self.detour = None  # it went away before it was confirmed
            elif self._passed(detour, s, direction):
                # Past it and the lane ahead is clear: steer back until lane keeping can.
                if abs(lane - d) > REJOIN_MM:
                    detour.phase, detour.lane_mm, detour.extent_s_mm = Phase.REJOINING, lane, None
                else:
                    self.detour = None
        return sighting

    def _back_in_lane_s(
        self, sighting: Sighting, detour_lane: float, lane: float, direction: float
    ) -> float:
        """Where a robot going round ``sighting`` in ``detour_lane`` is back in ``lane``, at
        the soonest: its rear past the obstacle, then across at ``max_lane_angle_deg``."""
        rear_past = self.footprint.length_mm / 2 + self.cfg.obstacle_clearance_mm
        across = abs(detour_lane - lane) / math.tan(math.radians(self.cfg.max_lane_angle_deg))
        return sighting.far_edge(direction) + direction * (rear_past + across)

    def _passed(self, detour: Detour, s: float, direction: float) -> bool:
        """The body's rear is beyond the obstacle's extent (rejoining: nothing to pass)."""
        if detour.extent_s_mm is None:
            return True
        rear = s - direction * (self.footprint.length_mm / 2 + self.cfg.obstacle_clearance_mm)
        return (rear - detour.extent_s_mm) * direction > 0

    def _hallway_cells(self, floor: Floor, now: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """The costmap's obstacle cells as hallway positions (n, 2: s, d), with since when
        each has been occupied and its margin, less those within ``wall_margin_mm`` and a
        cell of the side walls: those are the wall itself, read at a glancing angle from a
        pose a few centimetres off and left unexplained (a robot in its passing lane, its
        estimate 50 mm towards the middle, took such cells 84 mm from the wall for an
        obstacle in its lane, and the go-round, its rear's swing held by them, ended pressed
        against the wall)."""
        xs, ys, since, margins = self.costmap.obstacles(now)
        sd = np.array([floor.to_hallway(x, y) for x, y in zip(xs, ys, strict=True)]).reshape(-1, 2)
        wall_band = self.cfg.wall_margin_mm + self.cfg.costmap_resolution_mm
        off_walls = np.abs(sd[:, 1]) < floor.hallway.width_mm / 2 - wall_band
        return sd[off_walls], since[off_walls], margins[off_walls]

    def free_lane(
        self,
        floor: Floor,
        obstacle_s: float,
        lane: float,
        direction: float,
        now: float,
        settled: bool = False,
    ) -> float | None:
        """The lane nearest to ``lane`` whose corridor past the obstacle is free, if any;
        ``settled``: of the cells that have stood still for ``static_confirm_s``."""
        cfg = self.cfg
        sd, since, margins = self._hallway_cells(floor, now)
        if settled:
            keep = since <= now - cfg.static_confirm_s
            sd, margins = sd[keep], margins[keep]
        along = (sd[:, 0] - obstacle_s) * direction
        beside = (along > -self.footprint.length_mm - margins) & (along < cfg.lookahead_mm)
        near, near_margins = sd[beside, 1], margins[beside]
        half_body = self.footprint.width_mm / 2
        reach = floor.hallway.width_mm / 2 - half_body - cfg.side_clearance_mm
        clearance = half_body + cfg.obstacle_clearance_mm + cfg.costmap_resolution_mm
        step = cfg.costmap_resolution_mm
        offsets = sorted(np.arange(-reach, reach + 1.0, step), key=lambda d: abs(d - lane))
        for d in offsets:
            if not np.any(np.abs(near - d) < clearance + near_margins):
                return float(d)
        return None

    def obstacle_ahead(
        self,
        floor: Floor,
        s: float,
        lane: float,
        direction: float,
        now: float,
        horizon_mm: float | None = None,
    ) -> Sighting | None:
        """The nearest obstacle cell in the lane ahead within ``horizon_mm`` (default: the
        lookahead; a narrow return's nearer by its margin, and in the lane when what it may
        carry reaches into it) and whether it has stood still."""
        sd, since, margins = self._hallway_cells(floor, now)
        if since.size == 0:
            return None
        along = (sd[:, 0] - s) * direction
        reach = along - margins
        half = self.footprint.width_mm / 2 + self.cfg.obstacle_clearance_mm
        behind = self.footprint.length_mm / 2
        in_lane = (
            (np.abs(sd[:, 1] - lane) < half + margins)
            & (along + margins > -behind)
            & (reach < self.cfg.lookahead_mm)
            & (reach < (math.inf if horizon_mm is None else horizon_mm))
        )
        if not in_lane.any():
            return None
        nearest = int(np.argmin(np.where(in_lane, reach, np.inf)))
        near = in_lane & (reach < reach[nearest] + self.cfg.static_tolerance_mm)
        static = bool(np.all(since[near] <= now - self.cfg.static_confirm_s))
        return Sighting(float(sd[nearest, 0]), static, float(margins[nearest]))
