"""The aiohttp application: ``create_app(deps, bus)`` is the only way it is built.

Routes live in :mod:`coffeebot.web.api` (JSON) and :mod:`coffeebot.web.pages` (HTML); this
module adds what applies to all of them: the body size limit, the Host and cross-site checks
and the headers of :mod:`coffeebot.web.guard`, the orders' errors mapped to HTTP answers
(here and nowhere else), errors as JSON under ``/api`` and as a page elsewhere (an
unexpected one too: logged once with its traceback, answered 500 without it), and the
background task that follows the board.
"""

from __future__ import annotations

import asyncio
import contextlib
import logging
from collections.abc import AsyncIterator, Awaitable, Callable
from pathlib import Path

from aiohttp import web

from coffeebot.errors import OrderError
from coffeebot.logs import Event
from coffeebot.orders import OrderNotFound, OrdersUnavailable, WrongOrderKey
from coffeebot.web import api, pages
from coffeebot.web.context import (
    BUS,
    CHANGES,
    DEPS,
    FRAMES,
    LIMITER,
    TEMPLATES,
    TIMELINES,
    RateLimiter,
    error,
)
from coffeebot.web.deps import BoardIO, WebDeps
from coffeebot.web.eta import Pace
from coffeebot.web.guard import AllowedHosts, add_headers, refusal
from coffeebot.web.live import Changes, FrameCache
from coffeebot.web.timeline import TimelineMaker

log = logging.getLogger(__name__)

STATIC = Path(__file__).parent / "static"

ALLOWED_HOSTS = web.AppKey("allowed_hosts", AllowedHosts)

RETRY_AFTER_S = 5
"""What a client is told to wait when the orders are unavailable."""

Handler = Callable[[web.Request], Awaitable[web.StreamResponse]]

ORDER_ERROR_STATUS: dict[type[OrderError], int] = {
    OrderNotFound: 404,
    WrongOrderKey: 403,
    OrdersUnavailable: 503,
}
"""The HTTP answer to each kind of order error; any other is a conflict with the order's
state (409)."""


def order_error_status(exc: OrderError) -> int:
    return next(
        (ORDER_ERROR_STATUS[cls] for cls in type(exc).__mro__ if cls in ORDER_ERROR_STATUS), 409
    )


def _error_response(request: web.Request, status: int, message: str) -> web.Response:
    if request.path.startswith("/api/"):
        return error(status, message)
    return pages.render(request, "error.html", status=status, status_code=status, message=message)


@web.middleware
async def guard_and_errors(request: web.Request, handler: Handler) -> web.StreamResponse:
    refused = refusal(request, request.app[ALLOWED_HOSTS])
    if refused is not None:
        return _error_response(request, *refused)
    try:
        return await handler(request)
    except OrderError as exc:
        status = order_error_status(exc)
        response = _error_response(request, status, str(exc))
        if status == 503:
            response.headers["Retry-After"] = str(RETRY_AFTER_S)
        return response
    except web.HTTPException as exc:
        if exc.status < 400:
            raise
        response = _error_response(request, exc.status, exc.text or exc.reason)
        response.headers.update(
            {k: v for k, v in exc.headers.items() if k in ("Retry-After", "WWW-Authenticate")}
        )
        return response
    except (asyncio.CancelledError, ConnectionResetError):
        raise  # the client went away: nothing to answer
    except Exception as exc:
        log.exception(
            "web request %s %s failed",
            request.method,
            request.path,
            extra={"event": Event.FAULT.value, "cause": f"{type(exc).__name__}: {exc}"},
        )
        return _error_response(request, 500, "internal error; the operator's log has the details")


def create_app(deps: WebDeps, bus: BoardIO) -> web.Application:
    """The web app over ``deps``, publishing and subscribing through ``bus`` (under the
    daemon, the web module's restricted board view); serve it with ``web.AppRunner`` or
    aiohttp's test client."""
    app = web.Application(
        middlewares=[guard_and_errors], client_max_size=deps.config.max_body_bytes
    )
    app[DEPS] = deps
    app[ALLOWED_HOSTS] = AllowedHosts(deps.config.allowed_hosts)
    app[BUS] = bus
    app[CHANGES] = changes = Changes()
    app[FRAMES] = FrameCache(deps, changes, max_age_s=deps.config.stream_period_s / 2)
    app[TIMELINES] = TimelineMaker(
        deps.board,
        room_floor={r.id: r.floor for r in deps.rooms}.get,
        base_floor=None if deps.plan is None else deps.plan.tea_room.floor.level,
        pace=Pace(
            travel_mm_s=deps.config.eta_speed_mm_s,
            elevator_ride_s=deps.config.eta_elevator_ride_s,
            pickup_timeout_s=deps.pickup_timeout_s,
        ),
    )
    app[LIMITER] = RateLimiter(
        deps.config.order_burst, deps.config.order_refill_s, deps.board.clock
    )
    app[TEMPLATES] = pages.templates()
    app.add_routes(api.routes)
    app.add_routes(pages.routes)
    app.router.add_static("/static", STATIC)
    app.on_response_prepare.append(add_headers)
    app.cleanup_ctx.append(_follow_board)
    app.on_shutdown.append(_end_streams)
    return app


async def _follow_board(app: web.Application) -> AsyncIterator[None]:
    changes, bus, clock = app[CHANGES], app[BUS], app[DEPS].board.clock
    pumps = [
        asyncio.create_task(changes.pump(bus, clock), name="web:follow-orders"),
        asyncio.create_task(changes.pump_health(bus, clock), name="web:follow-health"),
    ]
    yield
    for pump in pumps:
        pump.cancel()
    with contextlib.suppress(asyncio.CancelledError):
        await asyncio.gather(*pumps)


async def _end_streams(app: web.Application) -> None:
    """Live pages hold their responses open; ending them lets the server stop promptly."""
    app[CHANGES].close()
