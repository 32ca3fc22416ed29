"""A ceiling camera's one-time calibration: its floor-to-image homography from floor marks.

Seed 003 calibrates each fixed camera once, from the camera's frame to the map's. Here a
surveyor tapes four to six marks on the floor spread over the image, measures them in the
floor frame and reads their pixels from a still; the homography through them replaces the
nominal one from the camera's pose and lens, which a bracket one degree askew already puts
45 mm off under a 2.6 m ceiling. A camera without marks keeps the nominal homography.

A calibration that cannot be trusted is refused with the floor plan's error, naming the
floor, the camera and what is wrong: a camera service would otherwise place every robot it
sees wherever a typo says.
"""

from __future__ import annotations

import functools
import itertools
import math
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import Literal

import cv2
import numpy as np

from coffeebot.cameras.geometry import nominal_homography, project, to_plane
from coffeebot.floorplan.features import Camera, FloorPlanError

MIN_MARKS = 4
"""A homography has eight unknowns, each mark gives two equations."""

MIN_SPREAD = 1 / 3
"""Fraction of the image's width and of its height the marks must span: beyond them the
homography is extrapolated, and a reading error at the marks grows towards the corners."""

MIN_LINE_CLEARANCE = 0.1
"""Four of the marks must keep this fraction of the image's shorter side (24 px of 240)
clear of the line through any two others: marks in a line leave the homography free to
tilt across it."""

MAX_RMS_PX = 1.5
"""Reprojection error allowed, RMS over the marks: honest marks (read to half a pixel, taped
to 5 mm, half a pixel at 10-16 mm a pixel) stay well under it; a mistyped or misread one
(1 m is 60 to 120 px) or a lens distortion the homography cannot describe does not."""

MAX_CENTRE_OFFSET_MM = 300.0
"""How far the marks may put the image centre from where the camera's surveyed pose puts
it: a tape measure and a bracket's tilt err by 50-100 mm, a mistyped digit by 1000."""

MAX_CORNER_OFFSET_MM = 600.0
"""The same at the image's corners, which also feel the yaw's error (5 degrees: 280 mm at
the corner of a 90-degree lens under a 2.6 m ceiling). With exactly four marks a 1 m typo
moves the centre only 250-550 mm but a corner more than 1200 mm: the corners catch it."""

Source = Literal["marks", "nominal"]


@dataclass(frozen=True, eq=False)
class Calibration:
    """A camera's floor-to-image homography and how far to trust it."""

    camera: Camera
    homography: np.ndarray
    """3 x 3, floor-frame (x, y, 1) in mm to pixel (u, v, 1)."""
    source: Source
    """"marks": fitted to the camera's floor marks; "nominal": from its pose and lens alone."""
    errors_px: tuple[float, ...]
    """Each mark's reprojection error, in the order of the camera's marks (none: nominal)."""
    rms_px: float | None
    """RMS of ``errors_px``; None for a nominal homography, which nothing has measured."""

    def image_centre_on_floor(self) -> tuple[float, float]:
        """Floor-frame point at the middle of the image: where the camera looks."""
        centre = np.array([[self.camera.width_px / 2, self.camera.height_px / 2]])
        x, y = to_plane(self.homography, centre)[0]
        return float(x), float(y)


def calibrate(
    camera: Camera, *, floor: int | None = None, path: str | Path = "<floor plan>"
) -> Calibration:
    """The camera's homography from its marks (or the nominal one without marks).

    ``floor`` and ``path`` only name the camera in a :class:`FloorPlanError`.
    """
    where = f"camera {camera.id}" if floor is None else f"floor {floor} / camera {camera.id}"
    refuse = functools.partial(FloorPlanError, path, where)
    if not camera.marks:
        return Calibration(camera, nominal_homography(camera), "nominal", (), None)
    if len(camera.marks) < MIN_MARKS:
        raise refuse(
            f"marks: {len(camera.marks)} given, a calibration needs at least {MIN_MARKS} "
            "(or none, for the nominal homography from the pose and lens)"
        )
    floor_mm = np.array([(m.x_mm, m.y_mm) for m in camera.marks], dtype=float)
    pixels = np.array([(m.u_px, m.v_px) for m in camera.marks], dtype=float)
    for index, (u, v) in enumerate(pixels):
        if not (0 <= u <= camera.width_px and 0 <= v <= camera.height_px):
            raise FloorPlanError(
                path,
                f"{where} / mark #{index + 1}",
                f"u_px, v_px: ({u:.1f}, {v:.1f}) lies outside the camera's "
                f"{camera.width_px} x {camera.height_px} image",
            )
    _check_spread(camera, pixels, refuse)
    homography = _fit(floor_mm, pixels)
    if homography is None:
        raise refuse("marks: no homography fits them")
    errors = _reprojection_errors(homography, floor_mm, pixels)
    rms = float(np.sqrt(np.mean(errors**2)))
    if rms > MAX_RMS_PX:
        suspect = _odd_one_out(floor_mm, pixels)
        raise refuse(
            f"marks: reprojection error {rms:.1f} px RMS (at most {MAX_RMS_PX}): "
            + (
                "a mark mismeasured or mistyped, and none stands out (that takes six or more)"
                if suspect is None
                else f"mark #{suspect + 1} mismeasured or mistyped, the others agree without it"
            )
        )
    _check_against_pose(camera, homography, refuse)
    return Calibration(camera, homography, "marks", tuple(float(e) for e in errors), rms)


