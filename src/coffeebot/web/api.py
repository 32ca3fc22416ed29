"""The JSON API: orders, the board, operator actions. Thin handlers over the orders protocol.

A customer acts on an order with its key (``?key=``, from the status link the order was
answered with); an operator, with the operator token, on any order. A request body must be
JSON and say so (``Content-Type: application/json``).
"""

from __future__ import annotations

from aiohttp import web
from pydantic import BaseModel, ConfigDict, Field, StrictBool, ValidationError

from coffeebot.errors import OrderError
from coffeebot.messages import (
    ESTOP,
    OPERATOR_EVENT,
    EStop,
    OperatorEvent,
    OrderStatus,
)
from coffeebot.orders import OrdersUnavailable
from coffeebot.store import NewOrder, Order, OrderRules, PlacedOrder
from coffeebot.web.context import (
    BUS,
    CHANGES,
    DEPS,
    FRAMES,
    LIMITER,
    TIMELINES,
    client_key,
    is_operator,
    validation_error,
)
from coffeebot.web.live import (
    HEARTBEAT_S,
    open_event_stream,
    send_event,
    sleep_unless_closed,
)

routes = web.RouteTableDef()

ORDER_ID = "{order_id:[A-Za-z0-9_-]{1,32}}"


class EStopRequest(BaseModel):
    model_config = ConfigDict(extra="forbid", str_strip_whitespace=True)

    engaged: StrictBool
    """JSON ``true`` or ``false`` only: "yes", 1 or "on" are no answer to "stop the robot?"."""
    reason: str = Field("", max_length=200)


def order_rules(request: web.Request) -> OrderRules:
    deps = request.app[DEPS]
    return OrderRules(rooms={r.id for r in deps.rooms}, drinks=set(deps.config.drinks))


def check_rate(request: web.Request) -> None:
    """Refuse with 429 when this client has placed too many orders lately."""
    wait = request.app[LIMITER].take(client_key(request))
    if wait:
        raise web.HTTPTooManyRequests(
            text=f"too many orders from this address; try again in {wait:.0f} s",
            headers={"Retry-After": str(max(1, round(wait)))},
        )


def order_json(order: Order, status: int = 200) -> web.Response:
    return web.json_response(text=order.model_dump_json(), status=status)


def status_link(order: PlacedOrder) -> str:
    """The customer's status page: the one link that lets its holder act on the order."""
    return f"/orders/{order.id}?key={order.key}"


async def order_for(request: web.Request) -> Order:
    """The order named in the path, for its customer (the ``key`` query parameter) or an
    operator (the token); ``WrongOrderKey`` for anyone else."""
    orders = request.app[DEPS].orders
    order_id = request.match_info["order_id"]
    if is_operator(request):
        return await orders.get(order_id)
    return await orders.authorize(order_id, request.query.get("key", ""))


async def json_body(request: web.Request) -> bytes:
    """The request body, refused with 415 unless it is declared as JSON."""
    if request.content_type != "application/json":
        raise web.HTTPUnsupportedMediaType(
            text=f"the body must be JSON (Content-Type: application/json), not "
            f"{request.content_type!r}"
        )
    return await request.read()


def operator_only(request: web.Request) -> None:
    deps = request.app[DEPS]
    if not deps.operator_token:
        # No token would do: say so, rather than let an operator try theirs again and again.
        raise web.HTTPForbidden(
            text=(
                "operator actions are off: no operator token is set on the robot "
                f"(set {deps.config.operator_token_env} and restart coffeebot)"
            )
        )
    if not is_operator(request):
        raise web.HTTPUnauthorized(
            text="operator token required",
            headers={"WWW-Authenticate": 'Bearer realm="coffeebot operator"'},
        )


@routes.post("/api/orders")
async def create_order(request: web.Request) -> web.Response:
    body = await json_body(request)
    try:
        new = NewOrder.model_validate_json(body, context=order_rules(request))
    except ValidationError as exc:
        return validation_error(exc, "order")
    check_rate(request)  # only orders that would be placed count against the limit
    order = await request.app[DEPS].orders.place(new, client_key(request))
    response = order_json(order, status=201)
    response.headers["Location"] = f"/api/orders/{order.id}?key={order.key}"
    response.headers["Link"] = f'<{status_link(order)}>; rel="alternate"; type="text/html"'
    return response


@routes.get("/api/orders")
async def list_orders(request: web.Request) -> web.Response:
    """Every order that has not ended, for operators (it shows customers' names)."""
    operator_only(request)
    orders = await request.app[DEPS].orders.active()
    return web.json_response(text="[" + ",".join(o.model_dump_json() for o in orders) + "]")


@routes.get(f"/api/orders/{ORDER_ID}")
async def get_order(request: web.Request) -> web.Response:
    return order_json(await order_for(request))


@routes.delete(f"/api/orders/{ORDER_ID}")
async def cancel_order(request: web.Request) -> web.Response:
    """Customers cancel while queued; an operator may also cancel an order that is out."""
    orders = request.app[DEPS].orders
    order = await order_for(request)
    order_id = order.id
    if order.status is OrderStatus.QUEUED or not is_operator(request):
        return order_json(await orders.cancel(order_id))
    if order.status.final:
        raise OrderError(f"order {order_id!r} has already ended ({order.status.value})")
    # The robot holds the cup: navigation ends the delivery and reports it cancelled.
    publish_event(request, "cancel", order_id)
    return order_json(order, status=202)


