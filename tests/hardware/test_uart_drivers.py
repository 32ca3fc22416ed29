"""DWM1001 and motor-controller drivers against their simulated devices on ptys."""

from __future__ import annotations

from collections.abc import Callable

import pytest

from coffeebot.hardware.dwm1001 import Dwm1001, parse_lec
from coffeebot.hardware.motor import Boot, MotorController, decode, encode, parse
from coffeebot.hardware.serial_port import LineReader, SerialPort
from coffeebot.messages import Odometry
from coffeebot.sim.dwm1001 import SimDwm1001
from coffeebot.sim.motor_controller import IdealDrive, SimMotorController

Opener = Callable[[str], SerialPort]

LEC = (
    "DIST,4,AN0,022E,7.94,8.03,0.00,3.44,AN1,9280,7.95,0.00,0.00,5.68,AN2,DCAE,0.00,8.03,0.00,"
    "7.76,AN3,5431,0.00,0.00,0.00,8.73,POS,6.95,5.37,-1.97,52"
)


def test_parse_lec_with_position() -> None:
    report = parse_lec(LEC)
    assert report.fix is not None
    assert (report.fix.x_mm, report.fix.y_mm, report.fix.z_mm) == (6950.0, 5370.0, -1970.0)
    assert report.fix.quality == 52
    assert [a.anchor_id for a in report.fix.anchors] == ["022E", "9280", "DCAE", "5431"]
    assert report.anchors[3].distance_mm == 8730.0


def test_parse_lec_without_position_has_no_fix() -> None:
    report = parse_lec(LEC.split(",POS")[0])
    assert report.fix is None and len(report.anchors) == 4


def test_parse_bare_pos() -> None:
    fix = parse_lec("POS,7.10,5.24,-2.03,53").fix
    assert fix is not None and fix.x_mm == 7100.0


@pytest.mark.parametrize(
    ("line", "anchors_mm", "fix_mm"),
    [
        # metres whose float times 1000 is not the millimetres: 4.02, 2.01, 8.03
        (
            "DIST,2,AN0,1C2A,4.02,2.01,2.50,3.15,AN1,8E14,0.00,8.03,2.50,4.02,POS,2.01,4.02,1.00,71",
            [(4020, 2010, 2500, 3150), (0, 8030, 2500, 4020)],
            (2010, 4020, 1000),
        ),
        (
            "DIST,1,AN0,022E,40.20,-0.07,0.00,12.34,POS,28.14,-0.05,0.3,100",
            [(40200, -70, 0, 12340)],
            (28140, -50, 300),
        ),
        ("POS,4.02,2.01,-8.03,53", [], (4020, 2010, -8030)),
        ("DIST,1,AN0,9280,8.03,4.020,0.00,2.01", [(8030, 4020, 0, 2010)], None),
    ],
)
def test_lec_decimals_are_exact_millimetres(
    line: str, anchors_mm: list[tuple[int, int, int, int]], fix_mm: tuple[int, int, int] | None
) -> None:
    report = parse_lec(line)
    assert [(a.x_mm, a.y_mm, a.z_mm, a.distance_mm) for a in report.anchors] == anchors_mm
    if fix_mm is None:
        assert report.fix is None
    else:
        assert report.fix is not None
        assert (report.fix.x_mm, report.fix.y_mm, report.fix.z_mm) == fix_mm


@pytest.mark.parametrize(
    "line",
    [
        "",
        "dwm> ",
        "@\x01\x01",
        LEC[:60],  # cut mid-line
        LEC[:60] + LEC,  # a partial line run into the next one
        LEC.replace("AN2,", "AN7,"),
        LEC.replace("6.95", "nan"),
        LEC.replace("6.95", "7e3"),  # metres as the shell prints them, nothing else
        LEC.replace("6.95", "6.9512"),  # finer than a millimetre
        LEC.replace("6.95", "6,95"),
        LEC.replace(",52", ",140"),
        LEC + ",7",
        "DIST,-1",
        "POS,1.00,2.00,53",
    ],
)
def test_parse_lec_rejects_garbage(line: str) -> None:
    with pytest.raises(ValueError):
        parse_lec(line)


def read_fix(tag: Dwm1001, attempts: int = 50) -> tuple[int, object]:
    """Read lines until one parses with a fix; returns (lines rejected, fix)."""
    rejected = 0
    for _ in range(attempts):
        line = tag.readline()
        if line is None:
            continue
        try:
            report = parse_lec(line)
        except ValueError:
            rejected += 1
            continue
        if report.fix is not None:
            return rejected, report.fix
    raise AssertionError("no fix")


def test_dwm_start_resets_then_streams(sim_dwm: SimDwm1001, open_sim_port: Opener) -> None:
    tag = Dwm1001(open_sim_port(sim_dwm.port))
    tag.start()
    assert sim_dwm.commands == ["reset", "lec"]
    rejected, fix = read_fix(tag)
    assert rejected == 0
    assert (fix.x_mm, fix.y_mm) == (1500.0, 850.0)  # type: ignore[attr-defined]


def test_dwm_text_in_tlv_mode_gets_error_tlv(sim_dwm: SimDwm1001, open_sim_port: Opener) -> None:
    port = open_sim_port(sim_dwm.port)
    port.write(b"lec\r")
    assert LineReader(port).read_until(b"\x40\x01\x01") == b""


