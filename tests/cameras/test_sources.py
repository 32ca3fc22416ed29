"""Frames from a stream OpenCV opens (a video file stands in for a network camera), and the
config's streams checked against the floor plan."""

from __future__ import annotations

from pathlib import Path

import cv2
import numpy as np
import pytest

from coffeebot.cameras.sources import StreamSource, stream_sources
from coffeebot.errors import ConfigError
from coffeebot.floorplan import Camera, load_floorplan

ROOT = Path(__file__).resolve().parents[2]
CAMERA = Camera(id="hall", x_mm=0.0, y_mm=0.0, width_px=320, height_px=240)


def write_video(path: Path, frames: list[np.ndarray]) -> None:
    height, width = frames[0].shape[:2]
    writer = cv2.VideoWriter(str(path), cv2.VideoWriter_fourcc(*"MJPG"), 10.0, (width, height))
    assert writer.isOpened()
    for frame in frames:
        writer.write(cv2.cvtColor(frame, cv2.COLOR_GRAY2BGR))
    writer.release()


def test_a_colour_stream_comes_as_grey_frames_of_the_cameras_size(tmp_path: Path) -> None:
    ramp = np.tile(np.linspace(0, 255, 320, dtype=np.uint8), (240, 1))
    video = tmp_path / "hall.avi"
    write_video(video, [ramp, 255 - ramp])
    source = StreamSource(CAMERA, str(video))
    first = source.grab(0.0)
    assert first is not None and first.dtype == np.uint8 and first.shape == (240, 320)
    assert np.abs(first.astype(int) - ramp).mean() < 4  # JPEG's loss only
    second = source.grab(0.1)
    assert second is not None and second[:, :10].mean() > 240
    assert source.problem is None
    source.close()


def test_a_stream_of_another_size_or_none_at_all_gives_no_frames_and_says_why(
    tmp_path: Path,
) -> None:
    video = tmp_path / "wrong.avi"
    write_video(video, [np.zeros((120, 160), np.uint8)])
    wrong = StreamSource(CAMERA, str(video))
    assert wrong.grab(0.0) is None
    assert (
        wrong.problem is not None and "160 x 120" in wrong.problem and "320 x 240" in wrong.problem
    )
    missing = StreamSource(CAMERA, str(tmp_path / "no-such-camera.avi"))
    assert missing.grab(0.0) is None
    assert missing.problem is not None and "cannot open" in missing.problem


def test_a_stream_for_a_camera_the_plan_does_not_have_is_refused_by_name() -> None:
    plan = load_floorplan(ROOT / "floorplans" / "cs-building.toml")
    sources = stream_sources({"lobby-2": "rtsp://10.0.0.5/stream"}, plan)
    assert sources["lobby-2"].camera.id == "lobby-2"
    with pytest.raises(ConfigError, match=r"cameras.streams: no camera 'lobby-9'.*'lobby-2'"):
        stream_sources({"lobby-9": "rtsp://10.0.0.9/stream"}, plan)
