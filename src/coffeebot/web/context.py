"""Shared pieces of the web app: typed app keys, the operator check, the order rate limit."""

from __future__ import annotations

import hmac
from typing import Any

import jinja2
from aiohttp import web
from pydantic import ValidationError

from coffeebot.clock import Clock
from coffeebot.web.deps import BoardIO, WebDeps
from coffeebot.web.live import Changes, FrameCache
from coffeebot.web.timeline import TimelineMaker


class RateLimiter:
    """A token bucket per client: ``burst`` orders at once, then one per ``refill_s``."""

    MAX_CLIENTS = 10_000

    def __init__(self, burst: int, refill_s: float, clock: Clock) -> None:
        self.burst = burst
        self.refill_s = refill_s
        self.clock = clock
        self._buckets: dict[str, tuple[float, float]] = {}

    def take(self, client: str) -> float:
        """Spend one token: 0.0 if allowed, else the seconds until the next one."""
        now = self.clock.now()
        tokens, stamp = self._buckets.get(client, (float(self.burst), now))
        tokens = min(float(self.burst), tokens + (now - stamp) / self.refill_s)
        if tokens < 1.0:
            self._buckets[client] = (tokens, now)
            return (1.0 - tokens) * self.refill_s
        if len(self._buckets) >= self.MAX_CLIENTS:
            self._forget_full(now)
        self._buckets[client] = (tokens - 1.0, now)
        return 0.0

    def _forget_full(self, now: float) -> None:
        """Drop clients whose bucket has refilled: they are indistinguishable from new ones."""
        horizon = self.burst * self.refill_s
        self._buckets = {k: v for k, v in self._buckets.items() if now - v[1] < horizon}


DEPS = web.AppKey("deps", WebDeps)
BUS = web.AppKey("bus", BoardIO)
CHANGES = web.AppKey("changes", Changes)
FRAMES = web.AppKey("frames", FrameCache)
LIMITER = web.AppKey("limiter", RateLimiter)
TEMPLATES = web.AppKey("templates", jinja2.Environment)
TIMELINES = web.AppKey("timelines", TimelineMaker)


def client_key(request: web.Request) -> str:
    """Who the rate limit counts against: the peer address (the robot serves its LAN directly)."""
    return request.remote or "unknown"


def is_operator(request: web.Request) -> bool:
    """A bearer token equal to the configured one, compared in constant time. A header that
    is not UTF-8 (the bytes aiohttp could not decode) is simply a wrong token."""
    expected = request.app[DEPS].operator_token
    header = request.headers.get("Authorization", "")
    scheme, _, given = header.partition(" ")
    if not expected or scheme.lower() != "bearer":
        return False
    return hmac.compare_digest(
        given.strip().encode("utf-8", "surrogateescape"), expected.encode("utf-8")
    )


def error(status: int, message: str, **extra: Any) -> web.Response:
    return web.json_response({"error": message, **extra}, status=status)


def validation_error(exc: ValidationError, what: str) -> web.Response:
    """400 for a body that is not JSON, 422 for fields that break the rules, each one named."""
    errors = exc.errors(include_url=False)
    if any(e["type"] == "json_invalid" for e in errors):
        return error(400, "request body is not valid JSON")
    fields = field_errors(exc)
    detail = "; ".join(f"{name}: {msg}" for name, msg in fields.items())
    return error(422, f"invalid {what}: {detail}", fields=fields)


def field_errors(exc: ValidationError) -> dict[str, str]:
    """Field name (``body`` for the whole document) to the first message about it."""
    fields: dict[str, str] = {}
    for e in exc.errors(include_url=False):
        name = ".".join(str(part) for part in e["loc"]) or "body"
        message = e["msg"].removeprefix("Value error, ")
        if e["type"] == "extra_forbidden":
            message = "unknown field"
        fields.setdefault(name, message)
    return fields
