"""Naming camera tracks after robots by their motion (seed 003, eqs 1-9), and refusing to guess."""

from __future__ import annotations

import math

import numpy as np
import pytest

from coffeebot.cameras.identify import Estimate, IdentifyRules, fit_similarity, identify

RULES = IdentifyRules()
Q = 50
"""Waypoints per path: 10 s at 5 Hz."""
DT_S = 0.2


def drive(
    start: tuple[float, float, float], speed_mm_s: float, turn_rad_s: np.ndarray | float
) -> np.ndarray:
    """A robot's true floor poses (Q, 3) from a start pose and per-step speed and turn rate."""
    turns = np.broadcast_to(np.asarray(turn_rad_s, dtype=float), (Q - 1,))
    poses = np.empty((Q, 3))
    poses[0] = start
    for k, turn in enumerate(turns):
        x, y, heading = poses[k]
        poses[k + 1] = (
            x + speed_mm_s * DT_S * math.cos(heading),
            y + speed_mm_s * DT_S * math.sin(heading),
            heading + turn * DT_S,
        )
    return poses


def odometry_of(truth: np.ndarray) -> np.ndarray:
    """The same poses in the robot's odometry frame, which starts where the robot started."""
    x0, y0, h0 = truth[0]
    c, s = math.cos(h0), math.sin(h0)
    dx, dy = truth[:, 0] - x0, truth[:, 1] - y0
    return np.column_stack([c * dx + s * dy, -s * dx + c * dy, truth[:, 2] - h0])


def camera_track(truth: np.ndarray, rng: np.random.Generator, noise_mm: float) -> np.ndarray:
    return truth[:, :2] + rng.normal(0.0, noise_mm, (Q, 2))


def person_wandering(rng: np.random.Generator, start: tuple[float, float]) -> np.ndarray:
    """A person dawdling about one spot: 80 mm steps in random directions."""
    angles = rng.uniform(0.0, 2 * np.pi, Q)
    return np.asarray(start) + np.cumsum(
        80.0 * np.column_stack([np.cos(angles), np.sin(angles)]), axis=0
    )


def person_walking(rng: np.random.Generator, start: tuple[float, float]) -> np.ndarray:
    """A person crossing the room at 1 m/s, drifting off course."""
    angles = rng.uniform(0.0, 2 * np.pi) + np.cumsum(rng.normal(0.0, 0.3, Q))
    return np.asarray(start) + np.cumsum(
        200.0 * np.column_stack([np.cos(angles), np.sin(angles)]), axis=0
    )


def estimate_at(
    truth: np.ndarray, k: int, off_mm: tuple[float, float] = (0.0, 0.0), sigma_mm: float = 20.0
) -> Estimate:
    """The robot's own estimate at waypoint ``k``: its true position ``off_mm`` off, claiming
    ``sigma_mm`` on each axis."""
    x, y = truth[k, :2] + np.asarray(off_mm)
    ox, oy, _ = odometry_of(truth)[k]
    return Estimate((ox, oy), (x, y), ((sigma_mm**2, 0.0), (0.0, sigma_mm**2)))


def heading_error(a: float, b: float) -> float:
    return abs(math.remainder(a - b, 2 * math.pi))


def test_fit_recovers_a_known_similarity_exactly() -> None:
    rng = np.random.default_rng(1)
    odometry = rng.uniform(-2000.0, 2000.0, (30, 2))
    scale, rotation, shift = 1.07, 2.3, np.array([3200.0, -1450.0])
    c, s = math.cos(rotation), math.sin(rotation)
    seen = scale * odometry @ np.array([[c, -s], [s, c]]).T + shift

    fit = fit_similarity(odometry, seen)

    assert fit.scale == pytest.approx(scale, rel=1e-9)
    assert fit.rotation_rad == pytest.approx(rotation, abs=1e-9)
    assert (fit.a0, fit.b0) == pytest.approx((scale * c, scale * s), abs=1e-9)
    assert (fit.x0_mm, fit.y0_mm) == pytest.approx(tuple(shift), abs=1e-6)
    assert fit.error_mm < 1e-6
    np.testing.assert_allclose(fit.to_floor(odometry), seen, atol=1e-6)


