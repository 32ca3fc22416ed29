"""ToF poller: cycles the VL53L1X sensors through the mux and publishes one scan per cycle.

Each sensor is independent: an ``OSError`` from one (a NACK, a bus timeout, a wrong model id)
marks that sensor unhealthy in the scan and on the health topic and schedules its
re-initialisation with backoff, while the others keep being read in the same cycle. So does a
sensor that answers but has had no new sample for ``STALE_PERIODS`` sample periods (it stopped
ranging, as after a brown-out): only a re-initialisation starts it again. A re-initialisation
after a failure never holds the bus for the others: its calibration measurement is started in
one cycle and polled in the following ones, like any sample (at start-up every sensor is
brought up at once, before the first scan). A sensor
going unhealthy is logged once as ``event=fault`` with the error, and once as
``event=recovered`` when it is re-initialised, however many retries that took.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

from coffeebot.clock import blocking_sleep
from coffeebot.config import I2CConfig, TofConfig, TofSensorConfig
from coffeebot.hardware.i2c import I2CBus
from coffeebot.hardware.tca9548a import TCA9548A
from coffeebot.hardware.vl53l1x import VL53L1X, DistanceMode
from coffeebot.hardware.worker import DeviceWorker
from coffeebot.logs import Event, Transitions
from coffeebot.messages import (
    HEALTH,
    RANGE_SCAN,
    Health,
    HealthStatus,
    RangeReading,
    RangeScan,
    ReadingStatus,
)
from coffeebot.modules.backoff import Backoff
from coffeebot.modules.base import Module, ModuleContext

DISTANCE_MODES = {"short": DistanceMode.SHORT, "long": DistanceMode.LONG}
HEALTHY, FAILED = "healthy", "failed"
STALE_PERIODS = 25
"""A sensor with no new sample for this many sample periods (0.5 s at 20 ms) has stopped
ranging: it is re-initialised."""
CALIBRATION_S = 1.0
"""A re-initialisation whose calibration measurement is not ready by then has failed."""


@dataclass
class SensorSlot:
    """One configured sensor, its driver and its health."""

    cfg: TofSensorConfig
    driver: VL53L1X
    backoff: Backoff
    healthy: bool = False
    retry_at: float = 0.0
    failures: int = 0
    error: str = "not initialised"
    last_sample_s: float = 0.0
    """When its last new sample was read (or it was brought up)."""
    calibrating_since: float | None = None
    """A re-initialisation's calibration measurement is under way since then."""

    @property
    def component(self) -> str:
        return f"tof{self.cfg.id}"


