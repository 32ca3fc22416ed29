"""Where a robot's own estimate puts it, as the cameras use it: the floor whose cameras look
for it, the spot the map's layer must not take it for an object, and, between robots whose
motion is alike (side by side the same way), which track is which."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from coffeebot.board import Envelope
from coffeebot.cameras.identify import Estimate
from coffeebot.cameras.odometry_path import PosePath
from coffeebot.messages import CurrentState, PoseEstimate


@dataclass(frozen=True)
class OwnEstimate:
    """The state module's fused position at ``t_s`` (on the clock of the robot's odometry
    path) with its covariance (mm²)."""

    t_s: float
    floor: int
    x_mm: float
    y_mm: float
    covariance_mm2: tuple[tuple[float, float], tuple[float, float]]

    @classmethod
    def of(cls, pose: PoseEstimate, t_s: float) -> OwnEstimate | None:
        """``pose`` published at ``t_s``; None while the robot is not localized."""
        if not pose.initialised:
            return None
        return cls.from_sigmas(
            t_s, pose.floor, pose.x_mm, pose.y_mm, pose.sigma_x_mm, pose.sigma_y_mm, pose.cov_xy_mm2
        )

    @classmethod
    def published(cls, state: Envelope[CurrentState] | None) -> OwnEstimate | None:
        """The state module's newest estimate, at the moment it was published (None before
        the first, or while the robot is not localized)."""
        return None if state is None else cls.of(state.msg.pose, state.stamp)

    @classmethod
    def from_sigmas(
        cls,
        t_s: float,
        floor: int,
        x_mm: float,
        y_mm: float,
        sigma_x_mm: float,
        sigma_y_mm: float,
        cov_xy_mm2: float = 0.0,
    ) -> OwnEstimate:
        """From the position's 1-sigmas and x-y covariance, as poses and messages carry it."""
        return cls(
            t_s, floor, x_mm, y_mm, ((sigma_x_mm**2, cov_xy_mm2), (cov_xy_mm2, sigma_y_mm**2))
        )

    @property
    def place(self) -> tuple[int, float, float]:
        """(floor, x mm, y mm)."""
        return self.floor, self.x_mm, self.y_mm

    def on(self, path: PosePath, slack_s: float) -> Estimate | None:
        """For identification, tied to the point of ``path`` at its moment; None when the
        path does not reach that moment (within ``slack_s`` of its newest sample)."""
        if not path.covers(self.t_s, self.t_s, slack_s):
            return None
        x, y, _ = path.at(np.array([self.t_s]))[0]
        return Estimate((float(x), float(y)), (self.x_mm, self.y_mm), self.covariance_mm2)
