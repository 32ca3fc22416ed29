"""VL53L1X time-of-flight sensor over I2C, following ST's ultra-lite driver (ULD) sequence.

Register indexes are 16 bits wide and SMBus calls carry only one command byte, so every
access is a combined ``i2c_rdwr`` transaction: a write of the big-endian index (plus data
for writes), then, for reads, a read message after a repeated START.
"""

from __future__ import annotations

import time
from collections.abc import Callable
from dataclasses import dataclass
from enum import IntEnum

from smbus2 import i2c_msg

from coffeebot.hardware.errors import DeviceError
from coffeebot.hardware.i2c import I2CBus
from coffeebot.messages import ReadingStatus

DEFAULT_ADDRESS = 0x29
MODEL_ID = 0xEACC  # 0x010F..0x0110; the ULD header's "0xEEAC" is a documentation error
IDENTIFICATION = bytes([0xEA, 0xCC, 0x10])
"""0x010F model id, 0x0110 module type, 0x0111 mask revision."""
WRITE_MESSAGES_KEPT = 64
"""Distinct write messages a driver keeps for reuse (the cycle's few, the set-up's dozen)."""

# Registers (names from ST's ULD and full API).
REG_I2C_ADDRESS = 0x0001
REG_VHV_CONFIG_TIMEOUT_MACROP_LOOP_BOUND = 0x0008
REG_VHV_CONFIG_INIT = 0x000B
REG_CONFIG_BLOCK = 0x002D
REG_GPIO_HV_MUX_CTRL = 0x0030
REG_GPIO_TIO_HV_STATUS = 0x0031
REG_PHASECAL_CONFIG_TIMEOUT_MACROP = 0x004B
REG_RANGE_CONFIG_TIMEOUT_MACROP_A = 0x005E
REG_RANGE_CONFIG_VCSEL_PERIOD_A = 0x0060
REG_RANGE_CONFIG_TIMEOUT_MACROP_B = 0x0061
REG_RANGE_CONFIG_VCSEL_PERIOD_B = 0x0063
REG_SIGMA_THRESHOLD = 0x0064  # RANGE_CONFIG__SIGMA_THRESH, mm in 14.2 fixed point
REG_MIN_SIGNAL_RATE = 0x0066  # RANGE_CONFIG__MIN_COUNT_RATE_RTN_LIMIT_MCPS, 9.7 fixed point
REG_RANGE_CONFIG_VALID_PHASE_HIGH = 0x0069
REG_INTERMEASUREMENT_MS = 0x006C
REG_SD_CONFIG_WOI_SD0 = 0x0078
REG_SD_CONFIG_INITIAL_PHASE_SD0 = 0x007A
REG_ROI_CENTRE = 0x007F  # ROI_CONFIG__USER_ROI_CENTRE_SPAD
REG_ROI_SIZE = 0x0080  # ROI_CONFIG__USER_ROI_REQUESTED_GLOBAL_XY_SIZE: (height-1) << 4 | width-1
REG_SYSTEM_INTERRUPT_CLEAR = 0x0086
REG_SYSTEM_MODE_START = 0x0087
REG_RESULT_RANGE_STATUS = 0x0089
REG_RESULT_SPADS = 0x008C  # DSS actual effective SPADs, 8.8
REG_RESULT_PEAK_SIGNAL = 0x008E  # peak signal count rate, Mcps 9.7
REG_RESULT_AMBIENT = 0x0090  # ambient count rate, Mcps 9.7
REG_RESULT_SIGMA = 0x0092  # estimated range sigma, mm 14.2
REG_RESULT_DISTANCE = 0x0096  # final crosstalk-corrected range, mm
REG_RESULT_SIGNAL = 0x0098  # peak signal count rate, crosstalk corrected, Mcps 9.7
REG_RESULT_OSC_CALIBRATE_VAL = 0x00DE
REG_FIRMWARE_SYSTEM_STATUS = 0x00E5
REG_MODEL_ID = 0x010F
REG_OPTICAL_CENTRE = 0x013E  # ROI_CONFIG__MODE_ROI_CENTRE_SPAD, from the part's NVM

MODE_START_CONTINUOUS = 0x40
MODE_STOP = 0x00
GPIO_ACTIVE_LOW_BIT = 0x10
IMP_CLOCK_FACTOR = 1.075  # ULD: IMP register = osc_calibrate * ms * 1.075

