"""The VL53L1X as the world sees it: what one ranging's photons say, and what the chip makes
of them.

The real chip does not report the nearest thing in its cone. Its single-photon detectors
integrate every photon that comes back through the lens during the timing budget, and the
firmware reports one distance: the signal-weighted mean of the paths those photons took (ST:
it "averages all the photon times it gets back"; there is no multi-target histogram on this
part). Near and bright surfaces weigh more, since the return of a surface falls with the
square of its distance, rises with its reflectance and falls with the incidence angle. So a
chair leg in front of a wall reads somewhere between the two, pulled towards the wall, and a
thin dark thing far away is not seen at all. This module models that (``docs/sensor-model.md``
gives each fact and its source):

* **The cone** is the lens imaging the 16 x 16 SPAD array: a region of interest (ROI) of
  ``width x height`` SPADs around a centre SPAD (ST's numbering) looks at a box of directions
  ``spad_pitch_deg`` per SPAD, blurred by the optics (``blur_deg``) and weighted by the
  emitter's beam (``emitter_sigma_deg``), so the response is strongest in the middle. The
  three numbers are fitted so that the full array gives the datasheet's 27 degree field of
  view and the smallest 4 x 4 ROI 15 degrees, a field of view being the full angle within
  which a target returns at least a tenth of the signal it returns on the axis.
* **The returns** are sampled on a dense grid of directions (``azimuth_step_deg`` x
  ``elevation_step_deg``) out to ``reach_deg``. Walls and box faces are hit by each direction;
  poles and legs, which can be thinner than a grid step, cover a computed fraction of each
  azimuth column, so a chair leg's share of the signal grows smoothly as it comes closer
  instead of jumping between grid lines. Each sample's signal is
  ``response x reflectance x cos(incidence) / distance^2``.
* **The chip's answer** (:func:`range_once`) comes from the summed signal, the ambient light
  and the spread of the returns: a shot-noise sigma that grows with ambient light and falls
  with signal and timing budget, widened when the returns spread over a depth comparable to
  the pulse (a blend of a near and a far surface reports a larger sigma), a short bias up
  close, and the status from the chip's own thresholds (minimum signal rate, sigma limit) and
  the distance mode's range. Under a bad status the distance register still holds a number,
  often garbage.

The chip model (``sim/i2c.py``) reads its ROI, thresholds, mode and budget from its registers
and asks the world for the returns of that ROI; benchmarks and tests call :meth:`World.scan`
with a :class:`RangingSetup`, which goes through the same :func:`range_once`.
"""

from __future__ import annotations

import functools
import math
from collections.abc import Sequence
from typing import NamedTuple

import numpy as np
from pydantic import BaseModel, ConfigDict, Field
from scipy.special import ndtr

from coffeebot.config import TofConfig
from coffeebot.hardware.vl53l1x import FULL_ROI, MIN_RANGE_MM, SPADS, SpadRoi
from coffeebot.messages import RangeReading, ReadingStatus
from coffeebot.sim.world.cast import first_surfaces, poles_in_view, visible
from coffeebot.sim.world.geometry import Surfaces

_EPS = 1e-6


class ConeOptics(BaseModel):
    """The lens, the emitter and the light: what decides which returns a ranging collects."""

    model_config = ConfigDict(frozen=True, extra="forbid")

    spad_pitch_deg: float = Field(1.25, gt=0, description="field of view per SPAD column")
    blur_deg: float = Field(3.3, gt=0, description="optical blur of a SPAD's view (sigma)")
    emitter_sigma_deg: float = Field(15.0, gt=0, description="the emitter's beam (sigma)")
    azimuth_step_deg: float = Field(1.25, gt=0)
    elevation_step_deg: float = Field(2.5, gt=0)
    reach_deg: float = Field(
        18.0, gt=0, description="directions cast from the axis; the response is < 1 % beyond"
    )
    signal_mcps: float = Field(
        15.4,
        gt=0,
        description="signal rate of a perfect white (R = 1) wall square-on at 1 m filling the "
        "full ROI: with the 1 Mcps minimum, an 88 % target is seen to 3.6 m in the dark and a "
        "17 % one to ~1.6 m (the datasheet's long-mode figures)",
    )
    ambient_mcps: float = Field(
        0.001,
        ge=0,
        description="ambient count rate on the full ROI: office lighting (LEDs and "
        "fluorescent tubes emit almost nothing at 940 nm, the register reads 0); strong "
        "sunlight is ~40",
    )
    floor_reflectance: float = Field(
        0.3, ge=0, le=1, description="linoleum or carpet; met at grazing angles, so weak"
    )
    max_path_mm: float = Field(
        7000.0, gt=0, description="surfaces further away return too little to matter"
    )