def test_the_error_is_the_mean_distance_left_after_the_fit() -> None:
    """Eight points on a circle pushed out and in by 40 mm * cos(2 angle): no rotation,
    scale or shift undoes that, so the fit is the identity and eq 7 averages 40, 0, 40, 0..."""
    angles = np.arange(8) * np.pi / 4
    radial = np.column_stack([np.cos(angles), np.sin(angles)])
    odometry = 1000.0 * radial
    seen = odometry + 40.0 * np.cos(2 * angles)[:, None] * radial

    fit = fit_similarity(odometry, seen)

    assert (fit.scale, fit.rotation_rad, fit.x0_mm, fit.y0_mm) == pytest.approx(
        (1.0, 0.0, 0.0, 0.0), abs=1e-9
    )
    assert fit.error_mm == pytest.approx(20.0, abs=1e-9)


def test_fit_with_10_mm_of_camera_noise_is_within_a_few_mm() -> None:
    rng = np.random.default_rng(2)
    truth = drive((1500.0, 800.0, 0.9), 300.0, 0.25)
    fit = fit_similarity(odometry_of(truth)[:, :2], camera_track(truth, rng, 10.0))

    assert fit.scale == pytest.approx(1.0, abs=0.01)
    assert heading_error(fit.rotation_rad, 0.9) < math.radians(0.5)
    assert math.hypot(fit.x0_mm - 1500.0, fit.y0_mm - 800.0) < 8.0
    # Eq 7 is a mean distance: 10 mm per axis leaves about 10 * sqrt(pi / 2) = 12.5 mm.
    assert 9.0 < fit.error_mm < 16.0


def test_the_error_is_small_for_the_robot_and_large_for_a_person() -> None:
    """Eq 7 alone rejects a person who walks, not one who dawdles: the fit may shrink the
    robot's path onto her spot, which bounds the error by her own spread. The scale shows it."""
    rng = np.random.default_rng(3)
    truth = drive((2000.0, 1000.0, -0.4), 300.0, np.linspace(-0.4, 0.4, Q - 1))
    odometry = odometry_of(truth)[:, :2]

    robot = fit_similarity(odometry, camera_track(truth, rng, 10.0))
    walker = fit_similarity(odometry, person_walking(rng, (2100.0, 1200.0)))
    dawdler = fit_similarity(odometry, person_wandering(rng, (2100.0, 1200.0)))

    assert robot.error_mm < 20.0
    assert robot.scale == pytest.approx(1.0, abs=0.01)
    assert walker.error_mm > 2 * RULES.gate_mm
    assert dawdler.error_mm > 5 * robot.error_mm
    assert dawdler.scale < 0.5


def test_two_robots_and_a_person_are_told_apart() -> None:
    rng = np.random.default_rng(4)
    alpha = drive((500.0, 500.0, 0.3), 300.0, 0.2)
    bravo = drive((3500.0, 2500.0, 3.0), 250.0, -0.3)
    tracks = {
        "t1": person_wandering(rng, (2000.0, 1500.0)),
        "t2": camera_track(bravo, rng, 10.0),
        "t3": camera_track(alpha, rng, 10.0),
    }
    robots = {"alpha": odometry_of(alpha), "bravo": odometry_of(bravo)}

    result = identify(tracks, robots, RULES)

    assert {robot: match.track_id for robot, match in result.matched.items()} == {
        "alpha": "t3",
        "bravo": "t2",
    }
    assert result.refused == {}
    assert result.unmatched_tracks == ["t1"]


def test_a_matched_robots_pose_is_its_true_pose() -> None:
    rng = np.random.default_rng(5)
    truth = drive((3000.0, 2000.0, 2.0), 300.0, np.linspace(0.5, -0.5, Q - 1))
    result = identify({"t1": camera_track(truth, rng, 10.0)}, {"alpha": odometry_of(truth)}, RULES)

    pose = result.matched["alpha"].pose
    x, y, heading = truth[-1]
    assert math.hypot(pose.x_mm - x, pose.y_mm - y) < 8.0
    assert heading_error(pose.heading_rad, heading) < math.radians(0.5)


