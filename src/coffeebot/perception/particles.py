"""The pose as a particle filter on the floor plan: seed 003's adaptive Monte Carlo localization.

A :class:`PoseFusion` like the Kalman filter, fed the same messages plus the raw ToF scans.
Each particle is a pose (x mm, y mm, heading rad) on the current floor:

* **motion**: seed 004's odometry steps, composed exactly and applied to every particle with
  random-walk noise (``along/lateral/heading/turn_sigma``) once per measurement, not per
  telemetry message;
* **measurements** as likelihoods: the ToF scan against the floor's likelihood field
  (:mod:`~coffeebot.perception.range_model`, after ``update_min_mm``/``update_min_deg`` of
  motion, as nav2 does), UWB fixes (a Gaussian with an outlier floor), a ceiling camera's
  pose fixes (a Gaussian in position and heading; one far from the cloud is not used), and
  optionally the angle and door modules' outputs;
* **resampling**: low variance, at a KLD-sampling count, when the effective sample size
  drops or when recovery asks for fresh particles;
* **recovery** (augmented MCL): when the scans' or the fixes' fit falls below its long-term
  level, a share of the resample is injected around the last UWB fix (or anywhere on the
  floor without one);
* **global localization**: without a prior, the first UWB fix seeds particles with every
  heading around it; after the elevator, the cloud is widened on the new floor's field.

The estimate is the weighted mean of the heaviest mode, and its covariance is the particles'
spread about it, so a cloud strung along a featureless hallway, or split in two, says so.
"""

from __future__ import annotations

import math
from collections.abc import Sequence

import numpy as np

from coffeebot.config import ParticleFilterConfig, StateConfig, TofConfig
from coffeebot.floorplan import Floor, FloorPlan
from coffeebot.messages import RangeScan
from coffeebot.perception.elevator_mask import ElevatorMask
from coffeebot.perception.fusion import CHI2_1DOF_999, OdometryStep, ParticleSummary
from coffeebot.perception.likelihood_field import LikelihoodField, field_for
from coffeebot.perception.range_model import RangeModel
from coffeebot.perception.recovery import RecoveryMonitor
from coffeebot.perception.resampling import (
    adaptive_count,
    effective_sample_size,
    low_variance_indices,
)
from coffeebot.perception.robot_mask import RobotMask

MODE_BIN_MM = 1000.0
MODE_BIN_RAD = math.radians(45.0)
"""Coarse bins that pick the heaviest mode of the cloud for the estimate."""
MODE_RADIUS_MM = 1500.0
MODE_RADIUS_RAD = math.radians(60.0)
MAX_HEADING_MARGIN_DEG = 30.0
"""The elevator mask widens each cone by three heading sigmas, up to this."""
FIELD_MARGIN_MM = 1000.0
"""The likelihood field reaches this far beyond the plan's walls; beyond, nothing is near."""
_RAD_TO_DEG = np.array([1.0, 1.0, math.degrees(1.0)])
_RAD_TO_DEG_COV = np.outer(_RAD_TO_DEG, _RAD_TO_DEG)
_RAD_TO_DEG_COV.flags.writeable = False
"""Takes a covariance of (x mm, y mm, heading rad) to one of (x mm, y mm, heading deg)."""


def wrap(angle: np.ndarray) -> np.ndarray:
    return np.mod(angle + math.pi, 2 * math.pi) - math.pi


