"""The building's ceiling cameras in simulation: each camera of the floor plan rendered by
:class:`~coffeebot.sim.world.ceiling_camera.SimCeilingCamera` from the shared world, as
frame sources for the camera module."""

from __future__ import annotations

import contextlib
from collections.abc import Callable

import numpy as np

from coffeebot.floorplan import Camera, FloorPlan
from coffeebot.sim.world import World
from coffeebot.sim.world.ceiling_camera import CameraSimSettings, SimCeilingCamera

WorldTime = Callable[[], contextlib.AbstractContextManager[World]]
"""The world under its lock, its CPU booked to the simulator (:meth:`SimWorld.world_time`)."""


class SimFrameSource:
    """One simulated camera, rendering the world as it is when asked."""

    def __init__(self, camera: SimCeilingCamera, world_time: WorldTime) -> None:
        self.camera: Camera = camera.camera
        self._sim = camera
        self._world_time = world_time

    def grab(self, t_s: float) -> np.ndarray | None:
        with self._world_time():
            return self._sim.frame()

    def close(self) -> None:
        """Nothing to release."""


def sim_cameras(
    world: World,
    plan: FloorPlan,
    world_time: WorldTime,
    settings: dict[str, CameraSimSettings] | None = None,
    seed: int = 0,
) -> dict[str, SimFrameSource]:
    """Every camera of the plan over ``world``, by id; ``settings`` per camera id (faults:
    noise, a lighting change, a dropout), the defaults otherwise."""
    settings = settings or {}
    return {
        camera.id: SimFrameSource(
            SimCeilingCamera(world, floor.level, camera, settings.get(camera.id), seed=seed + k),
            world_time,
        )
        for k, (floor, camera) in enumerate(
            (floor, camera) for floor in plan.floors for camera in floor.cameras
        )
    }
