"""Faults a scenario injects into the simulated devices, each over a window of simulated time.

Each fault drives the fault hooks the simulated chips already have (a NACKing sensor, one
that stops ranging, an unplugged or babbling UWB tag, a hung, babbling or unplugged motor
controller, an elevator that does not answer) or the order database's
(:mod:`coffeebot.sim.store`: locked, read only, full), so the daemon meets them through its
real drivers and its real store, exactly as it would on the robot. A module crash raises an
exception inside one of the daemon's modules, where it is at that moment
(:meth:`Simulation.crash_module`), as a bug would.
"""

from __future__ import annotations

import random
from abc import abstractmethod
from dataclasses import dataclass
from typing import TYPE_CHECKING, Annotated, ClassVar, Literal

from pydantic import BaseModel, ConfigDict, Field, PrivateAttr, model_validator

if TYPE_CHECKING:
    from coffeebot.sim.simulation import Simulation
    from coffeebot.sim.store import SimStore
    from coffeebot.sim.uart import UartDevice

GARBAGE_PERIOD_S = 0.1


@dataclass
class FaultRecord:
    """A fault that was injected: when, what, and when it was cleared (None: never)."""

    t_s: float
    fault: str
    detail: str
    cleared_s: float | None = None


class _Fault(BaseModel):
    model_config = ConfigDict(extra="forbid", allow_inf_nan=False)

    kind: str
    from_s: float = Field(ge=0, description="simulated time the fault starts")
    to_s: float | None = Field(None, ge=0, description="when it ends; leave out for the whole run")

    @model_validator(mode="after")
    def _ordered(self) -> _Fault:
        if self.to_s is not None and self.to_s <= self.from_s:
            raise ValueError(f"to_s ({self.to_s}) must be after from_s ({self.from_s})")
        return self

    _record: FaultRecord | None = PrivateAttr(None)

    def update(self, sim: Simulation) -> FaultRecord | None:
        """Start or end the fault as simulated time passes; the record when it starts."""
        t = sim.t_s
        active = t >= self.from_s and (self.to_s is None or t < self.to_s)
        if active and self._record is None:
            self._record = FaultRecord(t, self.kind, self.describe())
            self.begin(sim)
            return self._record
        if active:
            self.during(sim)
        elif self._record is not None and self._record.cleared_s is None:
            self.end(sim)
            self._record.cleared_s = t
        return None

    @abstractmethod
    def describe(self) -> str: ...

    @abstractmethod
    def begin(self, sim: Simulation) -> None: ...

    def during(self, sim: Simulation) -> None:
        """Called on every world step while the fault lasts."""

    @abstractmethod
    def end(self, sim: Simulation) -> None: ...


class SensorNack(_Fault):
    """ToF sensor ``sensor`` stops acknowledging on the I2C bus."""

    kind: Literal["sensor_nack"]
    sensor: int = Field(ge=0, le=7, description="sensor id as in the board file")

    def describe(self) -> str:
        return f"tof{self.sensor} NACKs"

    def begin(self, sim: Simulation) -> None:
        sim.tof.sensors[sim.sensor_channel[self.sensor]].nack = True

    def end(self, sim: Simulation) -> None:
        sim.tof.sensors[sim.sensor_channel[self.sensor]].nack = False


class SensorStale(_Fault):
    """ToF sensor ``sensor`` stops ranging without a word (a brown-out): it still answers on
    the bus, but no new sample is ever ready. Until the fault ends, re-initialising it does
    not help; after, a re-initialisation brings it back (nothing else does)."""

    kind: Literal["sensor_stale"]
    sensor: int = Field(ge=0, le=7, description="sensor id as in the board file")

    def describe(self) -> str:
        return f"tof{self.sensor} stops ranging"

    def begin(self, sim: Simulation) -> None:
        self.during(sim)

    def during(self, sim: Simulation) -> None:
        sim.tof.sensors[sim.sensor_channel[self.sensor]].halt()

    def end(self, sim: Simulation) -> None:
        """Nothing to undo: the chip ranges again once it is re-initialised."""


class _LineNoise(_Fault):
    """Random bytes on a serial line between the device's own lines, a burst every
    ``GARBAGE_PERIOD_S``."""

    bytes_per_burst: int = Field(40, gt=0)
    seed: int = 0
    _rng: random.Random = PrivateAttr(default_factory=random.Random)
    _next: float = PrivateAttr(0.0)
    _line_name: ClassVar[str]

    @abstractmethod
    def _device(self, sim: Simulation) -> UartDevice:
        """The device whose line the noise is on."""

    def describe(self) -> str:
        return (
            f"{self._line_name} line noise, {self.bytes_per_burst} bytes every "
            f"{GARBAGE_PERIOD_S:g} s"
        )

    def begin(self, sim: Simulation) -> None:
        self._rng.seed(self.seed)
        self._next = sim.t_s
        self.during(sim)

    def during(self, sim: Simulation) -> None:
        if sim.t_s >= self._next:
            self._next += GARBAGE_PERIOD_S
            self._device(sim).inject(self._rng.randbytes(self.bytes_per_burst))

    def end(self, sim: Simulation) -> None:
        """Nothing to undo: the noise simply stops."""


