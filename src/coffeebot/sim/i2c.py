"""A simulated I2C bus with a TCA9548A and VL53L1X register models behind it.

The bus offers the calls :class:`coffeebot.hardware.i2c.I2CBus` lists, taking real
``smbus2.i2c_msg`` objects, so the real drivers run unchanged. The chips are modelled at the
level of I2C messages and registers: a sensor on a channel the mux has not enabled does not
answer (``OSError`` EREMOTEIO, what a Pi reports for a NACK), a sensor not ranging never
signals data ready, a result read before data ready is the previous one, and a sensor whose
interrupt is not cleared keeps its old sample. Each sample is ranged through the region of
interest, distance mode, timing budget and thresholds the chip's registers hold at that
moment (``sim/world/tof.py`` is the physics), and lands in the result registers the real
chip fills: status, distance, signal and ambient rates, sigma and the SPAD count.

Faults are attributes set from the test: ``SimI2CBus.timeout``, ``SimTCA9548A.nack`` /
``frozen``, ``SimVL53L1X.nack`` / ``forced_status`` / ``model_id`` / ``halt()``.
"""

from __future__ import annotations

import ctypes
import errno
import os
import time
from collections.abc import Callable, Iterable
from contextlib import AbstractContextManager, nullcontext
from dataclasses import dataclass
from typing import Protocol

import numpy as np
from smbus2 import i2c_msg

from coffeebot.hardware import vl53l1x as chip
from coffeebot.hardware.i2c import I2C_M_RD
from coffeebot.hardware.tca9548a import CHANNELS
from coffeebot.hardware.tca9548a import DEFAULT_ADDRESS as MUX_ADDRESS
from coffeebot.hardware.vl53l1x import SpadRoi
from coffeebot.messages import ReadingStatus
from coffeebot.sim.world.tof import (
    ConeOptics,
    RangingNoise,
    RangingSetup,
    Returns,
    flat_target,
    range_once,
)

Scene = Callable[[int, SpadRoi], Returns]
"""What the sensor on a mux channel collects through a region of interest (the world's
optics, or :func:`targets_at` for hand-made tests)."""


def targets_at(distances: Callable[[int], float | None], optics: ConeOptics | None = None) -> Scene:
    """A scene of white cards square-on at ``distances(channel)`` mm (None: nothing)."""
    cone = optics or ConeOptics()
    return lambda channel, roi: flat_target(distances(channel), cone, roi)


def nack(address: int) -> OSError:
    return OSError(errno.EREMOTEIO, f"{os.strerror(errno.EREMOTEIO)} (no ACK from 0x{address:02X})")


class SimI2CDevice(Protocol):
    """A chip as the bus sees it: one call per I2C message, raising OSError for a NACK."""

    @property
    def address(self) -> int: ...

    def write(self, data: bytes) -> None: ...

    def read(self, length: int) -> bytes: ...


class SimI2CBus:
    """The upstream bus. Muxes attached to it route addresses they do not own to the devices
    on their enabled channels."""

    def __init__(
        self, simulating: Callable[[], AbstractContextManager[object]] = nullcontext
    ) -> None:
        """``simulating``: entered around each transaction, so whoever counts CPU time can
        tell the simulated chips' work from the driver's (:meth:`SimWorld.simulated`)."""
        self.devices: dict[int, SimI2CDevice] = {}
        self.muxes: list[SimTCA9548A] = []
        self.timeout = False
        self._simulating = simulating

    def attach(self, device: SimI2CDevice) -> None:
        self.devices[device.address] = device
        if isinstance(device, SimTCA9548A):
            self.muxes.append(device)

    def i2c_rdwr(self, *msgs: i2c_msg) -> None:
        with self._simulating():
            for msg in msgs:
                device = self._route(msg.addr)
                if msg.flags & I2C_M_RD:
                    data = device.read(msg.len)
                    ctypes.memmove(msg.buf, data, msg.len)
                else:
                    device.write(bytes(msg))

    def write_byte(self, i2c_addr: int, value: int) -> None:
        with self._simulating():
            self._route(i2c_addr).write(bytes([value]))

    def read_byte(self, i2c_addr: int) -> int:
        with self._simulating():
            return self._route(i2c_addr).read(1)[0]

    def close(self) -> None:
        """Nothing to release; present because smbus2.SMBus has it."""

    def _route(self, address: int) -> SimI2CDevice:
        if self.timeout:
            raise OSError(errno.ETIMEDOUT, f"{os.strerror(errno.ETIMEDOUT)} (I2C bus timeout)")
        if address in self.devices:
            return self.devices[address]
        behind = [dev for mux in self.muxes for dev in mux.downstream(address)]
        if not behind:
            raise nack(address)
        return behind[0] if len(behind) == 1 else _WiredAnd(behind)


