"""TCA9548A and VL53L1X drivers against the simulated bus, over the real i2c_rdwr path."""

from __future__ import annotations

import errno

import pytest

from coffeebot.hardware.errors import DeviceError
from coffeebot.hardware.i2c import CountingBus
from coffeebot.hardware.tca9548a import TCA9548A
from coffeebot.hardware.vl53l1x import (
    VL53L1X,
    DistanceMode,
    Measurement,
    SpadRoi,
    reading_status,
)
from coffeebot.messages import ReadingStatus
from coffeebot.sim.i2c import SimTofHardware, make_tof_hardware, targets_at
from coffeebot.sim.world.tof import ConeOptics, flat_target


class FakeTime:
    """Simulated seconds that advance only when the driver sleeps."""

    def __init__(self) -> None:
        self.t = 0.0

    def now(self) -> float:
        return self.t

    def sleep(self, seconds: float) -> None:
        self.t += seconds


@pytest.fixture
def fake_time() -> FakeTime:
    return FakeTime()


@pytest.fixture
def hw(fake_time: FakeTime) -> SimTofHardware:
    return make_tof_hardware(targets_at(lambda ch: 500.0 + 100 * ch), clock=fake_time.now)


def sensor_on(hw: SimTofHardware, fake_time: FakeTime, channel: int) -> VL53L1X:
    TCA9548A(hw.bus).select(channel)
    return VL53L1X(hw.bus, name=f"tof{channel}", sleep=fake_time.sleep)


def range_measurement(sensor: VL53L1X) -> Measurement:
    sensor.wait_data_ready()
    m = sensor.read_measurement()
    sensor.clear_interrupt()
    return m


def range_once(sensor: VL53L1X) -> tuple[ReadingStatus, int]:
    m = range_measurement(sensor)
    return m.status, m.distance_mm


def test_mux_selects_verifies_and_deselects(hw: SimTofHardware) -> None:
    mux = TCA9548A(hw.bus)
    mux.select(5)
    assert hw.mux.mask == 0b0010_0000 and mux.selected() == 0b0010_0000
    mux.deselect()
    assert hw.mux.mask == 0


def test_mux_nack_names_address_and_channel(hw: SimTofHardware) -> None:
    hw.mux.nack = True
    with pytest.raises(DeviceError, match=r"0x70 selecting channel 3") as err:
        TCA9548A(hw.bus).select(3)
    assert err.value.errno == errno.EREMOTEIO


def test_mux_that_keeps_old_selection_is_caught(hw: SimTofHardware) -> None:
    mux = TCA9548A(hw.bus)
    mux.select(1)
    hw.mux.frozen = True
    with pytest.raises(DeviceError, match="reads 0x02, wrote 0x04"):
        mux.select(2)


def test_sensor_behind_unselected_channel_nacks(hw: SimTofHardware) -> None:
    with pytest.raises(OSError) as err:
        VL53L1X(hw.bus).model_id()
    assert err.value.errno == errno.EREMOTEIO


def test_init_configure_and_range(hw: SimTofHardware, fake_time: FakeTime) -> None:
    sensor = sensor_on(hw, fake_time, 2)
    assert sensor.model_id() == 0xEACC
    sensor.init()
    sensor.configure(DistanceMode.SHORT, 20, 20)
    sim = hw.sensors[2]
    assert sim.mode() is DistanceMode.SHORT and sim.timing_budget_ms() == 20
    assert sim.inter_measurement_ms() == pytest.approx(20, abs=0.01)
    sensor.start_ranging()
    # The first sample after a start has no wrap-around check and is not trusted.
    assert range_once(sensor) == (ReadingStatus.OTHER, 700)
    assert range_once(sensor) == (ReadingStatus.VALID, 700)


def test_wrong_model_id_is_refused(hw: SimTofHardware, fake_time: FakeTime) -> None:
    hw.sensors[0].model_id = 0xEBAA  # a VL53L4CD
    with pytest.raises(DeviceError, match="model id 0xEBAA"):
        sensor_on(hw, fake_time, 0).init()


def test_not_ranging_means_never_ready(hw: SimTofHardware, fake_time: FakeTime) -> None:
    sensor = sensor_on(hw, fake_time, 0)
    sensor.init()
    fake_time.sleep(1.0)
    assert not sensor.data_ready()
    with pytest.raises(DeviceError, match="no data ready"):
        sensor.wait_data_ready(polls=5)