class TofPoller(Module):
    name = "tof"
    outputs = (RANGE_SCAN, HEALTH)

    def __init__(
        self,
        i2c: I2CConfig,
        tof: TofConfig,
        open_bus: Callable[[], I2CBus],
        *,
        poll_interval_s: float = 0.002,
        backoff_s: tuple[float, float] = (0.25, 8.0),
        blocking_sleep: Callable[[float], None] | None = None,
    ) -> None:
        """``open_bus`` makes the bus (smbus2 on the robot, the simulated bus in tests);
        ``blocking_sleep`` paces the driver's polls inside the bus thread (by default a sleep
        that agrees with the daemon's clock)."""
        self.i2c = i2c
        self.tof = tof
        self.open_bus = open_bus
        self.poll_interval_s = poll_interval_s
        self.backoff_s = backoff_s
        self.blocking_sleep = blocking_sleep
        budget_s = tof.timing_budget_ms / 1000.0
        self.period_s = 1.0 / tof.scan_rate_hz if tof.scan_rate_hz else budget_s
        # The sensors range at the scan rate, so each cycle reads a fresh sample.
        self.sample_period_ms = max(tof.timing_budget_ms, round(self.period_s * 1000))
        self.scans = 0
        self._faults: Transitions | None = None

    async def run(self, ctx: ModuleContext) -> None:
        bus = self.open_bus()
        worker = DeviceWorker(f"i2c-{self.i2c.bus}", ctx.clock)
        sleep = self.blocking_sleep or blocking_sleep(ctx.clock)
        mux = TCA9548A(bus, self.i2c.mux_address)
        slots = [
            SensorSlot(
                cfg,
                VL53L1X(
                    bus,
                    self.i2c.sensor_address,
                    name=f"VL53L1X tof{cfg.id} on mux channel {cfg.channel}",
                    sleep=sleep,
                ),
                Backoff(*self.backoff_s),
            )
            for cfg in sorted(self.tof.sensors, key=lambda s: s.id)
        ]
        # Sensors start as healthy: coming up at start-up is no recovery, failing is a fault.
        self._faults = Transitions(ctx.log, initial={slot.component: HEALTHY for slot in slots})
        try:
            while True:
                await self._cycle(ctx, worker, mux, slots)
        finally:
            worker.close()
            bus.close()

    async def _cycle(
        self, ctx: ModuleContext, worker: DeviceWorker, mux: TCA9548A, slots: list[SensorSlot]
    ) -> None:
        clock = ctx.clock
        start = clock.now()
        readings: dict[int, RangeReading] = {}
        for slot in slots:
            if not slot.healthy and start >= slot.retry_at:
                await self._bring_up(ctx, worker, mux, slot)
            if not slot.healthy:
                readings[slot.cfg.id] = _failed(slot)
        pending = [s for s in slots if s.healthy]
        deadline = start + 2 * self.sample_period_ms / 1000.0
        while pending:
            for slot, result in zip(
                pending, await worker.call(self._poll, mux, pending), strict=True
            ):
                if isinstance(result, OSError):
                    self._mark_failed(ctx, slot, result)
                    readings[slot.cfg.id] = _failed(slot)
                elif result is not None:
                    readings[slot.cfg.id] = result
                    slot.last_sample_s = start
            pending = [s for s in pending if s.cfg.id not in readings]
            if pending and clock.now() >= deadline:
                for slot in pending:
                    readings[slot.cfg.id] = RangeReading(
                        sensor=slot.cfg.id, status=ReadingStatus.NOT_READY
                    )
                    silent_s = start - slot.last_sample_s
                    if silent_s >= STALE_PERIODS * self.sample_period_ms / 1000.0:
                        self._mark_failed(
                            ctx,
                            slot,
                            OSError(f"no new sample for {silent_s:.1f} s: stopped ranging"),
                        )
                        readings[slot.cfg.id] = _failed(slot)
                break
            if pending:
                await clock.sleep(self.poll_interval_s)
        ctx.board.publish(
            RANGE_SCAN,
            RangeScan(
                cycle_start_s=start,
                cycle_time_s=clock.now() - start,
                readings=[readings[s.cfg.id] for s in slots],
            ),
        )
        self.scans += 1
        await clock.sleep(start + self.period_s - clock.now())

    def _poll(self, mux: TCA9548A, slots: list[SensorSlot]) -> list[RangeReading | OSError | None]:
        """One pass over the sensors still waiting, in the bus thread: each sensor's mux
        selection and transfers run back to back. None means "no new sample yet"."""
        results: list[RangeReading | OSError | None] = []
        for slot in slots:
            try:
                mux.select(slot.cfg.channel)
                if not slot.driver.data_ready():
                    results.append(None)
                    continue
                m = slot.driver.read_measurement()
                slot.driver.clear_interrupt()
            except OSError as exc:
                results.append(exc)
                continue
            valid = m.status is ReadingStatus.VALID
            results.append(
                RangeReading(
                    sensor=slot.cfg.id,
                    status=m.status,
                    distance_mm=m.distance_mm if valid else None,
                    signal_rate_mcps=m.signal_rate_mcps,
                    ambient_rate_mcps=m.ambient_rate_mcps,
                    sigma_mm=m.sigma_mm,
                )
            )
        return results

    def _init_sensor(self, mux: TCA9548A, slot: SensorSlot) -> None:
        mux.select(slot.cfg.channel)
        slot.driver.init()
        self._configure(slot)

    def _configure(self, slot: SensorSlot) -> None:
        slot.driver.configure(
            DISTANCE_MODES[self.tof.distance_mode],
            self.tof.timing_budget_ms,
            self.sample_period_ms,
        )
        slot.driver.set_thresholds(self.tof.min_signal_mcps, self.tof.sigma_limit_mm)
        size = slot.cfg.roi_spads
        slot.driver.set_roi(slot.driver.centred_roi(size, size))
        slot.driver.start_ranging()

    def _begin_init(self, mux: TCA9548A, slot: SensorSlot) -> None:
        mux.select(slot.cfg.channel)
        slot.driver.begin_init()

    def _calibrated(self, mux: TCA9548A, slot: SensorSlot) -> bool:
        mux.select(slot.cfg.channel)
        return slot.driver.data_ready()

    def _end_init(self, mux: TCA9548A, slot: SensorSlot) -> None:
        mux.select(slot.cfg.channel)
        slot.driver.end_init()
        self._configure(slot)

    async def _bring_up(
        self, ctx: ModuleContext, worker: DeviceWorker, mux: TCA9548A, slot: SensorSlot
    ) -> None:
        now = ctx.clock.now()
        try:
            if slot.failures == 0:  # start-up: the whole initialisation at once
                await worker.call(self._init_sensor, mux, slot)
            elif slot.calibrating_since is None:
                await worker.call(self._begin_init, mux, slot)
                slot.calibrating_since = now
                return
            elif not await worker.call(self._calibrated, mux, slot):
                if now - slot.calibrating_since < CALIBRATION_S:
                    return
                raise OSError(f"no calibration measurement within {CALIBRATION_S:g} s")
            else:
                await worker.call(self._end_init, mux, slot)
        except OSError as exc:
            slot.calibrating_since = None
            self._mark_failed(ctx, slot, exc)
            return
        slot.calibrating_since = None
        slot.healthy = True
        slot.last_sample_s = ctx.clock.now()
        slot.backoff.reset()
        self._transition(slot, HEALTHY, Event.RECOVERED, "re-initialised")
        self._report(ctx, slot, HealthStatus.RUNNING, f"mux channel {slot.cfg.channel}")

    def _mark_failed(self, ctx: ModuleContext, slot: SensorSlot, exc: OSError) -> None:
        slot.healthy = False
        slot.failures += 1
        slot.error = str(exc)
        delay = slot.backoff.next_delay()
        slot.retry_at = ctx.clock.now() + delay
        self._transition(slot, FAILED, Event.FAULT, slot.error)
        ctx.log.debug("%s failed, retry in %.2f s: %s", slot.component, delay, exc)
        self._report(ctx, slot, HealthStatus.DEGRADED, slot.error)

    def _report(
        self, ctx: ModuleContext, slot: SensorSlot, status: HealthStatus, detail: str
    ) -> None:
        ctx.board.publish(
            HEALTH,
            Health(
                module=self.name,
                component=slot.component,
                status=status,
                restarts=slot.failures,
                detail=detail,
            ),
        )

    def _transition(self, slot: SensorSlot, state: str, event: Event, cause: str) -> None:
        assert self._faults is not None, "only called from run()"
        self._faults.update(
            slot.component, state, event, cause, channel=slot.cfg.channel, failures=slot.failures
        )


def _failed(slot: SensorSlot) -> RangeReading:
    return RangeReading(sensor=slot.cfg.id, status=ReadingStatus.BUS_ERROR, healthy=False)
