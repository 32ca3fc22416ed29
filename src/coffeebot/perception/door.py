"""Door detection from the side sensors (seed 000 "fine-grained localization").

Seed rule: keep a sliding window of twice the number of readings a door spans; when the mean
of the newer half exceeds the mean of the older half by 80 mm, the sensor is at (or nearly
past) a door, which sits ~100 mm behind the wall line. The window shrinks as speed grows: a
door spans ``door_width / (speed / scan_rate)`` readings.

Beyond the seed: every reading is stored with where its ray met the wall along the hallway
(from the pose at the time), so a detection is turned into a position. The seed's rule finds
the rising edge (the split of the window with the largest step); the same rule mirrored
finds the falling edge where the wall comes back, and the door's centre is the midpoint of
the two. A cone blurs both edges by the same amount (a signal-weighted reading ramps from
the wall to the recess as the edge crosses the cone's footprint, ~210 mm at 890 mm for a 27
degree cone, and the near wall weighs more than the deeper recess), so the midpoint is free
of that bias whatever the cone's true ranging behaviour; a single edge would need the
footprint correction, which is only as good as the ranging model. The price is a later
event: the door is reported once the sensor has passed it. If the wall does not come back
within ``max_feature_mm`` (a wide opening, a missed edge), the near edge alone is used with
the footprint correction and the plan's width. The centre is matched to the floor plan's
doors and openings on that side, which names the room and tells how far the robot's along-
hallway position is off. A much larger step than a recess is an opening or an open door.
Detections of the same door by the second sensor on the side are merged.
"""

from __future__ import annotations

import math
from collections import deque
from collections.abc import Iterable
from dataclasses import dataclass, replace
from itertools import islice
from typing import Literal

import numpy as np

from coffeebot.config import DoorConfig, TofSensorConfig
from coffeebot.floorplan import Door, Floor, Opening, Side
from coffeebot.messages import (
    NOTHING_IN_RANGE,
    DoorEvent,
    PoseEstimate,
    RangeReading,
    RangeScan,
    ReadingStatus,
)
from coffeebot.perception.geometry import TravelFrame, sensor_origin

MIN_VISIBLE_MM = 200.0
"""The least of a door a side sensor is assumed to see, however far the wall."""

RECESS_STEP_SHARE = 0.8
"""How much of a recess the window's step reads at most: the cone's footprint blurs the edge
into both halves. With ``jump_mm`` 80, recesses of 50-90 mm went undetected in a second
building and 100-200 mm were seen."""


def min_visible_recess_mm(cfg: DoorConfig) -> float:
    """The shallowest door recess the detector finds: its blurred step must reach ``jump_mm``."""
    return cfg.jump_mm / RECESS_STEP_SHARE


def readings_per_door(
    cfg: DoorConfig, speed_mm_s: float, scan_rate_hz: float, visible_mm: float | None = None
) -> int:
    """How many readings one door spans at this speed and scan rate (clamped to the config).

    ``visible_mm`` is the stretch over which the sensor actually reads the recess: the cone's
    footprint on the wall blurs both edges, so a far wall shortens it (default: the whole
    door width).
    """
    width = cfg.door_width_mm if visible_mm is None else visible_mm
    step = abs(speed_mm_s) / scan_rate_hz
    n = cfg.max_readings_per_door if step <= 0 else round(width / step)
    return max(cfg.min_readings_per_door, min(cfg.max_readings_per_door, n))


def window_size(
    cfg: DoorConfig, speed_mm_s: float, scan_rate_hz: float, visible_mm: float | None = None
) -> int:
    """The seed's window: twice the readings per door."""
    return 2 * readings_per_door(cfg, speed_mm_s, scan_rate_hz, visible_mm)


@dataclass(frozen=True)
class _Sample:
    distance_mm: float
    along_mm: float
    """Where the ray met the wall line, along the hallway axis."""


@dataclass(frozen=True)
class _Edge:
    """A step between two neighbouring samples found by the window rule."""

    along_mm: float
    """Midway between the last sample before the step and the first after it."""
    jump_mm: float
    wall_mm: float
    """Distance of the sample on the wall side of the step (for the footprint correction)."""


