"""The collision verdict for one scan: seed 000's "private sphere", made speed-aware.

Seed rules: start in "stop"; "go" only once every face is clear; front radius 200 mm, side
radius 50 mm. Beyond the seed (in the spirit of nav2's collision monitor): the front stop
distance grows with speed as ``v*t + v^2/(2a) + margin`` and never drops below the seed's
radius; a slowdown zone lies in front of it; leaving a face's zone needs ``hysteresis_mm``
more clearance than entering it, so a reading jittering on a boundary does not chatter. The
hysteresis is the face's own: a robot held by something ahead, 60 mm from a wall beside it,
is outside the side's zone and drives on once the front clears (a hysteresis of the whole
verdict would hold it there for good, the side gap never growing). A sensor
that is unhealthy, reports a hardware/bus failure, or has had no usable reading for
``stale_cycles`` scans makes the verdict "stop" (driving blind is never "go"); a sensor that
sees nothing within its range is clear.

Beyond that, a return seen by only one or two adjacent front sensors while the others read
much further is narrow: a pole, a chair leg, a person's legs. What stands on a pole often
spreads out above the cones (a swivel chair's seat overhangs its pole by ~240 mm at
430-500 mm, where the body is), so a narrow return gets ``narrow_margin_mm`` more clearance,
in the stop distance and in the slowdown speed alike.

Things also drop out of view up close: a seat's edge leaves the top of the cone, a chair leg
falls between what the cone resolves, a person steps out of the cone and back. So a front
return that can only lie inside the body's corridor (the cone's whole footprint at that range
is within the body's width, so it cannot be a glance off a side wall) is remembered for
``memory_s``: its distance shrinks by the distance driven since (integrated from the speed),
and while it is nearer than what the sensor now reads it stands in for the reading. Only the
nearest such return per sensor is kept. Turning on the spot is not tracked: it does not close
the distance, and the memory is short.

Side readings measure the gap from the body directly (the sensors sit on the body's sides),
and so do front readings, so the radii apply to the raw distances.

A front reading is judged by where it can lie: somewhere on the arc its cone spans at that
range. Only the part of the arc inside the corridor the body sweeps driving ahead (its width
plus ``corridor_margin_mm`` each side) is in the way, at its distance ahead of the front face;
a toed-out outer sensor's glance off a side wall outside the corridor is not. A reading of
the VL53L1X is the signal-weighted mean of what its cone sees, so the nearest thing in the
arc is at most that far: the rule stays on the safe side of a blend.

Things moving into the way are seen before they are in it by :class:`ReturnTracker`: a mover
predicted inside the corridor ahead of the body stops the robot when the robot could not
stop short of where it enters, and slows it when it could only at a lower speed.

Held, the robot gets two ways out. A stop whose only cause is something ahead (no fault,
sides clear, nothing coming nearer) may turn on the spot (``may_rotate``). A stop whose only
cause is something within the side radius, with nothing ahead, may creep straight ahead
(``may_creep_ahead``): driving straight keeps the side gap, and nothing turns a corner into
it.
"""

from __future__ import annotations

import math
from collections.abc import Iterable
from dataclasses import dataclass

import numpy as np

from coffeebot.config import CollisionConfig, TofSensorConfig, TrackingConfig
from coffeebot.messages import (
    NOTHING_IN_RANGE,
    CollisionStatus,
    RangeReading,
    RangeScan,
    ReadingStatus,
    SafetyState,
)
from coffeebot.perception.geometry import valid_distance
from coffeebot.perception.tracking import Intrusion, ReturnTracker
from coffeebot.perception.walls import Explainer

FAILED = frozenset({ReadingStatus.HARDWARE_FAIL, ReadingStatus.BUS_ERROR})
"""Statuses meaning the sensor itself is broken: stop at once, do not wait for staleness."""

_RANK = {SafetyState.GO: 0, SafetyState.SLOW: 1, SafetyState.STOP: 2}

CLEARANCE_SMOOTHING = 0.2
"""Weight of each new scan in the smoothed front clearance that ``may_rotate`` watches."""

PATH_STEP_MM = 25.0
PATH_REACH_MM = 2500.0
"""Along a curved path the body is swept this far, in these steps, to find what it meets."""
_TRAVEL = np.arange(0.0, PATH_REACH_MM, PATH_STEP_MM)[:, None]
_TRAVEL.flags.writeable = False
"""The axle's travel at each step of the sweep (S, 1)."""
MIN_CURVATURE_PER_MM = 1e-5
"""Flatter than this (a 100 m radius) the path is straight ahead."""
MIN_ARC_SPEED_MM_S = 50.0
"""Slower than this the path is judged straight: turning on the spot is ``may_rotate``'s."""

