"""A local costmap from the ToF scans, in layers (seed 003; Lu et al.'s layered costmaps).

*Static layer*: the floor plan's walls, known in advance. *Obstacle layer*: a rolling grid
around the robot, marked and cleared from the time-of-flight readings the way sonar costmaps
are: a VL53L1X reading is the signal-weighted mean of what its cone sees, so the nearest
thing is at most that far and may be anywhere across the cone: a reading marks the whole arc
of the cone at that range as occupied and clears the cone in front of it (nearer, there is
nothing the cone would have weighed more; a thin leg in front of a wall can still hide in
the blend, which the collision rules, not the planner, answer for). Clearing uses the cone
narrowed on each side by the heading's possible error: off by a few degrees (while turning,
above all), the edge of the cone as placed would sweep cells the sensor did not look at. A
reading the plan's walls explain (some ray of the cone, widened by
``wall_heading_tolerance_deg`` for the pose's heading error, meets a wall within
``wall_margin_mm`` of the range) belongs to the static layer and marks nothing. Marks the
robot does not see again expire after ``obstacle_memory_s``.

Inflation is evaluated where it is needed, at the poses a planner asks about, rather than
over the whole grid: the lethal part is exact for the robot's rectangle (an obstacle cell
closer than ``obstacle_clearance_mm`` to the body), walls are lethal within
``side_clearance_mm`` of the body's rectangle, and the cost decays exponentially over
``inflation_mm`` beyond that, so the planner prefers to keep its distance when it can.

A cell marked by a narrow return (what the collision monitor calls narrow: a return seen by
one or two adjacent front sensors while the others read much further, a pole or a leg, with
sensors of the row reading further on both sides of it) keeps ``[collision]
narrow_margin_mm`` more clearance in every gap the planners ask for, and is placed at the
near end of the reading's spread, as the collision monitor judges it. What
stands on a pole often spreads out above the cones: a swivel chair's seat overhangs its pole
by ~240 mm where the body is, so a go-around planned on the pole alone swings a front corner
into the seat. A cell a pole's return marked keeps the margin whenever it is occupied for
``obstacle_memory_s`` after: the same pole, seen closer or turned, may read as part of
something wider, or blend, and mark the cell again, and the seat is still there.

Each cell also remembers since when it has been continuously occupied: an obstacle whose
nearest cells have stood for ``static_confirm_s`` is static; a walking person keeps producing
fresh cells (approaching) or clears the old ones (leaving), so they are never "static" and the
robot waits for them instead of steering around them.

*Camera layer*: the outlines of what the ceiling cameras see standing in the hallway
(:mod:`coffeebot.navigation.camera_blocks`), as points that count as occupied cells, standing
since the camera first saw them stand. The whole layer is replaced by each camera layer
message (what left the cameras' layer leaves the costmap) and dropped once it is stale; the
readings neither mark nor clear it, so it only ever adds to what the sensors see.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Iterable, Sequence
from dataclasses import dataclass, replace
from typing import NamedTuple

import numpy as np

from coffeebot.config import CollisionConfig, MotionConfig, TofSensorConfig
from coffeebot.floorplan import Floor, segment_distances, segments_crossed
from coffeebot.messages import NOTHING_IN_RANGE, RangeReading, RangeScan, ReadingStatus
from coffeebot.navigation.others import outline_points
from coffeebot.perception.collision import narrow_returns, near_end_mm
from coffeebot.perception.geometry import sensor_origins, spread_rad
from coffeebot.perception.walls import segment_ranges, wall_ranges

MAX_MARK_MM = 1500.0
"""Readings beyond this are too noisy to mark (seed 000: noise above ~1000 mm in mid mode)."""

Rays = tuple[list[int], np.ndarray, np.ndarray, np.ndarray]
"""The sensors asked whether something explains their reading: ids, origins (n, 2), the rays
of each widened cone (n, r), and how far along them it may lie (n,)."""

CameraMarks = dict[int, tuple[np.ndarray, np.ndarray, np.ndarray]]
"""The camera layer, per floor level: points (x, y) on the outlines of what the ceiling
cameras see standing, and since when each has stood (board clock)."""

EXPLAIN_RAYS = 15
"""Rays sampled across the widened cone when asking whether the plan's walls explain a
reading: finer than the marking, since a grazing wall is met only near the cone's edge."""


