"""TCA9548A 8-channel I2C switch: one control register, bit N enables channel N."""

from __future__ import annotations

from coffeebot.hardware.errors import DeviceError
from coffeebot.hardware.i2c import I2CBus

DEFAULT_ADDRESS = 0x70
CHANNELS = 8


class TCA9548A:
    """Selects one downstream channel at a time.

    Only one channel is ever enabled: our eight VL53L1X all sit at 0x29, and two enabled
    channels would put two of them on the bus at once. Each selection is read back, because
    a mux that silently kept the old channel would make us read the wrong sensor.
    """

    def __init__(self, bus: I2CBus, address: int = DEFAULT_ADDRESS) -> None:
        self.bus = bus
        self.address = address

    def select(self, channel: int) -> None:
        if not 0 <= channel < CHANNELS:
            raise ValueError(f"TCA9548A has channels 0..{CHANNELS - 1}, not {channel}")
        self._write_and_verify(1 << channel)

    def deselect(self) -> None:
        self._write_and_verify(0x00)

    def selected(self) -> int:
        """The control register: a bit mask of enabled channels."""
        return self.bus.read_byte(self.address)

    def _write_and_verify(self, mask: int) -> None:
        try:
            self.bus.write_byte(self.address, mask)
            got = self.bus.read_byte(self.address)
        except OSError as exc:
            raise DeviceError(exc.errno, f"{self._where(mask)}: {exc.strerror or exc}") from exc
        if got != mask:
            raise DeviceError(
                f"{self._where(mask)}: control register reads 0x{got:02X}, wrote 0x{mask:02X}"
            )

    def _where(self, mask: int) -> str:
        """The selection an error message names (built only for an error: every sensor's
        every poll selects a channel)."""
        what = f"channel {mask.bit_length() - 1}" if mask else "no channel"
        return f"TCA9548A at 0x{self.address:02X} selecting {what}"
