"""``coffeebot check-hardware``: probe every device once, the first thing to run on a newly
wired robot. Runs the same drivers as the daemon, against the real buses or the simulated
ones, and reports one row per part so a wiring fault names its place."""

from __future__ import annotations

import asyncio
import contextlib
import json
import os
import time
from collections.abc import Awaitable, Callable, Iterator
from dataclasses import asdict, dataclass

from coffeebot.config import RobotConfig
from coffeebot.hardware.dwm1001 import Dwm1001, parse_lec
from coffeebot.hardware.i2c import I2CBus, open_i2c_bus
from coffeebot.hardware.motor import MotorController
from coffeebot.hardware.serial_port import SerialPort, open_port
from coffeebot.hardware.tca9548a import TCA9548A
from coffeebot.hardware.vl53l1x import MODEL_ID, VL53L1X, DistanceMode
from coffeebot.messages import NOTHING_IN_RANGE, ReadingStatus

PORT_TIMEOUT_S = 0.2
TOF_SAMPLES = 5
WORKING = frozenset({ReadingStatus.VALID, *NOTHING_IN_RANGE})
"""A distance, or nothing it can range (an open door, a long hallway): the sensor works."""
FAULT_ENV = "COFFEEBOT_SIM_FAULT"
FAULTS = ("mux-nack", "tof<N>-nack", "tof<N>-status", "i2c-timeout", "uwb-unplug", "motor-unplug")


@dataclass(frozen=True)
class CheckResult:
    component: str
    where: str
    ok: bool
    detail: str


Opener = Callable[[str, int, float], SerialPort]


def check_tof(bus: I2CBus, config: RobotConfig) -> list[CheckResult]:
    mux = TCA9548A(bus, config.i2c.mux_address)
    where = f"i2c-{config.i2c.bus} 0x{config.i2c.mux_address:02X}"
    try:
        mux.deselect()
    except OSError as exc:
        return [CheckResult("TCA9548A mux", where, False, str(exc))]
    results = [CheckResult("TCA9548A mux", where, True, "control register reads back")]
    for cfg in sorted(config.tof.sensors, key=lambda s: s.id):
        sensor = VL53L1X(bus, config.i2c.sensor_address, name=f"tof{cfg.id}")
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
        return CheckResult("DWM1001 UWB tag", url, False, str(exc))
    return CheckResult("DWM1001 UWB tag", url, False, "shell ok but no lec line parsed")


def check_motor(config: RobotConfig, opener: Opener) -> CheckResult:
    url = config.motor.port
    try:
        with contextlib.closing(opener(url, config.motor.baudrate, PORT_TIMEOUT_S)) as port:
            ident = MotorController(port).identify()
    except (OSError, TimeoutError) as exc:
        return CheckResult("motor controller", url, False, str(exc))
    ok = ident.watchdog_ms == config.motor.watchdog_ms
    return CheckResult(
        "motor controller",
        url,
        ok,
        f"firmware {ident.firmware}, watchdog {ident.watchdog_ms} ms"
        + ("" if ok else f" (config says {config.motor.watchdog_ms} ms)"),
    )


def run_checks(config: RobotConfig, bus: I2CBus, opener: Opener = open_port) -> list[CheckResult]:
    return [*check_tof(bus, config), check_uwb(config, opener), check_motor(config, opener)]


class SelfCheckFailed(Exception):
    """A part failed the check the daemon runs before the robot may move."""


def service_check(
    config: RobotConfig, open_bus: Callable[[], I2CBus]
) -> Callable[[], Awaitable[str]]:
    """The daemon's start-up self-check (``run_as_service(self_check=...)``): every probe once,
    in a thread; raises naming the failed parts, or the device that cannot be opened."""

    def probe() -> str:
        try:
            bus = open_bus()
        except OSError as exc:
            raise SelfCheckFailed(f"cannot open the I2C bus: {exc}") from exc
        try:
            results = run_checks(config, bus)
        finally:
            bus.close()
        failed = [f"{r.component} ({r.where}): {r.detail}" for r in results if not r.ok]
        if failed:
            raise SelfCheckFailed("; ".join(failed))
        return f"self-check: {len(results)} parts ok"

    async def check() -> str:
        return await asyncio.to_thread(probe)

    return check


@contextlib.contextmanager
def simulated_robot(config: RobotConfig, fault: str | None) -> Iterator[tuple[RobotConfig, I2CBus]]:
    """The simulated buses wired as ``config`` says, with one named fault injected."""
    from coffeebot.sim.dwm1001 import SimDwm1001
    from coffeebot.sim.i2c import make_tof_hardware, targets_at
    from coffeebot.sim.motor_controller import SimMotorController

    hw = make_tof_hardware(
        targets_at(lambda ch: 800.0 + 10 * ch),
        [s.channel for s in config.tof.sensors],
        mux_address=config.i2c.mux_address,
    )
    with SimDwm1001(lambda: (2000.0, 850.0, 0.0)) as dwm, SimMotorController() as motor:
        sensor_by_id = {s.id: hw.sensors[s.channel] for s in config.tof.sensors}
        match (fault or "").split("-"):
            case [""]:
                pass
            case ["mux", "nack"]:
                hw.mux.nack = True
            case ["i2c", "timeout"]:
                hw.bus.timeout = True
            case [tof, kind] if (
                tof.startswith("tof") and tof[3:].isdigit() and kind in ("nack", "status")
            ):
                sim = sensor_by_id[int(tof[3:])]
                if kind == "nack":
                    sim.nack = True
                else:
                    sim.forced_status = 3  # a hardware (VCSEL) failure on every ranging
            case ["uwb", "unplug"]:
                dwm.unplug()
            case ["motor", "unplug"]:
                motor.unplug()
            case _:
                raise ValueError(f"unknown fault {fault!r}; choose one of {', '.join(FAULTS)}")
        sim_config = config.model_copy(
            update={
                "uwb": config.uwb.model_copy(update={"port": dwm.port}),
                "motor": config.motor.model_copy(update={"port": motor.port}),
            }
        )
        yield sim_config, hw.bus


def format_table(results: list[CheckResult]) -> str:
    rows = [("component", "channel/port", "result", "detail")] + [
        (r.component, r.where, "ok" if r.ok else "FAIL", r.detail) for r in results
    ]
    widths = [max(len(row[i]) for row in rows) for i in range(3)]
    return "\n".join(
        "  ".join(cell.ljust(w) for cell, w in zip(row[:3], widths, strict=True)) + "  " + row[3]
        for row in rows
    )


def main(config: RobotConfig, *, sim: bool, as_json: bool, fault: str | None = None) -> int:
    """Run every probe, print the table (or JSON); 0 only if every part passed."""
    started = time.monotonic()
    fault = fault or os.environ.get(FAULT_ENV)
    if sim:
        with simulated_robot(config, fault) as (sim_config, bus):
            results = run_checks(sim_config, bus)
    else:
        bus = open_i2c_bus(config.i2c.bus)
        try:
            results = run_checks(config, bus)
        finally:
            bus.close()
    ok = all(r.ok for r in results)
    if as_json:
        print(json.dumps({"ok": ok, "results": [asdict(r) for r in results]}, indent=2))
    else:
        print(format_table(results))
        print(f"\n{'all parts ok' if ok else 'FAILED'} ({time.monotonic() - started:.1f} s)")
    return 0 if ok else 1