REST_DPS = 2.0
REST_MM_S = 10.0
"""Turning and driving slower than these (by the wheels), the robot is at rest."""

ARC_SAMPLES = 9
"""Points along a front reading's arc when asking which part of it is in the corridor."""

NEAR_END_SIGMAS = 1.5
"""A valid reading counts this many of its reported sigmas nearer than it reads. The chip
averages every return in its cone, so a thin thing in front of a far one reads beyond where
it is, and says so with a large sigma (the spread of the returns): a pole 1.13 m ahead of a
wall reads ~1.31 m with sigma ~140 mm. Clean targets report a few mm and lose next to
nothing."""

ROTATE_NOISE_MM = 10.0
"""How much the front clearance may read below its value at the start of a stop and still
count as not decreasing while turning on the spot: two readings' noise (+/-5 mm each) up
close; a reading that reports a larger sigma (a blend, a dark target) gets twice that."""


def near_end_mm(reading: RangeReading) -> int:
    """The near end of a valid reading's spread: where to assume the nearest thing is."""
    assert reading.distance_mm is not None, "only valid readings have a distance"
    return max(0, round(reading.distance_mm - NEAR_END_SIGMAS * (reading.sigma_mm or 0.0)))


@dataclass(frozen=True)
class _Sighting:
    """A front return remembered in the robot's frame of travel."""

    distance_mm: float
    travel_mm: float
    """The odometer when it was seen."""
    turned_deg: float
    """The turn counter when it was seen: once the body has turned away, it is not ahead."""
    t_s: float
    narrow: bool


@dataclass(frozen=True)
class _Finding:
    """What one sensor says this scan, before the verdict is combined across sensors."""

    state: SafetyState
    sensor: TofSensorConfig
    distance_mm: int | None
    reason: str
    speed_limit_mm_s: float
    gap_mm: float | None = None
    """How far it is from where the body meets it: ahead of the front face, or off a side."""
    moving: bool = False
    """A tracked mover's predicted entry into the corridor, not a reading."""
    sigma_mm: float = 0.0
    """The sigma the sensor reported with its reading (0 when it said none)."""


def narrow_returns(
    sensors: Iterable[TofSensorConfig], readings: dict[int, RangeReading], cfg: CollisionConfig
) -> frozenset[int]:
    """Front sensors whose return is narrow: a pole, a chair leg, a person's legs. It and the
    adjacent sensors reading within ``narrow_depth_mm`` beyond it form a run of at most
    ``narrow_max_sensors``, so the sensors on either side of the run read much further (or
    nothing). The collision monitor and the costmap the detour plans on both ask this."""
    row = sorted((s for s in sensors if s.face == "front"), key=lambda s: s.y_mm)
    distances = [valid_distance(readings.get(s.id)) for s in row]
    found: set[int] = set()
    for i, distance in enumerate(distances):
        if distance is None or distance > cfg.narrow_max_range_mm:
            continue
        near = [d is not None and d < distance + cfg.narrow_depth_mm for d in distances]
        lo, hi = i, i
        while lo > 0 and near[lo - 1]:
            lo -= 1
        while hi < len(row) - 1 and near[hi + 1]:
            hi += 1
        if hi - lo + 1 <= cfg.narrow_max_sensors:
            found.add(row[i].id)
    return frozenset(found)


def stop_distance_mm(cfg: CollisionConfig, speed_mm_s: float) -> float:
    """Distance to stop from ``speed_mm_s`` towards the obstacle; never below the seed radius."""
    v = max(0.0, speed_mm_s)
    kinematic = v * cfg.reaction_latency_s + v * v / (2.0 * cfg.braking_mm_s2) + cfg.margin_mm
    return max(cfg.front_radius_mm, kinematic)


def safe_speed_mm_s(cfg: CollisionConfig, room_mm: float, closing_mm_s: float = 0.0) -> float:
    """The highest speed that can still be braked to zero within ``room_mm``, while what is
    ahead comes closer at ``closing_mm_s`` until the robot stands (it covers part of the
    room): ``v t + v^2 / 2a + c (t + v / a) <= room``."""
    a, t, c = cfg.braking_mm_s2, cfg.reaction_latency_s, max(0.0, closing_mm_s)
    room = room_mm - c * t
    if room <= 0:
        return 0.0
    reach = t + c / a
    return a * (-reach + math.sqrt(reach * reach + 2.0 * room / a))