class _Track:
    """The sliding window of one side sensor, and the rising edge of the door it is passing."""

    def __init__(self, sensor: TofSensorConfig, capacity: int) -> None:
        self.sensor = sensor
        self.samples: deque[_Sample] = deque(maxlen=capacity)
        self.distances: deque[float] = deque(maxlen=capacity)
        """The samples' distances alone, for the window rule's arithmetic every scan."""
        self.rise: _Edge | None = None

    def add(self, sample: _Sample) -> None:
        self.samples.append(sample)
        self.distances.append(sample.distance_mm)

    def clear(self) -> None:
        self.samples.clear()
        self.distances.clear()
        self.rise = None

    def step(self, window: int, jump_mm: float, rising: bool) -> _Edge | None:
        """The seed rule over the newest ``window`` samples: a rise (or, mirrored, a fall) of
        at least ``jump_mm`` between the halves, located at the split with the largest step."""
        if len(self.samples) < window:
            return None
        start = len(self.samples) - window
        recent = np.fromiter(islice(self.distances, start, None), float, count=window)
        sign = 1.0 if rising else -1.0
        half = window // 2
        # The halves' means as ndarray.mean computes them (a sum, then one division), without
        # its per-call overhead: this runs for every side sensor every scan.
        mean_after = np.add.reduce(recent[half:]) / (window - half)
        if sign * (mean_after - np.add.reduce(recent[:half]) / half) < jump_mm:
            return None
        cumulative = np.cumsum(recent)
        splits = np.arange(1, window)
        before = cumulative[:-1] / splits
        after = (cumulative[-1] - cumulative[:-1]) / (window - splits)
        steps = sign * (after - before)
        # The least-squares step fit: the split that explains most of the variance (a plain
        # largest difference of means favours splits near the window's ends).
        explained = np.where(steps > 0, splits * (window - splits) * steps**2, -1.0)
        best = int(np.argmax(explained))
        first, last = self.samples[start + best], self.samples[start + best + 1]
        wall = first if rising else last
        return _Edge((first.along_mm + last.along_mm) / 2.0, float(steps[best]), wall.distance_mm)

    def drop_before(self, along_mm: float, sign: float) -> None:
        """Forget the samples taken before ``along_mm`` (in the travel direction)."""
        while self.samples and sign * (self.samples[0].along_mm - along_mm) < 0:
            self.samples.popleft()
            self.distances.popleft()


@dataclass(frozen=True)
class _Passed:
    """A door one sensor has passed, before it is published."""

    track: _Track
    side: Side
    rise: _Edge
    centre: float
    """Along the hallway; from both edges, or from the near edge and the width."""
    both_edges: bool
    window: int


