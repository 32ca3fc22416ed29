"""What a ceiling camera sees move: blobs that differ from the empty floor, on the floor.

Seed 003, IV.A: a background image of the watched area, the difference of each frame from
it, smoothing, contours and their positions; VI.B: a running average of the foreground, from
which things that stand still are mapped.

The background is a per-pixel running average (``cv2.accumulateWeighted``) rather than
OpenCV's mixture of Gaussians: its one rate per pixel is a time constant one can reason
about (how long until a cart left standing becomes floor), it can be rescaled by a global
gain when the lights change, and it learns selectively: pixels under an object learn far
more slowly than bare floor, so a robot waiting half a minute stays foreground while a cart
left for minutes, or a lamp switched on, is absorbed.

A global lighting change (the whole image some percent brighter from one frame to the next,
as the lights or the camera's exposure change) is removed before subtraction: the
background is rescaled by the median ratio of frame to background over the pixels that
were floor in the previous frame, so the jump itself never shows as foreground.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass

import cv2
import numpy as np
from pydantic import BaseModel, ConfigDict, Field

from coffeebot.cameras.geometry import to_plane
from coffeebot.floorplan import Camera

SATURATED_GREY = 250.0
"""Pixels this bright (or as dark as ``255 - SATURATED_GREY``) are clipped by the sensor and
say nothing about the lighting's gain."""

GHOST_MARGIN_PX = 3
"""Around a blob's bounding box: its outline (3 px wide) and the gradient's 3 x 3 reach."""

PIXEL_CENTRE = 0.5
"""OpenCV numbers a pixel by its index; the homographies of
:mod:`~coffeebot.cameras.geometry` put the image's corner at 0 and its centre at half its
size, so pixel ``i`` is centred at ``i + 0.5`` there."""


class PipelineSettings(BaseModel):
    """Tuning of one camera's image pipeline, for the seed's 320 x 240 camera at 10 fps."""

    model_config = ConfigDict(frozen=True, extra="forbid")

    learn_frames: int = Field(
        20,
        ge=1,
        description="frames of the empty scene averaged into the first background (2 s): "
        "no detections until then",
    )
    floor_time_constant_s: float = Field(
        30.0,
        gt=0,
        description="how fast bare floor follows slow changes (daylight): it averages out "
        "the sensor's noise over a few hundred frames",
    )
    object_time_constant_s: float = Field(
        300.0,
        gt=0,
        description="how fast pixels under an object become background: a robot 90 grey "
        "levels darker than the floor is absorbed after 7-8 min, and keeps 90 % of its "
        "contrast after 30 s of waiting",
    )
    blur_sigma_px: float = Field(
        1.0,
        gt=0,
        description="Gaussian smoothing before subtraction: cuts the sensor's noise by about "
        "3.5 while blurring an edge by a pixel",
    )
    threshold_grey: float = Field(
        20.0,
        gt=0,
        lt=255,
        description="difference from the background, in grey levels, above which a pixel is "
        "foreground: over 20 sigma of the smoothed noise of a 3-grey-level sensor",
    )
    open_px: int = Field(3, ge=1, description="opening's kernel: removes specks narrower than this")
    close_px: int = Field(
        5,
        ge=1,
        description="closing's kernel: fills gaps narrower than this inside an object (and "
        "joins objects closer than this, 60 mm on the seed's floor)",
    )
    guard_px: int = Field(
        2,
        ge=0,
        description="margin around foreground that also learns at the object's slow rate: "
        "an object's blurred rim, below the threshold, must not leak into the floor",
    )
    min_area_mm2: float = Field(
        40_000.0,
        ge=0,
        description="smaller blobs are dropped (a 200 mm square; a person seen from above "
        "covers about 150 000 mm2, the robot 310 000 mm2)",
    )
    foreground_time_constant_s: float = Field(
        10.0,
        gt=0,
        description="time constant of the foreground's running average (seed VI.B): "
        "something standing still this long reaches 63 %",
    )
    ghost_edge_ratio: float = Field(
        0.5,
        gt=0,
        lt=1,
        description="a blob whose outline is this much sharper in the background than in "
        "the frame is a ghost (something that was there when the background was learned "
        "and has gone: the robot at its dock at start-up, a cart pushed away): the frame's "
        "floor texture shows weak edges there, the background the old object's strong ones",
    )
    max_step_s: float = Field(
        1.0,
        gt=0,
        description="a gap in the frames counts as at most this much learning, so whatever "
        "stands in view after an outage is not absorbed at once",
    )