class UwbGarbage(_LineNoise):
    """The UWB line carries random bytes between the tag's lines."""

    kind: Literal["uwb_garbage"]
    _line_name: ClassVar[str] = "UWB"

    def _device(self, sim: Simulation) -> UartDevice:
        return sim.uwb


class UwbUnplug(_Fault):
    """The UWB tag's USB cable is pulled (and pushed back at ``to_s``)."""

    kind: Literal["uwb_unplug"]

    def describe(self) -> str:
        return "UWB tag unplugged"

    def begin(self, sim: Simulation) -> None:
        sim.uwb.unplug()

    def end(self, sim: Simulation) -> None:
        sim.uwb.replug()


class MotorSilent(_Fault):
    """The motor controller's firmware hangs: no telemetry, commands ignored."""

    kind: Literal["motor_silent"]

    def describe(self) -> str:
        return "motor controller silent"

    def begin(self, sim: Simulation) -> None:
        sim.motor.silent = True

    def end(self, sim: Simulation) -> None:
        sim.motor.silent = False


class MotorGarbage(_LineNoise):
    """The motor controller's line carries random bytes between its telemetry lines."""

    kind: Literal["motor_garbage"]
    _line_name: ClassVar[str] = "motor"

    def _device(self, sim: Simulation) -> UartDevice:
        return sim.motor


class MotorUnplug(_Fault):
    """The motor controller's USB cable is pulled (and pushed back at ``to_s``, when the
    controller boots afresh)."""

    kind: Literal["motor_unplug"]

    def describe(self) -> str:
        return "motor controller unplugged"

    def begin(self, sim: Simulation) -> None:
        sim.motor.unplug()

    def end(self, sim: Simulation) -> None:
        sim.motor.replug()


class ElevatorSilent(_Fault):
    """The elevator interface ignores every request (its controller is down)."""

    kind: Literal["elevator_silent"]

    def describe(self) -> str:
        return "elevator does not answer"

    def begin(self, sim: Simulation) -> None:
        for elevator in sim.world.elevators:
            elevator.answering = False

    def end(self, sim: Simulation) -> None:
        for elevator in sim.world.elevators:
            elevator.answering = True


def _store(sim: Simulation) -> SimStore:
    if sim.store is None:
        raise RuntimeError("a store fault needs a simulation with an order store")
    return sim.store


class StoreLocked(_Fault):
    """Another process holds the order database's write lock (a backup, a shell left open)."""

    kind: Literal["store_locked"]
    _held: bool = PrivateAttr(False)

    def describe(self) -> str:
        return "order database locked by another process"

    def begin(self, sim: Simulation) -> None:
        self._held = _store(sim).lock()

    def during(self, sim: Simulation) -> None:
        if not self._held:  # the store was writing at the first attempt
            self._held = _store(sim).lock()

    def end(self, sim: Simulation) -> None:
        _store(sim).unlock()
        self._held = False


class StoreReadOnly(_Fault):
    """The file system holding the order database turned read only."""

    kind: Literal["store_read_only"]

    def describe(self) -> str:
        return "order database read only"

    def begin(self, sim: Simulation) -> None:
        _store(sim).set_read_only(True)

    def end(self, sim: Simulation) -> None:
        _store(sim).set_read_only(False)


class StoreFull(_Fault):
    """The disk holding the order database is full."""

    kind: Literal["store_full"]

    def describe(self) -> str:
        return "order database disk full"

    def begin(self, sim: Simulation) -> None:
        _store(sim).full = True

    def end(self, sim: Simulation) -> None:
        _store(sim).full = False


class ModuleCrash(_Fault):
    """Module ``module`` raises an exception wherever it is (a bug): the supervisor's turn.
    Once, at ``from_s``; ``to_s`` only bounds the record."""

    kind: Literal["module_crash"]
    module: str = Field(min_length=1, description="a module's name, as on the health topic")

    def describe(self) -> str:
        return f"module {self.module} crashes"

    def begin(self, sim: Simulation) -> None:
        sim.crash_module(self.module, f"simulated crash at {sim.t_s:.3f} s")

    def end(self, sim: Simulation) -> None:
        """Nothing to undo: the supervisor restarts the module."""


Fault = Annotated[
    SensorNack
    | SensorStale
    | UwbGarbage
    | UwbUnplug
    | MotorSilent
    | MotorGarbage
    | MotorUnplug
    | ElevatorSilent
    | ModuleCrash
    | StoreLocked
    | StoreReadOnly
    | StoreFull,
    Field(discriminator="kind"),
]