class RangingNoise(BaseModel):
    """The chip's noise and sigma estimate, fitted to the published figures."""

    model_config = ConfigDict(frozen=True, extra="forbid")

    shot_mm: float = Field(
        6.7,
        ge=0,
        description="sigma = shot_mm * sqrt(S + k A) / S / sqrt(budget / 100 ms), S and A in "
        "Mcps: a table at 415 mm reads +/-1.3 mm",
    )
    ambient_weight_long: float = Field(
        3365.0,
        ge=0,
        description="k in long mode: ambient photons arrive over the whole window, signal "
        "ones within a pulse; with 40 Mcps of sunlight a white target is lost at ~0.7 m",
    )
    ambient_weight_short: float = Field(
        840.0, ge=0, description="k in short mode, which ST gives better ambient immunity"
    )
    pulse_mm: float = Field(
        300.0,
        gt=0,
        description="effective pulse width as range (~2 ns): returns spread over a depth like "
        "this widen the pulse the chip times, so its sigma estimate grows",
    )
    near_bias_mm: float = Field(
        -15.0, description="reads short up close (a hand at 100-200 mm: -8 to -20 mm)"
    )
    near_bias_until_mm: float = Field(450.0, gt=0)
    near_bias_fade_mm: float = Field(550.0, gt=0, description="gone this much further out")


class RangingSetup(NamedTuple):
    """What the chip's registers say about one ranging."""

    max_range_mm: float = 4000.0
    """The distance mode's valid phase range: long 4 m, short 1.3 m."""
    timing_budget_ms: float = 20.0
    sigma_limit_mm: float = 90.0
    """RANGE_CONFIG__SIGMA_THRESH (ULD default 90 mm)."""
    min_signal_mcps: float = 1.0
    """RANGE_CONFIG__MIN_COUNT_RATE_RTN_LIMIT_MCPS (ULD default ~1 Mcps)."""
    short_mode: bool = False


DEFAULT_SETUP = RangingSetup()
"""Long mode, a 20 ms budget and the ULD's default thresholds (what ST's figures use)."""


def robot_setup(tof: TofConfig) -> RangingSetup:
    """How the ToF poller sets the chips up from the robot description."""
    short = tof.distance_mode == "short"
    return RangingSetup(
        max_range_mm=1300.0 if short else 4000.0,
        timing_budget_ms=tof.timing_budget_ms,
        sigma_limit_mm=tof.sigma_limit_mm,
        min_signal_mcps=tof.min_signal_mcps,
        short_mode=short,
    )


class Returns(NamedTuple):
    """What came back during one ranging, before the chip judges it."""

    signal_mcps: float
    ambient_mcps: float
    mean_mm: float
    """Signal-weighted mean path length; nan when nothing returned."""
    spread_mm: float
    """Signal-weighted standard deviation of the path lengths (a blend's depth)."""
    spads: int


class ToFReading(NamedTuple):
    """One ranging as the result registers hold it."""

    status: ReadingStatus
    distance_mm: int
    signal_mcps: float = 0.0
    ambient_mcps: float = 0.0
    sigma_mm: float = 0.0
    spads: int = SPADS * SPADS


def as_range_reading(sensor: int, reading: ToFReading) -> RangeReading:
    """A world ranging as the ToF poller publishes it: a distance only when valid."""
    valid = reading.status is ReadingStatus.VALID
    return RangeReading(
        sensor=sensor,
        status=reading.status,
        distance_mm=reading.distance_mm if valid else None,
        signal_rate_mcps=reading.signal_mcps,
        ambient_rate_mcps=reading.ambient_mcps,
        sigma_mm=reading.sigma_mm,
    )


class SensorMount(BaseModel):
    """Where a sensor sits on the body: robot frame (x forward, y left), yaw CCW from +x."""

    model_config = ConfigDict(frozen=True, extra="ignore")

    x_mm: float
    y_mm: float
    yaw_deg: float
    height_mm: float = Field(250.0, gt=0)
    fov_deg: float = Field(
        27.0, ge=15, le=27, description="nominal cone of the configured ROI (ground truth)"
    )


