from __future__ import annotations

from pathlib import Path

import pytest

from coffeebot.config import load_robot_config
from coffeebot.errors import ConfigError

BOARD = Path(__file__).resolve().parents[2] / "boards" / "coffeebot-v1.toml"


def test_shipped_board_has_the_seed_robot() -> None:
    config = load_robot_config(BOARD)
    assert (config.geometry.width_mm, config.geometry.length_mm) == (510, 610)
    assert config.i2c.mux_address == 0x70
    assert [s.id for s in config.tof.sensors] == list(range(8))
    right = [s for s in config.tof.sensors if s.face == "right"]
    assert abs(right[1].x_mm - right[0].x_mm) == 277
    assert config.collision.front_radius_mm == 200 and config.collision.side_radius_mm == 50
    assert config.angle.max_side_distance_mm == 850 and config.angle.min_angle_deg == 5
    assert config.door.jump_mm == 80


def write(tmp_path: Path, text: str) -> Path:
    path = tmp_path / "robot.toml"
    path.write_text(BOARD.read_text() + text)
    return path


def test_wrong_type_names_file_and_field(tmp_path: Path) -> None:
    path = tmp_path / "robot.toml"
    path.write_text(BOARD.read_text().replace("bus = 1", 'bus = "one"'))
    with pytest.raises(ConfigError) as err:
        load_robot_config(path)
    assert str(path) in str(err.value)
    assert "i2c.bus" in str(err.value) and "integer" in str(err.value)


def test_unknown_field_is_refused(tmp_path: Path) -> None:
    path = write(tmp_path, "\n[geometry2]\nwidth_mm = 3\n")
    with pytest.raises(ConfigError, match=r"geometry2: Extra inputs are not permitted"):
        load_robot_config(path)


def test_duplicate_mux_channel_is_refused(tmp_path: Path) -> None:
    path = tmp_path / "robot.toml"
    path.write_text(BOARD.read_text().replace("channel = 7", "channel = 6"))
    with pytest.raises(ConfigError, match=r"tof: .*duplicate sensor channel \[6\]"):
        load_robot_config(path)


def test_out_of_range_threshold_is_refused(tmp_path: Path) -> None:
    path = tmp_path / "robot.toml"
    path.write_text(BOARD.read_text().replace("front_radius_mm = 200.0", "front_radius_mm = -1"))
    with pytest.raises(ConfigError, match=r"collision.front_radius_mm: .*greater than 0"):
        load_robot_config(path)


def test_the_fusion_choice_and_particle_filter_bounds_are_checked(tmp_path: Path) -> None:
    path = tmp_path / "robot.toml"
    path.write_text(BOARD.read_text() + '\n[state]\nfusion = "kalman"\n')
    with pytest.raises(ConfigError, match=r"state.fusion: Input should be 'ekf' or 'particles'"):
        load_robot_config(path)
    path.write_text(
        BOARD.read_text() + '\n[state]\nfusion = "particles"\n\n[state.particles]\n'
        "min_particles = 5000\n"
    )
    with pytest.raises(ConfigError, match=r"state.particles: .*min_particles \(5000\) exceeds"):
        load_robot_config(path)
    path.write_text(BOARD.read_text() + '\n[state]\nfusion = "particles"\n')
    assert load_robot_config(path).state.fusion == "particles"


def test_broken_toml_and_missing_file(tmp_path: Path) -> None:
    path = tmp_path / "robot.toml"
    path.write_text("[i2c\nbus = 1")
    with pytest.raises(ConfigError, match=r"robot.toml: not valid TOML"):
        load_robot_config(path)
    with pytest.raises(ConfigError, match="file not found"):
        load_robot_config(tmp_path / "nope.toml")


def test_cli_refuses_a_broken_board_file_with_the_field(tmp_path: Path, capsys) -> None:
    from coffeebot.cli import main

    path = tmp_path / "robot.toml"
    path.write_text(BOARD.read_text().replace("mux_address = 0x70", "mux_address = 0x10"))
    assert main(["run", "--board", str(path)]) == 2
    err = capsys.readouterr().err
    assert "configuration error" in err and "i2c.mux_address" in err and str(path) in err
