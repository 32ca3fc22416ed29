"""The cameras module on the board: every camera's field on the map layer, a camera that
gives no frames reported out with the reason (and logged once), the others working on."""

from __future__ import annotations

import asyncio
import logging
from pathlib import Path

import numpy as np
import pytest

from camera_fakes import BareFloor
from coffeebot.board import Board
from coffeebot.clock import MonotonicClock
from coffeebot.config import load_robot_config
from coffeebot.floorplan import Camera, load_floorplan
from coffeebot.messages import ALL_TOPICS, CAMERA_LAYER, CameraLayer
from coffeebot.modules.base import ModuleBoard, ModuleContext
from coffeebot.modules.cameras import CameraModule

ROOT = Path(__file__).resolve().parents[2]
PLAN = load_floorplan(ROOT / "floorplans" / "cs-building.toml")
CAMERAS = {camera.id: camera for floor in PLAN.floors for camera in floor.cameras}
BASE = load_robot_config(ROOT / "boards" / "coffeebot-v1.toml")
CONFIG = BASE.model_copy(
    update={"cameras": BASE.cameras.model_copy(update={"enabled": True, "out_after_s": 0.3})}
)


class DeadSource:
    """A stream that never gives a frame."""

    problem = "cannot open rtsp://10.0.0.7/stream"

    def __init__(self, camera: Camera) -> None:
        self.camera = camera

    def grab(self, t_s: float) -> np.ndarray | None:
        return None

    def close(self) -> None:
        """Nothing to release."""


async def test_a_camera_without_frames_is_reported_out_with_its_reason_and_logged(
    caplog: pytest.LogCaptureFixture,
) -> None:
    board = Board(ALL_TOPICS, clock=MonotonicClock())
    module = CameraModule(
        CONFIG,
        PLAN,
        {"lobby-2": BareFloor(CAMERAS["lobby-2"]), "tea-room": DeadSource(CAMERAS["tea-room"])},
    )
    log = logging.getLogger("coffeebot.module.cameras")
    ctx = ModuleContext(ModuleBoard(board, module), board.clock, log)
    layers = board.subscribe(CAMERA_LAYER)
    task = asyncio.create_task(module.run(ctx))
    try:
        async with asyncio.timeout(20.0):
            while True:
                layer: CameraLayer = (await layers.get()).msg
                views = {view.camera_id: view for view in layer.cameras}
                if not views["tea-room"].working:
                    break
    finally:
        task.cancel()
        with pytest.raises(asyncio.CancelledError):
            await task
    assert views["lobby-2"].working and views["lobby-2"].problem is None
    problem = views["tea-room"].problem
    assert problem is not None and problem.startswith("no frames for")
    assert "cannot open rtsp://10.0.0.7/stream" in problem
    assert views["lobby-2"].floor == 2 and len(views["lobby-2"].corners_mm) == 4
    assert layer.objects == []
    disconnects = [r for r in caplog.records if getattr(r, "event", None) == "disconnect"]
    assert [r.camera for r in disconnects] == ["tea-room"]  # type: ignore[attr-defined]


def test_a_source_for_a_camera_the_plan_does_not_have_is_refused() -> None:
    stray = Camera(id="garage", x_mm=0.0, y_mm=0.0)
    with pytest.raises(ValueError, match="no camera garage in the floor plan"):
        CameraModule(CONFIG, PLAN, {"garage": BareFloor(stray)})
