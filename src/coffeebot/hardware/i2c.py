"""The I2C bus interface the drivers are typed against, and a byte-counting wrapper.

:class:`I2CBus` lists only the smbus2 calls our drivers make, so :class:`smbus2.SMBus` and
:class:`coffeebot.sim.i2c.SimI2CBus` both satisfy it.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING, Protocol

if TYPE_CHECKING:
    from smbus2 import i2c_msg

I2C_M_RD = 0x0001  # read flag of a Linux i2c_msg (include/uapi/linux/i2c.h)


class I2CBus(Protocol):
    def i2c_rdwr(self, *msgs: i2c_msg) -> None: ...

    def write_byte(self, i2c_addr: int, value: int) -> None: ...

    def read_byte(self, i2c_addr: int) -> int: ...

    def close(self) -> None: ...


def open_i2c_bus(bus: int) -> I2CBus:
    """Open ``/dev/i2c-<bus>``; smbus2 is imported here so the simulator never needs it."""
    from smbus2 import SMBus

    return SMBus(bus)


def kernel_bus_hz(bus: int, sys: Path = Path("/sys")) -> int | None:
    """The clock the kernel runs ``/dev/i2c-<bus>`` at, from the device tree (the Pi's
    ``dtparam=i2c_arm_baudrate``): a big-endian 32-bit ``clock-frequency``. None where the
    kernel does not say (no device tree, no such bus)."""
    path = sys / "class" / "i2c-adapter" / f"i2c-{bus}" / "of_node" / "clock-frequency"
    try:
        raw = path.read_bytes()
    except OSError:
        return None
    return int.from_bytes(raw[:4], "big") if len(raw) >= 4 else None


@dataclass
class BusTraffic:
    """What went over the wire: I2C messages, payload bytes and address bytes.

    ``address_bytes`` counts one address byte per message (each START or repeated START),
    which is what a real bus clocks out besides the payload.
    """

    messages: int = 0
    payload_bytes: int = 0

    @property
    def address_bytes(self) -> int:
        return self.messages

    @property
    def wire_bytes(self) -> int:
        return self.payload_bytes + self.address_bytes

    def bus_seconds(self, clock_hz: float) -> float:
        """Time to clock these bytes at ``clock_hz``: 9 clocks per byte (8 bits + ACK) plus
        a START/STOP condition per message, counted as one more clock each."""
        return (9 * self.wire_bytes + 2 * self.messages) / clock_hz


class CountingBus:
    """Wraps a bus and counts the traffic the drivers really generate (for benchmarks and
    diagnostics); failed transfers are counted too, they occupied the bus."""

    def __init__(self, bus: I2CBus) -> None:
        self._bus = bus
        self.traffic = BusTraffic()

    def i2c_rdwr(self, *msgs: i2c_msg) -> None:
        self.traffic.messages += len(msgs)
        self.traffic.payload_bytes += sum(m.len for m in msgs)
        self._bus.i2c_rdwr(*msgs)

    def write_byte(self, i2c_addr: int, value: int) -> None:
        self.traffic.messages += 1
        self.traffic.payload_bytes += 1
        self._bus.write_byte(i2c_addr, value)

    def read_byte(self, i2c_addr: int) -> int:
        self.traffic.messages += 1
        self.traffic.payload_bytes += 1
        return self._bus.read_byte(i2c_addr)

    def close(self) -> None:
        self._bus.close()

    def reset(self) -> BusTraffic:
        """Return the traffic so far and start counting from zero."""
        done, self.traffic = self.traffic, BusTraffic()
        return done
