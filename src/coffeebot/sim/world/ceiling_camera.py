"""A fixed ceiling camera over one floor of the simulated world (seed 003: 320 x 240 grey
pixels at 10 fps from 4 m).

The frames are made for background subtraction, so they carry what makes it hard: a floor
with a fixed speckle (on a flat colour any difference would be an object), sensor noise, a
lighting change and dropouts. Geometry is a pinhole looking straight down
(:mod:`coffeebot.cameras.geometry`): every horizontal plane maps to the image by its own
homography, so a tall thing's top shows bigger and further from the nadir than its
footprint, as a real camera shows it.

What is drawn, lowest first (painter's order by height, so higher things cover lower ones):

* the floor, then the walls' faces: each vertical segment of the plan as the quadrilateral
  between its bottom and top edges, which is what a downward camera sees of a wall. Floor
  and walls are the background, rendered once and kept until a wall moves (a lift's doors);
  so a person in a room behind a wall shows over the wall rather than hidden by it;
* obstacles' boxes (seats, shelves, sofas, boxes) as their faces and their top;
* cylinders (legs, poles, a person's torso) as a disc on the plane of their top;
* robots as their body's outline on the plane of their top, with a cup on it as a small
  bright disc at the body's centre.

The sides of cylinders and robots are not drawn: away from the nadir a real camera sees
them too, which pulls a blob's centroid a little towards the nadir.

Pixel (i, j) covers [i, i + 1) x [j, j + 1) in image coordinates, as in the geometry
module: its centre is at (i + 0.5, j + 0.5). OpenCV's anti-aliased fill comes out about half
a pixel larger on every side than the shape.
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from operator import attrgetter

import cv2
import numpy as np
from pydantic import BaseModel, ConfigDict, Field, model_validator

from coffeebot.cameras.geometry import mm_per_px, nominal_homography, project
from coffeebot.floorplan import Camera
from coffeebot.sim.world.geometry import Surfaces
from coffeebot.sim.world.world import World, WorldRobot

_SHIFT = 6
"""Fractional bits of the coordinates handed to OpenCV: 1/64 px, so sub-pixel motion shows."""

_HIGHEST_PLANE = 0.9
"""Fraction of the lens's height above which a surface is cut: a wall's top edge level with
the lens would project to infinity."""

CUP_RADIUS_MM = 40.0
"""A takeaway cup's lid, 80 mm across."""

CUP_HEIGHT_MM = 100.0
"""How far the lid stands above the robot's top, where the cup rides."""


class CameraSimSettings(BaseModel):
    """How the simulated camera renders and fails. Grey levels are on a 0-255 scale before
    the lighting gain and the noise."""

    model_config = ConfigDict(frozen=True, extra="forbid", allow_inf_nan=False)

    noise_sigma: float = Field(2.5, ge=0, description="Gaussian sensor noise, grey levels")
    lighting_gain: float = Field(
        1.0, gt=0, description="whole-frame gain once the lighting has changed (0.6: dimmed)"
    )
    lighting_change_at_s: float | None = Field(
        None, description="world time from which the gain applies (None: never)"
    )
    dropout_from_s: float | None = Field(
        None, description="world time from which the camera delivers nothing (None: never)"
    )
    dropout_until_s: float | None = Field(None, description="world time frames come back")
    floor_grey: float = Field(120.0, ge=0, le=255, description="mean of a mid-grey carpet")
    floor_texture_sigma: float = Field(
        6.0, ge=0, description="the carpet's speckle, standard deviation in grey levels"
    )
    wall_grey: float = Field(185.0, ge=0, le=255, description="light paint")
    obstacle_grey: float = Field(75.0, ge=0, le=255, description="furniture and clothes")
    robot_grey: float = Field(55.0, ge=0, le=255, description="the robot's dark shell")
    cup_grey: float = Field(240.0, ge=0, le=255, description="a white lid")

    @model_validator(mode="after")
    def _dropout_is_an_interval(self) -> CameraSimSettings:
        if (self.dropout_from_s is None) != (self.dropout_until_s is None):
            raise ValueError("a dropout needs both dropout_from_s and dropout_until_s")
        start, end = self.dropout_from_s, self.dropout_until_s
        if start is not None and end is not None and end <= start:
            raise ValueError("dropout_until_s must be after dropout_from_s")
        return self

    def gain_at(self, t_s: float) -> float:
        """The whole frame's gain at ``t_s``: a step, as when a bank of lights goes off."""
        changed = self.lighting_change_at_s is not None and t_s >= self.lighting_change_at_s
        return self.lighting_gain if changed else 1.0

    def dropped_at(self, t_s: float) -> bool:
        """Whether the camera delivers nothing at ``t_s`` (the dropout is [from, until))."""
        start, end = self.dropout_from_s, self.dropout_until_s
        return start is not None and end is not None and start <= t_s < end


