"""One ceiling camera at work: its frames through the pipeline and the tracker, and the
last seconds of its tracks in the form identification takes them.

The daemon's camera module (one robot) and the fleet's camera service (every robot) both
keep one of these per camera; the benchmark does too, so what it measures is this code.
"""

from __future__ import annotations

from collections import deque

import numpy as np

from coffeebot.cameras.calibration import calibrate
from coffeebot.cameras.geometry import project, raise_plane, to_plane
from coffeebot.cameras.pipeline import CameraPipeline, Detection, PipelineSettings
from coffeebot.cameras.tracks import Track, Tracker, TrackerSettings
from coffeebot.floorplan import Camera
from coffeebot.rectangles import corners


class CameraWatch:
    """Camera ``camera`` over floor ``level``; robots are read on the plane of their top,
    ``robot_height_mm`` above the floor, so a robot's blob is where the robot is. Frame
    times are kept for the last ``keep_s`` (the longest identification window, and how far
    before the newest frame a window may end)."""

    def __init__(
        self,
        camera: Camera,
        level: int,
        robot_height_mm: float,
        keep_s: float,
        pipeline: PipelineSettings | None = None,
        tracker: TrackerSettings | None = None,
    ) -> None:
        self.camera = camera
        self.level = level
        self._floor = calibrate(camera, floor=level).homography
        self._robot_top = raise_plane(self._floor, camera, robot_height_mm)
        self.pipeline = CameraPipeline(camera, self._robot_top, pipeline or PipelineSettings())
        self.tracker = Tracker(tracker or TrackerSettings())
        self.tracks: list[Track] = []
        self.last_frame_s: float | None = None
        self._frame_times: deque[float] = deque(maxlen=round(keep_s * camera.fps) + 1)

    def see(self, frame: np.ndarray, t_s: float) -> list[Track]:
        """Take the frame exposed at ``t_s``; return the live tracks."""
        self.tracks = self.tracker.update(self.pipeline.step(frame, t_s), t_s)
        self.last_frame_s = t_s
        self._frame_times.append(t_s)
        return self.tracks

    def window(
        self, window_s: float, until_s: float | None = None
    ) -> tuple[np.ndarray, dict[str, np.ndarray]] | None:
        """The frame times of the last ``window_s`` (of the frames up to ``until_s``, if
        given) and every track followed over all of them, resampled there (rows cut by the
        image's border are NaN); None until the camera has run that long without a gap."""
        frames = round(window_s * self.camera.fps) + 1
        stamps = [t for t in self._frame_times if until_s is None or t <= until_s]
        if len(stamps) < frames:
            return None
        times = np.array(stamps[-frames:])
        if times[-1] - times[0] > window_s * 1.5:
            return None  # frames were dropped: the window is not one stretch of motion
        start, end = float(times[0]), float(times[-1])
        return times, {t.id: t.resample(times) for t in self.tracks if t.spans(start, end)}

    def on_floor(self, detection: Detection) -> np.ndarray:
        """The corners (4, 2) of a detection's rectangle read on the floor: where a flat
        object would lie. The same blob read on the robot's top (the detection itself) is
        where an object as tall as a robot would stand; anything between lies between."""
        on_top = corners(
            detection.x_mm,
            detection.y_mm,
            detection.length_mm,
            detection.width_mm,
            detection.axis_deg,
        )
        return to_plane(self._floor, project(self._robot_top, on_top))

    def field(self) -> np.ndarray:
        """The image's corners (4, 2) on the floor: what the camera sees."""
        w, h = self.camera.width_px, self.camera.height_px
        return to_plane(self._floor, np.array([(0.0, 0.0), (w, 0.0), (w, h), (0.0, h)]))