def test_a_robot_that_stood_still_is_refused() -> None:
    """It fits a standing blob as well as a moving robot fits its own track: motion tells."""
    rng = np.random.default_rng(6)
    mover = drive((500.0, 500.0, 0.0), 300.0, 0.2)
    standing = np.tile([2000.0, 2500.0, 0.4], (Q, 1))
    blob = np.array([2500.0, 2000.0]) + rng.normal(0.0, 10.0, (Q, 2))
    # The pseudo-inverse's least-norm answer for a path that is one point: a close fit, at
    # about the right scale, of a rotation and translation that mean nothing.
    degenerate = fit_similarity(standing[:, :2], blob)
    assert degenerate.error_mm < RULES.gate_mm
    assert degenerate.scale == pytest.approx(RULES.expected_scale, abs=RULES.scale_tolerance)

    result = identify(
        {"t1": blob, "t2": camera_track(mover, rng, 10.0)},
        {"alpha": odometry_of(mover), "bravo": standing},
        RULES,
    )

    assert result.refused["bravo"].startswith("did not move enough")
    assert result.matched["alpha"].track_id == "t2"
    assert result.unmatched_tracks == ["t1"]


def test_a_robot_whose_track_is_missing_is_refused() -> None:
    rng = np.random.default_rng(7)
    truth = drive((500.0, 500.0, 0.0), 300.0, 0.2)
    result = identify(
        {"t1": person_walking(rng, (800.0, 900.0))}, {"alpha": odometry_of(truth)}, RULES
    )

    assert result.matched == {}
    assert result.refused["alpha"].startswith("no track fits within 150 mm")
    assert result.unmatched_tracks == ["t1"]


@pytest.mark.parametrize(
    ("bravo_turn_rad_s", "alpha_outcome", "bravo_outcome"),
    [
        (0.28, "t1", "its fitting tracks fit other robots better: t1 (robot alpha)"),
        (0.21, "ambiguous: robots alpha and bravo fit track t1 within 2x", None),
    ],
    ids=["clearly-alpha", "too-close-to-call"],
)
def test_a_track_two_robots_fit_goes_to_the_clearly_better_one_or_to_none(
    bravo_turn_rad_s: float, alpha_outcome: str, bravo_outcome: str | None
) -> None:
    """Bravo's own track is out of view, and its curve is a little tighter than alpha's."""
    rng = np.random.default_rng(10)
    alpha = drive((500.0, 500.0, 0.0), 300.0, 0.2)
    bravo = drive((2500.0, 500.0, 1.0), 300.0, bravo_turn_rad_s)
    result = identify(
        {"t1": camera_track(alpha, rng, 10.0)},
        {"alpha": odometry_of(alpha), "bravo": odometry_of(bravo)},
        RULES,
    )

    alpha_match = result.matched.get("alpha")
    assert (alpha_match.track_id if alpha_match else result.refused["alpha"]) == alpha_outcome
    if bravo_outcome is None:
        assert "bravo" in result.refused
    else:
        assert result.refused["bravo"] == bravo_outcome


@pytest.mark.parametrize("turn_rad_s", [0.0, 0.15], ids=["straight", "curving"])
def test_robots_driving_alike_side_by_side_are_refused_never_swapped(turn_rad_s: float) -> None:
    """Each odometry starts at its own origin, so two robots given the same commands report
    the same path; the similarity's translation absorbs the metre between them. Straight or
    curved, nothing in the fit can tell them apart."""
    rng = np.random.default_rng(8)
    alpha = drive((1000.0, 1000.0, 0.0), 300.0, turn_rad_s)
    bravo = drive((1000.0, 2000.0, 0.0), 300.0, turn_rad_s)
    tracks = {"t1": camera_track(alpha, rng, 10.0), "t2": camera_track(bravo, rng, 10.0)}
    robots = {"alpha": odometry_of(alpha), "bravo": odometry_of(bravo)}
    assert fit_similarity(robots["alpha"][:, :2], tracks["t2"]).error_mm < 20.0

    result = identify(tracks, robots, RULES)

    assert result.matched == {}
    assert set(result.refused) == {"alpha", "bravo"}
    assert all(reason.startswith("ambiguous") for reason in result.refused.values())
    assert result.unmatched_tracks == ["t1", "t2"]


