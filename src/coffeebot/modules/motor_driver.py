"""Motor driver module: motor commands to the controller, telemetry back as odometry.

The current command is re-sent every ``keepalive_s`` to feed the controller's 200 ms
watchdog; a command older than ``command_timeout_s`` is replaced by a stop, so a silent
motion module stops the robot here as well as at the controller. On shutdown it sends a stop
before the daemon cancels anything, and logs whether it got out.

A controller that sends no telemetry for ``[motor] telemetry_timeout_s`` (hung firmware, a
broken wire) is reported ``failed`` on the health topic; motion holds the robot on the same
silence (it reads the telemetry's age), so navigation tells the order the true reason.

Logged once each, with the cause: a lost port (``disconnect``), a controller reset while
running or silent (``fault``) and the telemetry coming back (``reconnect``); a moving command
going stale (``safety_stop``) and commands resuming (``safety_clear``).
"""

from __future__ import annotations

import asyncio
import contextlib
import logging
from dataclasses import dataclass

from coffeebot.config import MotorConfig
from coffeebot.hardware.motor import Boot, MotorController, parse
from coffeebot.hardware.serial_port import SerialPort, open_port
from coffeebot.hardware.worker import DeviceWorker
from coffeebot.logs import Event, Transitions, log_event
from coffeebot.messages import (
    HEALTH,
    MOTOR_COMMAND,
    ODOMETRY,
    Health,
    HealthStatus,
    MotorCommand,
    Odometry,
)
from coffeebot.modules.base import ModuleContext
from coffeebot.modules.serial_device import LinkCounters, Opener, SerialDeviceModule

RESET, SILENT = "reset", "silent"
FRESH, STALE = "fresh", "stale"


COMMANDS = "motor commands"
"""The health component that reports the driver's own stops when commands stop coming."""


@dataclass
class MotorCounters(LinkCounters):
    telemetry: int = 0
    garbage: int = 0
    controller_boots: int = 0
    commands: int = 0
    stale_stops: int = 0
    silences: int = 0


