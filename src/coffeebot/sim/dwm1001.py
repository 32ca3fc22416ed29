"""A simulated DWM1001 tag on a serial line, speaking the PANS UART shell.

Modelled: TLV mode after boot (text is answered with ``@\\x01\\x01``), double Enter into the
shell, echo and ``dwm> `` prompt, the ``lec``/``lep`` toggles, ``reset`` (reboot into TLV
mode, silent while booting), ``quit``, ``ut``. Streams at ``rate_hz`` from ``truth_fn`` with
Gaussian noise, or from ``fix_fn`` (the simulated world's own UWB model); ``POS`` is left out
when fewer than three anchors are in range.

Faults: :meth:`inject` (garbage, partial lines), :meth:`reset`, :meth:`unplug` /
:meth:`replug`, and ``drop_pos`` to stream lines without a position.
"""

from __future__ import annotations

import math
import random
import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass

from coffeebot.hardware.dwm1001 import PROMPT, TLV_UNKNOWN_COMMAND
from coffeebot.messages import AnchorRange, UwbFix
from coffeebot.sim.uart import Line, UartDevice

TruthFn = Callable[[], tuple[float, float, float]]
"""The tag's true position (x, y, z) in mm."""

FixFn = Callable[[], UwbFix | None]
"""A complete measurement (anchor ranges and position), or None with too few anchors."""


@dataclass(frozen=True)
class SimAnchor:
    anchor_id: str  # 4 hex digits, the anchor's short UWB address
    x_mm: float
    y_mm: float
    z_mm: float


DEFAULT_ANCHORS = (
    SimAnchor("022E", 0.0, 0.0, 2500.0),
    SimAnchor("9280", 20000.0, 0.0, 2500.0),
    SimAnchor("DCAE", 20000.0, 1700.0, 2500.0),
    SimAnchor("5431", 0.0, 1700.0, 2500.0),
)
BANNER = b"\r\nDWM1001 TWR Real Time Location System (simulated)\r\n\r\n"


class SimDwm1001(UartDevice):
    def __init__(
        self,
        truth_fn: TruthFn | None = None,
        *,
        fix_fn: FixFn | None = None,
        anchors: Sequence[SimAnchor] = DEFAULT_ANCHORS,
        rate_hz: float = 10.0,
        noise_mm: float = 30.0,
        quality: int = 80,
        anchor_range_mm: float = 30000.0,
        boot_s: float = 0.05,
        seed: int = 0,
        clock: Callable[[], float] = time.monotonic,
        tick_s: float = 0.005,
        line: Line | None = None,
    ) -> None:
        if (truth_fn is None) == (fix_fn is None):
            raise ValueError("give exactly one of truth_fn and fix_fn")
        self.truth_fn = truth_fn
        self.fix_fn = fix_fn
        self.anchors = list(anchors)
        self.period_s = 1.0 / rate_hz
        self.noise_mm = noise_mm
        self.quality = quality
        self.anchor_range_mm = anchor_range_mm
        self.boot_s = boot_s
        self.drop_pos = False
        self.resets = 0
        self.commands: list[str] = []  # every shell command received, for tests
        self._rng = random.Random(seed)
        super().__init__("dwm1001", clock=clock, tick_s=tick_s, line=line)

    def on_plugged(self) -> None:
        with self._lock:
            self._shell = False
            self._stream: str | None = None
            self._booting_until = 0.0
            self._line = bytearray()
            self._last_enter = -math.inf
            self._next_report = 0.0

    def reset(self) -> None:
        """Reboot: back to TLV mode with no stream, deaf while booting."""
        with self._lock:
            self.on_plugged()
            self._booting_until = self.clock() + self.boot_s
            self.resets += 1

    def on_data(self, data: bytes) -> None:
        with self._lock:
            if self.clock() < self._booting_until:
                return
            if self._shell:
                self._shell_input(data)
            else:
                self._tlv_input(data)

    def _tlv_input(self, data: bytes) -> None:
        text = data.strip(b"\r")
        for byte in data:
            if byte != 0x0D:
                continue
            now = self.clock()
            if now - self._last_enter <= 1.0:
                self._shell = True
                self.send(BANNER + PROMPT)
                return
            self._last_enter = now
        if text:
            self.send(TLV_UNKNOWN_COMMAND)

    def _shell_input(self, data: bytes) -> None:
        for byte in data:
            if byte == 0x0D:
                command = self._line.decode("ascii", errors="replace").strip()
                self._line.clear()
                if command:
                    self.commands.append(command)
                self.send(b"\r\n")
                self._execute(command)
                if not self._shell:
                    return
            elif byte != 0x0A:
                self._line.append(byte)
                self.send(bytes([byte]))  # the shell echoes what is typed

    def _execute(self, command: str) -> None:
        if command in ("lec", "lep"):
            self._stream = None if self._stream == command else command
            self._next_report = self.clock()
        elif command == "reset":
            self.reset()
            return
        elif command == "quit":
            self._shell = False
            return
        elif command == "ut":
            ms = int(self.clock() * 1000)
            self.send(f"[{ms / 1000:010.3f} INF] uptime: {ms} ms\r\n".encode())
        self.send(PROMPT)

    def on_tick(self, now: float) -> None:
        with self._lock:
            if not self._shell or self._stream is None or now < self._next_report:
                return
            self._next_report = max(self._next_report + self.period_s, now)
            line = self.report()
            if line:
                self.send(line.encode("ascii") + b"\r\n")

    def report(self) -> str:
        """One stream line for the current truth."""
        ranges, pos, quality = self._measure()
        if self.drop_pos:
            pos = None
        if self._stream == "lep":
            return "" if pos is None else "POS," + _pos(pos, quality)
        fields = [f"DIST,{len(ranges)}"]
        for i, r in enumerate(ranges):
            fields.append(
                f"AN{i},{r.anchor_id},{_m(r.x_mm)},{_m(r.y_mm)},{_m(r.z_mm)},{_m(r.distance_mm)}"
            )
        if pos is not None:
            fields.append("POS," + _pos(pos, quality))
        return ",".join(fields)

    def _measure(self) -> tuple[list[AnchorRange], list[float] | None, int]:
        """Anchor ranges, position (None with fewer than three anchors) and quality factor."""
        if self.fix_fn is not None:
            fix = self.fix_fn()
            if fix is None:
                return [], None, 0
            return list(fix.anchors), [fix.x_mm, fix.y_mm, fix.z_mm], fix.quality
        assert self.truth_fn is not None
        x, y, z = self.truth_fn()
        ranges = []
        for a in self.anchors:
            d = math.dist((x, y, z), (a.x_mm, a.y_mm, a.z_mm))
            if d <= self.anchor_range_mm:
                ranges.append(
                    AnchorRange(
                        anchor_id=a.anchor_id,
                        x_mm=a.x_mm,
                        y_mm=a.y_mm,
                        z_mm=a.z_mm,
                        distance_mm=d + self._rng.gauss(0.0, self.noise_mm),
                    )
                )
        pos = None
        if len(ranges) >= 3:
            pos = [c + self._rng.gauss(0.0, self.noise_mm) for c in (x, y, z)]
        return ranges, pos, self.quality


def _m(mm: float) -> str:
    return f"{mm / 1000.0:.2f}"


def _pos(xyz: list[float], quality: int) -> str:
    return ",".join(_m(c) for c in xyz) + f",{quality}"
