"""The ceiling cameras' rows in ``coffeebot check-hardware``: a frame's size when a stream
answers, a warning saying why and what the robot does without it when not."""

from __future__ import annotations

from pathlib import Path

import cv2
import numpy as np

from coffeebot.cameras.check import check_cameras
from coffeebot.cli import format_table
from coffeebot.config import CamerasConfig
from coffeebot.floorplan import load_floorplan

ROOT = Path(__file__).resolve().parents[2]
PLAN = load_floorplan(ROOT / "floorplans" / "cs-building.toml")


def test_each_stream_is_a_row_and_one_that_does_not_answer_is_a_warning(tmp_path: Path) -> None:
    video = tmp_path / "lobby.avi"
    writer = cv2.VideoWriter(str(video), cv2.VideoWriter_fourcc(*"MJPG"), 10.0, (320, 240))
    writer.write(np.full((240, 320, 3), 120, np.uint8))
    writer.release()
    cameras = CamerasConfig(
        enabled=True, streams={"lobby-2": str(video), "tea-room": str(tmp_path / "none.avi")}
    )
    lobby, tea_room = check_cameras(cameras, PLAN)
    assert (lobby.component, lobby.ok, lobby.warning) == ("ceiling camera lobby-2", True, False)
    assert lobby.detail == "320 x 240 frames"
    assert (tea_room.ok, tea_room.warning) == (True, True)
    assert "cannot open" in tea_room.detail and "runs without it" in tea_room.detail
    table = format_table([lobby, tea_room])
    assert "ceiling camera tea-room" in table and "WARN" in table
    assert check_cameras(cameras.model_copy(update={"enabled": False}), PLAN) == []
