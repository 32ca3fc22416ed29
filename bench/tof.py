"""ToF poller benchmark: 8 VL53L1X on the simulated bus, as fast as the timing budget allows.

Prints the achieved scan rate, the time per cycle spent in bus calls (simulated bus, so this
is Python overhead, not wire time), a baseline of the same transfers done in a plain loop
without the poller (measured in the same run, for the ratio), and the wire time the bytes the
driver really transferred per cycle would take on a real bus at 100 kHz and 400 kHz.

    python bench/tof.py [--seconds 3]
"""

from __future__ import annotations

import argparse
import asyncio
import contextlib
import logging
import time
from statistics import median

from smbus2 import i2c_msg

from coffeebot.board import Board
from coffeebot.clock import MonotonicClock
from coffeebot.config import I2CConfig, TofConfig, TofSensorConfig
from coffeebot.hardware.i2c import BusTraffic, CountingBus, I2CBus
from coffeebot.hardware.tca9548a import TCA9548A
from coffeebot.hardware.vl53l1x import VL53L1X
from coffeebot.messages import ALL_TOPICS, RANGE_SCAN
from coffeebot.modules.base import ModuleBoard, ModuleContext
from coffeebot.modules.tof_poller import TofPoller
from coffeebot.sim.i2c import make_tof_hardware, targets_at

SENSORS = 8
BUDGET_MS = 20


class TimedBus:
    """Adds up the time spent inside bus calls."""

    def __init__(self, bus: I2CBus) -> None:
        self._bus = bus
        self.seconds = 0.0

    def i2c_rdwr(self, *msgs: i2c_msg) -> None:
        t = time.perf_counter()
        try:
            self._bus.i2c_rdwr(*msgs)
        finally:
            self.seconds += time.perf_counter() - t

    def write_byte(self, i2c_addr: int, value: int) -> None:
        t = time.perf_counter()
        try:
            self._bus.write_byte(i2c_addr, value)
        finally:
            self.seconds += time.perf_counter() - t

    def read_byte(self, i2c_addr: int) -> int:
        t = time.perf_counter()
        try:
            return self._bus.read_byte(i2c_addr)
        finally:
            self.seconds += time.perf_counter() - t

    def close(self) -> None:
        self._bus.close()


def tof_config() -> TofConfig:
    return TofConfig(
        timing_budget_ms=BUDGET_MS,
        sensors=[
            TofSensorConfig(id=i, channel=i, face="front", x_mm=0, y_mm=0, yaw_deg=0)
            for i in range(SENSORS)
        ],
    )


async def run_poller(seconds: float) -> tuple[float, float, BusTraffic, int]:
    """Scan rate (Hz), bus seconds per cycle, total traffic, and the cycles it covers."""
    hw = make_tof_hardware(targets_at(lambda ch: 1000.0 + ch))
    timed = TimedBus(hw.bus)
    counting = CountingBus(timed)
    clock = MonotonicClock()
    board = Board(ALL_TOPICS, clock=clock)
    poller = TofPoller(I2CConfig(), tof_config(), lambda: counting)
    ctx = ModuleContext(ModuleBoard(board, poller), clock, logging.getLogger("bench"))
    task = asyncio.create_task(poller.run(ctx))
    with board.subscribe(RANGE_SCAN) as scans:
        await scans.get()  # sensors initialised and ranging
        await scans.get()
        counting.reset()
        timed.seconds = 0.0
        first = await scans.get()
        cycles = 0  # scans strictly between `first` and `last`
        while (last := await scans.get()).msg.cycle_start_s - first.msg.cycle_start_s < seconds:
            cycles += 1
        traffic, bus_s = counting.reset(), timed.seconds
    task.cancel()
    with contextlib.suppress(asyncio.CancelledError):
        await task
    elapsed = last.msg.cycle_start_s - first.msg.cycle_start_s
    counted = cycles + 2  # the traffic covers the cycles that produced `first` .. `last`
    return (cycles + 1) / elapsed, bus_s / counted, traffic, counted


def baseline_cycle_seconds(repeats: int = 200) -> float:
    """The same per-sensor transfers as one poller cycle (select, ready, result, clear), in a
    plain loop on a sensor that always has data: the floor for the simulated bus."""
    hw = make_tof_hardware(targets_at(lambda ch: 1000.0 + ch))
    timed = TimedBus(hw.bus)
    mux = TCA9548A(timed)
    sensors = [VL53L1X(timed, name=f"tof{i}") for i in range(SENSORS)]
    samples = []
    for _ in range(repeats):
        timed.seconds = 0.0
        for i, sensor in enumerate(sensors):
            mux.select(i)
            sensor.data_ready()
            sensor.read_measurement()
            sensor.clear_interrupt()
        samples.append(timed.seconds)
    return median(samples)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--seconds", type=float, default=3.0)
    args = parser.parse_args()
    rate, bus_s, traffic, n = asyncio.run(run_poller(args.seconds))
    base_s = baseline_cycle_seconds()
    budget_s = BUDGET_MS / 1000.0
    print(f"ToF poller, {SENSORS} x VL53L1X on the simulated bus, {BUDGET_MS} ms timing budget,")
    print(f"{n} cycles measured\n")
    print("| quantity | value |")
    print("|---|---|")
    print(f"| achieved scan rate | {rate:.1f} Hz (target {1 / budget_s:.0f} Hz) |")
    print(f"| simulated-bus time per cycle (poller) | {bus_s * 1e3:.2f} ms |")
    print(f"| simulated-bus time per cycle (plain loop baseline) | {base_s * 1e3:.2f} ms |")
    print(f"| poller / baseline | {bus_s / base_s:.2f} |")
    print(f"| I2C messages per cycle | {traffic.messages / n:.1f} |")
    print(
        f"| payload + address bytes per cycle | {traffic.payload_bytes / n:.1f} + "
        f"{traffic.address_bytes / n:.1f} |"
    )
    for hz in (100_000, 400_000):
        wire = traffic.bus_seconds(hz) / n
        print(
            f"| real-bus time per cycle at {hz // 1000} kHz | {wire * 1e3:.2f} ms "
            f"({wire / budget_s:.0%} of the {BUDGET_MS} ms cycle) |"
        )


if __name__ == "__main__":
    main()
