"""Angle correction: the seed's rules, its four situations, and the straddle rejections."""

from __future__ import annotations

import math

import numpy as np
import pytest
from perception_helpers import hallway_floor, pose, robot, scan, scan_at

from coffeebot.config import AngleConfig
from coffeebot.messages import AngleEstimate
from coffeebot.perception.angle import AngleEstimator, Rejection, pair_angle_deg

ZONES = [
    {"id": "Za", "from_mm": 3900, "to_mm": 5100},
    {"id": "open", "from_mm": 8000, "to_mm": 8400},
    {"id": "near104", "from_mm": 10500, "to_mm": 11500},
]


def estimator(**overrides: object) -> AngleEstimator:
    cfg = AngleConfig().model_copy(update={"scans_per_estimate": 1, **overrides})
    return AngleEstimator(robot().tof.sensors, cfg)


def measure(x: float, y: float, heading: float, **kwargs: object) -> AngleEstimate | Rejection:
    floor = hallway_floor(ZONES)
    est = estimator(**kwargs)
    return est.update(scan_at(floor, x, y, heading), 1, pose(x, y, heading), floor, False, 0.0)


def test_situation1_right_wall_35_degrees() -> None:
    result = measure(4300, -300, 35.0, prior_gate_deg=10.0)
    assert isinstance(result, AngleEstimate), result
    assert result.side == "right"
    assert result.angle_deg == pytest.approx(35.0, abs=0.1)
    assert result.correction_deg == pytest.approx(-35.0, abs=0.1)


def test_situation2_parallel_is_zero_correction() -> None:
    result = measure(4500, -100, 0.03)
    assert isinstance(result, AngleEstimate), result
    assert result.side == "both"
    assert abs(result.angle_deg) < 0.1
    assert result.correction_deg == 0.0


def test_angles_below_five_degrees_are_no_correction() -> None:
    small = measure(4500, -300, 4.0)
    assert isinstance(small, AngleEstimate)
    assert small.angle_deg == pytest.approx(4.0, abs=0.25)
    assert small.correction_deg == 0.0
    large = measure(4500, -300, -6.0)
    assert isinstance(large, AngleEstimate)
    assert large.correction_deg == pytest.approx(6.0, abs=0.25)


def test_situation3_open_hallway_uses_the_other_side() -> None:
    # Right front sensor looks into the side hallway at 9000; the left wall is nearer.
    result = measure(8200, 250, 12.0)
    assert isinstance(result, AngleEstimate), result
    assert result.side == "left"
    assert result.angle_deg == pytest.approx(12.0, abs=0.1)


def test_situation4_door_under_front_sensor_is_rejected() -> None:
    floor = hallway_floor(ZONES)
    x, y, heading = 11250, -300, 19.0
    s = scan_at(floor, x, y, heading)
    d = {r.sensor: r.distance_mm for r in s.readings}
    # The seed's failure, reproduced: the raw pair says about 36 degrees.
    assert pair_angle_deg(d[1] - d[0], 277.0, 0.0) == pytest.approx(36.0, abs=1.5)
    result = estimator().update(s, 1, pose(x, y, heading), floor, False, 0.0)
    assert isinstance(result, Rejection)
    assert "right: sensor 1 cone on 104" in result.reason


def test_door_straddle_caught_by_pose_prior_when_plan_position_is_off() -> None:
    # The pose is 1.5 m off along the hallway, so the plan sees flat wall under the cones;
    # the 17-degree disagreement with the pose heading still rejects the pair.
    floor = hallway_floor([{"id": "long", "from_mm": 10000, "to_mm": 11500}])
    s = scan_at(floor, 11250, -300, 19.0)
    result = estimator().update(s, 1, pose(10300, -300, 19.0), floor, False, 0.0)
    assert isinstance(result, Rejection)
    assert "from the pose heading" in result.reason


def test_only_inside_marked_zones() -> None:
    result = measure(2000, 0, 0.0)
    assert isinstance(result, Rejection) and result.reason == "outside the angle zones"


def test_not_while_an_obstacle_is_present() -> None:
    floor = hallway_floor(ZONES)
    s = scan_at(floor, 4500, -300, 0.0)
    result = estimator().update(s, 1, pose(4500, -300, 0.0), floor, True, 0.0)
    assert isinstance(result, Rejection) and result.reason == "obstacle present"


