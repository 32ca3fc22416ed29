"""Probe every device once: ``coffeebot check-hardware``, the first thing to run on a newly
wired robot, and the daemon's start-up self-check. Runs the same drivers as the daemon,
against whatever buses it is given, and reports one result per part so a wiring fault
names its place."""

from __future__ import annotations

import contextlib
import errno
import logging
import time
from collections.abc import Awaitable, Callable
from dataclasses import dataclass

from coffeebot.clock import Clock, blocking_sleep
from coffeebot.config import RobotConfig
from coffeebot.errors import HardwareError
from coffeebot.hardware.dwm1001 import Dwm1001, parse_lec
from coffeebot.hardware.i2c import I2CBus
from coffeebot.hardware.motor import MotorController
from coffeebot.hardware.serial_port import SerialPort, open_port
from coffeebot.hardware.tca9548a import TCA9548A
from coffeebot.hardware.vl53l1x import MODEL_ID, VL53L1X, DistanceMode
from coffeebot.hardware.worker import DeviceWorker
from coffeebot.messages import NOTHING_IN_RANGE, ReadingStatus

log = logging.getLogger(__name__)

PORT_TIMEOUT_S = 0.2
TOF_SAMPLES = 5
WORKING = frozenset({ReadingStatus.VALID, *NOTHING_IN_RANGE})
"""A distance, or nothing it can range (an open door, a long hallway): the sensor works."""


@dataclass(frozen=True)
class CheckResult:
    component: str
    where: str
    ok: bool
    detail: str
    warning: bool = False
    """Works, but not as the robot description needs (a slow bus): said, not a failure."""


Opener = Callable[[str, int, float], SerialPort]

I2C_HINT = (
    "check that I2C is enabled (raspi-config, Interface Options, I2C; or dtparam=i2c_arm=on "
    "in config.txt), that the device node {node} exists, and that this user may open it "
    "(its permissions; the i2c group)"
)
SERIAL_HINT = (
    "check the cable, that the device node {node} exists, and that this user may open it "
    "(its permissions; the dialout group)"
)
UART_HINT = (
    "; the Pi's own UART must be enabled with the serial console off (raspi-config, "
    "Interface Options, Serial Port)"
)
PI_UARTS = ("/dev/serial", "/dev/ttyAMA", "/dev/ttyS")


def cannot_open(exc: OSError, node: str, hint: str) -> str:
    """What a builder reads when a device node cannot be opened: the error, then what to do."""
    what = {
        errno.ENOENT: f"{node} does not exist",
        errno.EACCES: f"no permission to open {node}",
        errno.EPERM: f"no permission to open {node}",
        errno.EBUSY: f"{node} is in use by another program",
    }.get(exc.errno or 0, f"cannot open {node}: {exc.strerror or exc}")
    return f"{what}; {hint.format(node=node)}"


def i2c_node(config: RobotConfig) -> str:
    return f"/dev/i2c-{config.i2c.bus}"


def skipped_tof(config: RobotConfig, why: str) -> list[CheckResult]:
    """One FAIL row per part behind a bus that could not be opened: none of them was seen."""
    where = f"i2c-{config.i2c.bus} 0x{config.i2c.mux_address:02X}"
    return [
        CheckResult("TCA9548A mux", where, False, f"not probed: {why}"),
        *(
            CheckResult(f"VL53L1X tof{s.id}", f"channel {s.channel}", False, f"not probed: {why}")
            for s in sorted(config.tof.sensors, key=lambda s: s.id)
        ),
    ]


def check_tof(
    bus: I2CBus, config: RobotConfig, sleep: Callable[[float], None] = time.sleep
) -> list[CheckResult]:
    mux = TCA9548A(bus, config.i2c.mux_address)
    where = f"i2c-{config.i2c.bus} 0x{config.i2c.mux_address:02X}"
    try:
        mux.deselect()
    except OSError as exc:
        return [CheckResult("TCA9548A mux", where, False, str(exc))]
    results = [CheckResult("TCA9548A mux", where, True, "control register reads back")]
    for cfg in sorted(config.tof.sensors, key=lambda s: s.id):
        sensor = VL53L1X(bus, config.i2c.sensor_address, name=f"tof{cfg.id}", sleep=sleep)
        try:
            mux.select(cfg.channel)
            sensor.init()
            sensor.configure(
                DistanceMode[config.tof.distance_mode.upper()],
                config.tof.timing_budget_ms,
                config.tof.timing_budget_ms,
            )
            sensor.start_ranging()
            # The first range after a start is never trusted; after it, one usable sample
            # among a few is a working sensor (a far target is sometimes a sigma failure).
            for attempt in range(1 + TOF_SAMPLES):
                sensor.wait_data_ready()
                m = sensor.read_measurement()
                sensor.clear_interrupt()
                if attempt and m.status in WORKING:
                    break
            sensor.stop_ranging()
            mux.deselect()
        except OSError as exc:
            results.append(
                CheckResult(f"VL53L1X tof{cfg.id}", f"channel {cfg.channel}", False, str(exc))
            )
            continue
        ok = m.status in WORKING
        detail = (
            f"model 0x{MODEL_ID:04X}, {m.distance_mm} mm ({m.status.value}, raw {m.raw_status})"
        )
        results.append(CheckResult(f"VL53L1X tof{cfg.id}", f"channel {cfg.channel}", ok, detail))
    return results


