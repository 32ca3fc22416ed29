"""Which camera track is which robot, and where that robot is (seed 003, section IV.B).

A ceiling camera sees blobs, not robots. Each robot reports the path its odometry measured in
its own frame; the blob whose floor path the same motion explains, through a similarity
transform (rotation, scale, translation: eqs 1-6), is that robot, and the transform carries the
robot's odometry pose onto the floor. The seed takes the blob whose fit error (eq 7) is under
a threshold, and once placed a robot 2.5 m off that way. Here the fits go through an optimal
assignment instead, and a match stands only when nothing else explains the motion nearly as
well: a robot that stood still, a fit at the wrong scale or a close runner-up is refused,
because a robot sent to the wrong place is worse than one that waits for a better look.
Motion alone cannot tell apart two robots driving side by side the same way; where the
robots' own estimates of where they are (UWB, doors, walls) tell the candidates apart by
many of their sigmas, the estimate breaks the tie.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass
from typing import NamedTuple

import numpy as np
from pydantic import BaseModel, ConfigDict, Field, model_validator
from scipy.optimize import linear_sum_assignment


@dataclass(frozen=True)
class Similarity:
    """The seed's eq 4: floor = [[a0, -b0], [b0, a0]] @ odometry + (x0, y0), with the
    scale (eq 8), rotation (eq 9) and mean distance between the paths (eq 7) it left."""

    a0: float
    b0: float
    x0_mm: float
    y0_mm: float
    scale: float
    rotation_rad: float
    error_mm: float

    def to_floor(self, odometry: np.ndarray) -> np.ndarray:
        """Odometry points (..., 2) or poses (..., 3: x, y, heading) in the floor frame; a
        heading turns by the rotation alone, wrapped to [-pi, pi)."""
        values = np.asarray(odometry, dtype=float)
        if values.shape[-1] not in (2, 3):
            raise ValueError(f"expected points (..., 2) or poses (..., 3), got {values.shape}")
        linear = np.array([[self.a0, -self.b0], [self.b0, self.a0]])
        mapped = values.copy()
        mapped[..., :2] = values[..., :2] @ linear.T + np.array([self.x0_mm, self.y0_mm])
        if values.shape[-1] == 3:
            mapped[..., 2] = _wrap(values[..., 2] + self.rotation_rad)
        return mapped


def fit_similarity(odometry: np.ndarray, seen: np.ndarray) -> Similarity:
    """The seed's eq 6 on q time-aligned waypoints (q, 2) each: odometry frame and floor (mm).

    Least squares through the pseudo-inverse, so a degenerate path (a robot that stood still)
    still gives an answer, a meaningless one: :func:`identify` checks the motion first.
    """
    odometry = np.asarray(odometry, dtype=float)
    seen = np.asarray(seen, dtype=float)
    if odometry.ndim != 2 or odometry.shape[1] != 2 or seen.shape != odometry.shape:
        raise ValueError(
            f"expected two (q, 2) paths of the same q, got {odometry.shape} and {seen.shape}"
        )
    if odometry.shape[0] < 2:
        raise ValueError("a similarity needs at least two waypoints")
    x, y = odometry[:, 0], odometry[:, 1]
    ones, zeros = np.ones_like(x), np.zeros_like(x)
    design = np.block(
        [
            [x[:, None], -y[:, None], ones[:, None], zeros[:, None]],
            [y[:, None], x[:, None], zeros[:, None], ones[:, None]],
        ]
    )
    parameters = np.linalg.pinv(design) @ np.concatenate([seen[:, 0], seen[:, 1]])
    a0, b0, x0, y0 = parameters
    projected = (design @ parameters).reshape(2, -1).T
    return Similarity(
        a0=float(a0),
        b0=float(b0),
        x0_mm=float(x0),
        y0_mm=float(y0),
        scale=math.hypot(a0, b0),
        rotation_rad=math.atan2(b0, a0),
        error_mm=float(np.mean(np.hypot(*(projected - seen).T))),
    )


class IdentifyRules(BaseModel):
    """When a fit is good enough to name a robot. The defaults suit the seed's camera (12.5 mm
    pixels from 4 m) and a robot's odometry over a few metres."""

    model_config = ConfigDict(extra="forbid", frozen=True, allow_inf_nan=False)

    gate_mm: float = Field(
        150.0,
        gt=0,
        description="largest fit error (eq 7) a match may have: blob centroids jitter by a few "
        "12.5 mm pixels and odometry drifts 1-3 % over a few metres, so a right match stays "
        "well under it, while it is a fraction of the 2.5 m the seed's wrong match was off",
    )
    margin: float = Field(
        2.0,
        ge=1,
        description="a match stands only if every other fit at the expected scale of its "
        "robot or its track is more than this many times worse. A right fit's error is mostly "
        "camera noise (12 mm for 10 mm of jitter); a runner-up within 2x of it could be the right "
        "one seen through worse noise or a half-hidden blob, one past it misfits by as much "
        "again as all the noise",
    )
    min_motion_mm: float = Field(
        150.0,
        ge=0,
        description="how far the robot's waypoints must spread from their mean. The spread, not "
        "the path length, fixes the fit's rotation: a robot shuffling on the spot adds "
        "length but no spread, and a robot that stood still fits any standing blob. 150 mm "
        "(a straight 300 mm) over 20 waypoints turns 10 mm of blob jitter into about two "
        "degrees of heading, which the fix's heading sigma says; it names a robot at "
        "150-240 mm/s within 3 s of moving in view (300 mm named 29 of 64 such runs in "
        "time, 150 mm 62 of 64, with no wrong match in either benchmark run)",
    )
    scale_tolerance: float = Field(
        0.1,
        ge=0,
        description="how far the fit's scale may stray from expected_scale, as a fraction of "
        "it: odometry's scale error (wheel wear, 1-3 %) and the camera's calibration fit in "
        "10 %, a blob read on the wrong plane (25 % for an 800 mm top under a 4 m camera) "
        "or a walker keeping pace at another speed does not",
    )
    expected_scale: float = Field(
        1.0,
        gt=0,
        description="floor mm per odometry mm: 1.0 for positions of the robot's footprint; "
        "height / (height - top) for its top read on the floor's homography",
    )
    max_speed_mm_s: float = Field(
        1500.0,
        gt=0,
        description="a track that moves faster than this between two frames it saw whole is "
        "no robot's path over that window (a blob that split or merged with another, what "
        "was left when a cart went): 1.5 times the fastest robot, far above the jitter",
    )
    min_points: int = Field(
        10,
        ge=3,
        description="waypoints a fit needs where the track saw the whole object (a track's "
        "NaN rows, a blob cut by the image's border, are left out of its fits): through a "
        "few points almost any path fits",
    )
    estimate_agrees_sigma: float = Field(
        4.0,
        gt=0,
        description="a fit agrees with the robot's own estimate when it puts the robot within "
        "this many of the estimate's sigmas (Mahalanobis). The fused estimate's own error "
        "in simulated deliveries stayed within 4.0 of its claimed sigmas (p99 2.8)",
    )
    estimate_refutes_sigma: float = Field(
        10.0,
        gt=0,
        description="a fit the robot's own estimate refutes puts it more than this many "
        "sigmas away: only a rival refuted by it is set aside, and only for a match the "
        "estimate agrees with. Robots side by side in a hallway are 500 mm or more apart, "
        "25 of a localized robot's 20 mm sigmas",
    )
    estimate_sigma_floor_mm: float = Field(
        30.0,
        ge=0,
        description="added to the estimate's sigma (in quadrature) in both tests: the fit's "
        "own error at the estimate's moment and the estimate's lag behind the robot",
    )

    @model_validator(mode="after")
    def _refutes_beyond_agrees(self) -> IdentifyRules:
        if self.estimate_refutes_sigma <= self.estimate_agrees_sigma:
            raise ValueError(
                "estimate_refutes_sigma must be larger than estimate_agrees_sigma: a fit "
                "cannot both agree with the estimate and be refuted by it"
            )
        return self