def test_dwm_garbage_and_partial_lines_are_skipped(
    sim_dwm: SimDwm1001, open_sim_port: Opener
) -> None:
    tag = Dwm1001(open_sim_port(sim_dwm.port))
    tag.start()
    read_fix(tag)
    sim_dwm.inject(b"\x00\xff\xfe garbage\r\nDIST,4,AN0,02")
    rejected, fix = read_fix(tag)
    assert rejected == 2 and fix is not None


def test_dwm_restart_after_tag_reset(sim_dwm: SimDwm1001, open_sim_port: Opener) -> None:
    tag = Dwm1001(open_sim_port(sim_dwm.port))
    tag.start()
    read_fix(tag)
    sim_dwm.reset()
    tag.drain()
    assert tag.readline() is None  # the stream stopped with the reset
    tag.start()
    read_fix(tag)


def test_dwm_unplug_raises_oserror(sim_dwm: SimDwm1001, open_sim_port: Opener) -> None:
    tag = Dwm1001(open_sim_port(sim_dwm.port))
    tag.start()
    sim_dwm.unplug()
    with pytest.raises(OSError):
        for _ in range(100):
            tag.readline()
    with pytest.raises(OSError):
        open_sim_port(sim_dwm.port)
    sim_dwm.replug()
    tag = Dwm1001(open_sim_port(sim_dwm.port))
    tag.start()
    read_fix(tag)


def test_motor_line_round_trip_and_rejects() -> None:
    assert decode(encode("V", 120, -40).rstrip(b"\n")) == ("V", ["120", "-40"])
    assert isinstance(parse(b"B,fw*" + encode("B", "fw")[5:7]), Boot)
    for bad in (b"V,1,2*00", b"V,1,2", b"V,1*" + encode("V", 1)[4:6], b"\xff\xfe*00", b"X*58"):
        with pytest.raises(ValueError):
            parse(bad)


def telemetry(ctrl: MotorController, want: object = None, lines: int = 200) -> Odometry:
    """The next telemetry line (for which ``want(odo)`` holds, if given)."""
    for _ in range(lines):
        raw = ctrl.readline()
        if raw is None:
            continue
        try:
            event = parse(raw)
        except ValueError:
            continue
        if isinstance(event, Odometry) and (want is None or want(event)):  # type: ignore[operator]
            return event
    raise AssertionError("no matching telemetry")


def test_motor_drives_and_reports_odometry(
    sim_motor: SimMotorController, open_sim_port: Opener
) -> None:
    ctrl = MotorController(open_sim_port(sim_motor.port))
    ctrl.set_speeds(200, 100)
    odo = telemetry(ctrl, lambda o: o.left_mm_s == 200)
    assert odo.right_mm_s == 100 and not odo.watchdog_tripped
    assert odo.gyro_z_dps < 0  # right wheel slower: turning clockwise
    later = telemetry(ctrl, lambda o: o.left_ticks > odo.left_ticks)
    assert later.left_ticks > later.right_ticks
    ctrl.stop()
    assert telemetry(ctrl, lambda o: o.left_mm_s == 0).right_mm_s == 0
    assert [c.kind for c in sim_motor.commands] == ["V", "S"]


def test_motor_watchdog_stops_without_commands(
    sim_motor: SimMotorController, open_sim_port: Opener
) -> None:
    ctrl = MotorController(open_sim_port(sim_motor.port))
    ctrl.set_speeds(300, 300)
    telemetry(ctrl, lambda o: o.left_mm_s == 300)
    odo = telemetry(ctrl, lambda o: o.watchdog_tripped)
    assert (odo.left_mm_s, odo.right_mm_s) == (0, 0)
    assert sim_motor.watchdog_trips == 1 and sim_motor.setpoint == (0, 0)


def test_motor_identify_and_garbage_counted(
    sim_motor: SimMotorController, open_sim_port: Opener
) -> None:
    ctrl = MotorController(open_sim_port(sim_motor.port))
    ident = ctrl.identify()
    assert (ident.watchdog_ms, ident.telemetry_hz) == (200, 50)
    ctrl.port.write(b"V,100,100*00\n\xff\xfe\n")
    telemetry(ctrl, lambda o: sim_motor.rx_errors == 2)
    assert sim_motor.commands == []  # a bad line never moves the motors


def test_motor_watchdog_is_a_hardware_timer_the_firmware_thread_cannot_delay() -> None:
    """The watchdog stops the drive at its deadline even when the firmware's tick never
    runs (its thread starved): on the real board it is a separate hardware timer."""
    now = [0.0]
    drive = IdealDrive(ticks_per_mm=1.0)
    sim = SimMotorController(drive, clock=lambda: now[0])  # not started: no ticks at all
    try:
        sim.on_data(encode("V", 300, 300))
        now[0] = 2.0
        sample = drive.sample(now[0])
    finally:
        sim.close()
    assert (sample.left_ticks, sample.right_ticks) == (60, 60)  # 0.2 s at 300 mm/s
    assert (sample.left_mm_s, sample.right_mm_s) == (0.0, 0.0)
