"""The web app: order form, order status, board inspector, operator actions, JSON API."""

from coffeebot.web.app import create_app
from coffeebot.web.deps import RoomChoice, WebDeps
from coffeebot.web.module import WebModule

__all__ = ["RoomChoice", "WebDeps", "WebModule", "create_app"]