@dataclass(frozen=True)
class Estimate:
    """Where a robot's own estimate put it at one moment: the point of its odometry path at
    that moment (odometry frame, mm), and the floor position (mm) with its covariance (mm²).
    A fit that carries the first onto the second is where the robot believes it is."""

    odometry_xy: tuple[float, float]
    floor_xy: tuple[float, float]
    covariance_mm2: tuple[tuple[float, float], tuple[float, float]]

    def sigmas_from(self, similarity: Similarity, floor_mm: float) -> float:
        """How many of its sigmas (Mahalanobis, its covariance widened by ``floor_mm`` on
        each axis) the estimate is from where ``similarity`` puts the robot."""
        placed = similarity.to_floor(np.array(self.odometry_xy))
        offset = placed - np.array(self.floor_xy)
        covariance = np.array(self.covariance_mm2) + floor_mm**2 * np.eye(2)
        return float(math.sqrt(max(0.0, offset @ np.linalg.solve(covariance, offset))))


class FloorPose(NamedTuple):
    """Where a robot is on the floor frame the tracks are in."""

    x_mm: float
    y_mm: float
    heading_rad: float


@dataclass(frozen=True)
class Match:
    """A robot named on a camera track, and its pose now (its last waypoint's) on the floor."""

    track_id: str
    similarity: Similarity
    pose: FloorPose