def test_both_side_sensors_must_read_below_850() -> None:
    # 100 mm from the right wall: left sensors read ~1290 mm, so only the right side counts.
    result = measure(4500, -495, 3.0)
    assert isinstance(result, AngleEstimate) and result.side == "right"
    floor = hallway_floor(ZONES)
    far = scan({0: 900, 1: 905, 6: 900, 7: 910})
    rejected = estimator().update(far, 1, pose(4500, 0, 0.0), floor, False, 0.0)
    assert isinstance(rejected, Rejection) and "beyond 850" in rejected.reason


def test_sides_must_agree() -> None:
    floor = hallway_floor(ZONES)
    # Right pair says +5 deg, left pair -5 deg: something is not a wall.
    bad = scan({0: 570, 1: 594, 6: 594, 7: 570})
    result = estimator().update(bad, 1, pose(4500, 0, 0.0), floor, False, 0.0)
    assert isinstance(result, Rejection) and "sides disagree" in result.reason


def test_wall_where_the_plan_does_not_put_it_is_rejected() -> None:
    floor = hallway_floor(ZONES)
    # A box 300 mm deep against the right wall: flat, parallel, but not the wall.
    box = scan({0: 290, 1: 290, 6: 595, 7: 595})
    result = estimator().update(box, 1, pose(4500, 0, 0.0), floor, False, 0.0)
    assert isinstance(result, AngleEstimate) and result.side == "left"
    alone = scan({0: 290, 1: 290})
    result = estimator().update(alone, 1, pose(4500, 0, 0.0), floor, False, 0.0)
    assert isinstance(result, Rejection) and "plan says" in result.reason


def test_travelling_against_the_axis_swaps_walls() -> None:
    result = measure(4500, 300, 180.0 + 7.0)  # heading back, 300 mm right of it
    assert isinstance(result, AngleEstimate), result
    assert result.angle_deg == pytest.approx(7.0, abs=0.1)
    assert result.heading_deg == pytest.approx(-173.0, abs=0.1)


def test_window_averages_noise_and_compensates_turning() -> None:
    floor = hallway_floor(ZONES)
    rng = np.random.default_rng(5)
    errors = []
    for trial in range(60):
        est = AngleEstimator(robot().tof.sensors, AngleConfig())
        truth = float(rng.uniform(-8, 8))
        bias = float(rng.normal(0, 2.0))  # the pose's own heading error, drifting slowly
        result: AngleEstimate | Rejection = Rejection("")
        for k in range(AngleConfig().scans_per_estimate):
            heading = truth + 0.2 * k  # turning slowly while measuring
            x, y = 4000 + 40 * k, -300.0
            s = scan_at(floor, x, y, heading, noise_mm=5.0, rng=rng)
            prior = heading + bias + 0.05 * k
            result = est.update(s, k, pose(x, y, prior), floor, False, 0.1 * k)
        assert isinstance(result, AngleEstimate), (trial, result)
        errors.append(result.angle_deg - (truth + 0.2 * 7))
    assert math.sqrt(float(np.mean(np.square(errors)))) < 0.6
    assert max(abs(e) for e in errors) < 2.0


@pytest.mark.parametrize("h", [0.0, 5.0, 13.5])
@pytest.mark.parametrize("angle", [-40.0, -10.0, -2.0, 0.0, 3.0, 12.0, 35.0])
def test_pair_angle_inverts_the_ranging_model(h: float, angle: float) -> None:
    a = math.radians(angle)
    delta = 277.0 * math.sin(a) / math.cos(math.radians(max(0.0, abs(angle) - h)))
    assert pair_angle_deg(delta, 277.0, h) == pytest.approx(angle, abs=1e-6)


def test_a_reading_the_sensor_reports_unsure_is_not_used() -> None:
    """The chip's sigma says what a reading is worth: a weak or blended return is no wall."""
    floor = hallway_floor()
    x, y, heading = 4500.0, -300.0, 10.0
    s = scan_at(floor, x, y, heading)
    est = estimator()
    assert isinstance(est.update(s, 1, pose(x, y, heading), floor, False, 0.0), AngleEstimate)
    unsure = s.model_copy(
        update={
            "readings": [
                r.model_copy(update={"sigma_mm": 60.0}) if r.sensor == 1 else r for r in s.readings
            ]
        }
    )
    result = estimator().update(unsure, 1, pose(x, y, heading), floor, False, 0.0)
    assert isinstance(result, Rejection) and "right: no valid reading" in result.reason
