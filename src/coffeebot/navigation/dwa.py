"""The Dynamic Window Approach (Fox, Burgard, Thrun 1997; seed 003's local planner).

Each control period: take the (speed, turn rate) pairs reachable within one period from the
current ones under the acceleration limits (the dynamic window), forward-simulate each as an
arc over ``dwa_horizon_s``, drop the arcs on which the body would come within the lethal part
of the costmap (those are also the inadmissible ones: a speed that cannot be braked before an
obstacle ends on it inside the horizon), and score the rest. The score rewards progress along
the hallway and penalises distance from the lane, heading away from the direction of travel
and inflated cost, so with a clear lane the best arc is the lane itself, and with an obstacle
the best arc is the one that gets past it with the most room and rejoins the lane after.
Only forward speeds are sampled: the robot has no sensors facing backwards. The arcs are the
driven axle's, ahead of the body's centre: turning, the body swings about the axle, and its
rear corners sweep further out than a turn about the centre would take them.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import TypeVar

import numpy as np

from coffeebot.config import MotionConfig
from coffeebot.floorplan import Floor
from coffeebot.navigation.costmap import LocalCostmap

Coordinate = TypeVar("Coordinate", float, np.ndarray)

SIM_STEP_S = 0.1

W_PROGRESS = 1.0
W_LANE = 3.0
W_HEADING = 0.2
W_COST = 0.6


@dataclass(frozen=True)
class DwaChoice:
    """The best arc, or ``None`` speeds when every arc is lethal (blocked)."""

    speed_mm_s: float
    yaw_rate_dps: float
    score: float
    candidates: int
    admissible: int


def axle_point(
    x_mm: Coordinate, y_mm: Coordinate, heading_rad: Coordinate, axle_x_mm: float
) -> tuple[Coordinate, Coordinate]:
    """Where the driven axle is for a body-centre pose (a negative ``axle_x_mm``: the other
    way round); scalars or arrays alike."""
    return x_mm + axle_x_mm * np.cos(heading_rad), y_mm + axle_x_mm * np.sin(heading_rad)


def rollout(
    pose: tuple[float, float, float],
    speeds_mm_s: np.ndarray,
    rates_rad_s: np.ndarray,
    times_s: np.ndarray,
    axle_x_mm: float,
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Body-centre poses (x, y, heading rad; rows per command, columns per time) of a
    differential drive turning about its axle, from ``pose`` (x, y, heading rad) holding
    each (speed, turn rate) pair: the axle follows a circular arc (a line at zero rate)."""
    x0, y0, h0 = pose
    ax0, ay0 = axle_point(x0, y0, h0, axle_x_mm)
    v, w = speeds_mm_s[:, None], rates_rad_s[:, None]
    theta = h0 + w * times_s[None, :]
    straight = np.abs(w) < 1e-6
    radius = v / np.where(straight, 1.0, w)
    ax = np.where(
        straight, ax0 + v * times_s * math.cos(h0), ax0 + radius * (np.sin(theta) - math.sin(h0))
    )
    ay = np.where(
        straight, ay0 + v * times_s * math.sin(h0), ay0 - radius * (np.cos(theta) - math.cos(h0))
    )
    cx, cy = axle_point(ax, ay, theta, -axle_x_mm)
    return cx, cy, theta


class DynamicWindow:
    """Chooses (speed, yaw rate) for one control period against a :class:`LocalCostmap`."""

    def __init__(self, cfg: MotionConfig, axle_x_mm: float) -> None:
        self.cfg = cfg
        self.axle_x_mm = axle_x_mm

    def window(
        self, speed_mm_s: float, yaw_rate_dps: float, max_speed_mm_s: float, dt_s: float
    ) -> tuple[np.ndarray, np.ndarray]:
        """Speed and yaw-rate samples reachable within ``dt_s``."""
        cfg = self.cfg
        dv = cfg.accel_mm_s2 * max(dt_s, SIM_STEP_S)
        dw = cfg.turn_accel_dps2 * max(dt_s, SIM_STEP_S)
        v_lo, v_hi = max(0.0, speed_mm_s - dv), min(max_speed_mm_s, speed_mm_s + dv)
        w_lo = max(-cfg.max_turn_rate_dps, yaw_rate_dps - dw)
        w_hi = min(cfg.max_turn_rate_dps, yaw_rate_dps + dw)
        speeds = np.linspace(v_lo, max(v_lo, v_hi), cfg.dwa_speed_samples)
        rates = np.linspace(w_lo, max(w_lo, w_hi), cfg.dwa_turn_samples)
        return speeds, rates

    def choose(
        self,
        costmap: LocalCostmap,
        floor: Floor,
        pose: tuple[float, float, float],
        speed_mm_s: float,
        yaw_rate_dps: float,
        *,
        lane_mm: float,
        direction: float,
        max_speed_mm_s: float,
        dt_s: float,
        now: float,
    ) -> DwaChoice | None:
        """The best admissible arc from ``pose`` (x, y, heading deg); None if none is."""
        speeds, rates = self.window(speed_mm_s, yaw_rate_dps, max_speed_mm_s, dt_s)
        v, w = (a.ravel() for a in np.meshgrid(speeds, np.radians(rates), indexing="ij"))
        steps = max(1, round(self.cfg.dwa_horizon_s / SIM_STEP_S))
        t = SIM_STEP_S * np.arange(1, steps + 1)
        x0, y0, h0 = pose[0], pose[1], math.radians(pose[2])
        xs, ys, theta = rollout((x0, y0, h0), v, w, t, self.axle_x_mm)
        admissible, worst = costmap.admissible(xs, ys, theta, (x0, y0, h0), now)
        if not admissible.any():
            return None
        # Progress and lane are scored at the axle, which only moves along its arc: scored at
        # the centre, a turn on the spot that swings the centre sideways would pass for
        # moving towards the lane.
        s0 = floor.to_hallway(*axle_point(x0, y0, h0, self.axle_x_mm))[0]
        end_x, end_y = axle_point(xs[:, -1], ys[:, -1], theta[:, -1], self.axle_x_mm)
        ends = [floor.to_hallway(x, y) for x, y in zip(end_x, end_y, strict=True)]
        s_end = np.array([e[0] for e in ends])
        d_end = np.array([e[1] for e in ends])
        travel = math.radians(floor.travel_deg(direction))
        heading_error = np.abs(np.angle(np.exp(1j * (theta[:, -1] - travel))))
        reach = max(max_speed_mm_s * self.cfg.dwa_horizon_s, 1.0)
        progress = (s_end - s0) * direction / reach
        lane = np.abs(d_end - lane_mm) / (floor.hallway.width_mm / 2.0)
        score = (
            W_PROGRESS * progress
            - W_LANE * lane
            - W_HEADING * heading_error / (math.pi / 2)
            - W_COST * np.where(admissible, worst, 0.0)
        )
        score = np.where(admissible, score, -math.inf)
        best = int(np.argmax(score))
        return DwaChoice(
            speed_mm_s=float(v[best]),
            yaw_rate_dps=float(math.degrees(w[best])),
            score=float(score[best]),
            candidates=int(v.size),
            admissible=int(admissible.sum()),
        )
