"""The ceiling cameras in ``coffeebot check-hardware``: one frame from each configured
stream. The cameras are the building's, not the robot's: the robot works without them (no
fixes, nothing on the map from them), so a camera that does not answer is a warning row
saying why, not a failure that keeps the robot from starting."""

from __future__ import annotations

from coffeebot.cameras.sources import stream_sources
from coffeebot.config import CamerasConfig
from coffeebot.floorplan import FloorPlan
from coffeebot.hardware.selfcheck import CheckResult

WITHOUT_IT = "the robot runs without it: no pose fixes or map layer from this camera"


def check_cameras(cameras: CamerasConfig, plan: FloorPlan) -> list[CheckResult]:
    """A row per stream of ``[cameras] streams`` (none while the cameras are off)."""
    if not cameras.enabled:
        return []
    rows = []
    for camera_id, source in stream_sources(cameras.streams, plan).items():
        component = f"ceiling camera {camera_id}"
        try:
            frame = source.grab(0.0)
        finally:
            source.close()
        if frame is None:
            rows.append(
                CheckResult(component, source.url, True, f"{source.problem}; {WITHOUT_IT}", True)
            )
        else:
            rows.append(
                CheckResult(
                    component, source.url, True, f"{frame.shape[1]} x {frame.shape[0]} frames"
                )
            )
    return rows