# Result burst from 0x0089 (ULD GetResult reads these 17 bytes).
RESULT_BURST = 17
RESULT_SPADS_OFFSET = REG_RESULT_SPADS - REG_RESULT_RANGE_STATUS
RESULT_AMBIENT_OFFSET = REG_RESULT_AMBIENT - REG_RESULT_RANGE_STATUS
RESULT_SIGMA_OFFSET = REG_RESULT_SIGMA - REG_RESULT_RANGE_STATUS
RESULT_DISTANCE_OFFSET = REG_RESULT_DISTANCE - REG_RESULT_RANGE_STATUS
RESULT_SIGNAL_OFFSET = REG_RESULT_SIGNAL - REG_RESULT_RANGE_STATUS

SPADS = 16
"""The receiving array is 16 x 16 single-photon avalanche diodes."""
OPTICAL_CENTRE_SPAD = 199
"""The centre SPAD of the full array (ULD SetROI writes it for sizes above 10)."""
MIN_ROI = 4
MIN_RANGE_MM = 40
FOV_FULL_DEG, FOV_MIN_ROI_DEG = 27.0, 15.0
"""Field of view with the full 16 x 16 ROI and the smallest 4 x 4 one (UM2555)."""


def spad_row_col(spad: int) -> tuple[int, int]:
    """(row, column) of a SPAD in ST's numbering: 128..255 fill rows 8..15 column by column,
    0..127 rows 0..7 from the other end (the full driver's ``decode_row_col``)."""
    if spad > 127:
        return 8 + ((255 - spad) & 0x07), (spad - 128) >> 3
    return spad & 0x07, (127 - spad) >> 3


def spad_number(row: int, column: int) -> int:
    """The inverse of :func:`spad_row_col`."""
    if row > 7:
        return 128 + (column << 3) + (15 - row)
    return ((15 - column) << 3) + row


