"""Where a camera's frames come from: a stream OpenCV opens on the robot, the simulator's
rendering in simulation. The camera module asks each source for a frame at each tick of
the camera's rate, in a worker thread (reading a stream blocks)."""

from __future__ import annotations

from collections.abc import Mapping
from typing import Protocol

import cv2
import numpy as np

from coffeebot.errors import ConfigError
from coffeebot.floorplan import Camera, FloorPlan


class FrameSource(Protocol):
    """One camera's frames."""

    camera: Camera

    def grab(self, t_s: float) -> np.ndarray | None:
        """The frame exposed at (about) ``t_s``: uint8 grey, the camera's rows x columns;
        None when the camera gives none (dropped out, stream broken)."""
        ...

    def close(self) -> None: ...


class StreamSource:
    """A network camera or a local device through ``cv2.VideoCapture``. A broken stream
    is reopened at the next grab; until then the camera gives no frames, which the camera
    module reports (a camera that is out is a health problem, not a crash)."""

    def __init__(self, camera: Camera, url: str) -> None:
        self.camera = camera
        self.url = url
        self._capture: cv2.VideoCapture | None = None
        self.problem: str | None = None
        """Why the last grab gave nothing, in plain words."""

    def grab(self, t_s: float) -> np.ndarray | None:
        capture = self._capture
        if capture is None or not capture.isOpened():
            capture = self._capture = cv2.VideoCapture(self.url)
            if not capture.isOpened():
                self._drop(f"cannot open {self.url}")
                return None
        ok, image = capture.read()
        if not ok or image is None:
            self._drop(f"no frame from {self.url}")
            return None
        grey = cv2.cvtColor(image, cv2.COLOR_BGR2GRAY) if image.ndim == 3 else image
        expected = (self.camera.height_px, self.camera.width_px)
        if grey.shape != expected:
            self.problem = (
                f"{self.url} gives {grey.shape[1]} x {grey.shape[0]} frames; the floor plan "
                f"says {expected[1]} x {expected[0]}"
            )
            return None
        self.problem = None
        return np.ascontiguousarray(grey, dtype=np.uint8)

    def _drop(self, problem: str) -> None:
        self.problem = problem
        self.close()

    def close(self) -> None:
        if self._capture is not None:
            self._capture.release()
            self._capture = None


def stream_sources(streams: Mapping[str, str], plan: FloorPlan) -> dict[str, StreamSource]:
    """``[cameras] streams`` as sources; a camera id the floor plan does not have is refused
    at start, naming it (a typo would otherwise leave a camera silently unwatched)."""
    cameras = {camera.id: camera for floor in plan.floors for camera in floor.cameras}
    unknown = sorted(set(streams) - set(cameras))
    if unknown:
        raise ConfigError(
            f"cameras.streams: no camera {', '.join(map(repr, unknown))} in the floor plan "
            f"(it has {', '.join(map(repr, sorted(cameras))) or 'none'})"
        )
    return {camera_id: StreamSource(cameras[camera_id], url) for camera_id, url in streams.items()}