def test_reading_before_ready_is_stale(hw: SimTofHardware, fake_time: FakeTime) -> None:
    distances = {0: 300.0}
    hw.sensors[0].scene = targets_at(distances.__getitem__)
    sensor = sensor_on(hw, fake_time, 0)
    sensor.init()
    sensor.configure(DistanceMode.LONG, 20, 20)
    sensor.start_ranging()
    range_once(sensor)
    distances[0] = 900.0
    assert not sensor.data_ready()
    assert sensor.read_measurement().distance_mm == 300  # the previous sample, unchanged
    assert range_once(sensor) == (ReadingStatus.VALID, 900)


def test_uncleared_interrupt_keeps_the_old_sample(hw: SimTofHardware, fake_time: FakeTime) -> None:
    sim = hw.sensors[0]
    sensor = sensor_on(hw, fake_time, 0)
    sensor.init()
    sensor.configure(DistanceMode.LONG, 20, 20)
    sensor.start_ranging()
    sensor.wait_data_ready()
    latched = sim.samples
    fake_time.sleep(0.2)  # ten periods, interrupt never cleared
    sensor.read_measurement()
    assert sim.samples == latched
    sensor.clear_interrupt()
    assert range_once(sensor)[0] is ReadingStatus.VALID
    assert sim.samples == latched + 1


@pytest.mark.parametrize(
    ("raw", "status"),
    [
        (9, ReadingStatus.VALID),
        (4, ReadingStatus.SIGNAL_FAIL),
        (6, ReadingStatus.SIGMA_FAIL),
        (7, ReadingStatus.WRAP_AROUND),
        (3, ReadingStatus.HARDWARE_FAIL),
        (5, ReadingStatus.OUT_OF_BOUNDS),
        (8, ReadingStatus.TOO_CLOSE),
        (13, ReadingStatus.OTHER),
        (0x49, ReadingStatus.VALID),
    ],
)
def test_range_status_is_typed(raw: int, status: ReadingStatus) -> None:
    assert reading_status(raw) is status


def test_forced_status_error_reaches_the_reading(hw: SimTofHardware, fake_time: FakeTime) -> None:
    hw.sensors[4].forced_status = 4
    sensor = sensor_on(hw, fake_time, 4)
    sensor.init()
    sensor.start_ranging()
    assert range_once(sensor)[0] is ReadingStatus.SIGNAL_FAIL


def test_nothing_in_view_too_close_and_out_of_bounds(
    hw: SimTofHardware, fake_time: FakeTime
) -> None:
    distances: dict[int, float | None] = {0: None}
    hw.sensors[0].scene = targets_at(distances.__getitem__)
    sensor = sensor_on(hw, fake_time, 0)
    sensor.init()
    sensor.start_ranging()
    # Nothing sends light back: the signal is below the chip's minimum rate.
    assert range_once(sensor)[0] is ReadingStatus.SIGNAL_FAIL
    distances[0] = 20.0
    assert range_once(sensor) == (ReadingStatus.TOO_CLOSE, 20)
    # A white card 5 m away returns ~0.5 Mcps: lost under the default 1 Mcps minimum; with
    # a lower minimum it is seen, beyond the long mode's 4 m.
    distances[0] = 5000.0
    assert range_once(sensor)[0] is ReadingStatus.SIGNAL_FAIL
    sensor.set_thresholds(0.25, 90.0)
    assert range_once(sensor) == (ReadingStatus.OUT_OF_BOUNDS, 5000)


def test_identification_bytes_read_at_once(hw: SimTofHardware, fake_time: FakeTime) -> None:
    """A driver that reads model id, module type and mask revision in one burst (as ST's
    full driver does) finds the part's real values, not a zero mask revision."""
    sensor = sensor_on(hw, fake_time, 0)
    assert sensor.identification() == bytes([0xEA, 0xCC, 0x10])
    assert sensor.read_int(0x0111, 1) == 0x10