@dataclass(frozen=True, slots=True)
class Detection:
    """One blob seen in one frame, measured on the plane the pipeline's homography maps from
    (the floor, or the plane of a robot's top)."""

    t_s: float
    x_mm: float
    y_mm: float
    length_mm: float
    """The long side of its smallest enclosing rectangle: of the thresholded, blurred
    outline, so 1-2 px longer than a contrasted object is."""
    width_mm: float
    axis_deg: float
    """Direction of the long side in the floor frame, in [0, 180): the blob says nothing
    about which end is the front."""
    area_mm2: float
    camera_id: str
    cut: bool = False
    """The blob touches the image's border: part of the object lies outside the view, so
    its centroid and size are those of the part seen (a robot driving in seems to move at
    half its speed), not a position to fit a path to."""


class CameraPipeline:
    """Frames of one camera in, detections on the floor out (seed 003, IV.A)."""

    def __init__(self, camera: Camera, homography: np.ndarray, settings: PipelineSettings) -> None:
        if homography.shape != (3, 3):
            raise ValueError(f"a homography is 3 x 3, not {homography.shape}")
        self.camera = camera
        self.settings = settings
        self._homography = homography
        shape = (camera.height_px, camera.width_px)
        self._background = np.zeros(shape, np.float32)
        self._floor_pixels = np.ones(shape, bool)
        """Where the previous frame showed floor: the pixels the lighting's gain is read on."""
        self._foreground_average = np.zeros(shape, np.float32)
        self._frames_learned = 0
        self._last_t_s: float | None = None
        self._previous: tuple[np.ndarray, np.ndarray] | None = None
        """The last frame (smoothed) and where it was foreground."""
        self._open = _disc(settings.open_px)
        self._close = _disc(settings.close_px)
        self._guard = _disc(2 * settings.guard_px + 1)

    @property
    def learned(self) -> bool:
        """Whether the first background is complete and detections are meaningful."""
        return self._frames_learned >= self.settings.learn_frames

    def step(self, frame: np.ndarray, t_s: float) -> list[Detection]:
        """Take the next frame (uint8, one camera's rows x columns) taken at ``t_s``."""
        expected = (self.camera.height_px, self.camera.width_px)
        if frame.dtype != np.uint8 or frame.shape != expected:
            raise ValueError(
                f"camera {self.camera.id!r} gives uint8 frames of {expected}, "
                f"not {frame.dtype} {frame.shape}"
            )
        if self._last_t_s is not None and t_s <= self._last_t_s:
            raise ValueError(f"frame at {t_s} s is not after the previous at {self._last_t_s} s")
        step_s = (
            0.0 if self._last_t_s is None else min(t_s - self._last_t_s, self.settings.max_step_s)
        )
        self._last_t_s = t_s

        smoothed = cv2.GaussianBlur(frame, (0, 0), self.settings.blur_sigma_px).astype(np.float32)
        gain = self._follow_gain(smoothed) if self._frames_learned > 0 else 1.0
        if not self.learned:
            # A plain mean of the first frames: each counts alike.
            self._frames_learned += 1
            cv2.accumulateWeighted(smoothed, self._background, 1.0 / self._frames_learned)
            return []

        self._forget_vacated(smoothed, gain)
        mask = self._foreground(smoothed)
        self._previous = (smoothed, mask > 0)
        self._learn(smoothed, mask, step_s)
        cv2.accumulateWeighted(
            (mask > 0).astype(np.float32),
            self._foreground_average,
            _rate(step_s, self.settings.foreground_time_constant_s),
        )
        contours, _ = cv2.findContours(mask, cv2.RETR_EXTERNAL, cv2.CHAIN_APPROX_NONE)
        measured = [(c, d) for c in contours if (d := self._measure(c, t_s)) is not None]
        if not measured:
            return []
        ghost = self._ghost_test(smoothed)
        return [detection for contour, detection in measured if not ghost(contour)]

    def foreground_average(self) -> np.ndarray:
        """The running average of the foreground mask, 0-1 per pixel (seed VI.B): near 1
        where something has stood for a few time constants, near 0 where things only pass."""
        return self._foreground_average.copy()

    def _forget_vacated(self, smoothed: np.ndarray, gain: float) -> None:
        """Where something had stood (the foreground's average over half) and is gone at
        once (the pixel was foreground and changed by more than the threshold since the last
        frame), the background takes the frame: what it had learned of the thing would
        otherwise stand there as a ghost for minutes (a cart wheeled away after a while)."""
        if self._previous is None:
            return
        previous, was_foreground = self._previous
        changed = cv2.absdiff(smoothed, previous * gain) > self.settings.threshold_grey
        vacated = was_foreground & changed & (self._foreground_average > 0.5)
        if vacated.any():
            self._background[vacated] = smoothed[vacated]

    def _follow_gain(self, smoothed: np.ndarray) -> float:
        """Rescale the background to this frame's lighting: the median ratio over pixels
        that were floor, leaving out clipped ones, is robust to the objects among them.
        Returns the ratio (1 when no pixel can tell)."""
        usable = (
            self._floor_pixels
            & (self._background > 255.0 - SATURATED_GREY)
            & (smoothed > 255.0 - SATURATED_GREY)
            & (self._background < SATURATED_GREY)
            & (smoothed < SATURATED_GREY)
        )
        if not usable.any():
            return 1.0
        gain = float(np.median(smoothed[usable] / self._background[usable]))
        np.clip(self._background * gain, 0.0, 255.0, out=self._background)
        return gain

    def _foreground(self, smoothed: np.ndarray) -> np.ndarray:
        """The cleaned foreground mask (uint8, 255 where something is)."""
        difference = cv2.absdiff(smoothed, self._background)
        _, mask = cv2.threshold(difference, self.settings.threshold_grey, 255, cv2.THRESH_BINARY)
        mask = mask.astype(np.uint8)
        mask = cv2.morphologyEx(mask, cv2.MORPH_OPEN, self._open)
        return cv2.morphologyEx(mask, cv2.MORPH_CLOSE, self._close)

    def _learn(self, smoothed: np.ndarray, mask: np.ndarray, step_s: float) -> None:
        """Floor learns at the floor's rate, objects and their rims at the objects' slow one."""
        guarded = cv2.dilate(mask, self._guard)
        floor = cv2.bitwise_not(guarded)
        cv2.accumulateWeighted(
            smoothed,
            self._background,
            _rate(step_s, self.settings.object_time_constant_s),
            mask=guarded,
        )
        cv2.accumulateWeighted(
            smoothed,
            self._background,
            _rate(step_s, self.settings.floor_time_constant_s),
            mask=floor,
        )
        self._floor_pixels = floor > 0

    def _ghost_test(self, smoothed: np.ndarray) -> Callable[[np.ndarray], bool]:
        """Whether a blob is a ghost; a ghost's pixels become background at once (left to
        the slow objects' rate, a ghost would stand for minutes). Each blob is judged within
        its own bounding box, grown by the outline's width."""
        height, width = smoothed.shape

        def ghost(contour: np.ndarray) -> bool:
            left, top, w, h = cv2.boundingRect(contour)
            x0, y0 = max(0, left - GHOST_MARGIN_PX), max(0, top - GHOST_MARGIN_PX)
            x1 = min(width, left + w + GHOST_MARGIN_PX)
            y1 = min(height, top + h + GHOST_MARGIN_PX)
            box = (slice(y0, y1), slice(x0, x1))
            outline = np.zeros((y1 - y0, x1 - x0), np.uint8)
            cv2.drawContours(outline, [contour], -1, 255, thickness=3, offset=(-x0, -y0))
            # The image's border is no edge of the object: it was cut there.
            on_outline = outline > 0
            on_outline &= _inside_border(y0, y1, x0, x1, height, width)
            if not on_outline.any():
                return False
            seen = float(_edges(smoothed[box])[on_outline].mean())
            remembered = float(_edges(self._background[box])[on_outline].mean())
            if seen >= self.settings.ghost_edge_ratio * remembered:
                return False
            region = np.zeros((y1 - y0, x1 - x0), np.uint8)
            cv2.drawContours(region, [contour], -1, 255, thickness=cv2.FILLED, offset=(-x0, -y0))
            absorbed = cv2.dilate(region, self._guard) > 0
            self._background[box][absorbed] = smoothed[box][absorbed]
            return True

        return ghost

    def _measure(self, contour: np.ndarray, t_s: float) -> Detection | None:
        """The blob's area, centroid and enclosing rectangle, measured on the plane itself:
        exact for any homography, and the axis comes out in the floor frame."""
        on_plane = to_plane(self._homography, contour.reshape(-1, 2) + PIXEL_CENTRE)
        # Moments and the rectangle about a local origin: float32 keeps sub-mm precision
        # near it, not a kilometre away.
        origin = on_plane.mean(axis=0)
        local = (on_plane - origin).astype(np.float32)
        moments = cv2.moments(local)
        area_mm2 = moments["m00"]
        if area_mm2 <= 0.0 or area_mm2 < self.settings.min_area_mm2:
            return None
        centroid = origin + np.array([moments["m10"], moments["m01"]]) / area_mm2
        corners = cv2.boxPoints(cv2.minAreaRect(local))
        sides = np.diff(corners[:3], axis=0)
        lengths = np.hypot(sides[:, 0], sides[:, 1])
        long_side = sides[int(np.argmax(lengths))]
        left, top, width, height = cv2.boundingRect(contour)
        cut = (
            left <= 0
            or top <= 0
            or left + width >= self.camera.width_px
            or top + height >= self.camera.height_px
        )
        return Detection(
            t_s=t_s,
            x_mm=float(centroid[0]),
            y_mm=float(centroid[1]),
            length_mm=float(lengths.max()),
            width_mm=float(lengths.min()),
            axis_deg=_axis_deg(float(long_side[0]), float(long_side[1])),
            area_mm2=float(area_mm2),
            camera_id=self.camera.id,
            cut=cut,
        )