@dataclass(frozen=True)
class _Fill:
    """Convex polygons of one grey, drawn as the thing on the plane ``plane_mm`` high."""

    plane_mm: float
    grey: float
    polygons: Sequence[np.ndarray]

    def draw(self, image: np.ndarray) -> None:
        # One call each: cv2.fillPoly fills several at once even-odd, leaving overlaps empty.
        for polygon in self.polygons:
            cv2.fillConvexPoly(image, _fixed_point(polygon), (self.grey,), cv2.LINE_AA, _SHIFT)


@dataclass(frozen=True)
class _Disc:
    """A filled disc of one grey: a cylinder's top or a cup's lid, on the plane ``plane_mm``
    high."""

    plane_mm: float
    grey: float
    centre_px: np.ndarray
    radius_px: float

    def draw(self, image: np.ndarray) -> None:
        cu, cv = _fixed_point(self.centre_px)
        radius = round(self.radius_px * (1 << _SHIFT))
        cv2.circle(image, (int(cu), int(cv)), radius, (self.grey,), -1, cv2.LINE_AA, _SHIFT)


def _fixed_point(pixels: np.ndarray) -> np.ndarray:
    """Image coordinates to OpenCV's fixed point, whose integer coordinates are pixel
    centres."""
    return np.rint((pixels - 0.5) * (1 << _SHIFT)).astype(np.int32)


def _speckled_floor(
    shape: tuple[int, int], grey: float, sigma: float, rng: np.random.Generator
) -> np.ndarray:
    """A carpet's speckle: white noise blurred over about two pixels (a weave's flecks are
    wider than 12.5 mm), fixed for the camera's life like a real floor."""
    white = rng.standard_normal(shape).astype(np.float32)
    speckle = np.asarray(cv2.GaussianBlur(white, (0, 0), 1.0), dtype=np.float32)
    floor = grey + speckle * (sigma / float(speckle.std()))
    return np.clip(np.rint(floor), 0, 255).astype(np.uint8)