@dataclass(frozen=True)
class Identification:
    """Every robot is either matched or refused with a reason; every track not matched to a
    robot (people, obstacles, or robots that could not be told apart) is unmatched."""

    matched: dict[str, Match]
    refused: dict[str, str]
    unmatched_tracks: list[str]


def identify(
    tracks: Mapping[str, np.ndarray],
    robots: Mapping[str, np.ndarray],
    rules: IdentifyRules,
    estimates: Mapping[str, Estimate] | None = None,
) -> Identification:
    """Match camera tracks (q, 2: floor mm) to robots' odometry (q, 3: x mm, y mm, heading
    rad), all resampled to the same q timestamps; ``estimates``: where robots' own estimates
    put them (a robot without one, such as one not localized, is named by motion alone).

    A (robot, track) pair is plausible when the robot moved enough and the fit's scale is as
    expected, admissible when its error is also within the gate. The assignment minimises the
    total error over admissible pairs, those the robot's estimate agrees with first; an
    assigned pair is then refused if another fit of the same robot or the same track at the
    expected scale is within ``margin`` times its error. Rivals may be just outside the gate:
    a fit at 160 mm is no less a rival of one at 140 mm for it. Nor need a rival robot have
    moved enough to be named: one that crept 290 mm along a track may well be the one on it.
    A rival is set aside only when the robot's estimate agrees with the assigned pair and the
    estimate of the robot in the rival pair refutes that pair: an estimate never names a
    robot that motion does not, and a lost robot's estimate, which agrees with nothing,
    settles nothing.
    """
    _check_paths(tracks, robots)
    seen = _pieces({track_id: np.asarray(path, dtype=float) for track_id, path in tracks.items()})
    odometry = {robot_id: np.asarray(path, dtype=float) for robot_id, path in robots.items()}
    robot_ids, track_ids = list(odometry), list(seen)
    whole = {t: ~np.isnan(path).any(axis=1) for t, path in seen.items()}
    fits = [
        [_fit_where_seen(odometry[r][:, :2], seen[t], whole[t], rules) for t in track_ids]
        for r in robot_ids
    ]
    errors = np.array(
        [[math.inf if fit is None else fit.error_mm for fit in row] for row in fits]
    ).reshape(len(robot_ids), len(track_ids))
    scales = np.array(
        [[math.nan if fit is None else fit.scale for fit in row] for row in fits]
    ).reshape(errors.shape)
    # Moved enough over the waypoints the pair's fit uses (those the track saw whole).
    moved = np.array(
        [
            [
                fits[i][j] is not None
                and _spread_mm(odometry[r][whole[t], :2]) >= rules.min_motion_mm
                for j, t in enumerate(track_ids)
            ]
            for i, r in enumerate(robot_ids)
        ],
        dtype=bool,
    ).reshape(errors.shape)
    spreads = np.array([_spread_mm(odometry[r][:, :2]) for r in robot_ids]).reshape(-1, 1)
    scale_ok = np.abs(scales / rules.expected_scale - 1.0) <= rules.scale_tolerance
    plausible = moved & scale_ok
    # Named only on a track that sees its object whole now: one whose newest blob is cut by
    # the border (or merged there) may follow something else than the waypoints it was fitted
    # on. It still rivals, as does what a track followed before its last cut (_pieces).
    whole_now = np.array([bool(whole[t][-1]) if len(whole[t]) else False for t in track_ids])
    within_gate = plausible & (errors <= rules.gate_mm)
    admissible = within_gate & whole_now.reshape(1, -1)
    fits_but_cut = within_gate & ~admissible
    agrees, refutes = _against_estimates(fits, robot_ids, estimates or {}, rules)
    has_estimate = np.array([r in (estimates or {}) for r in robot_ids]).reshape(-1, 1)

    # Each tier costs more than any sum of the tier below, so no assignment trades a match
    # for a cheaper one, nor one its robot's estimate agrees with for a better fit.
    worst = float(errors[admissible].max()) if admissible.any() else 0.0
    disagreeing_cost = (worst + 1.0) * (min(errors.shape) + 1)
    inadmissible_cost = (worst + disagreeing_cost + 1.0) * (min(errors.shape) + 1)
    costs = np.where(has_estimate & ~agrees, errors + disagreeing_cost, errors)
    rows, cols = linear_sum_assignment(np.where(admissible, costs, inadmissible_cost))
    assigned = {int(i): int(j) for i, j in zip(rows, cols, strict=True) if admissible[i, j]}

    matched: dict[str, Match] = {}
    refused: dict[str, str] = {}
    for i, robot_id in enumerate(robot_ids):
        if spreads[i, 0] < rules.min_motion_mm:
            refused[robot_id] = (
                f"did not move enough ({spreads[i, 0]:.0f} mm < {rules.min_motion_mm:.0f} mm)"
            )
        elif i not in assigned and not admissible[i].any() and fits_but_cut[i].any():
            names = ", ".join(track_ids[j] for j in _indices(fits_but_cut[i]))
            refused[robot_id] = f"its track is cut by the image's border now: {names}"
        elif i not in assigned:
            refused[robot_id] = _why_unassigned(
                i, errors, admissible, assigned, robot_ids, track_ids, rules
            )
        else:
            j = assigned[i]
            # A fit its robot's estimate refutes is no rival of a pair the estimate agrees with.
            rivals = scale_ok & ~(refutes & agrees[i, j])
            ambiguity = _ambiguity(i, j, errors, rivals, robot_ids, track_ids, rules.margin)
            if ambiguity:
                refused[robot_id] = ambiguity
            else:
                similarity = fits[i][j]
                assert similarity is not None  # an admissible pair has a fit
                pose = similarity.to_floor(odometry[robot_id][-1])
                matched[robot_id] = Match(track_ids[j], similarity, FloorPose(*map(float, pose)))
    taken = {match.track_id for match in matched.values()}
    return Identification(matched, refused, [t for t in tracks if t not in taken])


