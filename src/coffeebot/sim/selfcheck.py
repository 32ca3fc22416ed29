"""The simulated robot ``coffeebot check-hardware --sim`` probes: the simulated I2C bus, UWB
tag and motor controller wired as a robot description says, with one named fault injected
(``--fault`` or ``COFFEEBOT_SIM_FAULT``) so a failing check can be seen to name its part."""

from __future__ import annotations

import contextlib
from collections.abc import Iterator

from coffeebot.config import RobotConfig
from coffeebot.hardware.i2c import I2CBus
from coffeebot.sim.dwm1001 import SimDwm1001
from coffeebot.sim.i2c import make_tof_hardware, targets_at
from coffeebot.sim.motor_controller import SimMotorController

FAULT_ENV = "COFFEEBOT_SIM_FAULT"
FAULTS = ("mux-nack", "tof<N>-nack", "tof<N>-status", "i2c-timeout", "uwb-unplug", "motor-unplug")


@contextlib.contextmanager
def simulated_robot(config: RobotConfig, fault: str | None) -> Iterator[tuple[RobotConfig, I2CBus]]:
    """The simulated buses wired as ``config`` says, with one named fault injected; yields
    ``config`` with the serial ports pointing at the simulated devices, and the I2C bus."""
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
