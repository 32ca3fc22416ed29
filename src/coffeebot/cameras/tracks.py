"""Which blob in this frame is which blob of the last: tracks of a camera's detections.

The trajectory matching of seed 003 (IV.B) compares each track's path with the robots'
odometry at the same instants, so a track must keep its id through a crossing and give its
position at any instant it covers. Detections are assigned to tracks by the Hungarian method
(one detection per track, least total distance) within a gate around where each track is
predicted to be now, which carries a track across a few missed frames.
"""

from __future__ import annotations

from collections import deque
from collections.abc import Sequence

import numpy as np
from pydantic import BaseModel, ConfigDict, Field
from scipy.optimize import linear_sum_assignment

from coffeebot.cameras.pipeline import Detection


class TrackerSettings(BaseModel):
    """Tuning of the tracker, for people and robots seen at 10 fps."""

    model_config = ConfigDict(frozen=True, extra="forbid")

    gate_mm: float = Field(
        500.0,
        gt=0,
        description="the furthest a detection may lie from a track's predicted position and "
        "still continue it: five frames of a robot at 1 m/s, well under the 800 mm at which "
        "people pass a robot",
    )
    end_after_s: float = Field(
        2.0, gt=0, description="a track not seen for longer than this has ended"
    )
    left_view_after_s: float = Field(
        0.5,
        gt=0,
        description="a track last seen cut by the image's border and not seen for longer "
        "than this has left the view and ended: whatever comes in there next is something "
        "else until it is shown to be the same (a person stepping in where a robot drove "
        "out 1.2 s before, 450 mm away, continued the robot's track and the robot was named "
        "on her). Five frames at 10 fps: a blob half out of view may miss a few",
    )
    max_history: int = Field(600, ge=2, description="positions kept per track (a minute at 10 fps)")
    velocity_window_s: float = Field(
        0.5,
        gt=0,
        description="the stretch of a track its velocity is read over, to predict it "
        "through missed frames: long enough to average out the detections' jitter",
    )
    still_window_s: float = Field(
        3.0, gt=0, description="how long a track must have stayed put to count as still"
    )
    still_tolerance_mm: float = Field(
        80.0,
        gt=0,
        description="the largest extent (bounding-box diagonal) of a still track's positions "
        "over the window: above the jitter of a person standing, below a robot creeping",
    )


class Track:
    """One object followed across frames: its latest detection and a bounded history."""

    def __init__(self, track_id: str, first: Detection, max_history: int) -> None:
        self.id = track_id
        self.latest = first
        self.still = False
        """Whether it has moved less than the tracker's tolerance over its window; set by
        the tracker on each update."""
        self._history: deque[tuple[float, float, float]] = deque(maxlen=max_history)
        self._history.append((first.t_s, first.x_mm, first.y_mm))
        self._cut: deque[bool] = deque([first.cut], maxlen=max_history)
        """Per history row: the blob was cut by the image's border (Detection.cut)."""

    @property
    def history(self) -> np.ndarray:
        """(n, 3) rows of (t_s, x_mm, y_mm), oldest first."""
        return np.array(self._history, dtype=float)

    def extend(self, detection: Detection) -> None:
        self.latest = detection
        self._history.append((detection.t_s, detection.x_mm, detection.y_mm))
        self._cut.append(detection.cut)

    def predict(self, t_s: float, velocity_window_s: float) -> np.ndarray:
        """Where it should be at ``t_s``, going on at its recent velocity."""
        history = self.history
        recent = history[history[:, 0] >= history[-1, 0] - velocity_window_s]
        elapsed_s = recent[-1, 0] - recent[0, 0]
        if elapsed_s <= 0.0:
            return history[-1, 1:]
        velocity = (recent[-1, 1:] - recent[0, 1:]) / elapsed_s
        return history[-1, 1:] + velocity * (t_s - history[-1, 0])

    def extent_mm(self, since_s: float) -> float | None:
        """The diagonal of the box holding its positions since ``since_s``; None when its
        history does not reach back that far (too new to tell)."""
        history = self.history
        if history[0, 0] > since_s:
            return None
        window = history[history[:, 0] >= since_s, 1:]
        if len(window) == 0:
            return None
        return float(np.hypot(*(window.max(axis=0) - window.min(axis=0))))

    def resample(self, times: np.ndarray) -> np.ndarray:
        """Positions (q, 2) at ``times`` by linear interpolation of the history; NaN outside
        the span it covers, so nothing is compared with where it was never seen, and NaN
        next to a blob cut by the image's border, whose centroid is not the object's."""
        history = self.history
        at = np.asarray(times, dtype=float)
        positions = np.column_stack(
            [
                np.interp(at, history[:, 0], history[:, 1]),
                np.interp(at, history[:, 0], history[:, 2]),
            ]
        )
        positions[(at < history[0, 0]) | (at > history[-1, 0])] = np.nan
        cut = np.array(self._cut, dtype=bool)
        if cut.any():
            after = np.clip(np.searchsorted(history[:, 0], at, side="left"), 0, len(cut) - 1)
            before = np.clip(np.searchsorted(history[:, 0], at, side="right") - 1, 0, len(cut) - 1)
            positions[cut[after] | cut[before]] = np.nan
        return positions

    def spans(self, start_s: float, end_s: float) -> bool:
        """Whether it was followed from ``start_s`` to ``end_s`` (cut stretches included)."""
        history = self.history
        return bool(history[0, 0] <= start_s and history[-1, 0] >= end_s)


class Tracker:
    """Keeps one camera's live tracks from frame to frame."""

    def __init__(self, settings: TrackerSettings) -> None:
        self.settings = settings
        self._tracks: list[Track] = []
        self._started: dict[str, int] = {}
        """Tracks started per camera: the counter in their ids."""

    def update(self, detections: Sequence[Detection], t_s: float) -> list[Track]:
        """Take a frame's detections at ``t_s``; return the live tracks, oldest first."""
        settings = self.settings
        self._tracks = [t for t in self._tracks if t_s - t.latest.t_s <= self._lasts_s(t)]
        unassigned = list(range(len(detections)))
        if self._tracks and detections:
            predicted = np.array([t.predict(t_s, settings.velocity_window_s) for t in self._tracks])
            seen = np.array([(d.x_mm, d.y_mm) for d in detections])
            distance = np.linalg.norm(predicted[:, None, :] - seen[None, :, :], axis=2)
            # Out of the gate: too dear to be chosen over any pairing within it.
            beyond_gate = settings.gate_mm * (1 + len(detections) + len(self._tracks))
            rows, cols = linear_sum_assignment(
                np.where(distance <= settings.gate_mm, distance, beyond_gate)
            )
            for row, col in zip(rows.tolist(), cols.tolist(), strict=True):
                if distance[row, col] <= settings.gate_mm:
                    self._tracks[row].extend(detections[col])
                    unassigned.remove(col)
        for index in unassigned:
            self._tracks.append(self._start(detections[index]))
        for track in self._tracks:
            extent_mm = track.extent_mm(t_s - settings.still_window_s)
            track.still = extent_mm is not None and extent_mm < settings.still_tolerance_mm
        return list(self._tracks)

    def _lasts_s(self, track: Track) -> float:
        """How long ``track`` may go unseen: less once it was last seen leaving the view."""
        if track.latest.cut:
            return self.settings.left_view_after_s
        return self.settings.end_after_s

    def _start(self, detection: Detection) -> Track:
        count = self._started.get(detection.camera_id, 0) + 1
        self._started[detection.camera_id] = count
        return Track(f"{detection.camera_id}-{count}", detection, self.settings.max_history)