@dataclass(frozen=True)
class Footprint:
    """The body as a rectangle around its centre (robot frame: x forward, y left)."""

    length_mm: float
    width_mm: float
    front_extra_mm: float = 0.0
    """Kept clear ahead of the body too, so the collision module's front stop never fires."""
    axle_x_mm: float = 0.0
    """The driven axle, about which the body turns, this far ahead of the centre."""

    def gap_mm(self, local_x: np.ndarray, local_y: np.ndarray) -> np.ndarray:
        """Distance from robot-frame points to the (extended) body outline (zero inside)."""
        half = self.length_mm / 2.0
        centre = self.front_extra_mm / 2.0
        dx = np.maximum(np.abs(local_x - centre) - half - centre, 0.0)
        dy = np.maximum(np.abs(local_y) - self.width_mm / 2.0, 0.0)
        return np.hypot(dx, dy)


class Clearances(NamedTuple):
    """The least gaps a path keeps to the plan's walls and to what the sensors saw."""

    wall_mm: float
    obstacle_mm: float


class Obstacles(NamedTuple):
    """What the costmap holds as obstacles, one entry per occupied cell or camera point."""

    xs: np.ndarray
    ys: np.ndarray
    since: np.ndarray
    """Since when each has been occupied (s)."""
    margins: np.ndarray
    """The clearance each needs beyond everything else's (mm)."""