def flat_target(
    distance_mm: float | None,
    optics: ConeOptics,
    roi: SpadRoi = FULL_ROI,
    reflectance: float = 0.88,
) -> Returns:
    """The returns of a white card square-on filling the cone (hand-made chip tests); no
    target at all for ``None``."""
    share = _response_share(optics, roi)
    ambient = optics.ambient_mcps * share
    if distance_mm is None or distance_mm <= 0:
        return Returns(0.0, ambient, math.nan, 0.0, roi.spad_count)
    signal = optics.signal_mcps * reflectance * share / (distance_mm / 1000.0) ** 2
    return Returns(signal, ambient, float(distance_mm), 0.0, roi.spad_count)


def range_once(
    returns: Returns,
    setup: RangingSetup,
    noise: RangingNoise | None,
    rng: np.random.Generator,
) -> ToFReading:
    """The chip's answer to ``returns``; ``noise`` None: exact (no shot noise, no bias)."""
    s, a = returns.signal_mcps, returns.ambient_mcps
    if s <= 0.0:
        garbage = int(rng.uniform(0, setup.max_range_mm))
        return ToFReading(ReadingStatus.SIGNAL_FAIL, garbage, 0.0, a, 16383.75, returns.spads)
    shot = 0.0
    distance = returns.mean_mm
    if noise is not None:
        k = noise.ambient_weight_short if setup.short_mode else noise.ambient_weight_long
        budget = math.sqrt(setup.timing_budget_ms / 100.0)
        shot = noise.shot_mm * math.sqrt(s + k * a) / s / budget
        distance += _near_bias(noise, distance) + shot * rng.standard_normal()
    spread = returns.spread_mm / noise.pulse_mm if noise is not None else 0.0
    sigma = min(shot * math.sqrt(1.0 + spread * spread), 16383.75)
    reported = max(0, min(0xFFFF, round(distance)))
    if s < setup.min_signal_mcps:
        status = ReadingStatus.SIGNAL_FAIL
    elif distance > setup.max_range_mm:
        status = ReadingStatus.OUT_OF_BOUNDS
    elif sigma > setup.sigma_limit_mm:
        status = ReadingStatus.SIGMA_FAIL
    elif distance < MIN_RANGE_MM:
        status = ReadingStatus.TOO_CLOSE
    else:
        status = ReadingStatus.VALID
    return ToFReading(status, reported, s, a, sigma, returns.spads)


def _near_bias(noise: RangingNoise, distance_mm: float) -> float:
    fade = (distance_mm - noise.near_bias_until_mm) / noise.near_bias_fade_mm
    return noise.near_bias_mm * min(1.0, max(0.0, 1.0 - fade))


def _box_response(u: np.ndarray, lo: float, hi: float, blur: float) -> np.ndarray:
    """A box of directions [lo, hi] (deg) seen through a Gaussian blur."""
    return ndtr((u - lo) / blur) - ndtr((u - hi) / blur)


def roi_response(
    optics: ConeOptics, roi: SpadRoi, az_deg: np.ndarray, el_deg: np.ndarray
) -> np.ndarray:
    """Response (A, E) of ``roi`` at azimuth/elevation offsets from the optical axis."""
    (c0, c1), (r0, r1) = roi.spans()
    p, b = optics.spad_pitch_deg, optics.blur_deg
    half = SPADS / 2
    x = _box_response(az_deg, (half - c1) * p, (half - c0) * p, b)
    y = _box_response(el_deg, (r0 - half) * p, (r1 - half) * p, b)
    spread = 2 * optics.emitter_sigma_deg**2
    emitter = np.exp(-(az_deg[:, None] ** 2 + el_deg[None, :] ** 2) / spread)
    return x[:, None] * y[None, :] * emitter