class _WiredAnd:
    """Two chips answering at one address (two mux channels enabled): both take every write,
    and on reads the open-drain bus ANDs their bytes together."""

    def __init__(self, devices: list[SimI2CDevice]) -> None:
        self.devices = devices

    @property
    def address(self) -> int:
        return self.devices[0].address

    def write(self, data: bytes) -> None:
        for dev in self.devices:
            dev.write(data)

    def read(self, length: int) -> bytes:
        out = bytearray(b"\xff" * length)
        for dev in self.devices:
            for i, b in enumerate(dev.read(length)):
                out[i] &= b
        return bytes(out)


class SimTCA9548A:
    """The switch: a single control register, bit N connects channel N downstream."""

    def __init__(self, address: int = MUX_ADDRESS) -> None:
        self._address = address
        self.mask = 0x00
        self.channels: list[list[SimI2CDevice]] = [[] for _ in range(CHANNELS)]
        self.nack = False
        self.frozen = False  # fault: acknowledges writes but keeps the old selection

    @property
    def address(self) -> int:
        return self._address

    def attach(self, channel: int, device: SimI2CDevice) -> None:
        """A chip on a downstream channel; it answers at whatever address it has now."""
        self.channels[channel].append(device)

    def write(self, data: bytes) -> None:
        self._check()
        if data and not self.frozen:
            self.mask = data[-1]  # the last byte of a multi-byte write wins

    def read(self, length: int) -> bytes:
        self._check()
        return bytes([self.mask]) * length

    def downstream(self, address: int) -> list[SimI2CDevice]:
        return [
            device
            for channel, devices in enumerate(self.channels)
            if self.mask & (1 << channel)
            for device in devices
            if device.address == address
        ]

    def _check(self) -> None:
        if self.nack:
            raise nack(self.address)


_MAX_RANGE_MM = {chip.DistanceMode.SHORT: 1300, chip.DistanceMode.LONG: 4000}
_PHASECAL_TO_MODE = {0x14: chip.DistanceMode.SHORT, 0x0A: chip.DistanceMode.LONG}
_RAW_VALID, _RAW_NO_WRAP_CHECK = 9, 19
_OSC_CALIBRATE = 0x012C
_RAW_STATUS = {
    ReadingStatus.SIGMA_FAIL: 6,
    ReadingStatus.SIGNAL_FAIL: 4,
    ReadingStatus.OUT_OF_BOUNDS: 5,
    ReadingStatus.TOO_CLOSE: 8,
}
"""The raw RESULT__RANGE_STATUS the chip latches for each way a ranging can fail."""


def _fixed(value: float, fraction_bits: int, limit: int = 0xFFFF) -> int:
    return max(0, min(limit, round(value * (1 << fraction_bits))))


