"""Driver errors.

They derive from :class:`OSError` as well as the product's :class:`HardwareError` on
purpose: to a caller, a chip that answers wrongly (a mux that does not read back its
selection, a sensor with the wrong model id) is as broken as one that does not answer at
all, and one ``except OSError`` handles both.
"""

from __future__ import annotations

from coffeebot.errors import HardwareError


class DeviceError(HardwareError, OSError):
    """A device answered, but not the way the chip should; the message names the part."""