@pytest.mark.parametrize("turn_rad_s", [0.0, 0.15], ids=["straight", "curving"])
def test_robots_side_by_side_are_told_apart_by_their_own_estimates(turn_rad_s: float) -> None:
    """The same two robots, each knowing where it is to 20 mm (and 40 mm off it): the
    estimates are a metre apart, 25 sigmas, and settle which track is which."""
    rng = np.random.default_rng(8)
    alpha = drive((1000.0, 1000.0, 0.0), 300.0, turn_rad_s)
    bravo = drive((1000.0, 2000.0, 0.0), 300.0, turn_rad_s)
    tracks = {"t1": camera_track(alpha, rng, 10.0), "t2": camera_track(bravo, rng, 10.0)}
    robots = {"alpha": odometry_of(alpha), "bravo": odometry_of(bravo)}
    estimates = {"alpha": estimate_at(alpha, 30, (40.0, 0.0)), "bravo": estimate_at(bravo, 45)}

    result = identify(tracks, robots, RULES, estimates)

    assert result.matched["alpha"].track_id == "t1"
    assert result.matched["bravo"].track_id == "t2"
    assert math.dist(result.matched["alpha"].pose[:2], alpha[-1, :2]) < 30.0


def test_one_estimate_settles_both_robots_only_for_the_robot_that_has_it() -> None:
    """Alpha knows where it is, bravo (just switched on) does not: alpha's estimate sets
    track t2 aside for alpha, but nothing says bravo is not on t1, so bravo's claim on t1
    still makes alpha's match ambiguous, and bravo is refused as well."""
    rng = np.random.default_rng(8)
    alpha = drive((1000.0, 1000.0, 0.0), 300.0, 0.0)
    bravo = drive((1000.0, 2000.0, 0.0), 300.0, 0.0)
    tracks = {"t1": camera_track(alpha, rng, 10.0), "t2": camera_track(bravo, rng, 10.0)}
    robots = {"alpha": odometry_of(alpha), "bravo": odometry_of(bravo)}

    result = identify(tracks, robots, RULES, {"alpha": estimate_at(alpha, Q - 1)})

    assert result.matched == {}
    assert result.refused["alpha"] == "ambiguous: robots alpha and bravo fit track t1 within 2x"


@pytest.mark.parametrize(
    ("alpha_off_mm", "bravo_off_mm"),
    [((0.0, 1000.0), (0.0, 0.0)), ((0.0, 500.0), (0.0, 500.0)), ((3000.0, 0.0), (0.0, 0.0))],
    ids=["alpha-on-bravos-spot", "both-between", "alpha-lost"],
)
def test_a_wrong_estimate_never_swaps_two_robots(
    alpha_off_mm: tuple[float, float], bravo_off_mm: tuple[float, float]
) -> None:
    """Alpha believing it is where bravo is, both halfway between, alpha lost 3 m away: a
    wrong estimate may cost a match, never make a wrong one. (Both wrong by exactly their
    spacing, each believing it is where the other is, would swap them: then nothing the
    cameras or the robots know tells them apart.)"""
    rng = np.random.default_rng(8)
    alpha = drive((1000.0, 1000.0, 0.0), 300.0, 0.0)
    bravo = drive((1000.0, 2000.0, 0.0), 300.0, 0.0)
    tracks = {"t1": camera_track(alpha, rng, 10.0), "t2": camera_track(bravo, rng, 10.0)}
    robots = {"alpha": odometry_of(alpha), "bravo": odometry_of(bravo)}
    estimates = {
        "alpha": estimate_at(alpha, Q - 1, alpha_off_mm),
        "bravo": estimate_at(bravo, Q - 1, bravo_off_mm),
    }

    result = identify(tracks, robots, RULES, estimates)

    truth = {"alpha": "t1", "bravo": "t2"}
    named = {robot: match.track_id for robot, match in result.matched.items()}
    assert all(named[robot] == truth[robot] for robot in named), named