class LocalCostmap:
    """The obstacle layer on a rolling grid, plus cost queries against both layers."""

    def __init__(
        self,
        cfg: MotionConfig,
        sensors: Iterable[TofSensorConfig],
        footprint: Footprint,
        half_fov_deg: float,
        narrow: CollisionConfig | None = None,
    ) -> None:
        """``narrow``: the collision config whose narrow-return rule (and margin) marks
        cells as narrow; None: no cell is."""
        self.cfg = cfg
        self.narrow_cfg = narrow
        self.narrow_margin_mm = 0.0 if narrow is None else narrow.narrow_margin_mm
        self.sensors = list(sensors)
        self._front_y = {s.id: s.y_mm for s in self.sensors}
        self.footprint = footprint
        self.half_fov_deg = half_fov_deg
        self.body = replace(footprint, front_extra_mm=0.0)
        """The body alone, without the zone kept free ahead for driving."""
        half_l, half_w = footprint.length_mm / 2.0, footprint.width_mm / 2.0
        self._corners = np.array(
            [[half_l, half_w], [half_l, -half_w], [-half_l, half_w], [-half_l, -half_w]]
        )
        self._rear_corners = (self._corners[:, 0] < 0).astype(float)
        """1 for each rear corner of ``_corners``, 0 for each front one."""
        self.res = cfg.costmap_resolution_mm
        self._rays = math.ceil(math.radians(2.0 * half_fov_deg) * MAX_MARK_MM / self.res) + 1
        """Rays across a cone, for clearing and marking: at most a cell apart out to
        ``MAX_MARK_MM``, so a thin pole (a mail cart's corner bar) is marked where it stands,
        not only at the rays either side of it."""
        self._spread = np.radians(np.linspace(-half_fov_deg, half_fov_deg, self._rays))
        """Ray offsets across a cone, for marking."""
        self._step = self.res / 2.0
        self._steps = np.arange(0.0, MAX_MARK_MM, self._step)
        """Distances along a ray where it clears, the longest ray's (shorter ones a prefix)."""
        widest = half_fov_deg + cfg.wall_heading_tolerance_deg
        self._explain = np.radians(np.linspace(-widest, widest, EXPLAIN_RAYS))
        """Ray offsets across the widened cone, for asking whether a wall explains a reading."""
        self.n = math.ceil(cfg.costmap_size_mm / self.res)
        self.floor: Floor | None = None
        self.origin = (0.0, 0.0)
        self.hit_t = np.full((self.n, self.n), -math.inf)
        self.clear_t = np.full((self.n, self.n), -math.inf)
        self.since_t = np.full((self.n, self.n), math.inf)
        self.pole_t = np.full((self.n, self.n), -math.inf)
        """When a pole's return last marked each cell."""
        self._camera: CameraMarks = {}
        self._camera_until = -math.inf

    # --- grid ------------------------------------------------------------------------------

    def reset(self, floor: Floor | None = None, x_mm: float = 0.0, y_mm: float = 0.0) -> None:
        self.floor = floor
        half = self.n * self.res / 2.0
        self.origin = (x_mm - half, y_mm - half)
        self.hit_t.fill(-math.inf)
        self.clear_t.fill(-math.inf)
        self.since_t.fill(math.inf)
        self.pole_t.fill(-math.inf)

    def _recentre(self, floor: Floor, x_mm: float, y_mm: float) -> None:
        """Keep the robot in the middle half of the window, shifting cells by whole cells."""
        if floor is not self.floor:
            self.reset(floor, x_mm, y_mm)
            return
        half = self.n * self.res / 2.0
        cx, cy = self.origin[0] + half, self.origin[1] + half
        if abs(x_mm - cx) < half / 2 and abs(y_mm - cy) < half / 2:
            return
        shift_i = round((x_mm - cx) / self.res)
        shift_j = round((y_mm - cy) / self.res)
        grids: tuple[tuple[np.ndarray, float], ...] = (
            (self.hit_t, -math.inf),
            (self.clear_t, -math.inf),
            (self.since_t, math.inf),
            (self.pole_t, -math.inf),
        )
        for grid, fill in grids:
            moved = np.full_like(grid, fill)
            src_i = slice(max(0, shift_i), min(self.n, self.n + shift_i))
            dst_i = slice(max(0, -shift_i), min(self.n, self.n - shift_i))
            src_j = slice(max(0, shift_j), min(self.n, self.n + shift_j))
            dst_j = slice(max(0, -shift_j), min(self.n, self.n - shift_j))
            moved[dst_i, dst_j] = grid[src_i, src_j]
            grid[...] = moved
        self.origin = (self.origin[0] + shift_i * self.res, self.origin[1] + shift_j * self.res)

    def _cells(self, xs: np.ndarray, ys: np.ndarray, *along: np.ndarray) -> tuple[np.ndarray, ...]:
        """The grid cells (i, j) of the points inside the window, and of each array ``along``
        the points the entries of those inside."""
        i = np.floor((xs - self.origin[0]) / self.res).astype(int)
        j = np.floor((ys - self.origin[1]) / self.res).astype(int)
        inside = (i >= 0) & (i < self.n) & (j >= 0) & (j < self.n)
        return i[inside], j[inside], *(a[inside] for a in along)

    # --- marking and clearing --------------------------------------------------------------

    def update(
        self,
        scan: RangeScan,
        floor: Floor,
        x_mm: float,
        y_mm: float,
        heading_deg: float,
        now: float,
        heading_error_deg: float = 0.0,
        robots: Sequence[np.ndarray] = (),
    ) -> None:
        """Clear each cone up to its reading and mark the arc at the reading. The pose's
        heading may be off by ``heading_error_deg``: only the part of each cone it looks
        through whatever the error is cleared. ``robots``: the outlines of the fleet's
        robots standing nearby (:mod:`coffeebot.navigation.others`); a reading one of them
        explains marks that outline instead of its arc."""
        self._recentre(floor, x_mm, y_mm)
        narrowed = max(0.0, self.half_fov_deg - heading_error_deg)
        clear_spread = spread_rad(narrowed, self._rays)
        readings = {r.sensor: r for r in scan.readings}
        placed = sensor_origins(x_mm, y_mm, heading_deg, self.sensors)
        rays = self._explaining_rays(readings, placed)
        walls = self._explained(floor, rays)
        seen, robot_read = self._robots_seen(robots, rays, walls)
        explained = walls | robot_read
        narrow = self._poles({i: r for i, r in readings.items() if i not in explained})
        # Every cone is cleared and then every arc marked, each in one go: a cell's state
        # after the update is the same in any order (a cell both cleared and marked now is
        # not occupied), and numpy's cost is in the calls, not the points.
        cones: list[tuple[float, float, float, float]] = []  # each cleared: x, y, look, free
        mark_x: list[np.ndarray] = []
        mark_y: list[np.ndarray] = []
        mark_pole: list[np.ndarray] = []
        for sensor, (sx, sy, look) in zip(self.sensors, placed, strict=True):
            reading = readings.get(sensor.id)
            if reading is None or not reading.healthy:
                continue
            if reading.status is ReadingStatus.VALID and reading.distance_mm is not None:
                distance: float | None = float(reading.distance_mm)
                if sensor.id in narrow:
                    # A thin thing before a far one reads beyond where it is (the chip
                    # averages both): placed at the near end of the reading's spread, as the
                    # collision monitor judges it, so the margin is kept from the pole, not
                    # from a point up to ~200 mm behind it.
                    distance = float(near_end_mm(reading))
            elif reading.status in NOTHING_IN_RANGE:
                distance = None
            else:
                continue
            free = MAX_MARK_MM if distance is None else min(distance, MAX_MARK_MM) - self.res
            if free > 0:
                cones.append((sx, sy, look, free))
            if distance is None or distance > MAX_MARK_MM or sensor.id in explained:
                continue  # nothing there, too far to mark, or a wall or robot explains it
            angles = math.radians(look) + self._spread
            mark_x.append(sx + distance * np.cos(angles))
            mark_y.append(sy + distance * np.sin(angles))
            mark_pole.append(np.full(len(angles), sensor.id in narrow))
        for outline in seen:
            xs, ys = outline_points(outline, self.res / 2.0)
            mark_x.append(xs)
            mark_y.append(ys)
            mark_pole.append(np.zeros(len(xs), dtype=bool))
        if cones:
            i, j = self._cells(*self._cleared(cones, clear_spread))
            self.clear_t[i, j] = now
        if mark_x:
            i, j, pole = self._cells(
                np.concatenate(mark_x), np.concatenate(mark_y), np.concatenate(mark_pole)
            )
            fresh = ~self._occupied_at(i, j, now)
            self.since_t[i[fresh], j[fresh]] = now
            self.pole_t[i[pole], j[pole]] = now
            self.hit_t[i, j] = now

    def _cleared(
        self, cones: list[tuple[float, float, float, float]], spread: np.ndarray
    ) -> tuple[np.ndarray, np.ndarray]:
        """The points (x, y) each cone (origin, look in degrees, free distance) clears, along
        its rays ``spread`` (radians off its look) out to its free distance: every cone's in
        one go, cone by cone, ray by ray."""
        x, y, look, free = (np.array(values) for values in zip(*cones, strict=True))
        counts = np.ceil(free / self._step)
        steps = self._steps[: int(counts.max())]
        angles = np.radians(look)[:, None] + spread  # (cones, rays)
        within = np.arange(len(steps)) < counts[:, None, None]  # (cones, 1, steps)
        within = np.broadcast_to(within, (len(cones), len(spread), len(steps)))
        xs = x[:, None, None] + np.cos(angles)[:, :, None] * steps
        ys = y[:, None, None] + np.sin(angles)[:, :, None] * steps
        return xs[within], ys[within]

    def _explaining_rays(
        self, readings: dict[int, RangeReading], placed: list[tuple[float, float, float]]
    ) -> Rays:
        """The sensors with a valid reading near enough to mark, each one's origin (n, 2),
        the rays of its cone widened by ``wall_heading_tolerance_deg`` (n, r), and how far
        something may lie along them to explain the reading, ``wall_margin_mm`` beyond it.
        ``placed``: where each sensor sits and looks (:func:`sensor_origins`)."""
        ids, origins, angles, reach = [], [], [], []
        for sensor, (sx, sy, look) in zip(self.sensors, placed, strict=True):
            reading = readings.get(sensor.id)
            if reading is None or not reading.healthy or reading.status is not ReadingStatus.VALID:
                continue
            if reading.distance_mm is None or reading.distance_mm > MAX_MARK_MM:
                continue
            ids.append(sensor.id)
            origins.append((sx, sy))
            angles.append(math.radians(look) + self._explain)
            reach.append(reading.distance_mm + self.cfg.wall_margin_mm)
        return (
            ids,
            np.array(origins, dtype=float).reshape(-1, 2),
            np.array(angles, dtype=float).reshape(len(ids), len(self._explain)),
            np.array(reach, dtype=float),
        )

    def _explained(self, floor: Floor, rays: Rays) -> frozenset[int]:
        """The sensors whose valid reading the plan's walls explain: some ray of the cone,
        widened by ``wall_heading_tolerance_deg``, meets a wall within ``wall_margin_mm`` of
        it (every sensor's rays cast at once)."""
        ids, origins, angles, reach = rays
        if not ids:
            return frozenset()
        wall = wall_ranges(floor, origins, angles, reach).min(axis=1)
        return frozenset(i for i, explained in zip(ids, wall <= reach, strict=True) if explained)

    @staticmethod
    def _robots_seen(
        robots: Sequence[np.ndarray],
        rays: Rays,
        walls: frozenset[int],
    ) -> tuple[list[np.ndarray], frozenset[int]]:
        """The robot outlines that explain some reading no wall does, as a wall would, and
        the sensors whose reading they explain."""
        ids, origins, angles, reach = rays
        unexplained = np.array([i not in walls for i in ids], dtype=bool)
        if not robots or not unexplained.any():
            return [], frozenset()
        ids = [i for i, keep in zip(ids, unexplained, strict=True) if keep]
        origins, angles, reach = origins[unexplained], angles[unexplained], reach[unexplained]
        seen: list[np.ndarray] = []
        read: set[int] = set()
        for outline in robots:
            ranges = segment_ranges(outline, origins, angles, reach).min(axis=1)
            hits = {i for i, hit in zip(ids, ranges <= reach, strict=True) if hit}
            if hits:
                seen.append(outline)
                read |= hits
        return seen, frozenset(read)

    def _poles(self, readings: dict[int, RangeReading]) -> frozenset[int]:
        """The front sensors whose return is a pole: narrow (the collision monitor's rule:
        one or two adjacent front sensors, the others reading much further or nothing, the
        readings the plan's walls explain counting as further), and not taking in the
        outermost front sensor of the row: such a run may be the edge of something wide
        reaching beyond the row (a box in one half of the lane reads so, the other half's
        sensors seeing the hallway beyond)."""
        if self.narrow_cfg is None:
            return frozenset()
        narrow = narrow_returns(self.sensors, readings, self.narrow_cfg)
        row = sorted(
            (s.id for s in self.sensors if s.face == "front"), key=lambda i: self._front_y[i]
        )
        keep: set[int] = set()
        run: list[int] = []
        for k, ident in enumerate(row):
            if ident in narrow:
                run.append(ident)
            if run and (ident not in narrow or k == len(row) - 1):
                if row[0] not in run and row[-1] not in run:
                    keep.update(run)
                run = []
        return frozenset(keep)

    def mark_camera(self, marks: CameraMarks, until_s: float) -> None:
        """Replace the camera layer with ``marks``, which hold until ``until_s`` unless
        replaced before: a layer that stops coming is no information."""
        self._camera, self._camera_until = marks, until_s

    def _camera_points(self, now: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """The camera layer's points on this floor within ``lookahead_mm`` of the window (the
        furthest the detour asks about), and since when each has stood."""
        marks = None if self.floor is None else self._camera.get(self.floor.level)
        if marks is None or now > self._camera_until:
            return np.empty(0), np.empty(0), np.empty(0)
        xs, ys, since = marks
        lo_x, lo_y = self.origin[0] - self.cfg.lookahead_mm, self.origin[1] - self.cfg.lookahead_mm
        span = self.n * self.res + 2 * self.cfg.lookahead_mm
        near = (xs >= lo_x) & (xs <= lo_x + span) & (ys >= lo_y) & (ys <= lo_y + span)
        return xs[near], ys[near], since[near]

    def _occupied_at(self, i: np.ndarray, j: np.ndarray, now: float) -> np.ndarray:
        hit = self.hit_t[i, j]
        return (hit > self.clear_t[i, j]) & (now - hit <= self.cfg.obstacle_memory_s)

    def _occupied(self, now: float) -> tuple[np.ndarray, np.ndarray]:
        occupied = (self.hit_t > self.clear_t) & (now - self.hit_t <= self.cfg.obstacle_memory_s)
        i, j = np.nonzero(occupied)
        return i, j

    def obstacles(self, now: float) -> Obstacles:
        """Centres of occupied cells, then the camera layer's points: where, since when, and
        the clearance each needs beyond everything else's (``narrow_margin_mm`` for a narrow
        return's cell, else 0)."""
        i, j = self._occupied(now)
        xs, ys = self._centres(i, j)
        camera_x, camera_y, camera_since = self._camera_points(now)
        pole = now - self.pole_t[i, j] <= self.cfg.obstacle_memory_s
        return Obstacles(
            np.concatenate([xs, camera_x]),
            np.concatenate([ys, camera_y]),
            np.concatenate([self.since_t[i, j], camera_since]),
            np.concatenate([np.where(pole, self.narrow_margin_mm, 0.0), np.zeros(camera_x.size)]),
        )

    def forget_marks(
        self, now: float, which: Callable[[np.ndarray, np.ndarray, np.ndarray], np.ndarray]
    ) -> None:
        """Clear the occupied cells ``which`` picks from their centres (x, y) and when each
        was last marked: what marked them is known, other than by looking, to have gone
        (:mod:`coffeebot.navigation.trails`)."""
        i, j = self._occupied(now)
        picked = which(*self._centres(i, j), self.hit_t[i, j])
        self.clear_t[i[picked], j[picked]] = now

    def _centres(self, i: np.ndarray, j: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """The centres (x, y) of grid cells (i, j)."""
        return self.origin[0] + (i + 0.5) * self.res, self.origin[1] + (j + 0.5) * self.res

    # --- cost queries ----------------------------------------------------------------------

    def obstacle_gaps(
        self,
        xs: np.ndarray,
        ys: np.ndarray,
        thetas: np.ndarray,
        now: float,
        footprint: Footprint | None = None,
    ) -> np.ndarray:
        """For each pose, the smallest gap between the body (``footprint``, by default the
        planner's, front extension included) and an obstacle cell (inf: none); a narrow
        return's cell counts ``narrow_margin_mm`` nearer than it is, for what it may carry."""
        ox, oy, _, margins = self.obstacles(now)
        if ox.size == 0:
            return np.full(np.shape(xs), math.inf)
        dx = ox[None, :] - np.ravel(xs)[:, None]
        dy = oy[None, :] - np.ravel(ys)[:, None]
        c, s = np.cos(np.ravel(thetas))[:, None], np.sin(np.ravel(thetas))[:, None]
        local_x, local_y = c * dx + s * dy, -s * dx + c * dy
        body = footprint or self.footprint
        gaps = (body.gap_mm(local_x, local_y) - margins[None, :]).min(axis=1) - self.res / 2.0
        return gaps.reshape(np.shape(xs))

    def wall_gaps(
        self, xs: np.ndarray, ys: np.ndarray, thetas: np.ndarray, rear_allowance_mm: float = 0.0
    ) -> np.ndarray:
        """For each pose, the smallest gap between the body's rectangle and a plan wall, the
        rear corners counted ``rear_allowance_mm`` wider; negative where a corner lies
        beyond a wall (the wall between it and the centre), by that corner's distance to it.

        Exact for a convex body and straight walls that do not cross it: the nearest points
        are a wall end against the rectangle or a body corner against a wall. A turn near a
        wall swings the corners out past the half width, which a centre distance misses.
        Without the sign, a turn checked every few degrees could carry a corner through a
        wall and find it clear again on the far side (a half turn beside a wall was judged
        free, and its rear corner struck the wall).
        """
        shape = np.shape(xs)
        if self.floor is None:
            return np.full(shape, math.inf)
        x, y, th = np.ravel(xs), np.ravel(ys), np.ravel(thetas)
        # Only walls near the poses are measured; further ones read as inf (nothing beyond
        # the side clearance plus the inflation distance changes the cost).
        body_reach = math.hypot(self.footprint.length_mm, self.footprint.width_mm) / 2.0
        reach = (
            math.hypot(np.ptp(x), np.ptp(y)) / 2.0
            + body_reach
            + self.cfg.side_clearance_mm
            + self.cfg.inflation_mm
        )
        seg = self.floor.segment_array
        middle_x, middle_y = (x.min() + x.max()) / 2.0, (y.min() + y.max()) / 2.0
        seg = seg[segment_distances(seg, float(middle_x), float(middle_y)) <= reach]
        if seg.size == 0:
            return np.full(shape, math.inf)
        c, s = np.cos(th)[:, None], np.sin(th)[:, None]
        ends_x = np.concatenate([seg[:, 0], seg[:, 2]])[None, :] - x[:, None]
        ends_y = np.concatenate([seg[:, 1], seg[:, 3]])[None, :] - y[:, None]
        from_ends = self.body.gap_mm(c * ends_x + s * ends_y, -s * ends_x + c * ends_y)
        from_ends = from_ends.min(axis=1)
        corners = self._corners
        cx = (x[:, None] + c * corners[:, 0] - s * corners[:, 1]).reshape(-1, 1)
        cy = (y[:, None] + s * corners[:, 0] + c * corners[:, 1]).reshape(-1, 1)
        distances = segment_distances(seg, cx, cy)
        # A wall between a corner and the centre lies within the corner's reach of it.
        pose, wall = np.nonzero(distances < body_reach)
        beyond = segments_crossed(seg[wall], x[pose // 4], y[pose // 4], cx[pose, 0], cy[pose, 0])
        distances[pose[beyond], wall[beyond]] *= -1.0
        per_corner = distances.min(axis=1).reshape(-1, 4)
        from_corners = (per_corner + self._rear_corners * rear_allowance_mm).min(axis=1)
        return np.minimum(from_ends, from_corners).reshape(shape)

    def cost(
        self,
        obstacle_gap_mm: np.ndarray,
        wall_gap_mm: np.ndarray,
        clearances: Clearances | None = None,
    ) -> np.ndarray:
        """Inflated cost in [0, 1], ``inf`` where the pose is lethal: nearer a wall or an
        obstacle than its clearance (``clearances``, default the configured ones)."""
        cfg = self.cfg
        if clearances is None:
            clearances = Clearances(cfg.side_clearance_mm, cfg.obstacle_clearance_mm)
        wall_gap = wall_gap_mm - clearances.wall_mm
        obstacle_gap = obstacle_gap_mm - clearances.obstacle_mm
        gap = np.minimum(wall_gap, obstacle_gap)
        cost = np.exp(-np.maximum(obstacle_gap, 0.0) / max(cfg.inflation_mm, 1.0))
        return np.where(gap < 0.0, math.inf, cost)

    def admissible(
        self,
        xs: np.ndarray,
        ys: np.ndarray,
        thetas: np.ndarray,
        start: tuple[float, float, float],
        now: float,
        footprint: Footprint | None = None,
        clearances: Clearances | None = None,
    ) -> tuple[np.ndarray, np.ndarray]:
        """For paths of poses (rows over time) leaving ``start`` (x, y, heading rad): which
        are admissible, and each one's worst cost (inf where not admissible); ``clearances``
        in place of the configured ones (:meth:`cost`).

        A path is admissible if no pose on it is lethal. From a start that is itself inside
        a lethal zone (the obstacle came closer, was seen late, or the pose estimate moved),
        a path that never comes nearer to that obstacle is admissible too; near a wall, one
        that ends no nearer to it and never comes within half the present gap on the way (a
        turn swings the rear towards it first). Either must keep clear of everything else:
        otherwise the robot could never get out.

        With the configured clearances the rear corners keep only ``turn_clearance_mm`` to
        the walls, as a turn on the spot does: no sensor watches them (the side stop cannot
        trip on them), and turning away from a wall about the front axle swings them towards
        it first. Held to the side clearance, a robot 100 mm from the wall, heading a degree
        or two towards it, found no arc but creeping straight on, and crept 2.85 m along it
        in 115 s to the car, whose turn in then had no room.
        """
        gaps = self.obstacle_gaps(xs, ys, thetas, now, footprint)
        cfg = self.cfg
        rear = 0.0 if clearances is not None else cfg.side_clearance_mm - cfg.turn_clearance_mm
        walls = self.wall_gaps(xs, ys, thetas, rear)
        worst = self.cost(gaps, walls, clearances).max(axis=1)
        hx, hy, htheta = (np.array([v]) for v in start)
        here_gap = float(self.obstacle_gaps(hx, hy, htheta, now, footprint)[0])
        here_wall = float(self.wall_gaps(hx, hy, htheta, rear)[0])

        def clear(obstacle_gaps: np.ndarray, wall_gaps: np.ndarray) -> np.ndarray:
            """Per path (the last axis over time): never lethal."""
            return np.asarray(np.isfinite(self.cost(obstacle_gaps, wall_gaps, clearances)).all(-1))

        none = np.array([math.inf])
        inside_obstacle = not clear(np.array([here_gap]), none)
        inside_wall = not clear(none, np.array([here_wall]))
        if not (inside_obstacle or inside_wall):
            return np.isfinite(worst), worst
        if inside_obstacle:
            # Never nearer to an obstacle: it may be a person, and the side stop is close.
            obstacle_ok = gaps.min(axis=1) >= here_gap - 1.0
        else:
            obstacle_ok = clear(gaps, np.full_like(walls, math.inf))
        if inside_wall:
            wall_ok = _escapes(walls, here_wall)
        else:
            wall_ok = clear(np.full_like(gaps, math.inf), walls)
        admissible = obstacle_ok & wall_ok
        return admissible, np.where(admissible, 1.0, math.inf)


def _escapes(gaps: np.ndarray, start_gap: float) -> np.ndarray:
    """Per path (rows of ``gaps`` over time): ends no nearer than it starts and never comes
    within half the starting gap on the way; from a start already past a wall (the
    estimate moved), never further past it."""
    least = start_gap / 2.0 if start_gap > 0.0 else start_gap - 1.0
    return (gaps[:, -1] >= start_gap - 1.0) & (gaps.min(axis=1) >= least)