def check_uwb(config: RobotConfig, opener: Opener) -> CheckResult:
    url = config.uwb.port
    try:
        with contextlib.closing(opener(url, config.uwb.baudrate, PORT_TIMEOUT_S)) as port:
            tag = Dwm1001(port)
            tag.start()
            try:
                for _ in range(50):
                    line = tag.readline()
                    with contextlib.suppress(ValueError):
                        report = parse_lec(line) if line is not None else None
                        if report is not None:
                            fix = report.fix
                            return CheckResult(
                                "DWM1001 UWB tag",
                                url,
                                True,
                                f"shell ok, {len(report.anchors)} anchors, "
                                + (
                                    f"fix {fix.x_mm:.0f},{fix.y_mm:.0f} mm qf {fix.quality}"
                                    if fix
                                    else "no position yet"
                                ),
                            )
            finally:
                tag.stop()
    except OSError as exc:
        return CheckResult("DWM1001 UWB tag", url, False, _port_error(exc, url))
    return CheckResult("DWM1001 UWB tag", url, False, "shell ok but no lec line parsed")


def check_motor(config: RobotConfig, opener: Opener) -> CheckResult:
    url = config.motor.port
    try:
        with contextlib.closing(opener(url, config.motor.baudrate, PORT_TIMEOUT_S)) as port:
            ident = MotorController(port).identify()
    except (OSError, TimeoutError) as exc:
        return CheckResult("motor controller", url, False, _port_error(exc, url))
    ok = ident.watchdog_ms == config.motor.watchdog_ms
    return CheckResult(
        "motor controller",
        url,
        ok,
        f"firmware {ident.firmware}, watchdog {ident.watchdog_ms} ms"
        + ("" if ok else f" (config says {config.motor.watchdog_ms} ms)"),
    )


def _port_error(exc: OSError, url: str) -> str:
    """A port that would not open says what to check; one that opened and then failed (a
    timeout, a broken line) keeps the driver's own words."""
    if isinstance(exc, TimeoutError) or exc.errno is None or "://" in url:
        return str(exc)
    hint = SERIAL_HINT + (UART_HINT if url.startswith(PI_UARTS) else "")
    return cannot_open(exc, url, hint)


def check_bus_speed(config: RobotConfig, kernel_hz: int | None) -> list[CheckResult]:
    """The kernel's clock for the I2C bus against the robot description's, where known."""
    if kernel_hz is None:
        return []
    where, needed = f"i2c-{config.i2c.bus}", config.i2c.frequency_hz
    if kernel_hz >= needed:
        return [CheckResult("I2C bus", where, True, f"{kernel_hz / 1000:g} kHz")]
    return [
        CheckResult(
            "I2C bus",
            where,
            True,
            f"{kernel_hz / 1000:g} kHz, below the {needed / 1000:g} kHz the robot description "
            "needs: the sensors' scans will be slower than configured",
            warning=True,
        )
    ]


def run_checks(
    config: RobotConfig,
    open_bus: Callable[[], I2CBus],
    opener: Opener = open_port,
    kernel_hz: int | None = None,
    sleep: Callable[[float], None] = time.sleep,
) -> list[CheckResult]:
    """Every probe once; ``kernel_hz``: the bus clock the kernel reports (None: unknown);
    ``sleep`` paces the sensors' polls. A bus that cannot be opened is a FAIL row for each
    part behind it, saying what to check; the serial devices are probed all the same."""
    try:
        bus = open_bus()
    except OSError as exc:
        why = cannot_open(exc, i2c_node(config), I2C_HINT)
        tof = [CheckResult("I2C bus", f"i2c-{config.i2c.bus}", False, why)]
        tof += skipped_tof(config, f"{i2c_node(config)} could not be opened")
    else:
        try:
            tof = [*check_bus_speed(config, kernel_hz), *check_tof(bus, config, sleep)]
        finally:
            bus.close()
    return [*tof, check_uwb(config, opener), check_motor(config, opener)]


class SelfCheckFailed(HardwareError):
    """A part failed the check the daemon runs before the robot may move."""


def service_check(
    config: RobotConfig,
    open_bus: Callable[[], I2CBus],
    kernel_hz: Callable[[], int | None] | None = None,
    opener: Opener = open_port,
    clock: Clock | None = None,
) -> Callable[[], Awaitable[str]]:
    """The daemon's start-up self-check (``run_as_service(self_check=...)``): every probe once,
    in a thread; raises naming the failed parts, or the device that cannot be opened, and
    logs a warning for each part that works but not as the robot description needs.
    ``clock``: the daemon's (the probes wait in its time)."""
    sleep = time.sleep if clock is None else blocking_sleep(clock)

    def probe() -> str:
        results = run_checks(
            config,
            open_bus,
            opener,
            kernel_hz=None if kernel_hz is None else kernel_hz(),
            sleep=sleep,
        )
        failed = [f"{r.component} ({r.where}): {r.detail}" for r in results if not r.ok]
        if failed:
            raise SelfCheckFailed("; ".join(failed))
        for r in results:
            if r.warning:
                log.warning("self-check: %s (%s): %s", r.component, r.where, r.detail)
        return f"self-check: {len(results)} parts ok"

    async def check() -> str:
        worker = DeviceWorker("self-check", clock)
        try:
            return await worker.call(probe)
        finally:
            worker.close()

    return check