def test_address_register_moves_the_sensor(hw: SimTofHardware, fake_time: FakeTime) -> None:
    sensor = sensor_on(hw, fake_time, 3)
    assert sensor.read_int(0x0001, 1) == 0x29
    sensor.set_address(0x31)
    assert sensor.model_id() == 0xEACC  # the driver follows it to 0x31
    with pytest.raises(OSError):
        VL53L1X(hw.bus, 0x29).model_id()  # nobody answers at the old address
    hw.sensors[3].power_cycle()
    assert VL53L1X(hw.bus, 0x29).model_id() == 0xEACC  # volatile: back after power-off
    with pytest.raises(ValueError, match="0x80"):
        sensor.set_address(0x80)


def test_roi_and_thresholds_are_registers_the_chip_ranges_with(
    hw: SimTofHardware, fake_time: FakeTime
) -> None:
    sensor = sensor_on(hw, fake_time, 0)
    sensor.init()
    sim = hw.sensors[0]
    assert sim.roi() == SpadRoi(16, 16, 199)  # the default configuration block's full array
    narrow = sensor.centred_roi(4, 4)
    sensor.set_roi(narrow)
    assert sensor.roi() == narrow == sim.roi()
    assert sim.regs[0x0080] == 0x33  # (height - 1) << 4 | (width - 1)
    left = SpadRoi.steered(4, 4, column=2)
    sensor.set_roi(left)
    assert sim.regs[0x007F] == left.centre and sim.roi().spans()[0] == (0, 4)
    assert (sim.setup().sigma_limit_mm, sim.setup().min_signal_mcps) == (90.0, 1.0)
    sensor.set_thresholds(0.5, 120.0)
    assert (sim.setup().sigma_limit_mm, sim.setup().min_signal_mcps) == (120.0, 0.5)


def test_result_registers_hold_what_the_ranging_computed(
    hw: SimTofHardware, fake_time: FakeTime
) -> None:
    """Signal, ambient, sigma and SPAD count reach the driver through the 17-byte burst."""
    sensor = sensor_on(hw, fake_time, 0)
    sensor.init()
    sensor.start_ranging()
    sensor.wait_data_ready()
    full = sensor.read_measurement()
    sensor.clear_interrupt()
    expected = flat_target(500.0, ConeOptics())
    assert full.distance_mm == 500
    assert full.signal_rate_mcps == pytest.approx(expected.signal_mcps, abs=1 / 128)
    assert full.ambient_rate_mcps == pytest.approx(expected.ambient_mcps, abs=1 / 128)
    assert full.spads == 255  # 256 SPADs do not fit the 8.8 register
    sensor.set_roi(sensor.centred_roi(4, 4))
    narrow = range_measurement(sensor)
    assert narrow.spads == 16
    assert narrow.signal_rate_mcps < full.signal_rate_mcps / 5  # a tenth of the SPADs


def test_sensor_nack_and_bus_timeout_are_oserrors(hw: SimTofHardware, fake_time: FakeTime) -> None:
    sensor = sensor_on(hw, fake_time, 1)
    hw.sensors[1].nack = True
    with pytest.raises(OSError) as nacked:
        sensor.data_ready()
    assert nacked.value.errno == errno.EREMOTEIO
    hw.sensors[1].nack = False
    hw.bus.timeout = True
    with pytest.raises(OSError) as timed_out:
        sensor.data_ready()
    assert timed_out.value.errno == errno.ETIMEDOUT


def test_unsupported_timing_budget_lists_choices(hw: SimTofHardware, fake_time: FakeTime) -> None:
    sensor = sensor_on(hw, fake_time, 0)
    sensor.init()
    with pytest.raises(ValueError, match=r"15 ms .* LONG"):
        sensor.set_timing_budget(15)


def test_two_channels_enabled_collide(hw: SimTofHardware) -> None:
    hw.bus.write_byte(0x70, 0b11)
    assert VL53L1X(hw.bus).model_id() == 0xEACC  # both answer the same bytes, ANDed
    hw.sensors[1].model_id = 0xEBAA
    assert VL53L1X(hw.bus).model_id() == 0xEA88


def test_counting_bus_counts_driver_traffic(hw: SimTofHardware) -> None:
    bus = CountingBus(hw.bus)
    TCA9548A(bus).select(0)
    VL53L1X(bus).read_measurement()
    traffic = bus.reset()
    # select: write + readback (1 byte each); result: 2 index bytes + 17 data bytes
    assert (traffic.messages, traffic.payload_bytes) == (4, 1 + 1 + 2 + 17)
    assert bus.traffic.messages == 0
