"""What the ceiling cameras see standing still that is not a robot: the map's camera layer
(seed 003, VI.B: the map updated from the cameras).

A track becomes an object once it has stood still for ``standing_after_s`` (a cart left in
the hallway; a person who stops to talk for that long is an obstacle too). It leaves the
layer as soon as its camera sees it move or no longer sees it (pushed away, or absorbed into
the background after several minutes: then the robot's own sensors take over), and, while
its camera is out, ``expiry_s`` after it was last seen: a camera that sees nothing cannot
say the hallway is clear, nor keep a robot waiting for ever.
"""

from __future__ import annotations

import math
from collections.abc import Iterable, Sequence

import cv2
import numpy as np
from pydantic import BaseModel, ConfigDict, Field

from coffeebot.cameras.pipeline import Detection
from coffeebot.cameras.watch import CameraWatch
from coffeebot.messages import CameraObject
from coffeebot.rectangles import corners


class StandingRules(BaseModel):
    """When a still track is an object on the map."""

    model_config = ConfigDict(frozen=True, extra="forbid")

    standing_after_s: float = Field(
        10.0,
        gt=0,
        description="how long a track must stand still before it goes on the map: past a "
        "person pausing at a door, short of a robot driving up to a cart from the far end "
        "of a camera's view",
    )
    gone_after_s: float = Field(
        2.0,
        gt=0,
        description="an object its working camera has not seen for this long is gone",
    )
    expiry_s: float = Field(
        60.0,
        gt=0,
        description="how long an object stays on the map after it was last seen while its "
        "camera is out: long enough to ride out a short outage, short enough that a robot "
        "does not wait long for a hallway nobody can see",
    )
    robot_clearance_mm: float = Field(
        700.0,
        ge=0,
        description="a still track this close to a robot's estimated position is that "
        "robot standing, not an object (half the body's diagonal and the pose's error)",
    )


class StandingObjects:
    """The camera layer's objects, kept across frames."""

    def __init__(self, rules: StandingRules) -> None:
        self.rules = rules
        self._still_since: dict[str, dict[str, float]] = {}
        """Per camera, per track: when it was first seen still."""
        self._objects: dict[str, CameraObject] = {}

    @property
    def objects(self) -> list[CameraObject]:
        return list(self._objects.values())

    def update(
        self,
        watch: CameraWatch,
        now_s: float,
        robots: Sequence[tuple[int, float, float]],
        robot_tracks: Iterable[str] = (),
    ) -> bool:
        """Read ``watch``'s tracks after its frame at ``now_s``. ``robots``: (floor, x, y) of
        every robot's estimate; ``robot_tracks``: tracks matched to a robot at some time.
        Returns whether an object came or went (one seen again only moves a little)."""
        changed = False
        robot_tracks = set(robot_tracks)
        live = {t.id for t in watch.tracks}
        still_since = self._still_since.setdefault(watch.camera.id, {})
        for track_id in [t for t in still_since if t not in live]:
            del still_since[track_id]
        for track in watch.tracks:
            seen_now = track.latest.t_s >= now_s
            if not seen_now:
                continue
            # A blob cut by the image's border is still a thing: the part in view is mapped.
            still = track.still and track.id not in robot_tracks
            if still and self._near_robot(
                watch.level, track.latest.x_mm, track.latest.y_mm, robots
            ):
                still = False
            if not still:
                still_since.pop(track.id, None)
                changed |= self._objects.pop(track.id, None) is not None
                continue
            since = still_since.setdefault(track.id, now_s)
            if now_s - since < self.rules.standing_after_s:
                continue
            changed |= track.id not in self._objects
            self._objects[track.id] = _object(watch, track.id, track.latest, since, now_s)
        changed |= self._forget(now_s, watch.camera.id, working=True)
        return changed

    def camera_out(self, camera_id: str, now_s: float) -> bool:
        """Camera ``camera_id`` gives no frames: its objects stay until they expire."""
        return self._forget(now_s, camera_id, working=False)

    def _forget(self, now_s: float, camera_id: str, working: bool) -> bool:
        limit = self.rules.gone_after_s if working else self.rules.expiry_s
        stale = [
            key
            for key, obj in self._objects.items()
            if obj.camera_id == camera_id and now_s - obj.seen_s > limit
        ]
        for key in stale:
            del self._objects[key]
        return bool(stale)

    def _near_robot(
        self, level: int, x_mm: float, y_mm: float, robots: Sequence[tuple[int, float, float]]
    ) -> bool:
        return any(
            floor == level and math.hypot(x - x_mm, y - y_mm) < self.rules.robot_clearance_mm
            for floor, x, y in robots
        )


def _object(
    watch: CameraWatch, track_id: str, detection: Detection, since_s: float, now_s: float
) -> CameraObject:
    """A track's latest blob as a map object: the smallest rectangle holding the blob read
    on the floor and on a robot's top, so the footprint covers the thing whatever its height
    up to a robot's (a flat box lies where the floor reading puts it, a cart's top shows
    further out from the camera's nadir than it stands)."""
    on_top = corners(
        detection.x_mm, detection.y_mm, detection.length_mm, detection.width_mm, detection.axis_deg
    )
    both = np.vstack([on_top, watch.on_floor(detection)]).astype(np.float32)
    (x, y), (a, b), angle = cv2.minAreaRect(both)
    length, width, axis = (a, b, angle) if a >= b else (b, a, angle + 90.0)
    return CameraObject(
        id=track_id,
        camera_id=watch.camera.id,
        floor=watch.level,
        x_mm=round(float(x), 1),
        y_mm=round(float(y), 1),
        length_mm=round(float(length), 1),
        width_mm=round(float(width), 1),
        axis_deg=round(float(axis) % 180.0, 2),
        standing_since_s=since_s,
        seen_s=now_s,
    )