def test_a_lost_robots_estimate_does_not_stop_motion_from_naming_it() -> None:
    """A robot whose estimate is 3 m off (kidnapped, a bad UWB fix) is still named on the
    one track its motion explains: that is the fix that brings it back."""
    rng = np.random.default_rng(12)
    alpha = drive((500.0, 1500.0, 0.2), 350.0, 0.1)
    result = identify(
        {"t1": camera_track(alpha, rng, 5.0), "p1": person_walking(rng, (3000.0, 0.0))},
        {"alpha": odometry_of(alpha)},
        RULES,
        {"alpha": estimate_at(alpha, Q - 1, (3000.0, 0.0))},
    )
    assert result.matched["alpha"].track_id == "t1"


def test_estimate_rules_must_leave_a_band_between_agreeing_and_refuting() -> None:
    with pytest.raises(ValueError, match="estimate_refutes_sigma must be larger"):
        IdentifyRules(estimate_agrees_sigma=5.0, estimate_refutes_sigma=5.0)


def test_robots_side_by_side_at_different_speeds_are_told_apart_by_scale() -> None:
    """The same straight line at 300 and 400 mm/s: each fits the other's track perfectly, but
    only at a scale of 4/3 or 3/4, which no odometry is that wrong by."""
    rng = np.random.default_rng(9)
    alpha = drive((1000.0, 1000.0, 0.0), 300.0, 0.0)
    bravo = drive((1000.0, 2000.0, 0.0), 400.0, 0.0)
    tracks = {"t1": camera_track(bravo, rng, 10.0), "t2": camera_track(alpha, rng, 10.0)}
    robots = {"alpha": odometry_of(alpha), "bravo": odometry_of(bravo)}
    swapped = fit_similarity(robots["alpha"][:, :2], tracks["t1"])
    assert swapped.error_mm < 20.0
    assert swapped.scale == pytest.approx(4 / 3, abs=0.02)

    result = identify(tracks, robots, RULES)

    assert result.matched["alpha"].track_id == "t2"
    assert result.matched["bravo"].track_id == "t1"


def test_paths_of_different_lengths_are_rejected() -> None:
    truth = drive((0.0, 0.0, 0.0), 300.0, 0.2)
    with pytest.raises(ValueError, match="same q"):
        identify({"t1": truth[:-1, :2]}, {"alpha": odometry_of(truth)}, RULES)
    with pytest.raises(ValueError, match="same q"):
        fit_similarity(odometry_of(truth)[:, :2], truth[1:, :2])


def test_a_robot_too_slow_to_be_named_still_keeps_another_off_its_track() -> None:
    """Alpha crept a straight line just too short to name it (its odometry spreads 97 % of
    ``min_motion_mm``), yet explains its own track. Bravo, out of view, drove a straight
    line 7 % longer: its odometry fits alpha's track too, at a scale of 0.94. Nothing tells
    which of the two the track is, so neither is named on it (the bench's camera trials
    placed a robot 4.9 m off this way, on a robot's track that had spread 296 mm when the
    least was 300)."""
    rng = np.random.default_rng(11)
    least = RULES.min_motion_mm
    alpha = drive((1000.0, 1000.0, 0.0), 2 * 0.967 * least / ((Q - 1) * DT_S), 0.0)
    bravo = drive((6000.0, 3000.0, 1.0), 2 * 1.033 * least / ((Q - 1) * DT_S), 0.0)
    track = camera_track(alpha, rng, 10.0)
    robots = {"alpha": odometry_of(alpha), "bravo": odometry_of(bravo)}
    intruder = fit_similarity(robots["bravo"][:, :2], track)
    assert intruder.error_mm < RULES.gate_mm
    assert intruder.scale == pytest.approx(RULES.expected_scale, abs=RULES.scale_tolerance)

    result = identify({"t1": track}, robots, RULES)

    assert result.matched == {}
    assert result.refused["alpha"].startswith(f"did not move enough ({0.967 * least:.0f} mm")
    assert result.refused["bravo"] == "ambiguous: robots bravo and alpha fit track t1 within 2x"
    assert result.unmatched_tracks == ["t1"]


