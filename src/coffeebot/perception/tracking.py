"""Returns followed over scans with a velocity: who is walking into the robot's way.

The collision rules judge what is in the corridor now. A person stepping in diagonally ahead
is in it only once it is too late to stop, but before that they are a return in one of the
outer cones that moves sideways. So every valid front or side reading becomes a point in a
local odometry frame (dead-reckoned from the wheel speeds between scans: the robot's own
motion is taken out), and points are associated with tracks that each carry a constant-
velocity Kalman filter. A reading's position is precise along the cone's axis and vague
across it (the return may come from anywhere in the cone), which the measurement noise says.

A track confirmed by ``confirm_hits`` points is a *mover* once its speed exceeds
``mover_speed_mm_s``; :meth:`ReturnTracker.intrusion` predicts, for the robot driving on at
its speed, whether and when a mover enters the corridor ahead of the body. A static return
(a wall, a box) yields a track with no velocity and is left to the corridor rules. A mover
that drops out of every cone is not gone: :meth:`ReturnTracker.lost_near` remembers where it
was last, for ``lost_mover_s``, so the robot can go carefully past where someone may step
back out of its blind spots.
"""

from __future__ import annotations

import math
from collections.abc import Collection, Iterable
from dataclasses import dataclass, field

import numpy as np
from scipy.optimize import linear_sum_assignment

from coffeebot.config import TofSensorConfig, TrackingConfig
from coffeebot.messages import RangeScan, ReadingStatus

TRANSITIONS_KEPT = 16
"""Step lengths whose prediction matrices a tracker keeps (the scan period's few values)."""


@dataclass(frozen=True)
class Sighting:
    """One reading as a point in the odometry frame, with its measurement covariance."""

    x_mm: float
    y_mm: float
    covariance: np.ndarray
    sensor: int


@dataclass
class Track:
    id: int
    state: np.ndarray
    """x, y, vx, vy in the odometry frame (mm, mm/s)."""
    covariance: np.ndarray
    last_s: float
    hits: int = 1
    sensors: set[int] = field(default_factory=set)

    @property
    def speed_mm_s(self) -> float:
        return float(math.hypot(self.state[2], self.state[3]))


@dataclass(frozen=True)
class Intrusion:
    """A mover predicted to be in the corridor ahead of the body."""

    track: int
    time_s: float
    """From now until it is in the corridor, the robot driving on."""
    ahead_mm: float
    """Where, ahead of the front face (robot frame), when it gets there."""
    speed_mm_s: float


@dataclass(frozen=True)
class LostMover:
    """A mover no cone sees any more: where it was last seen (odometry frame), and when."""

    x_mm: float
    y_mm: float
    t_s: float


def _in_frame(pose: tuple[float, float, float], x: float, y: float) -> tuple[float, float]:
    """An odometry-frame point in the robot frame of ``pose`` (x, y, theta)."""
    c, s = math.cos(pose[2]), math.sin(pose[2])
    dx, dy = x - pose[0], y - pose[1]
    return c * dx + s * dy, -s * dx + c * dy


class Odometry2D:
    """The robot's pose in a local frame, dead-reckoned from speed and yaw rate."""

    def __init__(self) -> None:
        self.x = self.y = self.theta = 0.0

    def advance(self, speed_mm_s: float, yaw_rate_dps: float, dt_s: float) -> None:
        w = math.radians(yaw_rate_dps)
        mid = self.theta + w * dt_s / 2.0
        self.x += speed_mm_s * dt_s * math.cos(mid)
        self.y += speed_mm_s * dt_s * math.sin(mid)
        self.theta += w * dt_s

    def to_local(self, x: float, y: float) -> tuple[float, float]:
        """An odometry-frame point in the robot frame."""
        return _in_frame((self.x, self.y, self.theta), x, y)

    def to_odom(self, x: float, y: float) -> tuple[float, float]:
        c, s = math.cos(self.theta), math.sin(self.theta)
        return self.x + c * x - s * y, self.y + s * x + c * y

    def snapshot(self) -> tuple[float, float, float]:
        return self.x, self.y, self.theta

    def since(self, snapshot: tuple[float, float, float]) -> tuple[float, float, float]:
        """How far the robot moved since ``snapshot``: (forward mm, left mm, turned rad) in
        the robot frame it had then."""
        forward, left = _in_frame(snapshot, self.x, self.y)
        return forward, left, self.theta - snapshot[2]

    def rotate_to_local(self, vx: float, vy: float) -> tuple[float, float]:
        c, s = math.cos(self.theta), math.sin(self.theta)
        return c * vx + s * vy, -s * vx + c * vy


