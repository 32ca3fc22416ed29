"""When a particle filter should inject fresh particles: augmented MCL's fit averages.

Probabilistic Robotics (table 8.3) keeps a slow and a fast running average of how well the
particles explain the measurements. When the fast one falls below the slow one, the filter
is worse at explaining the world than it used to be: likely lost (kidnapped, a wrong floor,
a wrong start), and a share ``1 - fast / slow`` of the next resample should be new
particles. Both averages are reset after an injection, as nav2 and Beluga do, so one bad
stretch does not keep replacing particles ("spiraling off into complete randomness").
"""

from __future__ import annotations

import math


class RecoveryMonitor:
    """Slow and fast exponential averages of one source's fit (a likelihood in 0..1)."""

    def __init__(self, alpha_slow: float, alpha_fast: float) -> None:
        self.alpha_slow = alpha_slow
        self.alpha_fast = alpha_fast
        self.slow: float | None = None
        self.fast: float | None = None

    def update(self, fit: float) -> None:
        if not math.isfinite(fit):
            return
        if self.slow is None or self.fast is None:
            self.slow = self.fast = fit
            return
        self.slow += self.alpha_slow * (fit - self.slow)
        self.fast += self.alpha_fast * (fit - self.fast)

    @property
    def injection_probability(self) -> float:
        if self.slow is None or self.fast is None or self.slow <= 0:
            return 0.0
        return min(1.0, max(0.0, 1.0 - self.fast / self.slow))

    def reset(self) -> None:
        self.slow = self.fast = None