def _fit(floor_mm: np.ndarray, pixels: np.ndarray) -> np.ndarray | None:
    """Least squares over every mark, not RANSAC: with four to six marks a robust fit would
    quietly drop a mistyped mark, where the surveyor needs to hear of it."""
    homography, _ = cv2.findHomography(floor_mm, pixels, method=0)
    return None if homography is None else np.asarray(homography, dtype=float)


def _reprojection_errors(
    homography: np.ndarray, floor_mm: np.ndarray, pixels: np.ndarray
) -> np.ndarray:
    """How far, in pixels, each mark shows from where the homography puts its floor point."""
    return np.linalg.norm(project(homography, floor_mm) - pixels, axis=1)


def _odd_one_out(floor_mm: np.ndarray, pixels: np.ndarray) -> int | None:
    """The one mark that the others, fitted without it, agree on (within the RMS allowed)
    and show elsewhere (further off than that), if exactly one does. A fit spreads a bad
    mark's error over the others, so its own residual is often not the largest (a mistyped
    corner mark leaves the middle ones worst); and it takes six marks to tell, as any four
    fit exactly. Where two marks answer (five left with three of them in a line fit nearly
    anything), none is named."""
    if len(pixels) < MIN_MARKS + 2:
        return None
    suspects = []
    for left_out in range(len(pixels)):
        keep = np.arange(len(pixels)) != left_out
        homography = _fit(floor_mm[keep], pixels[keep])
        if homography is None:
            continue
        others = _reprojection_errors(homography, floor_mm[keep], pixels[keep])
        own = _reprojection_errors(homography, floor_mm[~keep], pixels[~keep])[0]
        if np.sqrt(np.mean(others**2)) <= MAX_RMS_PX < own:
            suspects.append(left_out)
    return suspects[0] if len(suspects) == 1 else None


def _check_spread(
    camera: Camera, pixels: np.ndarray, refuse: Callable[[str], FloorPlanError]
) -> None:
    """The marks must span the image and hold four in general position."""
    span_u, span_v = np.ptp(pixels, axis=0)
    need_u, need_v = camera.width_px * MIN_SPREAD, camera.height_px * MIN_SPREAD
    if span_u < need_u or span_v < need_v:
        raise refuse(
            f"marks: span {span_u:.0f} x {span_v:.0f} px of the {camera.width_px} x "
            f"{camera.height_px} image; spread them wider, over {need_u:.0f} x {need_v:.0f} px "
            "at least"
        )
    clearance = MIN_LINE_CLEARANCE * min(camera.width_px, camera.height_px)
    if not any(
        _thinnest(pixels[list(four)]) >= clearance
        for four in itertools.combinations(range(len(pixels)), 4)
    ):
        raise refuse(
            f"marks: lie (nearly) in a line: a homography needs four of them with none "
            f"within {clearance:.0f} px of the line through two others"
        )


def _thinnest(points: np.ndarray) -> float:
    """The smallest distance, over the triangles of ``points``, from a corner to the line
    through the other two (a triangle's smallest height)."""
    thinnest = math.inf
    for a, b, c in itertools.combinations(points, 3):
        ab, ac, bc = b - a, c - a, c - b
        double_area = abs(ab[0] * ac[1] - ab[1] * ac[0])
        longest = max(np.hypot(*ab), np.hypot(*ac), np.hypot(*bc))
        thinnest = min(thinnest, double_area / longest if longest > 0 else 0.0)
    return thinnest


def _check_against_pose(
    camera: Camera, homography: np.ndarray, refuse: Callable[[str], FloorPlanError]
) -> None:
    """The marks and the camera's surveyed pose must see the same floor: where they part,
    one of them holds a typo."""
    w, h = camera.width_px, camera.height_px
    places = [
        ("the image centre", (w / 2, h / 2), MAX_CENTRE_OFFSET_MM),
        ("the image's top-left corner", (0, 0), MAX_CORNER_OFFSET_MM),
        ("the image's top-right corner", (w, 0), MAX_CORNER_OFFSET_MM),
        ("the image's bottom-right corner", (w, h), MAX_CORNER_OFFSET_MM),
        ("the image's bottom-left corner", (0, h), MAX_CORNER_OFFSET_MM),
    ]
    pixels = np.array([pixel for _, pixel, _ in places], dtype=float)
    offsets = np.linalg.norm(
        to_plane(homography, pixels) - to_plane(nominal_homography(camera), pixels), axis=1
    )
    for (name, _, limit), offset in zip(places, offsets, strict=True):
        if offset > limit:
            raise refuse(
                f"marks: put {name} {offset:.0f} mm from where the camera's pose and lens put "
                f"it (at most {limit:.0f} mm): a typo in a mark, or in the camera's x_mm, "
                "y_mm, yaw_deg, height_mm or fov_deg"
            )