@dataclass(frozen=True)
class SpadRoi:
    """A region of interest: ``width x height`` SPADs (4..16) around the SPAD ``centre``.

    Looking out of the sensor, columns 0..15 run from the left edge of the field of view to
    the right and rows 0..15 from the bottom to the top (on a module the sense depends on
    how it is mounted; ST's numbering is kept, so register values mean what they say).
    """

    width: int = SPADS
    height: int = SPADS
    centre: int = OPTICAL_CENTRE_SPAD

    def __post_init__(self) -> None:
        for name in ("width", "height"):
            if not MIN_ROI <= getattr(self, name) <= SPADS:
                raise ValueError(f"ROI {name} {getattr(self, name)} is outside 4..16 SPADs")
        if not 0 <= self.centre <= 255:
            raise ValueError(f"ROI centre SPAD {self.centre} is outside 0..255")

    @classmethod
    def steered(cls, width: int, height: int, column: float, row: float = 8.0) -> SpadRoi:
        """An ROI whose middle is at (``column``, ``row``) in SPADs (8, 8: the axis)."""
        centre = spad_number(round(row), round(column))
        return cls(width, height, centre)

    def spans(self) -> tuple[tuple[int, int], tuple[int, int]]:
        """(first, last + 1) columns and rows it covers, kept inside the array."""
        row, column = spad_row_col(self.centre)
        c0 = min(max(column - self.width // 2, 0), SPADS - self.width)
        r0 = min(max(row - self.height // 2, 0), SPADS - self.height)
        return (c0, c0 + self.width), (r0, r0 + self.height)

    @property
    def spad_count(self) -> int:
        return self.width * self.height

    @property
    def size_register(self) -> int:
        return (self.height - 1) << 4 | (self.width - 1)


FULL_ROI = SpadRoi()


def field_of_view_deg(roi_width: int) -> float:
    """The nominal field of view of an ROI ``roi_width`` SPADs wide: 27 degrees for the full
    array, 15 for the smallest, in between in proportion (UM2555 gives the two ends)."""
    share = (roi_width - MIN_ROI) / (SPADS - MIN_ROI)
    return FOV_MIN_ROI_DEG + share * (FOV_FULL_DEG - FOV_MIN_ROI_DEG)


# The 91-byte default configuration written to 0x2D..0x87 (ST ULD 1.x / Adafruit values).
DEFAULT_CONFIGURATION = bytes.fromhex(
    "00 00 00 01 02 00 02 08 00 08 10 01 01 00 00 00"  # 0x2D..0x3C
    "00 FF 00 0F 00 00 00 00 00 20 0B 00 00 02 0A 21"  # 0x3D..0x4C
    "00 00 05 00 00 00 00 C8 00 00 38 FF 01 00 08 00"  # 0x4D..0x5C
    "00 01 CC 0F 01 F1 0D 01 68 00 80 08 B8 00 00 00"  # 0x5D..0x6C
    "00 0F 89 00 00 00 00 00 00 00 01 0F 0D 0E 0E 00"  # 0x6D..0x7C
    "00 02 C7 FF 9B 00 00 00 01 00 00"  # 0x7D..0x87
)


class DistanceMode(IntEnum):
    SHORT = 1
    LONG = 2


# Register values per distance mode (hardware.md 1.6); 16-bit entries are written big-endian.
DISTANCE_MODE_REGISTERS: dict[DistanceMode, tuple[tuple[int, int, int], ...]] = {
    DistanceMode.SHORT: (
        (REG_PHASECAL_CONFIG_TIMEOUT_MACROP, 0x14, 1),
        (REG_RANGE_CONFIG_VCSEL_PERIOD_A, 0x07, 1),
        (REG_RANGE_CONFIG_VCSEL_PERIOD_B, 0x05, 1),
        (REG_RANGE_CONFIG_VALID_PHASE_HIGH, 0x38, 1),
        (REG_SD_CONFIG_WOI_SD0, 0x0705, 2),
        (REG_SD_CONFIG_INITIAL_PHASE_SD0, 0x0606, 2),
    ),
    DistanceMode.LONG: (
        (REG_PHASECAL_CONFIG_TIMEOUT_MACROP, 0x0A, 1),
        (REG_RANGE_CONFIG_VCSEL_PERIOD_A, 0x0F, 1),
        (REG_RANGE_CONFIG_VCSEL_PERIOD_B, 0x0D, 1),
        (REG_RANGE_CONFIG_VALID_PHASE_HIGH, 0xB8, 1),
        (REG_SD_CONFIG_WOI_SD0, 0x0F0D, 2),
        (REG_SD_CONFIG_INITIAL_PHASE_SD0, 0x0E0E, 2),
    ),
}

# Timing budget ms -> (TIMEOUT_MACROP_A, TIMEOUT_MACROP_B) words, per mode (hardware.md 1.7).
TIMING_BUDGETS: dict[DistanceMode, dict[int, tuple[int, int]]] = {
    DistanceMode.SHORT: {
        15: (0x001D, 0x0027),
        20: (0x0051, 0x006E),
        33: (0x00D6, 0x006E),
        50: (0x01AE, 0x01E8),
        100: (0x02E1, 0x0388),
        200: (0x03E1, 0x0496),
        500: (0x0591, 0x05C1),
    },
    DistanceMode.LONG: {
        20: (0x001E, 0x0022),
        33: (0x0060, 0x006E),
        50: (0x00AD, 0x00C6),
        100: (0x01CC, 0x01EA),
        200: (0x02D9, 0x02F8),
        500: (0x048F, 0x04A4),
    },
}

# RESULT__RANGE_STATUS & 0x1F -> typed status. Anything not listed is OTHER (ULD's 255).
# Raw 8 (target closer than the minimum range) is TOO_CLOSE, never lumped with raw 5
# (OUT_OF_BOUNDS, beyond what it can see): the first means something touches the robot, the
# second that nothing is there. Raw 19 is "valid but without the wrap-around check" (the
# first range after a start), which we do not trust.
RANGE_STATUS: dict[int, ReadingStatus] = {
    9: ReadingStatus.VALID,
    6: ReadingStatus.SIGMA_FAIL,
    4: ReadingStatus.SIGNAL_FAIL,
    23: ReadingStatus.SIGNAL_FAIL,
    5: ReadingStatus.OUT_OF_BOUNDS,
    8: ReadingStatus.TOO_CLOSE,
    3: ReadingStatus.HARDWARE_FAIL,
    7: ReadingStatus.WRAP_AROUND,
}
RANGE_STATUS_MASK = 0x1F


def reading_status(raw: int) -> ReadingStatus:
    return RANGE_STATUS.get(raw & RANGE_STATUS_MASK, ReadingStatus.OTHER)


@dataclass(frozen=True, slots=True)
class Measurement:
    status: ReadingStatus
    raw_status: int
    distance_mm: int
    signal_rate_mcps: float
    ambient_rate_mcps: float
    sigma_mm: float
    spads: int


class VL53L1X:
    """One sensor at ``address`` on ``bus`` (behind a mux channel the caller selected).

    Methods block; call them from the bus's worker thread. ``sleep`` paces the boot and
    data-ready polls and is injectable so a simulated sensor can run on simulated time.
    """

    def __init__(
        self,
        bus: I2CBus,
        address: int = DEFAULT_ADDRESS,
        *,
        name: str = "VL53L1X",
        sleep: Callable[[float], None] = time.sleep,
    ) -> None:
        self.bus = bus
        self.address = address
        self.name = name
        self._sleep = sleep
        self._ready_level = 1  # GPIO level meaning "data ready"; read from 0x30 in init()
        self._mode = DistanceMode.LONG
        self._writes: dict[tuple[int, int, bytes], i2c_msg] = {}
        """Write messages by (address, register, data): the same few are sent every cycle
        (a register's index before a read, the interrupt clear), and the kernel and the
        bus only read a write message's bytes, so one of each serves every transaction."""

    def _write_msg(self, reg: int, data: bytes = b"") -> i2c_msg:
        """The message writing ``data`` at ``reg`` (just the index, to read from it)."""
        key = (self.address, reg, data)
        msg = self._writes.get(key)
        if msg is None:
            msg = i2c_msg.write(self.address, bytes([reg >> 8, reg & 0xFF]) + data)
            if len(self._writes) < WRITE_MESSAGES_KEPT:
                self._writes[key] = msg
        return msg

    # --- register access ----------------------------------------------------------------

    def read(self, reg: int, length: int) -> bytes:
        data = i2c_msg.read(self.address, length)
        self.bus.i2c_rdwr(self._write_msg(reg), data)
        return bytes(data)

    def write(self, reg: int, data: bytes) -> None:
        self.bus.i2c_rdwr(self._write_msg(reg, bytes(data)))

    def read_int(self, reg: int, size: int) -> int:
        return int.from_bytes(self.read(reg, size), "big")

    def write_int(self, reg: int, value: int, size: int) -> None:
        self.write(reg, value.to_bytes(size, "big"))

    # --- bring-up -----------------------------------------------------------------------

    def model_id(self) -> int:
        return self.read_int(REG_MODEL_ID, 2)

    def identification(self) -> bytes:
        """Model id, module type and mask revision in one read (0x010F..0x0111)."""
        return self.read(REG_MODEL_ID, len(IDENTIFICATION))

    def set_address(self, address: int) -> None:
        """Move the sensor to another 7-bit address (until power-off or XSHUT)."""
        if not 0x08 <= address <= 0x77:
            raise ValueError(f"{self.name}: 0x{address:02X} is not a usable 7-bit address")
        self.write_int(REG_I2C_ADDRESS, address, 1)
        self.address = address

    def check_model_id(self) -> None:
        got = self.model_id()
        if got != MODEL_ID:
            raise DeviceError(f"{self.name}: model id 0x{got:04X}, expected 0x{MODEL_ID:04X}")

    def wait_booted(self, polls: int = 100, interval_s: float = 0.002) -> None:
        for _ in range(polls):
            if self.read_int(REG_FIRMWARE_SYSTEM_STATUS, 1):
                return
            self._sleep(interval_s)
        raise DeviceError(f"{self.name}: not booted after {polls} polls of 0x00E5")

    def init(self) -> None:
        """ULD SensorInit: boot wait, id check, default configuration, one VHV calibration
        measurement, then stop. Leaves the sensor configured but not ranging."""
        self.begin_init()
        self.wait_data_ready()
        self.end_init()

    def begin_init(self) -> None:
        """:meth:`init` up to its calibration measurement, started and not waited for: poll
        :meth:`data_ready`, then :meth:`end_init` (a bus shared with other sensors need not
        stand still for it)."""
        self.wait_booted()
        self.check_model_id()
        self.write(REG_CONFIG_BLOCK, DEFAULT_CONFIGURATION)
        self._ready_level = 0 if self.read_int(REG_GPIO_HV_MUX_CTRL, 1) & GPIO_ACTIVE_LOW_BIT else 1
        self.start_ranging()

    def end_init(self) -> None:
        """The rest of :meth:`init` once the calibration measurement is ready."""
        self.clear_interrupt()
        self.stop_ranging()
        self.write_int(REG_VHV_CONFIG_TIMEOUT_MACROP_LOOP_BOUND, 0x09, 1)
        self.write_int(REG_VHV_CONFIG_INIT, 0x00, 1)
        self._mode = DistanceMode.LONG  # what the default block sets

    def configure(self, mode: DistanceMode, budget_ms: int, period_ms: int) -> None:
        """Distance mode, timing budget and inter-measurement period, in the order the
        registers require (the budget words depend on the mode)."""
        self.set_distance_mode(mode)
        self.set_timing_budget(budget_ms)
        self.set_inter_measurement(period_ms)

    def set_distance_mode(self, mode: DistanceMode) -> None:
        for reg, value, size in DISTANCE_MODE_REGISTERS[mode]:
            self.write_int(reg, value, size)
        self._mode = mode

    def set_timing_budget(self, budget_ms: int) -> None:
        table = TIMING_BUDGETS[self._mode]
        if budget_ms not in table:
            raise ValueError(
                f"{self.name}: no {budget_ms} ms timing budget in {self._mode.name} mode; "
                f"choose one of {sorted(table)}"
            )
        a, b = table[budget_ms]
        self.write_int(REG_RANGE_CONFIG_TIMEOUT_MACROP_A, a, 2)
        self.write_int(REG_RANGE_CONFIG_TIMEOUT_MACROP_B, b, 2)

    def set_roi(self, roi: SpadRoi) -> None:
        """Range on ``roi`` from the next sample on (a smaller ROI narrows the cone and
        collects less light; moving its centre steers it)."""
        self.write_int(REG_ROI_CENTRE, roi.centre, 1)
        self.write_int(REG_ROI_SIZE, roi.size_register, 1)

    def roi(self) -> SpadRoi:
        size = self.read_int(REG_ROI_SIZE, 1)
        return SpadRoi((size & 0x0F) + 1, (size >> 4) + 1, self.read_int(REG_ROI_CENTRE, 1))

    def centred_roi(self, width: int, height: int) -> SpadRoi:
        """An ROI on the optical axis, as ULD's SetROI places it: small ones around the
        part's own centre SPAD (measured in production, 0x013E), large ones around 199."""
        if width > 10 or height > 10:
            return SpadRoi(width, height, OPTICAL_CENTRE_SPAD)
        return SpadRoi(width, height, self.read_int(REG_OPTICAL_CENTRE, 1))

    def set_thresholds(self, min_signal_mcps: float, sigma_limit_mm: float) -> None:
        """The chip's own validity limits: below the signal rate or above the sigma a ranging
        is reported as a failure (ULD defaults: ~1 Mcps, 90 mm)."""
        if not 0 <= min_signal_mcps < 512 or not 0 < sigma_limit_mm < 16384:
            raise ValueError(
                f"{self.name}: thresholds {min_signal_mcps} Mcps / {sigma_limit_mm} mm are "
                "outside what the registers hold (0..512 Mcps, 0..16384 mm)"
            )
        self.write_int(REG_MIN_SIGNAL_RATE, round(min_signal_mcps * 128), 2)
        self.write_int(REG_SIGMA_THRESHOLD, round(sigma_limit_mm * 4), 2)

    def set_inter_measurement(self, period_ms: int) -> None:
        clock_pll = self.read_int(REG_RESULT_OSC_CALIBRATE_VAL, 2) & 0x3FF
        self.write_int(REG_INTERMEASUREMENT_MS, int(clock_pll * period_ms * IMP_CLOCK_FACTOR), 4)

    # --- ranging ------------------------------------------------------------------------

    def start_ranging(self) -> None:
        self.clear_interrupt()  # a stale interrupt would otherwise hide the first sample
        self.write_int(REG_SYSTEM_MODE_START, MODE_START_CONTINUOUS, 1)

    def stop_ranging(self) -> None:
        self.write_int(REG_SYSTEM_MODE_START, MODE_STOP, 1)

    def clear_interrupt(self) -> None:
        self.write_int(REG_SYSTEM_INTERRUPT_CLEAR, 0x01, 1)

    def data_ready(self) -> bool:
        return (self.read_int(REG_GPIO_TIO_HV_STATUS, 1) & 0x01) == self._ready_level

    def wait_data_ready(self, polls: int = 1000, interval_s: float = 0.001) -> None:
        for _ in range(polls):
            if self.data_ready():
                return
            self._sleep(interval_s)
        raise DeviceError(f"{self.name}: no data ready after {polls} polls")

    def read_measurement(self) -> Measurement:
        """The latched result. Call only after :meth:`data_ready`, then clear the interrupt,
        or the sensor keeps the old sample and signals no new one."""
        burst = self.read(REG_RESULT_RANGE_STATUS, RESULT_BURST)
        raw = burst[0] & RANGE_STATUS_MASK

        def word(offset: int) -> int:
            return int.from_bytes(burst[offset : offset + 2], "big")

        # Rates are Mcps in 9.7 fixed point, sigma mm in 14.2, the SPAD count 8.8.
        return Measurement(
            status=reading_status(raw),
            raw_status=raw,
            distance_mm=word(RESULT_DISTANCE_OFFSET),
            signal_rate_mcps=word(RESULT_SIGNAL_OFFSET) / 128.0,
            ambient_rate_mcps=word(RESULT_AMBIENT_OFFSET) / 128.0,
            sigma_mm=word(RESULT_SIGMA_OFFSET) / 4.0,
            spads=word(RESULT_SPADS_OFFSET) >> 8,
        )