class MotorDriver(SerialDeviceModule[MotorCounters]):
    name = "motor"
    device = "motor controller"
    inputs = (MOTOR_COMMAND,)
    outputs = (ODOMETRY, HEALTH)
    shutdown_order = 0  # first: the motors stop before anything else goes down
    critical = True

    def __init__(
        self,
        motor: MotorConfig,
        *,
        keepalive_s: float = 0.05,
        command_timeout_s: float = 0.25,
        read_timeout_s: float = 0.05,
        backoff_s: tuple[float, float] = (0.25, 4.0),
        opener: Opener = open_port,
    ) -> None:
        if keepalive_s * 2 > motor.watchdog_ms / 1000.0:
            raise ValueError("keepalive must be at most half the controller watchdog")
        super().__init__(
            motor,
            MotorCounters(),
            read_timeout_s=read_timeout_s,
            backoff_s=backoff_s,
            opener=opener,
        )
        self.keepalive_s = keepalive_s
        self.command_timeout_s = command_timeout_s
        self.telemetry_timeout_s = motor.telemetry_timeout_s
        self.watchdog_ms = motor.watchdog_ms
        self._log = logging.getLogger(f"coffeebot.module.{self.name}")
        """The daemon's logger for this module (``shutdown`` runs without a context)."""
        self._controller: MotorController | None = None
        self._writer: DeviceWorker | None = None
        self._commands: Transitions | None = None
        self._stopping = False

    async def run(self, ctx: ModuleContext) -> None:
        """The connection loop, with a second thread for commands: pyserial allows one reader
        and one writer at once, so commands keep flowing while a read waits."""
        self._writer = DeviceWorker("motor-tx", ctx.clock)
        self._commands = Transitions(ctx.log, initial={MOTOR_COMMAND.name: FRESH})
        try:
            await super().run(ctx)
        finally:
            self._writer.close()

    async def talk(self, ctx: ModuleContext, port: SerialPort, io: DeviceWorker) -> str:
        """Run the telemetry and command loops until either fails; re-raise its error."""
        assert self._writer is not None and self._commands is not None, "only called from run()"
        ctrl = MotorController(port)
        self._controller = ctrl
        tasks = [
            asyncio.create_task(self._read_loop(ctx, io, ctrl)),
            asyncio.create_task(self._write_loop(ctx, self._writer, ctrl, self._commands)),
        ]
        try:
            done, _ = await asyncio.wait(tasks, return_when=asyncio.FIRST_EXCEPTION)
        finally:
            self._controller = None
            for task in tasks:
                task.cancel()
            for task in tasks:
                with contextlib.suppress(asyncio.CancelledError):
                    await task
        for task in done:
            task.result()
        return "telemetry and commands ended"

    async def _read_loop(
        self, ctx: ModuleContext, reader: DeviceWorker, ctrl: MotorController
    ) -> None:
        healthy = False
        heard = ctx.clock.now()  # the port just opened: the first telemetry is due
        silent_since: float | None = None
        timeout_s = self.telemetry_timeout_s
        while True:
            line = await reader.call(ctrl.readline)
            now = ctx.clock.now()
            if silent_since is None and now - heard > timeout_s:
                silent_since, healthy = heard, False
                self.counters.silences += 1
                cause = f"no telemetry from the motor controller for {timeout_s:g} s"
                self.link(SILENT, Event.FAULT, cause)
                self.health(ctx, HealthStatus.FAILED, f"{cause}; motion holds the robot")
            if line is None:
                continue
            try:
                event = parse(line)
            except ValueError:
                self.counters.garbage += 1
                continue
            if isinstance(event, Odometry):
                self.counters.telemetry += 1
                heard = now
                ctx.board.publish(ODOMETRY, event)
                if not healthy:
                    healthy = True
                    cause = "telemetry resumed"
                    if silent_since is not None:
                        cause += f" after {now - silent_since:.1f} s of silence"
                    silent_since = None
                    self.connected(ctx, cause, f"telemetry on {self.port}")
            elif isinstance(event, Boot):
                # Counters restarted at zero: consumers must not difference across this.
                self.counters.controller_boots += 1
                if healthy:  # a boot line right after opening the port is the normal start
                    self.link(
                        RESET,
                        Event.FAULT,
                        f"motor controller reset while running (firmware {event.firmware})",
                    )
                self.health(ctx, HealthStatus.DEGRADED, f"controller booted ({event.firmware})")
                healthy = False

    async def _write_loop(
        self,
        ctx: ModuleContext,
        writer: DeviceWorker,
        ctrl: MotorController,
        commands: Transitions,
    ) -> None:
        while True:
            with contextlib.suppress(TimeoutError):
                await ctx.board.next(MOTOR_COMMAND, timeout=self.keepalive_s)
            latest = ctx.board.latest(MOTOR_COMMAND)
            age = ctx.board.age(MOTOR_COMMAND)
            fresh = latest is not None and age is not None and age <= self.command_timeout_s
            if fresh and latest is not None and not self._stopping:
                if commands.update(
                    MOTOR_COMMAND.name, FRESH, Event.SAFETY_CLEAR, "motor commands resumed"
                ):
                    self._commands_health(ctx, HealthStatus.RUNNING, "motor commands resumed")
                if latest.msg.brake:
                    await writer.call(ctrl.stop)
                else:
                    await writer.call(ctrl.set_speeds, latest.msg.left_mm_s, latest.msg.right_mm_s)
                self.counters.commands += 1
            else:
                if latest is not None and not self._stopping:
                    self.counters.stale_stops += 1
                if latest is not None and not self._stopping and _moving(latest.msg):
                    # A stop that was not renewed is an idle robot, not a safety stop.
                    why = f"no motor command for {self.command_timeout_s:g} s: motors stopped"
                    if commands.update(MOTOR_COMMAND.name, STALE, Event.SAFETY_STOP, why):
                        self._commands_health(ctx, HealthStatus.DEGRADED, why)
                await writer.call(ctrl.stop)

    def _commands_health(self, ctx: ModuleContext, status: HealthStatus, detail: str) -> None:
        """The driver's own stop for want of commands, on the health topic as a component
        (operators and run reports see it beside the collision module's stops)."""
        ctx.board.publish(
            HEALTH,
            Health(module=self.name, component=COMMANDS, status=status, detail=detail),
        )

    async def shutdown(self) -> None:
        """Send a stop now and only stops from here on, and say whether it got out; the
        controller's watchdog is the fallback if it did not."""
        self._stopping = True
        ctrl, writer = self._controller, self._writer
        fallback = f"the controller's {self.watchdog_ms} ms watchdog stops the motors"
        if ctrl is None or writer is None:
            self._log.warning("shutdown: no motor controller connected to stop; %s", fallback)
            return
        try:
            await writer.call(ctrl.stop)
        except OSError as exc:
            log_event(
                self._log, Event.FAULT, f"shutdown: the motor stop failed ({exc}); {fallback}"
            )
            return
        log_event(self._log, Event.SAFETY_STOP, "shutdown: motors stopped", port=self.port)


def _moving(command: MotorCommand) -> bool:
    return command.left_mm_s != 0 or command.right_mm_s != 0