class SimCeilingCamera:
    """Camera ``camera`` over floor ``level`` of ``world``, rendering frames on demand;
    ``seed`` fixes its floor's speckle and its noise, so a run is reproducible."""

    def __init__(
        self,
        world: World,
        level: int,
        camera: Camera,
        settings: CameraSimSettings | None = None,
        seed: int = 0,
    ) -> None:
        self.world = world
        self.level = world.plan.floor(level).level  # raises KeyError naming the floors
        self.camera = camera
        self.settings = settings or CameraSimSettings()
        texture_seed, noise_seed = np.random.SeedSequence(seed).spawn(2)
        self._noise_rng = np.random.default_rng(noise_seed)
        self._floor_homography = nominal_homography(camera)
        self._floor = _speckled_floor(
            (camera.height_px, camera.width_px),
            self.settings.floor_grey,
            self.settings.floor_texture_sigma,
            np.random.default_rng(texture_seed),
        )
        self._background_walls: bytes | None = None
        self._background = self._floor

    def frame_times(self, start_s: float, end_s: float) -> np.ndarray:
        """World times in [start_s, end_s) at which the camera exposes a frame: every
        1 / fps from time 0, as a free-running camera does."""
        fps = self.camera.fps
        first = math.ceil(start_s * fps - 1e-9)
        last = math.ceil(end_s * fps - 1e-9)
        return np.arange(first, max(first, last)) / fps

    def frame(
        self, t_s: float | None = None, cups: Mapping[str, bool] | None = None
    ) -> np.ndarray | None:
        """The frame (height_px x width_px, uint8) exposed at world time ``t_s`` (None: now);
        obstacles are where they were then, robots where they are now (as
        :meth:`World.surfaces`). ``cups``: which robots, by name, carry a cup. None while
        the camera drops out."""
        t = self.world.t_s if t_s is None else t_s
        if self.settings.dropped_at(t):
            return None
        exposed = self._render(t_s, cups or {}).astype(np.float32) * self.settings.gain_at(t)
        if self.settings.noise_sigma > 0:
            noise = self._noise_rng.standard_normal(exposed.shape, dtype=np.float32)
            exposed += self.settings.noise_sigma * noise
        return np.clip(np.rint(exposed), 0, 255).astype(np.uint8)

    # --- rendering ---------------------------------------------------------------------------

    def _render(self, t_s: float | None, cups: Mapping[str, bool]) -> np.ndarray:
        """The noiseless scene: background, then everything standing, lowest first."""
        settings = self.settings
        robots = [r for r in self.world.robots if r.floor_level == self.level]
        obstacles = [
            self.world.obstacle_at(i, t_s)
            for i, spec in enumerate(self.world.obstacles)
            if spec.floor == self.level
        ]
        structure = self._structure(self.world.surfaces(self.level, t_s), robots, obstacles)
        image = self._background_with(structure.segments).copy()
        shapes: list[_Fill | _Disc] = [
            self._disc(c[:2], c[2], c[4], settings.obstacle_grey) for c in structure.cylinders
        ]
        for obstacle in obstacles:
            shapes.extend(
                self._disc(c[:2], c[2], c[4], settings.obstacle_grey) for c in obstacle.cylinders
            )
            # obstacle_surfaces gives each box as its four sides in turn, around it.
            for box in obstacle.segments.reshape(-1, 4, 6):
                top = self._pixels(box[:, :2], box[0, 5])
                shapes.append(_Fill(box[0, 5], settings.obstacle_grey, [*self._faces(box), top]))
        for robot in robots:
            top_mm = robot.spec.height_mm
            corners = robot.outline().segments[:, :2]
            shapes.append(_Fill(top_mm, settings.robot_grey, [self._pixels(corners, top_mm)]))
            if cups.get(robot.name, False):
                centre = np.array(robot.pose[:2])
                lid_mm = top_mm + CUP_HEIGHT_MM
                shapes.append(self._disc(centre, CUP_RADIUS_MM, lid_mm, settings.cup_grey))
        for shape in sorted(shapes, key=attrgetter("plane_mm")):
            shape.draw(image)
        return image

    @staticmethod
    def _structure(
        surfaces: Surfaces, robots: Sequence[WorldRobot], obstacles: Sequence[Surfaces]
    ) -> Surfaces:
        """What is left of the floor's surfaces once robots and obstacles, drawn as
        themselves, are taken out: walls, doors, the lift."""
        drawn_apart = {r.name for r in robots}
        for obstacle in obstacles:
            drawn_apart.update(obstacle.segment_ids, obstacle.cylinder_ids)
        segments = [i for i, e in enumerate(surfaces.segment_ids) if e not in drawn_apart]
        cylinders = [i for i, e in enumerate(surfaces.cylinder_ids) if e not in drawn_apart]
        return surfaces.take(np.array(segments, dtype=int), np.array(cylinders, dtype=int))

    def _background_with(self, walls: np.ndarray) -> np.ndarray:
        """Floor and walls, drawn again only when a wall has moved."""
        key = walls.tobytes()
        if key != self._background_walls:
            image = self._floor.copy()
            if len(walls):
                _Fill(0.0, self.settings.wall_grey, list(self._faces(walls))).draw(image)
            self._background_walls, self._background = key, image
        return self._background

    def _faces(self, segments: np.ndarray) -> np.ndarray:
        """Each vertical segment (N, 6) as the quadrilateral between its bottom and top
        edges in the image, (N, 4, 2): a trapezoid (the top edge is the bottom one scaled
        about the nadir), so convex."""
        starts, ends = segments[:, 0:2], segments[:, 2:4]
        bottom, top = segments[:, 4], segments[:, 5]
        return np.stack(
            [
                self._pixels(starts, bottom),
                self._pixels(ends, bottom),
                self._pixels(ends, top),
                self._pixels(starts, top),
            ],
            axis=1,
        )

    def _disc(self, centre_mm: np.ndarray, radius_mm: float, plane_mm: float, grey: float) -> _Disc:
        plane = min(plane_mm, _HIGHEST_PLANE * self.camera.height_mm)
        radius_px = radius_mm / mm_per_px(self.camera, plane)
        return _Disc(plane_mm, grey, self._pixels(centre_mm, plane_mm)[0], radius_px)

    def _pixels(self, points_mm: np.ndarray, planes_mm: np.ndarray | float) -> np.ndarray:
        """Image coordinates (N, 2) of floor-frame points (N, 2) lying on planes
        ``planes_mm`` high: each scaled about the nadir by its height's ratio, then through
        the floor's homography (:func:`coffeebot.cameras.geometry.raise_plane`, one plane a
        point)."""
        lens_mm = self.camera.height_mm
        planes = np.minimum(np.asarray(planes_mm, dtype=float), _HIGHEST_PLANE * lens_mm)
        scale = np.atleast_1d(lens_mm / (lens_mm - planes))[:, None]
        nadir = np.array([self.camera.x_mm, self.camera.y_mm])
        raised = nadir + (np.asarray(points_mm, dtype=float).reshape(-1, 2) - nadir) * scale
        return project(self._floor_homography, raised)
