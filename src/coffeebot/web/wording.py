"""What customers read: every order status and every form mistake in plain words.

The model's own messages ("String should have at least 1 character") are for the JSON API
and the logs; a person filling in the form is told what to do instead.
"""

from __future__ import annotations

from pydantic import ValidationError

from coffeebot.messages import OrderStatus

STATUS_TEXT: dict[OrderStatus, str] = {
    OrderStatus.QUEUED: "Waiting in the queue",
    OrderStatus.PREPARING: "Being prepared in the tea room",
    OrderStatus.ON_THE_WAY: "On the way",
    OrderStatus.WAITING_FOR_ELEVATOR: "Taking the elevator",
    OrderStatus.ARRIVED: "At your door",
    OrderStatus.DELIVERED: "Delivered, enjoy!",
    OrderStatus.CANCELLED: "Cancelled",
    OrderStatus.FAILED: "Could not be delivered",
}

FIELD_ASK: dict[str, str] = {
    "drink": "Please pick a drink.",
    "name": "Please tell us your name, so the robot knows whose cup it carries.",
    "room": "Please pick your office.",
}

FIELD_LIMIT: dict[str, str] = {
    "name": "Please keep your name to {limit} characters.",
    "notes": "Please keep the notes to {limit} characters.",
}


def form_errors(exc: ValidationError) -> dict[str, str]:
    """Field name to one sentence a customer can act on."""
    errors: dict[str, str] = {}
    for e in exc.errors(include_url=False):
        field = str(e["loc"][0]) if e["loc"] else "form"
        if field in errors:
            continue
        limit = (e.get("ctx") or {}).get("max_length")
        if e["type"] == "string_too_long" and field in FIELD_LIMIT:
            errors[field] = FIELD_LIMIT[field].format(limit=limit)
        elif field in FIELD_ASK:
            errors[field] = FIELD_ASK[field]
        else:
            errors[field] = "This form was sent with a field it does not have; please reload it."
    return errors


def orders_ahead(count: int) -> str:
    if count == 0:
        return "Yours is next."
    return f"{count} order{'s' if count != 1 else ''} ahead of yours."
