"""DWM1001 UWB tag (PANS firmware) in UART shell mode, streaming ``lec`` lines.

Why the shell's ``lec`` stream and not the binary TLV API:

* Framing. TLV frames are delimited by inter-byte gaps (~763 us), which a Linux process
  behind a USB CDC adapter cannot guarantee, and a binary stream has no sync marker: after a
  dropped byte every later frame is misread. ``lec`` lines end in CR LF, so after garbage or
  a partial line the reader is back in sync at the next line end, and a bad line is simply
  skipped and counted.
* Content. One ``lec`` line carries the position with its quality factor *and* every
  anchor's id, position and range; with TLV that is a ``dwm_loc_get`` poll per fix.
* Push, not poll. The tag streams at its update rate (10 Hz) without a request per fix.
* Debuggable: a builder can watch the same stream in any terminal.

The cost is resolution (metres with two decimals, 10 mm steps, against the tag's ~100 mm
accuracy that is no loss) and a larger line than the TLV frame.

``lec`` is a toggle, and a stream started before we opened the port survives re-entering
the shell, so :meth:`Dwm1001.start` does not guess the tag's state: it resets the tag
(back to TLV mode, no stream), enters the shell and toggles ``lec`` on exactly once.
"""

from __future__ import annotations

import re
from dataclasses import dataclass

from coffeebot.hardware.errors import DeviceError
from coffeebot.hardware.serial_port import LineReader, SerialPort
from coffeebot.messages import AnchorRange, UwbFix

PROMPT = b"dwm> "
ENTER_SHELL = b"\r\r"  # two Enters within one second leave TLV mode
TLV_UNKNOWN_COMMAND = b"\x40\x01\x01"  # what TLV mode answers to text

ANCHOR_RANGE_MM = 25_000.0
"""How far an anchor is taken to reach the tag along a hallway (line of sight): the simulator
ranges anchors up to this, and a floor plan's check counts anchors within it."""


@dataclass(frozen=True, slots=True)
class LecReport:
    """One parsed ``lec`` line: anchor ranges always, a fix only when the tag computed one."""

    anchors: list[AnchorRange]
    fix: UwbFix | None


METRES = re.compile(r"(-?)(\d+)(?:\.(\d{1,3}))?")
"""How the shell prints a coordinate or a range: metres with (at most millimetre) decimals."""


def _millimetres(field: str) -> int:
    """The decimal text of metres as exact integer millimetres: "4.02" is 4020, where
    ``float("4.02") * 1000`` is 4019.9999999999995."""
    match = METRES.fullmatch(field.strip())
    if match is None:
        raise ValueError(f"not a distance in metres: {field!r}")
    sign, whole, decimals = match.groups()
    mm = int(whole) * 1000 + int((decimals or "").ljust(3, "0"))
    return -mm if sign else mm


def _position(fields: list[str]) -> tuple[int, int, int, int]:
    """``x,y,z,qf`` in metres and percent."""
    if len(fields) != 4:
        raise ValueError(f"POS needs x,y,z,qf, got {len(fields)} fields")
    qf = int(fields[3])
    if not 0 <= qf <= 100:
        raise ValueError(f"quality factor {qf} outside 0..100")
    return _millimetres(fields[0]), _millimetres(fields[1]), _millimetres(fields[2]), qf


def parse_lec(line: str) -> LecReport:
    """Parse ``DIST,<n>,AN0,<id>,<x>,<y>,<z>,<d>,...[,POS,<x>,<y>,<z>,<qf>]`` or a bare
    ``POS,...`` line. Anything else, including a truncated or run-together line, raises
    ``ValueError``: a wrong field count is never guessed around."""
    fields = line.strip().split(",")
    if fields[0] == "POS":
        x, y, z, qf = _position(fields[1:])
        return LecReport([], UwbFix(x_mm=x, y_mm=y, z_mm=z, quality=qf))
    if fields[0] != "DIST" or len(fields) < 2:
        raise ValueError(f"not a lec line: {line[:40]!r}")
    count = int(fields[1])
    anchors_end = 2 + 6 * count
    if count < 0 or len(fields) < anchors_end:
        raise ValueError(f"DIST,{count} with only {len(fields)} fields")
    anchors = []
    for i in range(count):
        tag, anchor_id, ax, ay, az, ad = fields[2 + 6 * i : 8 + 6 * i]
        if tag != f"AN{i}" or len(anchor_id) != 4:
            raise ValueError(f"anchor block {i} malformed: {tag},{anchor_id}")
        int(anchor_id, 16)
        anchors.append(
            AnchorRange(
                anchor_id=anchor_id,
                x_mm=_millimetres(ax),
                y_mm=_millimetres(ay),
                z_mm=_millimetres(az),
                distance_mm=_millimetres(ad),
            )
        )
    rest = fields[anchors_end:]
    if not rest:
        return LecReport(anchors, None)  # no POS: the location engine had no fix
    if rest[0] != "POS":
        raise ValueError(f"expected POS after {count} anchors, got {rest[0][:10]!r}")
    x, y, z, qf = _position(rest[1:])
    return LecReport(anchors, UwbFix(x_mm=x, y_mm=y, z_mm=z, quality=qf, anchors=anchors))


class Dwm1001:
    """The tag on an open port (blocking calls; run them in the port's worker thread)."""

    def __init__(self, port: SerialPort, *, shell_attempts: int = 20) -> None:
        self.port = port
        self.lines = LineReader(port)
        self.shell_attempts = shell_attempts

    def enter_shell(self) -> None:
        """Send double Enter until the prompt shows; a tag still booting misses the first
        ones, so keep trying for ``shell_attempts`` read timeouts."""
        for _ in range(self.shell_attempts):
            self.port.write(ENTER_SHELL)
            if self.lines.read_until(PROMPT) is not None:
                return
        raise DeviceError(f"DWM1001: no shell prompt after {self.shell_attempts} attempts")

    def command(self, cmd: str) -> None:
        """Run a shell command whose output we read as lines afterwards."""
        self.port.write(cmd.encode("ascii") + b"\r")

    def start(self) -> None:
        """Reset the tag into a known state, then start exactly one ``lec`` stream."""
        self.lines.clear()
        self.enter_shell()
        self.command("reset")
        self.drain()  # extra prompts from the double Enter must not pass for the new shell
        self.enter_shell()
        self.command("lec")
        self.lines.readline()  # the command's echo

    def drain(self) -> None:
        """Discard input until the line stays quiet for one read timeout."""
        self.lines.clear()
        while self.port.read(max(1, self.port.in_waiting)):
            pass

    def stop(self) -> None:
        """Leave the tag without a stream running (``lec`` is a toggle, so reset)."""
        self.command("reset")

    def readline(self) -> str | None:
        """The next complete line, decoded leniently (garbage is for the parser to reject);
        None on a read timeout."""
        raw = self.lines.readline()
        if raw is None:
            return None
        # The prompt printed after a command precedes the stream's first line.
        while raw.startswith(PROMPT):
            raw = raw[len(PROMPT) :]
        return raw.decode("ascii", errors="replace")