class SimVL53L1X:
    """Register model of one VL53L1X.

    Samples happen every ``max(timing budget, inter-measurement period)`` after a start, on
    ``clock``. A sample is latched into the result registers only when the previous one's
    interrupt was cleared; otherwise it is lost, as on the chip. ``noise`` None ranges
    exactly (hand-made tests); the world's noise model otherwise.
    """

    def __init__(
        self,
        channel: int,
        scene: Scene,
        *,
        clock: Callable[[], float] = time.monotonic,
        noise: RangingNoise | None = None,
        boot_polls: int = 2,
        seed: int = 0,
    ) -> None:
        self.channel = channel
        self.scene = scene
        self.clock = clock
        self.noise = noise
        self.boot_polls = boot_polls
        self.nack = False
        self.forced_status: int | None = None  # fault: raw range status for every sample
        self.model_id = chip.MODEL_ID
        self.samples = 0  # samples latched since power-on, for tests
        self._rng = np.random.default_rng(seed)
        self.power_cycle()

    def power_cycle(self) -> None:
        """Power on (or XSHUT): registers cleared, the address back to 0x29."""
        self.regs = bytearray(0x200)
        self.regs[chip.REG_I2C_ADDRESS] = chip.DEFAULT_ADDRESS
        self.regs[chip.REG_RESULT_OSC_CALIBRATE_VAL : chip.REG_RESULT_OSC_CALIBRATE_VAL + 2] = (
            _OSC_CALIBRATE.to_bytes(2, "big")
        )
        self.regs[chip.REG_OPTICAL_CENTRE] = chip.OPTICAL_CENTRE_SPAD
        self.index = 0
        self._boot_reads = 0
        self._ranging_since: float | None = None
        self._period_s = 0.1
        self._latched = 0
        self._int_pending = False

    @property
    def address(self) -> int:
        """The 7-bit address it answers at (I2C_SLAVE__DEVICE_ADDRESS, volatile)."""
        return self.regs[chip.REG_I2C_ADDRESS] & 0x7F

    # --- I2C messages -------------------------------------------------------------------

    def write(self, data: bytes) -> None:
        self._check()
        if len(data) < 2:
            return  # an incomplete index: the chip waits for the second byte, nothing happens
        self._advance()
        self.index = (data[0] << 8) | data[1]
        for value in data[2:]:
            self._store(self.index, value)
            self.index += 1

    def read(self, length: int) -> bytes:
        self._check()
        self._advance()
        out = bytes(self._load(self.index + i) for i in range(length))
        self.index += length
        return out

    # --- registers ----------------------------------------------------------------------

    def _load(self, reg: int) -> int:
        if reg == chip.REG_FIRMWARE_SYSTEM_STATUS:
            self._boot_reads += 1
            return 0x03 if self._boot_reads > self.boot_polls else 0x00
        ident = reg - chip.REG_MODEL_ID
        if 0 <= ident < len(chip.IDENTIFICATION):
            return (self.model_id.to_bytes(2, "big") + chip.IDENTIFICATION[2:])[ident]
        if reg == chip.REG_GPIO_TIO_HV_STATUS:
            active_low = bool(self.regs[chip.REG_GPIO_HV_MUX_CTRL] & chip.GPIO_ACTIVE_LOW_BIT)
            return int(self._int_pending != active_low)
        return self.regs[reg] if reg < len(self.regs) else 0

    def _store(self, reg: int, value: int) -> None:
        if reg >= len(self.regs):
            return
        self.regs[reg] = value
        if reg == chip.REG_SYSTEM_INTERRUPT_CLEAR and value & 0x01:
            self._int_pending = False
            if self._ranging_since is not None:
                self._latched = self._sample_index()  # samples until now are gone
        elif reg == chip.REG_SYSTEM_MODE_START:
            self._start() if value == chip.MODE_START_CONTINUOUS else self.halt()

    def _int(self, reg: int, size: int) -> int:
        return int.from_bytes(self.regs[reg : reg + size], "big")

    def mode(self) -> chip.DistanceMode:
        phasecal = self.regs[chip.REG_PHASECAL_CONFIG_TIMEOUT_MACROP]
        return _PHASECAL_TO_MODE.get(phasecal, chip.DistanceMode.LONG)

    def timing_budget_ms(self) -> int:
        a_word = self._int(chip.REG_RANGE_CONFIG_TIMEOUT_MACROP_A, 2)
        for budget, (a, _b) in chip.TIMING_BUDGETS[self.mode()].items():
            if a == a_word:
                return budget
        return 100

    def inter_measurement_ms(self) -> float:
        return self._int(chip.REG_INTERMEASUREMENT_MS, 4) / (_OSC_CALIBRATE * chip.IMP_CLOCK_FACTOR)

    def roi(self) -> SpadRoi:
        """The region of interest the registers hold (sizes below 4 SPADs act as 4)."""
        size = self.regs[chip.REG_ROI_SIZE]
        width, height = (size & 0x0F) + 1, (size >> 4) + 1
        return SpadRoi(max(4, width), max(4, height), self.regs[chip.REG_ROI_CENTRE])

    def setup(self) -> RangingSetup:
        """How the next sample is ranged: mode, budget and thresholds from the registers."""
        mode = self.mode()
        return RangingSetup(
            max_range_mm=_MAX_RANGE_MM[mode],
            timing_budget_ms=self.timing_budget_ms(),
            sigma_limit_mm=self._int(chip.REG_SIGMA_THRESHOLD, 2) / 4.0,
            min_signal_mcps=self._int(chip.REG_MIN_SIGNAL_RATE, 2) / 128.0,
            short_mode=mode is chip.DistanceMode.SHORT,
        )

    # --- ranging ------------------------------------------------------------------------

    def _start(self) -> None:
        self._period_s = max(self.timing_budget_ms(), self.inter_measurement_ms()) / 1000.0
        self._ranging_since = self.clock()
        self._latched = 0

    def halt(self) -> None:
        """Stop ranging (also a fault: a sensor that silently stops, as after a brown-out)."""
        self._ranging_since = None

    def _sample_index(self) -> int:
        assert self._ranging_since is not None
        return int((self.clock() - self._ranging_since) / self._period_s)

    def _advance(self) -> None:
        if self._ranging_since is None or self._int_pending:
            return
        n = self._sample_index()
        if n > self._latched:
            self._latch(first=self._latched == 0)
            self._latched = n
            self._int_pending = True

    def _latch(self, first: bool) -> None:
        roi = self.roi()
        reading = range_once(self.scene(self.channel, roi), self.setup(), self.noise, self._rng)
        if self.forced_status is not None:
            raw = self.forced_status
        elif reading.status is ReadingStatus.VALID:
            raw = _RAW_NO_WRAP_CHECK if first else _RAW_VALID
        else:
            raw = _RAW_STATUS[reading.status]
        signal = _fixed(reading.signal_mcps, 7)
        results = {
            chip.REG_RESULT_RANGE_STATUS: (raw, 1),
            chip.REG_RESULT_SPADS: (_fixed(reading.spads, 8), 2),
            chip.REG_RESULT_PEAK_SIGNAL: (signal, 2),
            chip.REG_RESULT_AMBIENT: (_fixed(reading.ambient_mcps, 7), 2),
            chip.REG_RESULT_SIGMA: (_fixed(reading.sigma_mm, 2), 2),
            chip.REG_RESULT_DISTANCE: (reading.distance_mm, 2),
            chip.REG_RESULT_SIGNAL: (signal, 2),
        }
        for reg, (value, size) in results.items():
            self.regs[reg : reg + size] = value.to_bytes(size, "big")
        self.samples += 1

    def _check(self) -> None:
        if self.nack:
            raise nack(self.address)


@dataclass
class SimTofHardware:
    """The robot's ToF wiring in simulation: one bus, one mux, a sensor per channel."""

    bus: SimI2CBus
    mux: SimTCA9548A
    sensors: dict[int, SimVL53L1X]


def make_tof_hardware(
    scene: Scene,
    channels: Iterable[int] = range(CHANNELS),
    *,
    mux_address: int = MUX_ADDRESS,
    clock: Callable[[], float] = time.monotonic,
    noise: RangingNoise | None = None,
    seed: int = 0,
    simulating: Callable[[], AbstractContextManager[object]] = nullcontext,
) -> SimTofHardware:
    bus = SimI2CBus(simulating)
    mux = SimTCA9548A(mux_address)
    bus.attach(mux)
    sensors = {}
    for ch in channels:
        sensors[ch] = SimVL53L1X(ch, scene, clock=clock, noise=noise, seed=seed * 8 + ch)
        mux.attach(ch, sensors[ch])
    return SimTofHardware(bus, mux, sensors)