class CollisionMonitor:
    """Turns each :class:`RangeScan` into a :class:`CollisionStatus`, synchronously.

    ``update`` does no I/O and never awaits, so the module can publish the verdict in the same
    event-loop turn in which the scan arrived.
    """

    def __init__(
        self,
        sensors: Iterable[TofSensorConfig],
        cfg: CollisionConfig,
        max_speed_mm_s: float,
        max_range_mm: int = 4000,
        body_width_mm: float = 510.0,
        body_length_mm: float = 610.0,
        tracking: TrackingConfig | None = None,
        axle_x_mm: float = 150.0,
    ) -> None:
        self.cfg = cfg
        self.sensors = {s.id: s for s in sensors}
        self.max_speed_mm_s = max_speed_mm_s
        self.max_range_mm = max_range_mm
        self.half_width_mm = body_width_mm / 2.0
        self.front_mm = body_length_mm / 2.0
        self._front_sensor = next(s for s in self.sensors.values() if s.face == "front")
        """The sensor a tracked mover's finding is filed under (it is no one reading)."""
        self.axle_x_mm = axle_x_mm
        self._front_sweep_mm = math.hypot(self.front_mm - axle_x_mm, self.half_width_mm)
        """How far from the axle the front corners reach when the body turns on the spot."""
        self.state = SafetyState.STOP
        """Seed rule: the robot starts in "stop" and only goes once every face is clear."""
        self._faces = {s.face: SafetyState.STOP for s in self.sensors.values()}
        """Each face's verdict at the last scan, for its hysteresis; every face starts held."""
        self._missed = dict.fromkeys(self.sensors, cfg.stale_cycles)
        """Consecutive scans without a usable reading; starts stale so the first scan counts."""
        self._corridor_mm = {
            s.id: max(0.0, body_width_mm / 2.0 - abs(s.y_mm))
            / math.tan(math.radians(s.fov_deg / 2))
            for s in self.sensors.values()
            if s.face == "front"
        }
        """Per front sensor: the range within which its whole cone lies inside the body's width."""
        self._arcs = {
            s.id: np.radians(s.yaw_deg + np.linspace(-s.fov_deg / 2, s.fov_deg / 2, ARC_SAMPLES))
            for s in self.sensors.values()
            if s.face == "front"
        }
        self.tracker = ReturnTracker(self.sensors.values(), tracking or TrackingConfig())
        self._memory: dict[int, _Sighting] = {}
        self._travel_mm = 0.0
        self._turned_deg = 0.0
        self._last_t: float | None = None
        self._stop_clearance: float | None = None
        """The front clearance once the robot came to rest in the current front stop."""
        self._clearance_ema: float | None = None
        """The front clearance smoothed over scans (a noisy blend jitters by tens of mm)."""
        self._side_gap: float | None = None
        """The side gap when the current side hold began."""

    def ahead_mm(
        self,
        sensor: TofSensorConfig,
        distance: float,
        where: np.ndarray | None = None,
        curvature_per_mm: float = 0.0,
    ) -> float | None:
        """How far the body can drive on along its present arc (``curvature_per_mm``, left
        positive; 0: straight ahead) before a front reading is in its way (None: never
        within ``PATH_REACH_MM``, so it is not in the way). The reading lies somewhere on the
        arc its cone spans, or at robot-frame points ``where`` (k, 2) when the plan's walls
        explain it."""
        if where is None:
            angles = self._arcs[sensor.id]
            xs = sensor.x_mm + distance * np.cos(angles)
            ys = sensor.y_mm + distance * np.sin(angles)
            margin = self.cfg.corridor_margin_mm
        else:
            # A wall return is where the plan says: only the seed's side radius is kept.
            xs, ys = where[:, 0], where[:, 1]
            margin = self.cfg.side_radius_mm
        half = self.half_width_mm + margin
        if abs(curvature_per_mm) < MIN_CURVATURE_PER_MM:
            inside = np.abs(ys) <= half
            if not inside.any():
                return None
            return max(0.0, float(xs[inside].min()) - self.front_mm)
        # Along an arc the body turns about its driven axle: sweep it in steps of the axle's
        # travel and find the first pose whose rectangle (widened by the margin) holds a point.
        k, a = curvature_per_mm, self.axle_x_mm
        travel = _TRAVEL  # (S, 1)
        turn = k * travel
        cos, sin = np.cos(turn), np.sin(turn)
        cx = a + sin / k - a * cos
        cy = (1.0 - cos) / k - a * sin
        dx, dy = xs[None, :] - cx, ys[None, :] - cy  # (S, K)
        along = cos * dx + sin * dy
        across = -sin * dx + cos * dy
        hit = (np.abs(along) <= self.front_mm) & (np.abs(across) <= half)
        steps = hit.any(axis=1)
        return float(travel[steps.argmax(), 0]) if steps.any() else None  # the first hit

    def beyond_front_sweep(self, sensor: TofSensorConfig, distance: float) -> bool:
        """Whether every point of a front reading's arc is out of reach of the front corners
        turning on the spot (with ``corridor_margin_mm`` to spare)."""
        angles = self._arcs[sensor.id]
        xs = sensor.x_mm + distance * np.cos(angles) - self.axle_x_mm
        ys = sensor.y_mm + distance * np.sin(angles)
        reach = self._front_sweep_mm + self.cfg.corridor_margin_mm
        return bool(np.hypot(xs, ys).min() > reach)

    def _recall(self, sensor: TofSensorConfig, now: float) -> tuple[float, _Sighting] | None:
        """The remembered return of ``sensor`` and its distance now, unless it has expired."""
        seen = self._memory.get(sensor.id)
        if (
            seen is None
            or now - seen.t_s > self.cfg.memory_s
            or self._turned_deg - seen.turned_deg > self.cfg.memory_max_turn_deg
        ):
            self._memory.pop(sensor.id, None)
            return None
        return max(0.0, seen.distance_mm - (self._travel_mm - seen.travel_mm)), seen

    def _remember(self, sensor: TofSensorConfig, distance: int, narrow: bool, now: float) -> None:
        if self.cfg.memory_s <= 0 or distance > self._corridor_mm.get(sensor.id, 0.0):
            return
        recalled = self._recall(sensor, now)
        if recalled is None or distance <= recalled[0]:
            self._memory[sensor.id] = _Sighting(
                distance, self._travel_mm, self._turned_deg, now, narrow
            )

    def _radius(self, face: str, speed_mm_s: float) -> float:
        if face == "front":
            return stop_distance_mm(self.cfg, speed_mm_s)
        if face == "rear":
            return stop_distance_mm(self.cfg, -speed_mm_s)
        return self.cfg.side_radius_mm

    def narrow(self, readings: dict[int, RangeReading]) -> frozenset[int]:
        """Front sensors whose return is narrow (:func:`narrow_returns`)."""
        return narrow_returns(self.sensors.values(), readings, self.cfg)

    def _assess(
        self,
        sensor: TofSensorConfig,
        reading: RangeReading | None,
        speed: float,
        narrow: bool,
        now: float,
        wall: np.ndarray | None,
        curvature_per_mm: float,
    ) -> _Finding:
        """``wall``: where the plan's walls put this sensor's reading, if they explain it;
        ``curvature_per_mm``: the arc the robot is driving."""
        cfg = self.cfg
        if reading is not None and (not reading.healthy or reading.status in FAILED):
            self._missed[sensor.id] = cfg.stale_cycles
            why = "unhealthy" if not reading.healthy else reading.status.value
            return _Finding(SafetyState.STOP, sensor, None, f"sensor {sensor.id} {why}", 0.0)
        distance = None
        if reading is not None and reading.status is ReadingStatus.VALID:
            distance = near_end_mm(reading)
        elif reading is not None and reading.status is ReadingStatus.TOO_CLOSE:
            distance = 0  # inside the sensor's minimum range: something is touching close
        nothing = reading is not None and reading.status in NOTHING_IN_RANGE
        usable = distance is not None or nothing
        self._missed[sensor.id] = 0 if usable else self._missed[sensor.id] + 1
        if self._missed[sensor.id] >= cfg.stale_cycles:
            return _Finding(
                SafetyState.STOP,
                sensor,
                None,
                f"sensor {sensor.id} stale: no reading for {self._missed[sensor.id]} scans",
                0.0,
            )
        seen = ""
        if distance is not None and sensor.face == "front" and wall is None:
            # What the plan's walls explain is not remembered: a wall ahead is seen again.
            self._remember(sensor, distance, narrow, now)
        recalled = self._recall(sensor, now) if sensor.face == "front" else None
        if recalled is not None and (distance is None or recalled[0] < distance):
            distance, narrow = round(recalled[0]), recalled[1].narrow
            seen = f" (seen {now - recalled[1].t_s:.1f} s ago)"
        if distance is None or distance > self.max_range_mm:
            return _Finding(SafetyState.GO, sensor, None, "clear", self.max_speed_mm_s)
        gap: float = distance
        if sensor.face == "front":
            ahead = self.ahead_mm(sensor, distance, None if seen else wall, curvature_per_mm)
            if ahead is None:  # a glance outside the corridor: not in the way
                return _Finding(SafetyState.GO, sensor, None, "clear", self.max_speed_mm_s)
            gap = ahead
        # A plan wall carries nothing that overhangs it: only an unexplained narrow return gets
        # the margin for what may stand on a pole (a wall glanced by one toed-out cone while
        # turning out reads as narrow as a pole).
        narrow = narrow and (wall is None or bool(seen))
        # Leaving a zone needs extra clearance: its face's thresholds grow while it is inside.
        margin = cfg.narrow_margin_mm if narrow else 0.0
        stop_at = self._radius(sensor.face, speed) + margin
        slow_at = stop_at + (cfg.slowdown_extra_mm if sensor.face in ("front", "rear") else 0.0)
        held = self._faces[sensor.face]
        if held is SafetyState.STOP:
            stop_at += cfg.hysteresis_mm
        if held is not SafetyState.GO:
            slow_at += cfg.hysteresis_mm
        what = f"{sensor.face} {'narrow ' if narrow else ''}obstacle at {distance} mm{seen}"
        sigma = (reading.sigma_mm if reading is not None else None) or 0.0
        if gap < stop_at:
            reason = f"{what}, stop distance {stop_at:.0f} mm"
            return _Finding(SafetyState.STOP, sensor, distance, reason, 0.0, gap, sigma_mm=sigma)
        if gap < slow_at:
            # Slow enough to stop before the seed's radius (plus any narrow margin), so the
            # robot creeps up to it.
            room = gap - cfg.front_radius_mm - cfg.hysteresis_mm - margin
            limit = max(cfg.min_slow_speed_mm_s, safe_speed_mm_s(cfg, room))
            reason = f"{what}, slowing"
            return _Finding(
                SafetyState.SLOW,
                sensor,
                distance,
                reason,
                min(limit, self.max_speed_mm_s),
                gap,
                sigma_mm=sigma,
            )
        return _Finding(
            SafetyState.GO, sensor, distance, "clear", self.max_speed_mm_s, gap, sigma_mm=sigma
        )

    def _explained(
        self, readings: dict[int, RangeReading], explain: Explainer | None
    ) -> dict[int, np.ndarray]:
        """Per sensor, where the plan's walls put its valid reading, if they explain it."""
        if explain is None:
            return {}
        valid = [
            (sensor, float(distance))
            for sensor in self.sensors.values()
            if (distance := valid_distance(readings.get(sensor.id))) is not None
        ]
        return explain(valid)

    def _intrusion(self, speed: float) -> _Finding | None:
        """A mover predicted in the corridor ahead: stop if the robot could not stop short of
        where it enters, slow to a speed that could."""
        cfg = self.cfg
        horizon = (
            cfg.reaction_latency_s + max(0.0, speed) / cfg.braking_mm_s2
        ) + self.tracker.cfg.horizon_s
        found: Intrusion | None = self.tracker.intrusion(
            max(0.0, speed), self.front_mm, self.half_width_mm, horizon
        )
        if found is None:
            return None
        what = (
            f"someone moving into the way {found.ahead_mm:.0f} mm ahead in {found.time_s:.1f} s "
            f"({found.speed_mm_s:.0f} mm/s)"
        )
        stop_at = stop_distance_mm(cfg, speed) + cfg.hysteresis_mm
        if found.ahead_mm < stop_at:
            return _Finding(
                SafetyState.STOP, self._front_sensor, None, what, 0.0, found.ahead_mm, True
            )
        limit = max(cfg.min_slow_speed_mm_s, safe_speed_mm_s(cfg, found.ahead_mm - stop_at))
        return _Finding(
            SafetyState.SLOW,
            self._front_sensor,
            None,
            f"{what}, slowing",
            limit,
            found.ahead_mm,
            True,
        )

    def _oncoming(self) -> _Finding | None:
        """A mover in the corridor ahead walking towards the robot: it keeps coming while the
        robot brakes, so the robot slows to a speed it can stop from before they meet, and
        stands once it cannot; someone who then walks into it has walked into a standing
        robot. Its closing speed is taken ``closing_sigmas`` above the estimate: a person
        first seen 2 m ahead is a new track whose speed is still being learned, and at
        1.5 m/s closing the robot cannot wait for it."""
        cfg = self.cfg
        worst: tuple[float, float, float] | None = None  # (limit, gap, closing)
        tracking = self.tracker.cfg
        for track in self.tracker.movers():
            x, y = self.tracker.odometry.to_local(track.state[0], track.state[1])
            vx, _ = self.tracker.odometry.rotate_to_local(track.state[2], track.state[3])
            beside = abs(y) > self.half_width_mm + tracking.corridor_margin_mm
            if beside or x < self.front_mm or vx >= 0:
                continue
            closing = -vx + tracking.closing_sigmas * self.tracker.speed_sigma_ahead_mm_s(track)
            gap = x - self.front_mm
            limit = safe_speed_mm_s(cfg, gap - cfg.margin_mm - cfg.hysteresis_mm, closing)
            if worst is None or limit < worst[0]:
                worst = (limit, gap, closing)
        if worst is None or worst[0] >= self.max_speed_mm_s:
            return None
        limit, gap, closing = worst
        what = f"someone coming towards the robot {gap:.0f} mm ahead ({closing:.0f} mm/s)"
        if limit < cfg.min_slow_speed_mm_s:
            return _Finding(SafetyState.STOP, self._front_sensor, None, what, 0.0, gap, True)
        return _Finding(
            SafetyState.SLOW, self._front_sensor, None, f"{what}, slowing", limit, gap, True
        )

    def _lost_mover(self, now: float) -> _Finding | None:
        """Someone who walked out of every cone near the path may step back into it from a
        blind spot at any moment: past there, the robot goes slowly enough to stop at once."""
        tracking = self.tracker.cfg
        lost = self.tracker.lost_near(self.front_mm, self.half_width_mm, tracking.lost_reach_mm)
        if lost is None:
            return None
        what = f"someone went out of view beside the path {now - lost.t_s:.1f} s ago, slowing"
        return _Finding(
            SafetyState.SLOW, self._front_sensor, None, what, tracking.lost_speed_mm_s, None, True
        )

    def update(
        self,
        scan: RangeScan,
        speed_mm_s: float | None,
        scan_seq: int,
        yaw_rate_dps: float = 0.0,
        explain: Explainer | None = None,
    ) -> CollisionStatus:
        """The verdict for ``scan`` at forward speed ``speed_mm_s`` (None: unknown, assume max)
        while turning at ``yaw_rate_dps``; ``explain`` places readings the floor plan's walls
        explain (given only with a pose to trust)."""
        speed = self.max_speed_mm_s if speed_mm_s is None else speed_mm_s
        now = scan.cycle_start_s
        if self._last_t is not None and now > self._last_t:
            self._travel_mm += max(0.0, speed) * (now - self._last_t)
            self._turned_deg += abs(yaw_rate_dps) * (now - self._last_t)
        self._last_t = now
        readings = {r.sensor: r for r in scan.readings}
        walls = self._explained(readings, explain)
        # What the plan's walls explain is a wall, not someone walking: it is not tracked.
        self.tracker.update(
            scan, 0.0 if speed_mm_s is None else speed_mm_s, yaw_rate_dps, skip=set(walls)
        )
        narrow = self.narrow(readings)
        curvature = 0.0
        if speed >= MIN_ARC_SPEED_MM_S:
            curvature = math.radians(yaw_rate_dps) / speed
        findings = [
            self._assess(
                s, readings.get(s.id), speed, s.id in narrow, now, walls.get(s.id), curvature
            )
            for s in self.sensors.values()
        ]
        intrusion = self._intrusion(speed)
        if intrusion is not None:
            findings.append(intrusion)
        for extra in (self._oncoming(), self._lost_mover(now)):
            if extra is not None:
                findings.append(extra)
        worst = max(
            findings,
            key=lambda f: (
                _RANK[f.state],
                -f.speed_limit_mm_s,
                -(f.gap_mm if f.gap_mm is not None else math.inf),
            ),
        )
        previous, self.state = self.state, worst.state
        self._faces = {
            face: max((f.state for f in findings if f.sensor.face == face), key=_RANK.__getitem__)
            for face in self._faces
        }
        front = [
            (f.distance_mm, f.sigma_mm)
            for f in findings
            if f.sensor.face == "front" and f.distance_mm is not None and not f.moving
        ]
        clearance, clearance_sigma = min(front) if front else (None, 0.0)
        if worst.state is SafetyState.GO:
            self._stop_clearance = self._side_gap = None
            reason = "clear again" if previous is not SafetyState.GO else "clear"
            return CollisionStatus(
                state=SafetyState.GO,
                scan_seq=scan_seq,
                reason=reason,
                speed_limit_mm_s=self.max_speed_mm_s,
                front_clearance_mm=clearance,
            )
        stops = [f for f in findings if f.state is SafetyState.STOP]
        faces = tuple(
            sorted({f.sensor.face for f in stops if f.distance_mm is not None and not f.moving})
        )
        return CollisionStatus(
            state=worst.state,
            scan_seq=scan_seq,
            face=worst.sensor.face,
            sensor=None if worst.moving else worst.sensor.id,
            distance_mm=worst.distance_mm,
            reason=worst.reason,
            speed_limit_mm_s=worst.speed_limit_mm_s,
            blocked_faces=faces,
            front_clearance_mm=clearance,
            may_rotate=self._may_rotate(
                stops,
                faces,
                clearance,
                clearance_sigma,
                at_rest=speed < REST_MM_S and abs(yaw_rate_dps) < REST_DPS,
            ),
            may_creep_ahead=self._may_creep(stops, faces, findings),
        )

    def _may_rotate(
        self,
        stops: list[_Finding],
        faces: tuple[str, ...],
        clearance: int | None,
        sigma_mm: float,
        at_rest: bool,
    ) -> bool:
        """Turning on the spot is allowed only while every stop is an obstacle on the front
        face (no sensor fault, no mover, sides clear) and either everything in the way is
        out of the front corners' reach, or the (smoothed) front clearance has not fallen
        since the robot came to rest in the stop: a turn that brings the front nearer, or
        anything coming closer, ends it. The clearance to hold is taken at rest, not as the
        stop fires: a turn the stop ends brakes for a scan or two, the front coming nearer
        meanwhile, and measured from the first scan that alone forbade turning either way
        for good (a robot turning towards a wall, stopped 224 mm from it, came to rest at
        186 mm and stood there)."""
        front_only = bool(stops) and faces == ("front",)
        front_only = front_only and all(f.distance_mm is not None and not f.moving for f in stops)
        if not front_only or clearance is None:
            self._stop_clearance = self._clearance_ema = None
            return False
        ema = self._clearance_ema
        ema = clearance if ema is None else ema + CLEARANCE_SMOOTHING * (clearance - ema)
        self._clearance_ema = ema
        out_of_reach = all(
            f.sensor.face == "front"
            and f.distance_mm is not None
            and self.beyond_front_sweep(f.sensor, f.distance_mm)
            for f in stops
        )
        if out_of_reach:
            return True
        if self._stop_clearance is None:
            if not at_rest:
                return False
            # The smoothed value still falls for a few scans after the robot stops: the
            # reading at rest, if lower, is where it stands.
            self._stop_clearance = min(ema, clearance)
        return ema >= self._stop_clearance - max(ROTATE_NOISE_MM, 2.0 * sigma_mm)

    def _may_creep(
        self, stops: list[_Finding], faces: tuple[str, ...], findings: list[_Finding]
    ) -> bool:
        """Creeping straight ahead is allowed while every stop is something within a side
        radius (no fault, no mover), nothing is in the way ahead, and the side gap has not
        shrunk since the hold began."""
        sides_only = bool(stops) and all(face in ("left", "right") for face in faces)
        sides_only = sides_only and all(f.distance_mm is not None and not f.moving for f in stops)
        ahead_clear = all(
            f.state is SafetyState.GO for f in findings if f.sensor.face in ("front", "rear")
        )
        if not sides_only or not ahead_clear:
            self._side_gap = None
            return False
        gap = min(float(f.distance_mm or 0) for f in stops)
        if self._side_gap is None:
            self._side_gap = gap
        return gap >= self._side_gap - ROTATE_NOISE_MM
