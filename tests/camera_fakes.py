"""Cameras that stand in for a stream: bare floor, or nothing at all."""

from __future__ import annotations

import numpy as np

from coffeebot.floorplan import Camera


class BareFloor:
    """A camera that sees bare floor with a little noise."""

    def __init__(self, camera: Camera) -> None:
        self.camera = camera
        self._rng = np.random.default_rng(1)

    def grab(self, t_s: float) -> np.ndarray | None:
        shape = (self.camera.height_px, self.camera.width_px)
        return np.clip(120 + 3 * self._rng.standard_normal(shape), 0, 255).astype(np.uint8)

    def close(self) -> None:
        """Nothing to release."""