def _inside_border(y0: int, y1: int, x0: int, x1: int, height: int, width: int) -> np.ndarray:
    """Of the box [y0, y1) x [x0, x1), the pixels not on the image's outermost rows and
    columns."""
    rows = np.arange(y0, y1)
    columns = np.arange(x0, x1)
    return ((rows > 0) & (rows < height - 1))[:, None] & ((columns > 0) & (columns < width - 1))


def _edges(image: np.ndarray) -> np.ndarray:
    """Gradient magnitude per pixel (Sobel)."""
    dx = cv2.Sobel(image, cv2.CV_32F, 1, 0, ksize=3)
    dy = cv2.Sobel(image, cv2.CV_32F, 0, 1, ksize=3)
    return cv2.magnitude(dx, dy)


def _disc(size_px: int) -> np.ndarray:
    """A round structuring element: objects seen from above have no preferred direction."""
    return cv2.getStructuringElement(cv2.MORPH_ELLIPSE, (size_px, size_px))


def _axis_deg(dx: float, dy: float) -> float:
    """The direction of a line (not of a vector), in [0, 180)."""
    degrees = math.degrees(math.atan2(dy, dx)) % 180.0
    return 0.0 if degrees >= 180.0 else degrees  # a tiny negative angle wraps to 180.0


def _rate(step_s: float, time_constant_s: float) -> float:
    """The running average's weight for a step: a time constant independent of frame rate."""
    return 1.0 - math.exp(-step_s / time_constant_s)
