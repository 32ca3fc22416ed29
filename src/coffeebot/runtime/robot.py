"""The daemon on the robot: smbus2 on ``/dev/i2c-<i2c.bus>`` and the board file's serial ports.

Nothing here (or in what it imports) loads the simulator.
"""

from __future__ import annotations

import functools

from coffeebot.clock import MonotonicClock
from coffeebot.config import RobotConfig
from coffeebot.floorplan import FloorPlan
from coffeebot.hardware.i2c import kernel_bus_hz, open_i2c_bus
from coffeebot.runtime.assemble import Runtime, assemble
from coffeebot.store import OrderStore


def build_robot(config: RobotConfig, plan: FloorPlan) -> Runtime:
    """The daemon on the robot; an order database that cannot be used is refused here with
    one line (``StoreError``)."""
    store = OrderStore(config.store.path, busy_timeout_s=config.store.busy_timeout_s)
    return assemble(
        config,
        plan,
        clock=MonotonicClock(),
        open_i2c=functools.partial(open_i2c_bus, config.i2c.bus),
        kernel_hz=functools.partial(kernel_bus_hz, config.i2c.bus),
        store=store,
    )