class ReturnTracker:
    """Tracks of valid readings in a local odometry frame (see the module docstring)."""

    def __init__(self, sensors: Iterable[TofSensorConfig], cfg: TrackingConfig) -> None:
        self.cfg = cfg
        self.sensors = {s.id: s for s in sensors}
        self.odometry = Odometry2D()
        self.tracks: list[Track] = []
        self.lost: list[LostMover] = []
        self._next_id = 1
        self._last_t: float | None = None
        self._transitions: dict[tuple[float, float], tuple[np.ndarray, np.ndarray]] = {}
        """:meth:`_transition`'s arrays by (step length, acceleration variance)."""

    def sightings(self, scan: RangeScan, skip: Collection[int] = ()) -> list[Sighting]:
        """Each healthy valid reading within ``max_range_mm`` and ``max_sigma_mm`` as a point
        in the odometry frame, but those of the sensors in ``skip``: a reading with a larger
        sigma is a blend of near and far returns, a position that jumps between them."""
        found = []
        for reading in scan.readings:
            sensor = self.sensors.get(reading.sensor)
            if (
                sensor is None
                or reading.sensor in skip
                or not reading.healthy
                or reading.status is not ReadingStatus.VALID
                or reading.distance_mm is None
                or reading.distance_mm > self.cfg.max_range_mm
                or (reading.sigma_mm or 0.0) > self.cfg.max_sigma_mm
            ):
                continue
            d = float(reading.distance_mm)
            look = math.radians(sensor.yaw_deg)
            lx = sensor.x_mm + d * math.cos(look)
            ly = sensor.y_mm + d * math.sin(look)
            x, y = self.odometry.to_odom(lx, ly)
            across = max(d * math.tan(math.radians(sensor.fov_deg / 2.0)) / 2.0, 20.0)
            # The chip's own sigma widens the point along the axis: a far or dim return (a
            # person 2 m ahead) counts, but moves the track less than a crisp one.
            along = math.hypot(self.cfg.range_sigma_mm, reading.sigma_mm or 0.0)
            heading = self.odometry.theta + look
            c, s = math.cos(heading), math.sin(heading)
            rotation = np.array([[c, -s], [s, c]])
            covariance = rotation @ np.diag([along**2, across**2]) @ rotation.T
            found.append(Sighting(x, y, covariance, reading.sensor))
        return found

    def update(
        self,
        scan: RangeScan,
        speed_mm_s: float,
        yaw_rate_dps: float,
        skip: Collection[int] = (),
    ) -> list[Track]:
        """Advance by the robot's motion since the last scan, associate, correct, prune;
        the readings of the sensors in ``skip`` (the walls) are left out."""
        now = scan.cycle_start_s
        dt = 0.0 if self._last_t is None else max(0.0, now - self._last_t)
        self._last_t = now
        self.odometry.advance(speed_mm_s, yaw_rate_dps, dt)
        if self.turning_in_place(speed_mm_s, yaw_rate_dps):
            # The cones sweep along the walls: their returns slide, nobody walks.
            self.tracks = []
            return self.tracks
        for track in self.tracks:
            self._predict(track, dt)
        sightings = self.sightings(scan, skip)
        matched = self._associate(sightings)
        used = set()
        for t_index, s_index in matched:
            track, sighting = self.tracks[t_index], sightings[s_index]
            self._correct(track, sighting, now)
            used.add(s_index)
        for k, sighting in enumerate(sightings):
            if k not in used:
                self._start(sighting, now)
        movers = {t.id for t in self.movers()}
        for track in self.tracks:
            if now - track.last_s > self.cfg.forget_s and track.id in movers:
                self.lost.append(LostMover(float(track.state[0]), float(track.state[1]), now))
        self.lost = [m for m in self.lost if now - m.t_s <= self.cfg.lost_mover_s]
        self.tracks = [t for t in self.tracks if now - t.last_s <= self.cfg.forget_s]
        return self.tracks

    def turning_in_place(self, speed_mm_s: float, yaw_rate_dps: float) -> bool:
        cfg = self.cfg
        return (
            abs(yaw_rate_dps) >= cfg.turn_in_place_dps
            and abs(speed_mm_s) < cfg.turn_in_place_speed_mm_s
        )

    def _predict(self, track: Track, dt: float) -> None:
        f, noise = self._transition(dt)
        track.state = f @ track.state
        track.covariance = f @ track.covariance @ f.T + noise

    def _transition(self, dt: float) -> tuple[np.ndarray, np.ndarray]:
        """The constant-velocity step over ``dt`` and the process noise it adds, kept for
        the step lengths seen last: every track is predicted every scan, and the scan period
        takes a handful of distinct values (the same arrays, built once each)."""
        q = self.cfg.accel_sigma_mm_s2**2
        cached = self._transitions.get((dt, q))
        if cached is None:
            f = np.eye(4)
            f[0, 2] = f[1, 3] = dt
            g = np.array([[dt * dt / 2, 0], [0, dt * dt / 2], [dt, 0], [0, dt]])
            cached = (f, g @ (q * np.eye(2)) @ g.T)
            for array in cached:
                array.flags.writeable = False
            if len(self._transitions) >= TRANSITIONS_KEPT:
                self._transitions.clear()
            self._transitions[dt, q] = cached
        return cached

    def _associate(self, sightings: list[Sighting]) -> list[tuple[int, int]]:
        """Track-sighting pairs within the gate, the best overall (Hungarian)."""
        if not self.tracks or not sightings:
            return []
        gate = self.cfg.gate_sigmas**2
        cost = np.full((len(self.tracks), len(sightings)), 1e9)
        for i, track in enumerate(self.tracks):
            for j, sighting in enumerate(sightings):
                residual = np.array([sighting.x_mm, sighting.y_mm]) - track.state[:2]
                innovation = track.covariance[:2, :2] + sighting.covariance
                d2 = float(residual @ np.linalg.solve(innovation, residual))
                if d2 <= gate:
                    cost[i, j] = d2
        rows, cols = linear_sum_assignment(cost)
        return [(int(i), int(j)) for i, j in zip(rows, cols, strict=True) if cost[i, j] < 1e9]

    def _correct(self, track: Track, sighting: Sighting, now: float) -> None:
        h = np.zeros((2, 4))
        h[0, 0] = h[1, 1] = 1.0
        residual = np.array([sighting.x_mm, sighting.y_mm]) - h @ track.state
        s = h @ track.covariance @ h.T + sighting.covariance
        gain = track.covariance @ h.T @ np.linalg.inv(s)
        track.state = track.state + gain @ residual
        track.covariance = (np.eye(4) - gain @ h) @ track.covariance
        track.last_s = now
        track.hits += 1
        track.sensors.add(sighting.sensor)

    def _start(self, sighting: Sighting, now: float) -> None:
        covariance = np.zeros((4, 4))
        covariance[:2, :2] = sighting.covariance
        v = self.cfg.initial_speed_sigma_mm_s**2
        covariance[2, 2] = covariance[3, 3] = v
        state = np.array([sighting.x_mm, sighting.y_mm, 0.0, 0.0])
        self.tracks.append(Track(self._next_id, state, covariance, now, 1, {sighting.sensor}))
        self._next_id += 1

    def movers(self) -> list[Track]:
        """Confirmed tracks moving over the ground faster than ``mover_speed_mm_s`` and no
        faster than anyone walks or runs indoors (faster is readings jumping between things)."""
        cfg = self.cfg
        return [
            t
            for t in self.tracks
            if t.hits >= cfg.confirm_hits
            and cfg.mover_speed_mm_s <= t.speed_mm_s <= cfg.max_mover_speed_mm_s
        ]

    def speed_sigma_ahead_mm_s(self, track: Track) -> float:
        """The 1-sigma uncertainty of ``track``'s velocity along the robot's heading: large
        while a new track's velocity is still being learned."""
        c, s = math.cos(self.odometry.theta), math.sin(self.odometry.theta)
        p = track.covariance[2:, 2:]
        variance = c * c * p[0, 0] + 2.0 * c * s * p[0, 1] + s * s * p[1, 1]
        return math.sqrt(max(0.0, float(variance)))

    def lost_near(self, front_mm: float, half_width_mm: float, reach_mm: float) -> LostMover | None:
        """The latest lost mover last seen beside or in the corridor ahead: within
        ``reach_mm`` of it sideways, from the rear of the body to ``reach_mm`` past its front
        (robot frame); None if none."""
        for lost in reversed(self.lost):
            x, y = self.odometry.to_local(lost.x_mm, lost.y_mm)
            if -front_mm <= x <= front_mm + reach_mm and abs(y) <= half_width_mm + reach_mm:
                return lost
        return None

    def intrusion(
        self,
        speed_mm_s: float,
        front_mm: float,
        half_width_mm: float,
        horizon_s: float,
        step_s: float = 0.05,
    ) -> Intrusion | None:
        """The earliest mover outside the corridor predicted inside it, ahead of the body,
        within ``horizon_s``, the robot driving straight on at ``speed_mm_s``; None if none."""
        best: Intrusion | None = None
        margin = self.cfg.corridor_margin_mm
        times = np.arange(0.0, horizon_s + step_s / 2, step_s)
        for track in self.movers():
            x0, y0 = self.odometry.to_local(track.state[0], track.state[1])
            if abs(y0) <= half_width_mm + margin:
                continue  # in the corridor already: the corridor rules judge it
            vx, vy = self.odometry.rotate_to_local(track.state[2], track.state[3])
            # In the robot frame while it drives on, the mover's ground velocity less the
            # robot's own.
            xs = x0 + (vx - speed_mm_s) * times
            ys = y0 + vy * times
            inside = (np.abs(ys) <= half_width_mm + margin) & (xs >= front_mm)
            if not inside.any():
                continue
            k = int(np.argmax(inside))
            found = Intrusion(track.id, float(times[k]), float(xs[k] - front_mm), track.speed_mm_s)
            if best is None or found.time_s < best.time_s:
                best = found
        return best
