"""coffeebot: the software of an indoor coffee-delivery robot."""

__version__ = "0.1.0"