def test_waypoints_where_the_blob_was_cut_by_the_border_are_left_out_of_the_fit() -> None:
    """Driving into view, a robot's blob is cut by the image's edge and its centroid lags
    (here: the first 20 waypoints at half the robot's progress). As NaN rows those are left
    out and the robot is named on the rest; fitted as they are, its own fit is off scale
    and another robot driving straight fits its track instead."""
    rng = np.random.default_rng(11)
    alpha = drive((500.0, 1500.0, 0.0), 400.0, 0.0)
    bravo = drive((500.0, -2500.0, 0.4), 300.0, 0.0)
    lagging = camera_track(alpha, rng, 5.0)
    lagging[:20, 0] = alpha[20, 0] - 0.5 * (alpha[20, 0] - alpha[:20, 0])
    masked = lagging.copy()
    masked[:20] = np.nan
    robots = {"alpha": odometry_of(alpha), "bravo": odometry_of(bravo)}

    result = identify({"t1": masked}, robots, RULES)
    assert result.matched["alpha"].track_id == "t1"
    assert math.dist(result.matched["alpha"].pose[:2], alpha[-1, :2]) < 10.0

    as_seen = identify({"t1": lagging}, robots, RULES)
    assert "alpha" not in as_seen.matched
    assert as_seen.matched["bravo"].track_id == "t1", "the wrong match the mask prevents"


def test_a_robot_is_not_named_on_a_track_whose_newest_blob_is_cut_but_it_still_rivals() -> None:
    """Driving out of view, the robot's newest blobs are cut by the border: what its track
    follows now may be something else (another robot driving in, merged with it there), so
    no fix comes from it; it still keeps a robot that fits it too off the other track."""
    rng = np.random.default_rng(13)
    alpha = drive((1000.0, 1000.0, 0.0), 300.0, 0.0)
    bravo = drive((1000.0, 2000.0, 0.0), 300.0, 0.0)
    leaving = camera_track(alpha, rng, 5.0)
    leaving[-3:] = np.nan
    tracks = {"t1": leaving, "t2": camera_track(bravo, rng, 5.0)}
    robots = {"alpha": odometry_of(alpha), "bravo": odometry_of(bravo)}

    alone = identify({"t1": leaving}, {"alpha": robots["alpha"]}, RULES)
    assert alone.matched == {}
    assert alone.refused["alpha"] == "its track is cut by the image's border now: t1"

    result = identify(tracks, robots, RULES)
    assert result.matched == {}
    assert result.refused["alpha"] == "ambiguous: tracks t2 and t1 fit within 2x"


def test_after_its_blob_was_cut_a_track_names_only_from_what_it_saw_since() -> None:
    """Two robots meet at the image's border, merged and cut there, and part with the track
    gone on with bravo: the waypoints before the cut were alpha's. Alpha is not named on it
    (its older waypoints would fit), bravo is once it has enough whole ones since."""
    rng = np.random.default_rng(14)
    alpha = drive((1000.0, 1000.0, 0.0), 300.0, 0.25)
    bravo = drive((1000.0, 1400.0, 0.3), 300.0, 0.0)
    swapped = camera_track(alpha, rng, 5.0)
    swapped[20:25] = np.nan
    swapped[25:] = camera_track(bravo, rng, 5.0)[25:]
    robots = {"alpha": odometry_of(alpha), "bravo": odometry_of(bravo)}
    assert fit_similarity(robots["alpha"][:20, :2], swapped[:20]).error_mm < 20.0

    result = identify({"t1": swapped}, robots, RULES)

    assert "alpha" not in result.matched
    assert result.matched["bravo"].track_id == "t1"
    assert math.dist(result.matched["bravo"].pose[:2], bravo[-1, :2]) < 15.0


def test_a_track_seen_whole_too_briefly_is_neither_a_match_nor_a_rival() -> None:
    rng = np.random.default_rng(12)
    alpha = drive((500.0, 1500.0, 0.2), 350.0, 0.1)
    glimpse = camera_track(alpha, rng, 5.0)
    glimpse[: Q - RULES.min_points + 1] = np.nan
    result = identify(
        {"t1": glimpse, "t2": camera_track(alpha, rng, 5.0)}, {"alpha": odometry_of(alpha)}, RULES
    )
    assert result.matched["alpha"].track_id == "t2"
    alone = identify({"t1": glimpse}, {"alpha": odometry_of(alpha)}, RULES)
    assert alone.matched == {}
    assert "no track seen whole" in alone.refused["alpha"]
