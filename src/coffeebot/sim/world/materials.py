"""How much of the VL53L1X's 940 nm light each surface in the world sends back.

The reflectance of a surface is what its return weighs in a ranging (``tof.py``): a white
card and a black chair at the same distance differ by an order of magnitude in signal, so
the dark one drops out of a blended reading first. Values are diffuse (Lambertian)
reflectances in the near infrared, chosen from what ST's own test targets and the usual
material tables give:

* ST specifies the VL53L1X against a white target of 88 % and a grey one of 17 % (the
  datasheet's ranging tables); "white" and "grey" below are those two.
* Painted walls are white or light emulsion: 0.6-0.85 at 940 nm. Wood, cardboard and most
  textiles reflect the near infrared better than they look (their dyes absorb visible light,
  not 940 nm): kraft cardboard ~0.6, wood 0.3-0.5, cotton and denim 0.4-0.6.
* Carbon-black plastics and black synthetic fabrics absorb it: 0.03-0.1. Brushed steel is
  mostly specular, so little comes back diffusely at anything but normal incidence.

What a surface is made of is decided here by the element's name (floor-plan elements) or by
the part of an obstacle, so the floor-plan format does not have to carry optics.
"""

from __future__ import annotations

WHITE = 0.88
GREY = 0.17
BLACK = 0.05

WALL = 0.7
"""Light emulsion paint."""
DOOR = 0.45
"""Painted or varnished wooden door leaf."""
STEEL = 0.3
"""Brushed stainless steel (elevator car and doors): mostly specular, some diffuse return."""
DEFAULT = 0.5
ROBOT_SHELL = 0.6
"""Another robot's light grey plastic shell, as this robot's sensors see it."""

_ELEMENT_PREFIXES: tuple[tuple[str, float], ...] = (
    ("elevator car", STEEL),
    ("hallway", WALL),
    ("wall", WALL),
    ("opening", WALL),
    ("door", DOOR),
)


def element_reflectance(element: str) -> float:
    """Reflectance of a floor-plan element by its name (``"door 205 jamb"``, ...)."""
    if element.endswith("jamb"):
        return WALL
    for prefix, value in _ELEMENT_PREFIXES:
        if element.startswith(prefix):
            return value
    return DEFAULT
