"""The typed publish/subscribe message board that connects every module."""

from coffeebot.board.board import Board, BoardOverflowError, Subscription
from coffeebot.board.stats import BoardSnapshot, SubscriberStats, TopicStats
from coffeebot.board.topic import Delivery, Envelope, Topic
from coffeebot.board.view import BoardView
from coffeebot.errors import BoardError

__all__ = [
    "Board",
    "BoardError",
    "BoardOverflowError",
    "BoardSnapshot",
    "BoardView",
    "Delivery",
    "Envelope",
    "SubscriberStats",
    "Subscription",
    "Topic",
    "TopicStats",
]