@functools.cache
def _grid(optics: ConeOptics) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Azimuth offsets (A,), elevation offsets (E,) in degrees and the (A, E) mask of the
    directions within ``reach_deg`` of the axis."""
    n_az = math.ceil(optics.reach_deg / optics.azimuth_step_deg)
    n_el = math.ceil(optics.reach_deg / optics.elevation_step_deg)
    az = np.arange(-n_az, n_az + 1) * optics.azimuth_step_deg
    el = np.arange(-n_el, n_el + 1) * optics.elevation_step_deg
    mask = az[:, None] ** 2 + el[None, :] ** 2 <= optics.reach_deg**2 + _EPS
    return az, el, mask


@functools.cache
def roi_weights(optics: ConeOptics, roi: SpadRoi) -> np.ndarray:
    """Per-direction weights (A, E) of ``roi``, scaled so the full ROI's sum to 1 (a smaller
    ROI collects less of the same light)."""
    az, el, mask = _grid(optics)
    solid_angle = np.where(mask, np.cos(np.radians(el))[None, :], 0.0)
    full = (roi_response(optics, FULL_ROI, az, el) * solid_angle).sum()
    return roi_response(optics, roi, az, el) * solid_angle / full


def _response_share(optics: ConeOptics, roi: SpadRoi) -> float:
    return float(roi_weights(optics, roi).sum())


def field_of_view_deg(optics: ConeOptics, roi: SpadRoi = FULL_ROI, level: float = 0.1) -> float:
    """Full horizontal angle within which ``roi`` responds at least ``level`` of its peak."""
    u = np.linspace(-40.0, 40.0, 8001)
    response = roi_response(optics, roi, u, np.zeros(1))[:, 0]
    inside = u[response >= level * response.max()]
    return float(inside[-1] - inside[0])


class Layers(NamedTuple):
    """What every direction of every sensor meets, before any ROI weighs it: per sensor,
    azimuth, elevation and layer (the surface behind, then each pole in front of it)."""

    path_mm: np.ndarray
    """(S, A, E, L) path length along the ray; 0 where the layer holds nothing."""
    strength: np.ndarray
    """(S, A, E, L) visible share x reflectance x cos(incidence) / path^2 (m)."""


class _Poles(NamedTuple):
    """The poles some column of some cone covers, in those columns only."""

    columns: tuple[np.ndarray, np.ndarray]
    """(sensor, azimuth) index arrays of the N columns."""
    t: np.ndarray
    """(N, 1, K) horizontal distance to each pole."""
    gain: np.ndarray
    """(N, E, K) visible share x reflectance x cos(incidence)."""
    through: np.ndarray
    """(S, A, E) share of each direction that gets through all of them."""


class SensorArray:
    """The robot's sensors as optics: their directions, cast from any robot pose at once."""

    def __init__(self, mounts: Sequence[SensorMount], optics: ConeOptics) -> None:
        self.mounts = tuple(mounts)
        self.optics = optics
        az, el, _mask = _grid(optics)
        self._az = np.radians(az)
        self._tan_el = np.tan(np.radians(el))
        self._cos_el = np.cos(np.radians(el))
        self._sin_dep = np.maximum(-np.sin(np.radians(el)), 0.0)
        self._half_column = math.radians(optics.azimuth_step_deg) / 2
        self._tan_reach = math.tan(math.radians(optics.reach_deg))
        self._mx = np.array([m.x_mm for m in self.mounts])
        self._my = np.array([m.y_mm for m in self.mounts])
        self._mz = np.array([m.height_mm for m in self.mounts])
        self._yaw = np.radians([m.yaw_deg for m in self.mounts])

    def returns(self, layers: Layers, sensor: int, roi: SpadRoi = FULL_ROI) -> Returns:
        """What sensor ``sensor`` (index into the mounts) collects through ``roi``."""
        return self.every_return(layers, roi)[sensor]

    def every_return(self, layers: Layers, roi: SpadRoi = FULL_ROI) -> list[Returns]:
        """What each sensor collects through ``roi``: one pass over every sensor's layers
        (each sensor's sums are its own rows', added up as for that sensor alone)."""
        weights = roi_weights(self.optics, roi)
        ambient = self.optics.ambient_mcps * float(weights.sum())
        rows = len(self.mounts)
        signal = weights[None, ..., None] * layers.strength
        total = signal.reshape(rows, -1).sum(axis=1)
        path = layers.path_mm
        with np.errstate(divide="ignore", invalid="ignore"):
            mean = (signal * path).reshape(rows, -1).sum(axis=1) / total
            deviation = (path - mean[:, None, None, None]) ** 2
            variance = (signal * deviation).reshape(rows, -1).sum(axis=1) / total
        return [
            Returns(
                self.optics.signal_mcps * float(total[k]),
                ambient,
                float(mean[k]),
                math.sqrt(max(0.0, float(variance[k]))),
                roi.spad_count,
            )
            if total[k] > 0.0
            else Returns(0.0, ambient, math.nan, 0.0, roi.spad_count)
            for k in range(rows)
        ]

    def layers(self, x: float, y: float, theta: float, surfaces: Surfaces) -> Layers:
        """Every sensor's returns from a robot pose (mm, theta in rad) among ``surfaces``."""
        c, s = math.cos(theta), math.sin(theta)
        ox = (x + c * self._mx - s * self._my)[:, None]  # (S, 1)
        oy = (y + s * self._mx + c * self._my)[:, None]
        oz = self._mz[:, None, None]  # (S, 1, 1)
        azimuths = theta + self._yaw[:, None] + self._az[None, :]  # (S, A)
        dx, dy = np.cos(azimuths), np.sin(azimuths)
        bg_t, bg_gain = self._background(surfaces, ox, oy, oz, dx, dy)
        poles = self._poles(surfaces, ox, oy, oz, azimuths, bg_t)
        shape = (*bg_t.shape, 1 + (0 if poles is None else poles.gain.shape[-1]))
        path, strength = np.zeros(shape), np.zeros(shape)
        through = 1.0 if poles is None else poles.through
        visible(
            bg_t,
            bg_gain * through,
            np.broadcast_to(self._cos_el, bg_t.shape),
            self.optics.max_path_mm,
            path[..., 0],
            strength[..., 0],
        )
        if poles is not None:
            # Elsewhere a pole layer holds nothing: no path, no strength.
            rows, cols = poles.columns
            pole_path, pole_strength = np.empty(poles.gain.shape), np.empty(poles.gain.shape)
            visible(
                np.broadcast_to(poles.t, poles.gain.shape),
                poles.gain,
                np.broadcast_to(self._cos_el[None, :, None], poles.gain.shape),
                self.optics.max_path_mm,
                pole_path,
                pole_strength,
            )
            path[rows, cols, :, 1:], strength[rows, cols, :, 1:] = pole_path, pole_strength
        return Layers(path, strength)

    def _background(
        self,
        surfaces: Surfaces,
        ox: np.ndarray,
        oy: np.ndarray,
        oz: np.ndarray,
        dx: np.ndarray,
        dy: np.ndarray,
    ) -> tuple[np.ndarray, np.ndarray]:
        """Horizontal distance (S, A, E) to the first wall, face or floor each direction
        meets, and its reflectance x cos(incidence)."""
        tan_el = self._tan_el[None, None, :]
        floor_t = np.where(tan_el < 0, oz / np.maximum(-tan_el, _EPS), np.inf)  # (S, 1, E)
        floor_gain = self.optics.floor_reflectance * self._sin_dep[None, None, :]
        shape = (*dx.shape, len(self._tan_el))
        best_t = np.broadcast_to(floor_t, shape).copy()
        best_gain = np.broadcast_to(floor_gain, shape).copy()
        if len(surfaces.segments):
            first_surfaces(
                ox.ravel(),
                oy.ravel(),
                oz.ravel(),
                dx,
                dy,
                self._tan_el,
                self._cos_el,
                surfaces.segments,
                surfaces.segment_reflectance,
                self._tan_reach,
                _EPS,
                best_t,
                best_gain,
            )
        return best_t, best_gain

    def _poles(
        self,
        surfaces: Surfaces,
        ox: np.ndarray,
        oy: np.ndarray,
        oz: np.ndarray,
        azimuths: np.ndarray,
        bg_t: np.ndarray,
    ) -> _Poles | None:
        """Poles in front of the background, nearest first, in the columns one covers (None
        when no cone sees one)."""
        cyl = surfaces.cylinders
        if not len(cyl):
            return None
        order = np.argsort(np.hypot(cyl[:, 0] - ox.mean(), cyl[:, 1] - oy.mean()))
        seen, rows, azs, t, gain, through = poles_in_view(
            cyl[order],
            surfaces.cylinder_reflectance[order],
            ox.ravel(),
            oy.ravel(),
            oz.ravel(),
            azimuths,
            self._tan_el,
            self._cos_el,
            bg_t,
            self._half_column,
            _EPS,
        )
        if not len(seen):
            return None
        return _Poles((rows, azs), t[:, None, :], gain, through)
