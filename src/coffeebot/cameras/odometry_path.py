"""A robot's path as its own odometry measured it: what identification compares with the
tracks a camera sees (seed 003, IV.B).

Dead reckoning alone, from (0, 0, 0) where the path began, through the daemon's odometer
(seed 004: encoders and gyro) and the EKF's motion model: the fused pose would not do, as
it is pulled onto the plan by the very fixes the cameras are to check. On the robot the path
is made from telemetry (:class:`OdometryPath`); the fleet's camera service receives the same
path over the broker, sample by sample (:class:`PosePath`).
"""

from __future__ import annotations

import math
from collections import deque

import numpy as np

from coffeebot.config import MotorConfig, StateConfig
from coffeebot.messages import Odometry
from coffeebot.perception.fusion import EkfPoseFusion, Odometer


class PosePath:
    """Timestamped poses (x mm, y mm, heading rad) in one odometry frame, the last ``keep_s``
    seconds of them."""

    def __init__(self, keep_s: float) -> None:
        self._keep_s = keep_s
        self._poses: deque[tuple[float, float, float, float]] = deque()

    def add_pose(self, t_s: float, x_mm: float, y_mm: float, heading_rad: float) -> None:
        """One pose at ``t_s``; one older than the newest is ignored (interpolation needs
        time in order)."""
        if self._poses:
            if t_s < self._poses[-1][0]:
                return
            # Unwrapped, so interpolating between two samples never turns the long way round.
            previous = self._poses[-1][3]
            heading_rad = previous + math.remainder(heading_rad - previous, math.tau)
        self._poses.append((t_s, x_mm, y_mm, heading_rad))
        while self._poses and self._poses[0][0] < t_s - self._keep_s:
            self._poses.popleft()

    @property
    def latest(self) -> tuple[float, np.ndarray] | None:
        """(time, pose) of the newest sample, None before the first."""
        if not self._poses:
            return None
        t, *pose = self._poses[-1]
        return t, np.array(pose)

    def covers(self, start_s: float, end_s: float, slack_s: float) -> bool:
        """Whether it reaches from ``start_s`` to within ``slack_s`` of ``end_s`` (telemetry
        and frames tick at their own rates)."""
        return (
            bool(self._poses)
            and self._poses[0][0] <= start_s
            and self._poses[-1][0] >= end_s - slack_s
        )

    def at(self, times: np.ndarray) -> np.ndarray:
        """Poses (q, 3) at ``times`` by linear interpolation (held at the ends)."""
        if not self._poses:
            raise ValueError("no odometry yet")
        samples = np.array(self._poses, dtype=float)
        return np.column_stack([np.interp(times, samples[:, 0], samples[:, k]) for k in (1, 2, 3)])

    def moved_since(self, t_s: float) -> np.ndarray | None:
        """How the robot moved from ``t_s`` to the newest sample: (ahead mm, left mm, turn
        rad) in its own frame at ``t_s``, which carries a pose known for ``t_s`` to now
        whatever the frame; None when the path does not reach back to ``t_s``."""
        if not self._poses or self._poses[0][0] > t_s:
            return None
        x, y, heading = self.at(np.array([t_s]))[0]
        _, x_now, y_now, heading_now = self._poses[-1]
        dx, dy = x_now - x, y_now - y
        cos, sin = math.cos(heading), math.sin(heading)
        return np.array([cos * dx + sin * dy, cos * dy - sin * dx, heading_now - heading])


class OdometryPath(PosePath):
    """The path dead-reckoned from the motor controller's telemetry."""

    def __init__(self, motor: MotorConfig, state: StateConfig, keep_s: float) -> None:
        super().__init__(keep_s)
        self._odometer = Odometer(motor, state)
        self._motion = EkfPoseFusion(state)
        self._motion.reset(0.0, 0.0, 0.0, 1.0, 1.0)

    def add(self, odometry: Odometry, t_s: float) -> None:
        """One telemetry message from the motor controller, received at ``t_s``."""
        step = self._odometer.step(odometry)
        if step is not None:
            self._motion.predict(step)
        x, y, heading_deg = self._motion.pose()
        self.add_pose(t_s, x, y, math.radians(heading_deg))