class DoorDetector:
    """Feed it every scan with the pose and speed; it returns the doors it has just passed."""

    def __init__(
        self,
        sensors: Iterable[TofSensorConfig],
        cfg: DoorConfig,
        half_fov_deg: float = 0.0,
        target_door: str | None = None,
    ) -> None:
        self.cfg = cfg
        self.half_fov_deg = half_fov_deg
        """Half the sensors' cone: how far a recess edge blurs across the wall it is on."""
        self.target_door = target_door
        self.tracks = {
            s.id: _Track(s, 2 * cfg.max_readings_per_door)
            for s in sensors
            if s.face in ("left", "right")
        }
        self._last_span: dict[Side, tuple[float, float]] = {}
        self._pending: dict[Side, _Passed] = {}
        self._gate_mm = cfg.match_gate_mm
        """How far from a plan door a detection may be to be taken for it (:meth:`gate_mm`)."""

    def reset(self) -> None:
        for track in self.tracks.values():
            track.clear()
        self._last_span.clear()
        self._pending.clear()

    def _distance(self, reading: RangeReading | None) -> float | None:
        """A window value: valid distances clamped, "no target" as the clamp, else unusable."""
        if reading is None or not reading.healthy:
            return None
        if reading.status is ReadingStatus.VALID and reading.distance_mm is not None:
            return float(min(reading.distance_mm, self.cfg.max_side_distance_mm))
        if reading.status in NOTHING_IN_RANGE:
            return self.cfg.max_side_distance_mm
        return None

    def update(
        self,
        scan: RangeScan,
        scan_seq: int,
        pose: PoseEstimate | None,
        floor: Floor | None,
        speed_mm_s: float,
        scan_rate_hz: float,
    ) -> list[DoorEvent]:
        """Add one scan; the door events it completes (usually none)."""
        cfg = self.cfg
        if pose is None or floor is None:
            self.reset()
            return []
        if abs(speed_mm_s) < cfg.min_speed_mm_s:
            return []
        frame = TravelFrame.for_heading(floor, pose.heading_deg)
        self._gate_mm = self.gate_mm(pose, floor)
        tan_half_fov = math.tan(math.radians(self.half_fov_deg))
        sign = -1.0 if frame.reversed else 1.0
        readings = {r.sensor: r for r in scan.readings}
        events = []
        for track in self.tracks.values():
            distance = self._distance(readings.get(track.sensor.id))
            if distance is None:
                continue
            sx, sy, look = sensor_origin(pose.x_mm, pose.y_mm, pose.heading_deg, track.sensor)
            # Where the optical axis meets the wall line (clamped reads as the wall line).
            reach = min(distance, floor.hallway.width_mm)
            along = frame.along(
                sx + reach * math.cos(math.radians(look)), sy + reach * math.sin(math.radians(look))
            )
            track.add(_Sample(distance, along))
            footprint = 2.0 * distance * tan_half_fov
            # Before the rise, the window spans what the cone can see of the door (its
            # footprint on the wall hides part of it); after, the wall's return spreads over
            # the footprint, so the fall is confirmed over that.
            stretch = cfg.door_width_mm - footprint if track.rise is None else footprint
            window = window_size(cfg, speed_mm_s, scan_rate_hz, max(stretch, MIN_VISIBLE_MM))
            edge = track.step(window, cfg.jump_mm, rising=track.rise is None)
            if track.rise is None:
                if edge is not None:
                    track.rise = edge
                    track.drop_before(edge.along_mm, sign)
                continue
            if edge is None and sign * (along - track.rise.along_mm) <= cfg.max_feature_mm:
                continue
            passed = self._passed(track, track.rise, edge, frame, window)
            track.clear()
            events += self._report(passed, frame, scan_seq)
        for side, pending in list(self._pending.items()):
            if not self._other_inside(pending):
                del self._pending[side]
                events += self._publish(pending, frame, scan_seq)
        return events

    def _passed(
        self, track: _Track, rise: _Edge, fall: _Edge | None, frame: TravelFrame, window: int
    ) -> _Passed:
        """One sensor's estimate of the door between ``rise`` and ``fall`` (None: the wall
        never came back, so the near edge and the plan's width are all there is)."""
        side = frame.hallway_side("left" if track.sensor.face == "left" else "right")
        if fall is not None:
            centre = (rise.along_mm + fall.along_mm) / 2.0
            return _Passed(track, side, rise, centre, both_edges=True, window=window)
        cfg = self.cfg
        sign = -1.0 if frame.reversed else 1.0
        # The sensor only sees the recess once its whole effective cone is past the edge.
        footprint = rise.wall_mm * math.tan(math.radians(self.half_fov_deg))
        near = rise.along_mm - sign * footprint
        feature = self._match(frame.floor, side, near + sign * cfg.door_width_mm / 2.0)
        width = feature.width_mm if feature is not None else cfg.door_width_mm
        return _Passed(track, side, rise, near + sign * width / 2.0, False, window)

    def _other_inside(self, passed: _Passed) -> bool:
        """Whether the side's other sensor is passing the same door (risen at the same edge)."""
        return any(
            other is not passed.track
            and other.sensor.face == passed.track.sensor.face
            and other.rise is not None
            and abs(other.rise.along_mm - passed.rise.along_mm) <= self.cfg.door_width_mm / 2.0
            for other in self.tracks.values()
        )

    def _report(self, passed: _Passed, frame: TravelFrame, scan_seq: int) -> list[DoorEvent]:
        """Publish a passed door, or hold it until the side's other sensor has passed it too:
        the two sensors' centres have independent errors, so their mean halves the variance."""
        pending = self._pending.pop(passed.side, None)
        events: list[DoorEvent] = []
        if pending is not None:
            if passed.both_edges and abs(pending.centre - passed.centre) <= (
                self.cfg.door_width_mm / 2.0
            ):
                centre = (pending.centre + passed.centre) / 2.0
                return self._publish(replace(pending, centre=centre), frame, scan_seq)
            events += self._publish(pending, frame, scan_seq)
        if passed.both_edges and self._other_inside(passed):
            self._pending[passed.side] = passed
            return events
        return events + self._publish(passed, frame, scan_seq)

    def _publish(self, passed: _Passed, frame: TravelFrame, scan_seq: int) -> list[DoorEvent]:
        """The door event for ``passed``, matched to the plan (none if already reported)."""
        cfg = self.cfg
        side, centre = passed.side, passed.centre
        last = self._last_span.get(side)
        if last is not None and last[0] <= centre <= last[1]:
            return []  # the other sensor on this side already reported this door
        sign = -1.0 if frame.reversed else 1.0
        feature = self._match(frame.floor, side, centre)
        width = feature.width_mm if feature is not None else cfg.door_width_mm
        self._last_span[side] = (centre - width / 2.0, centre + width / 2.0)
        wall_d = frame.floor.hallway.width_mm / 2.0 * (1.0 if side == "left" else -1.0)
        x, y = frame.floor.from_hallway(centre, wall_d)
        kind: Literal["door", "opening"] = (
            "door" if passed.rise.jump_mm <= cfg.max_door_jump_mm else "opening"
        )
        room = None
        plan_x = plan_y = correction = None
        if feature is not None:
            kind = "door" if isinstance(feature, Door) else "opening"
            room = feature.room if isinstance(feature, Door) else None
            plan_x, plan_y = frame.floor.from_hallway(feature.at_mm, wall_d)
            correction = sign * (feature.at_mm - centre)
        return [
            DoorEvent(
                scan_seq=scan_seq,
                side=side,
                sensor=passed.track.sensor.id,
                kind=kind,
                floor=frame.floor.level,
                x_mm=x,
                y_mm=y,
                jump_mm=passed.rise.jump_mm,
                window=passed.window,
                travel_heading_deg=frame.direction_deg,
                room=room,
                plan_x_mm=plan_x,
                plan_y_mm=plan_y,
                along_correction_mm=correction,
                arrived_at_target=isinstance(feature, Door) and feature.id == self.target_door,
            )
        ]

    def gate_mm(self, pose: PoseEstimate, floor: Floor) -> float:
        """How far a detected centre may lie from a plan door's to be taken for it:
        ``match_sigmas`` times the pose's and the detection's sigmas along the hallway
        together, at most ``match_gate_mm``. A fixed gate wider than the spacing of real
        doors matches a false detection to a door a metre away; with a good pose that is
        many sigmas off, and refused."""
        heading = math.radians(floor.hallway.heading_deg)
        c, s = math.cos(heading), math.sin(heading)
        along_var = (
            (c * pose.sigma_x_mm) ** 2 + (s * pose.sigma_y_mm) ** 2 + 2 * c * s * pose.cov_xy_mm2
        )
        sigma = math.sqrt(max(along_var, 0.0) + self.cfg.centre_sigma_mm**2)
        return min(self.cfg.match_gate_mm, self.cfg.match_sigmas * sigma)

    def _match(self, floor: Floor, side: Side, centre: float) -> Door | Opening | None:
        """The plan feature on ``side`` within the gate of ``centre`` (:meth:`gate_mm`), if
        there is exactly one: with two, the pose is too unsure for the doors' spacing to tell
        which one was passed, and the detection is refused rather than guessed."""
        within = [f for f in floor.features(side) if abs(f.at_mm - centre) <= self._gate_mm]
        return within[0] if len(within) == 1 else None
