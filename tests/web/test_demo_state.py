"""The demo keeps its orders: a status link still works after ``coffeebot sim`` restarts."""

from __future__ import annotations

import asyncio
import contextlib
import logging
from collections.abc import AsyncIterator
from pathlib import Path

import aiohttp
import pytest

from coffeebot.cli import build_parser
from coffeebot.config import load_robot_config
from coffeebot.floorplan import load_floorplan
from coffeebot.runtime.service import serve
from coffeebot.runtime.sim import build_sim
from coffeebot.sim.simulation import demo_setup
from coffeebot.web import WebModule

from .test_browser import BOARD_FILE, REPO

PLAN = load_floorplan(REPO / "floorplans" / "cs-building.toml")


@contextlib.asynccontextmanager
async def demo(state_dir: Path | None) -> AsyncIterator[str]:
    """The demo daemon with its web UI on a free port; yields the UI's address."""
    config = load_robot_config(BOARD_FILE)
    config = config.model_copy(update={"web": config.web.model_copy(update={"port": 0})})
    async with build_sim(config, PLAN, demo_setup(PLAN), state_dir=state_dir) as (runtime, _):
        serving = asyncio.create_task(serve(runtime))
        web = runtime.module("web")
        assert isinstance(web, WebModule)
        await asyncio.wait_for(web.started.wait(), 30)
        assert web.url is not None
        try:
            yield web.url
        finally:
            runtime.request_stop("test over")
            with contextlib.suppress(asyncio.CancelledError):
                await asyncio.wait_for(serving, 30)


async def place_order(url: str) -> str:
    """The order's status link, with its key."""
    async with aiohttp.ClientSession() as http:
        order = {"room": "207", "drink": "tea", "name": "Ada", "notes": ""}
        async with http.post(f"{url}/api/orders", json=order) as response:
            assert response.status == 201
            placed = await response.json()
            return f"/orders/{placed['id']}?key={placed['key']}"


async def status_page(url: str, link: str) -> int:
    async with aiohttp.ClientSession() as http, http.get(url + link) as page:
        return page.status


async def test_the_demo_keeps_its_orders_across_a_restart(tmp_path: Path) -> None:
    async with demo(tmp_path / "state") as url:
        link = await place_order(url)
    async with demo(tmp_path / "state") as url:
        assert await status_page(url, link) == 200


async def test_fresh_runs_start_empty(tmp_path: Path) -> None:
    async with demo(None) as url:
        link = await place_order(url)
    async with demo(None) as url:
        assert await status_page(url, link) == 404


def test_the_demo_keeps_its_state_by_default_unless_asked_not_to(
    monkeypatch: pytest.MonkeyPatch, tmp_path: Path
) -> None:
    monkeypatch.setenv("XDG_STATE_HOME", str(tmp_path))
    args = build_parser().parse_args(["sim"])
    assert args.state_dir == tmp_path / "coffeebot" / "sim" and not args.fresh
    assert build_parser().parse_args(["sim", "--fresh"]).fresh


@pytest.mark.parametrize("token", [None, "s3cret"])
async def test_the_terminal_says_whether_operator_actions_are_on(
    token: str | None, monkeypatch: pytest.MonkeyPatch, caplog: pytest.LogCaptureFixture
) -> None:
    caplog.set_level(logging.INFO)
    if token is None:
        monkeypatch.delenv("COFFEEBOT_OPERATOR_TOKEN", raising=False)
    else:
        monkeypatch.setenv("COFFEEBOT_OPERATOR_TOKEN", token)
    async with demo(None):
        pass
    said = [r.getMessage() for r in caplog.records if "operator actions" in r.getMessage()]
    assert len(said) == 1
    if token is None:
        assert said[0].startswith("operator actions off")
        assert "export COFFEEBOT_OPERATOR_TOKEN=" in said[0] and "/inspect" in said[0]
    else:
        assert said[0].startswith("operator actions on") and token not in said[0]