EARLIER = " (before its blob was cut)"
"""Appended to a track's id for what it followed before its last cut stretch."""


def _pieces(tracks: dict[str, np.ndarray]) -> dict[str, np.ndarray]:
    """Each track from its last cut stretch on, under its own id, and what it followed before
    that as a rival only, under the id with ``EARLIER``. While its blob was cut by the border
    (its NaN rows) the track may have gone on with something else: two robots merged at the
    border and parted with their tracks swapped, and the first was named on the second's
    track from its own older waypoints."""
    pieces: dict[str, np.ndarray] = {}
    for track_id, path in tracks.items():
        cut = np.isnan(path).any(axis=1)
        seen_whole = np.flatnonzero(~cut)
        gaps = np.flatnonzero(cut)
        gaps = gaps[gaps > seen_whole[0]] if seen_whole.size else gaps[:0]
        if not gaps.size or cut[-1]:
            pieces[track_id] = path  # cut now: a rival only, as a whole (see identify)
            continue
        after, before = path.copy(), path.copy()
        after[: gaps[-1] + 1] = np.nan
        before[gaps[-1] :] = np.nan
        pieces[track_id] = after
        pieces[track_id + EARLIER] = before
    return pieces


def _fit_where_seen(
    odometry: np.ndarray, seen: np.ndarray, whole: np.ndarray, rules: IdentifyRules
) -> Similarity | None:
    """The fit over the waypoints where the track saw the whole object; None with fewer
    than ``rules.min_points`` of them (no fit, and no rival either)."""
    if whole.sum() < rules.min_points:
        return None
    return fit_similarity(odometry[whole], seen[whole])


