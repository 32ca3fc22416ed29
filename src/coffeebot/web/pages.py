"""Server-rendered pages. Jinja2 with autoescaping on for every template.

Why Jinja2 and not ``string.Template`` + ``html.escape``: with autoescape on, every value is
escaped unless a template says otherwise, so forgetting to escape a customer's name is not a
possible mistake; the pages also need loops and conditions, which string.Template lacks.
The pages' scripts only ever use ``textContent``, never ``innerHTML``, for the same reason.
"""

from __future__ import annotations

from collections.abc import Mapping
from itertools import groupby
from pathlib import Path
from typing import Any

import jinja2
from aiohttp import web
from pydantic import ValidationError

from coffeebot.store import NewOrder
from coffeebot.web.api import ORDER_ID, check_rate, order_for, order_rules, status_link
from coffeebot.web.context import DEPS, TEMPLATES, TIMELINES, client_key
from coffeebot.web.graph import module_graph
from coffeebot.web.wording import STATUS_TEXT, form_errors

routes = web.RouteTableDef()

FAVICON = Path(__file__).parent / "static" / "favicon.svg"


def templates() -> jinja2.Environment:
    env = jinja2.Environment(
        loader=jinja2.PackageLoader("coffeebot.web", "templates"),
        autoescape=True,
        undefined=jinja2.StrictUndefined,
    )
    env.globals["status_text"] = {s.value: t for s, t in STATUS_TEXT.items()}
    return env


def render(request: web.Request, template: str, status: int = 200, **context: Any) -> web.Response:
    html = request.app[TEMPLATES].get_template(template).render(**context)
    return web.Response(text=html, status=status, content_type="text/html")


def order_form(
    request: web.Request,
    values: Mapping[str, str] | None = None,
    errors: Mapping[str, str] | None = None,
    status: int = 200,
) -> web.Response:
    deps = request.app[DEPS]
    rooms = sorted(deps.rooms, key=lambda r: (r.floor, r.id))
    floors = [(floor, list(group)) for floor, group in groupby(rooms, key=lambda r: r.floor)]
    return render(
        request,
        "order_form.html",
        status=status,
        floors=floors,
        drinks=deps.config.drinks,
        values=values or {},
        errors=errors or {},
    )


@routes.get("/")
async def index(request: web.Request) -> web.Response:
    return order_form(request)


@routes.post("/orders")
async def submit_order(request: web.Request) -> web.StreamResponse:
    """The form without JavaScript: same model, same rate limit as ``POST /api/orders``."""
    form = {k: v for k, v in (await request.post()).items() if isinstance(v, str)}
    try:
        new = NewOrder.model_validate(form, context=order_rules(request))
    except ValidationError as exc:
        return order_form(request, values=form, errors=form_errors(exc), status=422)
    check_rate(request)
    order = await request.app[DEPS].orders.place(new, client_key(request))
    raise web.HTTPSeeOther(status_link(order))


@routes.get(f"/orders/{ORDER_ID}")
async def order_page(request: web.Request) -> web.Response:
    """The customer's status page, reached by the link with the order's key."""
    order = await order_for(request)
    timeline = request.app[TIMELINES].timeline(order)
    return render(
        request, "order.html", order=order, timeline=timeline, key=request.query.get("key", "")
    )


@routes.get("/favicon.ico")
async def favicon(request: web.Request) -> web.FileResponse:
    """Browsers ask for it on every page; the same cup the pages link to."""
    return web.FileResponse(FAVICON, headers={"Content-Type": "image/svg+xml"})


@routes.get("/inspect")
async def inspect_page(request: web.Request) -> web.Response:
    deps = request.app[DEPS]
    floors = sorted({r.floor for r in deps.rooms})
    robot = {
        "length_mm": deps.geometry.length_mm,
        "width_mm": deps.geometry.width_mm,
        "floors": floors,
        "status_text": {s.value: t for s, t in STATUS_TEXT.items()},
    }
    return render(request, "inspect.html", robot=robot)


@routes.get("/inspect/graph.svg")
async def graph_svg(request: web.Request) -> web.Response:
    graph = module_graph(request.app[DEPS].modules())
    svg = request.app[TEMPLATES].get_template("graph.svg").render(graph=graph)
    return web.Response(text=svg, content_type="image/svg+xml")