class ParticlePoseFusion:
    """AMCL over (x, y, heading) on the plan's floors; see the module docstring."""

    def __init__(
        self,
        plan: FloorPlan,
        tof: TofConfig,
        cfg: StateConfig,
        *,
        clearance_mm: float = 250.0,
        seed: int = 0,
    ) -> None:
        """``clearance_mm``: how close the body centre can come to a wall (where global
        localization may put particles); ``seed``: the filter's own random generator."""
        self.plan = plan
        self.state_cfg = cfg
        self.cfg: ParticleFilterConfig = cfg.particles
        self.model = RangeModel(tof.sensors, tof.max_range_mm, self.cfg)
        self.elevator_mask = ElevatorMask(
            tof.sensors,
            self.cfg.elevator_margin_mm,
            self.cfg.elevator_blind_mm,
            float(tof.max_range_mm),
        )
        self.robot_mask = RobotMask(tof.sensors, self.cfg.robot_margin_mm)
        self.clearance_mm = clearance_mm
        self.rng, self._draw_rng = (
            np.random.default_rng(s) for s in np.random.SeedSequence(seed).spawn(2)
        )
        """The filter's noise, and a separate one for drawing the published cloud, so that
        how often the map asks does not change what the filter does."""
        self.level = cfg.initial_floor
        # Every floor's field now, not on arrival: building one takes ~0.6 s here (seconds
        # on the robot), which in the elevator would stall the event loop, control included.
        self._fields: dict[int, LikelihoodField] = {
            f.level: field_for(f, self.cfg.grid_mm, FIELD_MARGIN_MM) for f in plan.floors
        }
        self._free = {level: self._free_space(level) for level in self._fields}
        """Where the body fits on each floor: global localization and injection sample it."""
        self.particles = np.zeros((0, 3))
        self.log_w = np.zeros(0)
        self._pending = np.zeros(3)
        """Odometry not yet applied to the particles: x, y, heading in the frame of the pose
        they were last moved to."""
        self._pending_travel_mm = 0.0
        self._pending_turn_rad = 0.0
        self._scan_travel_mm = 0.0
        self._scan_turn_rad = 0.0
        self._scan_due = True
        self._last_fix: tuple[float, float] | None = None
        self.monitors = {
            "ranges": RecoveryMonitor(self.cfg.recovery_alpha_slow, self.cfg.recovery_alpha_fast),
            "uwb": RecoveryMonitor(self.cfg.recovery_alpha_slow, self.cfg.recovery_alpha_fast),
        }
        self.injected = 0
        """Particles injected by recovery since the start (for benchmarks and logs)."""
        self._estimate: tuple[np.ndarray, np.ndarray] | None = None
        self._weights: np.ndarray | None = None
        self._ess: tuple[np.ndarray, float] | None = None
        """The effective sample size and the weights it is of (:meth:`_sample_size`)."""

    # --- the floor ------------------------------------------------------------------------

    @property
    def floor(self) -> Floor:
        return self.plan.floor(self.level)

    @property
    def field(self) -> LikelihoodField:
        """The current floor's likelihood field."""
        return self.likelihood_field(self.level)

    def likelihood_field(self, level: int) -> LikelihoodField:
        """A floor's field (all are built with the filter)."""
        return self._fields[level]

    def free_space(self) -> np.ndarray:
        """Cell centres where the body fits on this floor, connected to the hallway: (k, 2)."""
        return self._free[self.level]

    def _free_space(self, level: int) -> np.ndarray:
        floor = self.plan.floor(level)
        hallway = floor.from_hallway(floor.hallway.length_mm / 2, 0.0)
        return self._fields[level].free_cells(self.clearance_mm, hallway)

    def change_floor(self, level: int) -> None:
        """The robot is on another floor (out of the elevator): the new floor's field, and a
        cloud widened around the estimate, since the ride's pose is not to be trusted."""
        if level == self.level or level not in {f.level for f in self.plan.floors}:
            return
        self.level = level
        if not self.initialised:
            return
        x, y, heading = self.pose()
        self._seed_gaussian(
            x, y, heading, self.cfg.relocalize_sigma_mm, self.cfg.relocalize_sigma_deg
        )

    # --- state ----------------------------------------------------------------------------

    @property
    def initialised(self) -> bool:
        return len(self.particles) > 0

    @property
    def weights(self) -> np.ndarray:
        """Normalised weights (cached until the next measurement)."""
        if self._weights is None:
            w = np.exp(self.log_w - self.log_w.max())
            self._weights = w / w.sum()
        return self._weights

    def _set(self, particles: np.ndarray) -> None:
        particles[:, 2] = wrap(particles[:, 2])
        self.particles = particles
        self.log_w = np.zeros(len(particles))
        self._weights = None
        self._estimate = None

    def _forget_motion(self) -> None:
        self._pending[:] = 0.0
        self._pending_travel_mm = self._pending_turn_rad = 0.0
        self._scan_travel_mm = self._scan_turn_rad = 0.0
        self._scan_due = True
        for monitor in self.monitors.values():
            monitor.reset()

    def _seed_gaussian(
        self, x: float, y: float, heading_deg: float, sigma_mm: float, sigma_deg: float
    ) -> None:
        n = self.cfg.max_particles
        cloud = np.column_stack(
            [
                self.rng.normal(x, sigma_mm, n),
                self.rng.normal(y, sigma_mm, n),
                self.rng.normal(math.radians(heading_deg), math.radians(sigma_deg), n),
            ]
        )
        self._set(cloud)
        self._forget_motion()

    def reset(
        self, x_mm: float, y_mm: float, heading_deg: float, sigma_mm: float, sigma_deg: float
    ) -> None:
        self._seed_gaussian(x_mm, y_mm, heading_deg, sigma_mm, sigma_deg)

    def localize_globally(self, around: tuple[float, float] | None = None) -> None:
        """Particles with every heading: around a UWB fix, or over the floor's free space."""
        n = self.cfg.max_particles
        self._set(self._random_poses(n, around, self.cfg.global_sigma_mm))
        self._forget_motion()

    def _random_poses(
        self, n: int, around: tuple[float, float] | None, sigma_mm: float
    ) -> np.ndarray:
        """``n`` poses with uniform headings, in free space: near ``around`` if given."""
        free = self.free_space()
        headings = self.rng.uniform(-math.pi, math.pi, n)
        if around is not None:
            xy = self.rng.normal(around, sigma_mm, (n, 2))
            if len(free):
                # Keep the body out of walls: each sample moves to a free cell near it.
                near = self.field.nearest(xy[:, 0], xy[:, 1]) >= self.clearance_mm
                for _ in range(5):
                    if near.all():
                        break
                    redo = ~near
                    xy[redo] = self.rng.normal(around, sigma_mm, (int(redo.sum()), 2))
                    near[redo] = self.field.nearest(xy[redo, 0], xy[redo, 1]) >= self.clearance_mm
        elif len(free):
            cells = free[self.rng.integers(len(free), size=n)]
            half = self.field.resolution_mm / 2
            xy = cells + self.rng.uniform(-half, half, (n, 2))
        else:
            # A floor with no room for the body: the grid is all there is.
            lo = self.field.origin
            hi = lo + self.field.resolution_mm * (np.array(self.field.shape) - 1)
            xy = self.rng.uniform(lo, hi, (n, 2))
        return np.column_stack([xy, headings])

    # --- motion ---------------------------------------------------------------------------

    def predict(self, step: OdometryStep) -> None:
        ds, dth = step.distance_mm, math.radians(step.heading_change_deg)
        if not (math.isfinite(ds) and math.isfinite(dth)):
            return
        a = step.axle_x_mm
        # The body turns about the driven axle, ``a`` ahead of the centre (as the EKF).
        bx = ds * math.cos(dth / 2) - a * (math.cos(dth) - 1.0)
        by = ds * math.sin(dth / 2) - a * math.sin(dth)
        c, s = math.cos(self._pending[2]), math.sin(self._pending[2])
        self._pending += (c * bx - s * by, s * bx + c * by, dth)
        self._pending_travel_mm += abs(ds)
        self._pending_turn_rad += abs(dth)
        self._scan_travel_mm += abs(ds)
        self._scan_turn_rad += abs(dth)

    def _apply_motion(self) -> None:
        """Move every particle by the pending odometry, with the motion noise it earned."""
        if not self.initialised or (self._pending_travel_mm == 0 and self._pending_turn_rad == 0):
            return
        cfg, n = self.cfg, len(self.particles)
        metres = self._pending_travel_mm / 1000.0
        along = self.rng.normal(0.0, cfg.along_sigma_mm * math.sqrt(metres), n)
        lateral = self.rng.normal(0.0, cfg.lateral_sigma_mm * math.sqrt(metres), n)
        sigma_heading = math.radians(
            math.hypot(
                cfg.heading_sigma_deg * math.sqrt(metres),
                cfg.turn_sigma_deg * math.sqrt(self._pending_turn_rad),
            )
        )
        dx, dy, dth = self._pending
        th = self.particles[:, 2]
        c, s = np.cos(th), np.sin(th)
        bx, by = dx + along, dy + lateral
        self.particles[:, 0] += c * bx - s * by
        self.particles[:, 1] += s * bx + c * by
        self.particles[:, 2] = wrap(th + dth + self.rng.normal(0.0, sigma_heading, n))
        self._pending[:] = 0.0
        self._pending_travel_mm = self._pending_turn_rad = 0.0
        self._estimate = None

    # --- measurements ---------------------------------------------------------------------

    def _weigh(self, log_likelihood: np.ndarray, fit: tuple[str, float] | None = None) -> None:
        """Fold one measurement into the weights, then resample if it is time. ``fit``: the
        recovery monitor it feeds (scans and fixes do; the optional extra sources do not)."""
        self.log_w = self.log_w + log_likelihood
        self.log_w -= self.log_w.max()
        self._weights = None
        self._estimate = None
        if fit is not None:
            source, value = fit
            self.monitors[source].update(value)
        inject = max(m.injection_probability for m in self.monitors.values())
        ess = self._sample_size()
        if inject > 0 or ess < self.cfg.resample_ess_fraction * len(self.particles):
            self._resample(inject)

    def _fit(self, log_fit: np.ndarray) -> float:
        """The weighted mean likelihood ratio: 1 when every particle explains it perfectly."""
        return float(np.dot(self.weights, np.exp(log_fit)))

    def update_ranges(
        self,
        scan: RangeScan,
        shut_doors: frozenset[str] = frozenset(),
        others: Sequence[np.ndarray] = (),
    ) -> bool:
        if not self.initialised:
            return False
        cfg = self.cfg
        moved = (
            self._scan_travel_mm >= cfg.update_min_mm
            or math.degrees(self._scan_turn_rad) >= cfg.update_min_deg
        )
        if not (moved or self._scan_due):
            return False
        x, y, heading = self.pose()
        if self.elevator_mask.blind(self.floor, x, y, heading, shut_doors):
            return False
        heading_margin = min(MAX_HEADING_MARGIN_DEG, 3.0 * self.sigmas()[2])
        robots = self.robot_mask.masked(scan, (x, y, heading), heading_margin, others)
        masked = (
            self.elevator_mask.masked(self.floor, scan, (x, y, heading), heading_margin, shut_doors)
            | robots
        )
        if masked:
            kept = [r for r in scan.readings if r.sensor not in masked]
            scan = scan.model_copy(update={"readings": kept})
        self._apply_motion()
        result = self.model.evaluate(self.field, scan, self.particles)
        if result.readings == 0:
            return False
        self._scan_travel_mm = self._scan_turn_rad = 0.0
        self._scan_due = False
        # A scan that saw another robot says little of whether the filter is lost.
        fit = None if robots else ("ranges", self._fit(result.log_fit))
        self._weigh(result.log_likelihood, fit)
        return True

    def update_position(self, x_mm: float, y_mm: float, sigma_mm: float) -> bool:
        if not (math.isfinite(x_mm) and math.isfinite(y_mm) and sigma_mm > 0):
            return False
        self._last_fix = (x_mm, y_mm)
        if not self.initialised:
            self.localize_globally((x_mm, y_mm))
        self._apply_motion()
        d2 = ((self.particles[:, 0] - x_mm) ** 2 + (self.particles[:, 1] - y_mm) ** 2) / (
            sigma_mm**2
        )
        eps = self.cfg.uwb_outlier_probability
        floor = eps * math.exp(-0.5 * self.state_cfg.uwb_gate_sigma**2)
        likelihood = (1.0 - eps) * np.exp(-0.5 * d2) + floor
        fit = float(np.dot(self.weights, likelihood)) / (1.0 - eps + floor)
        self._weigh(np.log(likelihood), ("uwb", fit))
        return True

    def _update_gaussian(self, innovation: np.ndarray, sigma: float) -> bool:
        """A scalar measurement: ``innovation`` per particle, a 1-sigma, a 99.9 % outlier floor."""
        if not (np.isfinite(innovation).all() and sigma > 0 and self.initialised):
            return False
        z2 = (innovation / sigma) ** 2
        self._weigh(np.log(np.exp(-0.5 * z2) + math.exp(-0.5 * CHI2_1DOF_999)))
        return True

    def update_heading(self, heading_deg: float, sigma_deg: float) -> bool:
        if not (math.isfinite(heading_deg) and self.initialised):
            return False
        self._apply_motion()
        innovation = wrap(math.radians(heading_deg) - self.particles[:, 2])
        return self._update_gaussian(innovation, math.radians(sigma_deg))

    def update_offset(self, direction_deg: float, offset_mm: float, sigma_mm: float) -> bool:
        if not (math.isfinite(direction_deg) and math.isfinite(offset_mm) and self.initialised):
            return False
        x, y, _ = self.pose()
        self._apply_motion()
        u = math.radians(direction_deg)
        measured = (x * math.cos(u) + y * math.sin(u)) + offset_mm
        along = self.particles[:, 0] * math.cos(u) + self.particles[:, 1] * math.sin(u)
        return self._update_gaussian(measured - along, sigma_mm)

    def update_pose_fix(
        self, x_mm: float, y_mm: float, heading_deg: float, sigma_mm: float, sigma_deg: float
    ) -> bool:
        """A whole pose measured from outside (a ceiling camera's fix).

        It seeds the particles when there are none, and is not used when it is more than
        ``camera_gate_sigma`` sigmas (the fix's and the cloud's together) from the cloud: one
        fix cannot tell a kidnap from a wrong match, and moving a robot that knows where it is
        metres away on a wrong one is the worse mistake. Otherwise it weighs the particles by
        a Gaussian in position and heading, with no outlier floor (the gate already judged
        the fix; a floor would let a fix much tighter than the cloud barely move it). The
        recovery monitors are not fed: such a fix fits the cloud poorly without the cloud
        being lost.
        """
        values = (x_mm, y_mm, heading_deg, sigma_mm, sigma_deg)
        if not (all(math.isfinite(v) for v in values) and sigma_mm > 0 and sigma_deg > 0):
            return False
        if not self.initialised:
            self.reset(*values)
            return True
        if self._far_from_cloud(*values):
            return False
        self._apply_motion()
        d2 = (self.particles[:, 0] - x_mm) ** 2 + (self.particles[:, 1] - y_mm) ** 2
        turn = wrap(math.radians(heading_deg) - self.particles[:, 2])
        self._weigh(-0.5 * (d2 / sigma_mm**2 + (turn / math.radians(sigma_deg)) ** 2))
        return True

    def _far_from_cloud(
        self, x_mm: float, y_mm: float, heading_deg: float, sigma_mm: float, sigma_deg: float
    ) -> bool:
        """Whether a pose is beyond ``camera_gate_sigma`` of the cloud: the position by its
        Mahalanobis distance (a cloud long along a hallway reaches further along it), the
        heading by its own."""
        limit = self.state_cfg.camera_gate_sigma
        x, y, heading = self.pose()
        cov = self.covariance()
        offset = np.array([x_mm - x, y_mm - y])
        combined = cov[:2, :2] + np.eye(2) * sigma_mm**2
        if float(offset @ np.linalg.solve(combined, offset)) > limit**2:
            return True
        turn = math.remainder(heading_deg - heading, 360.0)
        return turn**2 > limit**2 * (cov[2, 2] + sigma_deg**2)

    # --- resampling -----------------------------------------------------------------------

    def _resample(self, inject: float) -> None:
        cfg = self.cfg
        weights = self.weights
        n = adaptive_count(
            self.particles,
            weights,
            minimum=cfg.min_particles,
            maximum=cfg.max_particles,
            bin_mm=cfg.kld_bin_mm,
            bin_rad=math.radians(cfg.kld_bin_deg),
            error=cfg.kld_error,
            quantile=cfg.kld_quantile,
            rng=self.rng,
        )
        # Fresh particles need every heading: their share is of the most the filter may
        # hold, not of a converged count of a few hundred.
        fresh = round(inject * cfg.max_particles)
        kept = self.particles[
            low_variance_indices(weights, max(1, round((1 - inject) * n)), self.rng)
        ]
        if cfg.roughening > 0 and len(kept) > 1:
            spread = np.array([kept[:, 0].std(), kept[:, 1].std(), self._heading_spread(kept)])
            jitter = cfg.roughening * spread * len(kept) ** (-1.0 / 3.0)
            kept = kept + self.rng.normal(0.0, 1.0, kept.shape) * jitter
        if fresh:
            new = self._random_poses(fresh, self._last_fix, cfg.injection_sigma_mm)
            kept = np.vstack([kept, new])
            self.injected += fresh
            for monitor in self.monitors.values():
                monitor.reset()
        self._set(kept)

    @staticmethod
    def _heading_spread(particles: np.ndarray) -> float:
        mean = math.atan2(np.sin(particles[:, 2]).mean(), np.cos(particles[:, 2]).mean())
        return float(np.sqrt(np.mean(wrap(particles[:, 2] - mean) ** 2)))

    # --- the estimate ---------------------------------------------------------------------

    def _mode_estimate(self) -> tuple[np.ndarray, np.ndarray]:
        """(mean pose, 3x3 covariance in mm, mm, rad) of the heaviest mode; cached."""
        if self._estimate is not None:
            return self._estimate
        p, w = self.particles, self.weights
        mean = self._weighted_mean(p, w)
        delta = np.column_stack([p[:, 0] - mean[0], p[:, 1] - mean[1], wrap(p[:, 2] - mean[2])])
        if (np.abs(delta[:, :2]) <= MODE_RADIUS_MM).all() and (
            np.abs(delta[:, 2]) <= MODE_RADIUS_RAD
        ).all():
            # One compact cloud (tracking): its mean is the mode.
            self._estimate = (mean, (delta * w[:, None]).T @ delta)
            return self._estimate
        keys = (
            np.floor(p[:, 0] / MODE_BIN_MM).astype(np.int64) * 100_003
            + np.floor(p[:, 1] / MODE_BIN_MM).astype(np.int64)
        ) * 11 + np.floor(np.mod(p[:, 2], 2 * math.pi) / MODE_BIN_RAD).astype(np.int64)
        unique, inverse = np.unique(keys, return_inverse=True)
        heaviest = np.bincount(inverse, weights=w, minlength=len(unique)).argmax()
        seed = self._weighted_mean(p[inverse == heaviest], w[inverse == heaviest])
        near = (np.hypot(p[:, 0] - seed[0], p[:, 1] - seed[1]) <= MODE_RADIUS_MM) & (
            np.abs(wrap(p[:, 2] - seed[2])) <= MODE_RADIUS_RAD
        )
        mean = self._weighted_mean(p[near], w[near])
        # The spread of every particle about the estimate: honest when the cloud is split.
        delta = np.column_stack([p[:, 0] - mean[0], p[:, 1] - mean[1], wrap(p[:, 2] - mean[2])])
        cov = (delta * w[:, None]).T @ delta
        self._estimate = (mean, cov)
        return self._estimate

    @staticmethod
    def _weighted_mean(p: np.ndarray, w: np.ndarray) -> np.ndarray:
        w = w / w.sum()
        heading = math.atan2(float(np.dot(w, np.sin(p[:, 2]))), float(np.dot(w, np.cos(p[:, 2]))))
        return np.array([float(np.dot(w, p[:, 0])), float(np.dot(w, p[:, 1])), heading])

    def pose(self) -> tuple[float, float, float]:
        if not self.initialised:
            return 0.0, 0.0, 0.0
        mean, _ = self._mode_estimate()
        dx, dy, dth = self._pending
        c, s = math.cos(mean[2]), math.sin(mean[2])
        heading = math.remainder(mean[2] + dth, math.tau)
        return (
            float(mean[0] + c * dx - s * dy),
            float(mean[1] + s * dx + c * dy),
            math.degrees(heading),
        )

    def covariance(self) -> np.ndarray:
        """3x3 covariance of (x mm, y mm, heading deg)."""
        if not self.initialised:
            return np.diag([1e12, 1e12, 180.0**2])
        _, cov = self._mode_estimate()
        return cov * _RAD_TO_DEG_COV

    def sigmas(self) -> tuple[float, float, float]:
        d = np.sqrt(np.maximum(np.diag(self.covariance()), 0.0))
        return float(d[0]), float(d[1]), float(d[2])

    def summary(self) -> ParticleSummary:
        if not self.initialised:
            return ParticleSummary(0, 0.0)
        return ParticleSummary(len(self.particles), self._sample_size())

    def _sample_size(self) -> float:
        """The effective sample size of :attr:`weights`, computed once per set of weights:
        every published pose asks for it, and the weights change only with a measurement
        (a new array each time, never changed in place)."""
        weights = self.weights
        if self._ess is None or self._ess[0] is not weights:
            self._ess = (weights, effective_sample_size(weights))
        return self._ess[1]

    def cloud(self, points: int) -> np.ndarray | None:
        """Up to ``points`` particles drawn by weight, moved by the pending odometry:
        (k, 3) x mm, y mm, heading deg, for drawing."""
        if not self.initialised or points <= 0:
            return None
        pick = self.particles[low_variance_indices(self.weights, points, self._draw_rng)]
        dx, dy, dth = self._pending
        c, s = np.cos(pick[:, 2]), np.sin(pick[:, 2])
        return np.column_stack(
            [
                pick[:, 0] + c * dx - s * dy,
                pick[:, 1] + s * dx + c * dy,
                np.degrees(wrap(pick[:, 2] + dth)),
            ]
        )