def _against_estimates(
    fits: list[list[Similarity | None]],
    robot_ids: list[str],
    estimates: Mapping[str, Estimate],
    rules: IdentifyRules,
) -> tuple[np.ndarray, np.ndarray]:
    """Which fits the robots' own estimates agree with and which they refute (robots by
    tracks; both False where a robot has no estimate or a pair no fit)."""
    sigmas = np.array(
        [
            [
                math.nan
                if fit is None or robot not in estimates
                else estimates[robot].sigmas_from(fit, rules.estimate_sigma_floor_mm)
                for fit in row
            ]
            for robot, row in zip(robot_ids, fits, strict=True)
        ]
    ).reshape(len(fits), len(fits[0]) if fits else 0)
    with np.errstate(invalid="ignore"):
        return sigmas <= rules.estimate_agrees_sigma, sigmas > rules.estimate_refutes_sigma


def _check_paths(tracks: Mapping[str, np.ndarray], robots: Mapping[str, np.ndarray]) -> None:
    """Every path's shape, and one q for all: fits over unequal spans are not comparable, and
    silently trimming would hide a resampling bug."""
    for kind, paths, width in (("track", tracks, 2), ("robot", robots, 3)):
        for name, path in paths.items():
            if np.ndim(path) != 2 or np.shape(path)[1] != width:
                raise ValueError(f"{kind} {name!r} must be (q, {width}), got {np.shape(path)}")
    lengths = {
        f"{kind} {name!r}": len(path)
        for kind, paths in (("track", tracks), ("robot", robots))
        for name, path in paths.items()
    }
    if len(set(lengths.values())) > 1:
        listed = ", ".join(f"{name}: {length}" for name, length in lengths.items())
        raise ValueError(f"paths must share the same q timestamps, got {listed}")


def _spread_mm(points: np.ndarray) -> float:
    """Largest distance of a waypoint from the waypoints' mean."""
    return float(np.max(np.hypot(*(points - points.mean(axis=0)).T)))


def _why_unassigned(
    robot: int,
    errors: np.ndarray,
    admissible: np.ndarray,
    assigned: dict[int, int],
    robot_ids: list[str],
    track_ids: list[str],
    rules: IdentifyRules,
) -> str:
    """Why a robot that moved got no track: the tracks it fits went to robots fitting them
    better, or none fits at all (then the closest, to tell a bad camera from a missing blob)."""
    if admissible[robot].any():
        owners = {j: i for i, j in assigned.items()}
        taken = [
            f"{track_ids[j]} (robot {robot_ids[owners[j]]})"
            for j in _indices(admissible[robot])
            if j in owners
        ]
        return "its fitting tracks fit other robots better: " + ", ".join(taken)
    reason = (
        f"no track fits within {rules.gate_mm:.0f} mm at scale "
        f"{rules.expected_scale:.2f} ± {rules.scale_tolerance:.0%}"
    )
    if errors.shape[1] == 0:
        return reason + " (no tracks)"
    best = int(np.argmin(errors[robot]))
    if not math.isfinite(errors[robot, best]):
        return reason + f" (no track seen whole over {rules.min_points} waypoints)"
    return reason + f" (closest: {track_ids[best]} at {errors[robot, best]:.0f} mm)"


def _ambiguity(
    robot: int,
    track: int,
    errors: np.ndarray,
    can_rival: np.ndarray,
    robot_ids: list[str],
    track_ids: list[str],
    margin: float,
) -> str:
    """Why the assigned pair is ambiguous, or "" if it is not: a pair ``can_rival`` allows
    that shares its robot or its track and fits within ``margin`` times its error (at or
    below counts as close, so two perfect, zero-error fits are ambiguous too)."""
    bound = margin * errors[robot, track]
    rival_tracks = [j for j in _indices(can_rival[robot] & (errors[robot] <= bound)) if j != track]
    if rival_tracks:
        names = " and ".join(track_ids[j] for j in [track, *rival_tracks])
        return f"ambiguous: tracks {names} fit within {margin:g}x"
    rival_robots = [
        i for i in _indices(can_rival[:, track] & (errors[:, track] <= bound)) if i != robot
    ]
    if rival_robots:
        names = " and ".join(robot_ids[i] for i in [robot, *rival_robots])
        return f"ambiguous: robots {names} fit track {track_ids[track]} within {margin:g}x"
    return ""


def _indices(mask: np.ndarray) -> list[int]:
    return [int(index) for index in np.flatnonzero(mask)]


def _wrap(angle: np.ndarray) -> np.ndarray:
    return (angle + math.pi) % (2 * math.pi) - math.pi