def publish_event(request: web.Request, kind: str, order_id: str) -> None:
    request.app[BUS].publish(
        OPERATOR_EVENT, OperatorEvent.model_validate({"kind": kind, "order_id": order_id})
    )


async def _event_if(request: web.Request, kind: str, required: OrderStatus) -> web.Response:
    order = await order_for(request)
    if order.status is not required:
        raise OrderError(f"order {order.id!r} is {order.status.value}, not {required.value}")
    publish_event(request, kind, order.id)
    return order_json(order, status=202)


@routes.post(f"/api/orders/{ORDER_ID}/pickup")
async def confirm_pickup(request: web.Request) -> web.Response:
    """The customer's "I have my coffee": only once the robot is at their door."""
    return await _event_if(request, "pickup_confirmed", OrderStatus.ARRIVED)


@routes.post(f"/api/orders/{ORDER_ID}/cup-loaded")
async def cup_loaded(request: web.Request) -> web.Response:
    """Staff in the tea room put the cup on the robot."""
    operator_only(request)
    return await _event_if(request, "cup_loaded", OrderStatus.PREPARING)


@routes.post(f"/api/orders/{ORDER_ID}/elevator-confirm")
async def elevator_confirm(request: web.Request) -> web.Response:
    """An operator vouches for the elevator step the robot is stuck on (the fallback when the
    elevator does not answer, or the robot cannot confirm the floor)."""
    operator_only(request)
    return await _event_if(request, "elevator_confirm", OrderStatus.WAITING_FOR_ELEVATOR)


@routes.get(f"/api/orders/{ORDER_ID}/timeline")
async def order_timeline(request: web.Request) -> web.Response:
    """The order as its customer sees it: steps, plain words, arrival estimate, countdown."""
    order = await order_for(request)
    return web.json_response(text=request.app[TIMELINES].timeline(order).model_dump_json())


@routes.get(f"/api/orders/{ORDER_ID}/events")
async def order_events(request: web.Request) -> web.StreamResponse:
    """The order as JSON each time it (or its place in the queue) changes, and with it a
    ``timeline`` event, repeated every ``progress_period_s`` while the robot has the order
    (the arrival estimate moves); ends when the order ends. While the orders cannot be read
    the stream stays open on heartbeats."""
    deps = request.app[DEPS]
    changes, timelines = request.app[CHANGES], request.app[TIMELINES]
    last = await order_for(request)
    response = await open_event_stream(request)
    payload: str | None = last.model_dump_json()
    while not changes.closed.is_set() and await send_event(response, payload):
        in_flight = last.status is not OrderStatus.QUEUED
        if payload is not None or in_flight:
            timeline = timelines.timeline(last).model_dump_json()
            if not await send_event(response, timeline, event="timeline"):
                break
        if last.status.final:
            break
        seen = changes.version
        await changes.wait(seen, deps.config.progress_period_s if in_flight else HEARTBEAT_S)
        try:
            order = await deps.orders.get(last.id)
        except OrdersUnavailable:
            payload = None
            continue
        payload = None if order == last else order.model_dump_json()
        last = order
    return response


@routes.get("/api/board")
async def board_snapshot(request: web.Request) -> web.Response:
    return web.json_response(text=request.app[FRAMES].json())


@routes.get("/api/board/stream")
async def board_stream(request: web.Request) -> web.StreamResponse:
    """An inspector frame every ``stream_period_s``, until the client or the server goes."""
    deps = request.app[DEPS]
    changes = request.app[CHANGES]
    response = await open_event_stream(request)
    frames = request.app[FRAMES]
    while not changes.closed.is_set():
        if not await send_event(response, frames.json()):
            break
        await sleep_unless_closed(changes, deps.config.stream_period_s)
    return response


@routes.post("/api/estop")
async def estop(request: web.Request) -> web.Response:
    """Engage or release the emergency stop (motion refuses to move while it is engaged)."""
    operator_only(request)
    body = await json_body(request)
    try:
        wanted = EStopRequest.model_validate_json(body)
    except ValidationError as exc:
        return validation_error(exc, "e-stop request")
    msg = EStop(engaged=wanted.engaged, source="web operator", reason=wanted.reason)
    request.app[BUS].publish(ESTOP, msg)
    return web.json_response(text=msg.model_dump_json())


@routes.get("/api/map/{floor:-?[0-9]{1,3}}.svg")
async def floor_map(request: web.Request) -> web.Response:
    source = request.app[DEPS].floor_svg
    svg = source(int(request.match_info["floor"])) if source is not None else None
    if svg is None:
        raise web.HTTPNotFound(text="no floor plan for this floor")
    return web.Response(text=svg, content_type="image/svg+xml")


@routes.get("/healthz")
async def healthz(request: web.Request) -> web.Response:
    """Liveness for systemd and load balancers; also the benchmark's baseline request."""
    return web.Response(text="ok")
