"""Door detection from the side sensors (seed 000 "fine-grained localization").

Seed rule: keep a sliding window of twice the number of readings a door spans; when the mean
of the newer half exceeds the mean of the older half by 80 mm, the sensor is at (or nearly
past) a door, which sits ~100 mm behind the wall line. The window shrinks as speed grows: a
door spans ``door_width / (speed / scan_rate)`` readings.

Beyond the seed: every reading is stored with where its ray met the wall along the hallway
(from the pose at the time), so a detection is turned into a position. The rising edge (the
split of the window with the largest step) marks the door's near edge; the detection is
matched to the floor plan's doors and openings on that side by that edge, which names the
room and tells how far the robot's along-hallway position is off. A much larger step than a
recess is an opening or an open door. Detections of the same door by the second sensor on the
side are merged.
"""

from __future__ import annotations

import math
from collections import deque
from collections.abc import Iterable
from dataclasses import dataclass

import numpy as np

from coffeebot.config import DoorConfig, TofSensorConfig
from coffeebot.floorplan import Door, Floor, Opening, Side
from coffeebot.messages import DoorEvent, PoseEstimate, RangeReading, RangeScan, ReadingStatus
from coffeebot.perception.geometry import TravelFrame, sensor_origin

MIN_VISIBLE_MM = 200.0
"""The least of a door a side sensor is assumed to see, however far the wall."""


def readings_per_door(
    cfg: DoorConfig, speed_mm_s: float, scan_rate_hz: float, visible_mm: float | None = None
) -> int:
    """How many readings one door spans at this speed and scan rate (clamped to the config).

    ``visible_mm`` is the stretch over which the sensor actually reads the recess: a sensor
    reporting the nearest return in its cone sees the door only once the whole cone is past
    the edge, so a far wall shortens it (default: the whole door width).
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


class _Track:
    """The sliding window of one side sensor."""

    def __init__(self, sensor: TofSensorConfig, capacity: int) -> None:
        self.sensor = sensor
        self.samples: deque[_Sample] = deque(maxlen=capacity)

    def step(self, window: int, jump_mm: float) -> tuple[float, int] | None:
        """(step size, index of the first sample after the edge) when the seed rule fires."""
        if len(self.samples) < window:
            return None
        recent = np.fromiter(
            (s.distance_mm for s in list(self.samples)[-window:]), float, count=window
        )
        half = window // 2
        if recent[half:].mean() - recent[:half].mean() < jump_mm:
            return None
        # The edge: the split of the window with the largest step between its two sides.
        cumulative = np.cumsum(recent)
        splits = np.arange(1, window)
        before = cumulative[:-1] / splits
        after = (cumulative[-1] - cumulative[:-1]) / (window - splits)
        best = int(np.argmax(after - before))
        return float(after[best] - before[best]), len(self.samples) - window + best + 1


class DoorDetector:
    """Feed it every scan with the pose and speed; it returns the doors it has just passed."""

    def __init__(
        self,
        sensors: Iterable[TofSensorConfig],
        cfg: DoorConfig,
        half_fov_deg: float = 0.0,
        target_room: str | None = None,
    ) -> None:
        self.cfg = cfg
        self.half_fov_deg = half_fov_deg
        """The ranging model: a reading is the nearest return within this of the axis."""
        self.target_room = target_room
        self.tracks = {
            s.id: _Track(s, 2 * cfg.max_readings_per_door)
            for s in sensors
            if s.face in ("left", "right")
        }
        self._last_span: dict[Side, tuple[float, float]] = {}

    def reset(self) -> None:
        for track in self.tracks.values():
            track.samples.clear()
        self._last_span.clear()

    def _distance(self, reading: RangeReading | None) -> float | None:
        """A window value: valid distances clamped, "no target" as the clamp, else unusable."""
        if reading is None or not reading.healthy:
            return None
        if reading.status is ReadingStatus.VALID and reading.distance_mm is not None:
            return float(min(reading.distance_mm, self.cfg.max_side_distance_mm))
        if reading.status in (ReadingStatus.NO_TARGET, ReadingStatus.OUT_OF_BOUNDS):
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
        tan_half_fov = math.tan(math.radians(self.half_fov_deg))
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
            track.samples.append(_Sample(distance, along))
            # The cone's footprint on the wall hides part of the door: size the window by what
            # the sensor can see of it at its current distance from the wall.
            visible = max(cfg.door_width_mm - 2.0 * distance * tan_half_fov, MIN_VISIBLE_MM)
            window = window_size(cfg, speed_mm_s, scan_rate_hz, visible)
            fired = track.step(window, cfg.jump_mm)
            if fired is not None:
                event = self._event(track, fired, frame, pose, scan_seq, window)
                if event is not None:
                    events.append(event)
                track.samples.clear()
        return events

    def _event(
        self,
        track: _Track,
        fired: tuple[float, int],
        frame: TravelFrame,
        pose: PoseEstimate,
        scan_seq: int,
        window: int,
    ) -> DoorEvent | None:
        cfg = self.cfg
        jump, index = fired
        samples = list(track.samples)
        wall = samples[index - 1]
        sign = -1.0 if frame.reversed else 1.0
        # The sensor only sees the recess once its whole effective cone is past the edge.
        footprint = wall.distance_mm * math.tan(math.radians(self.half_fov_deg))
        edge = (wall.along_mm + samples[index].along_mm) / 2.0 - sign * footprint
        side = frame.hallway_side("left" if track.sensor.face == "left" else "right")
        last = self._last_span.get(side)
        if last is not None and last[0] - 300.0 <= edge <= last[1] + 300.0:
            return None  # the other sensor on this side already reported this door
        feature = self._match(frame.floor, side, edge, sign)
        width = feature.width_mm if feature is not None else cfg.door_width_mm
        centre = edge + sign * width / 2.0
        self._last_span[side] = (min(edge, edge + sign * width), max(edge, edge + sign * width))
        wall_d = frame.floor.hallway.width_mm / 2.0 * (1.0 if side == "left" else -1.0)
        x, y = frame.floor.from_hallway(centre, wall_d)
        kind = "door" if jump <= cfg.max_door_jump_mm else "opening"
        room = None
        plan_x = plan_y = correction = None
        if feature is not None:
            kind = "door" if isinstance(feature, Door) else "opening"
            room = feature.room if isinstance(feature, Door) else None
            plan_x, plan_y = frame.floor.from_hallway(feature.at_mm, wall_d)
            correction = sign * (feature.at_mm - centre)
        return DoorEvent(
            scan_seq=scan_seq,
            side=side,
            sensor=track.sensor.id,
            kind=kind,
            floor=frame.floor.level,
            x_mm=x,
            y_mm=y,
            jump_mm=jump,
            window=window,
            travel_heading_deg=frame.direction_deg,
            room=room,
            plan_x_mm=plan_x,
            plan_y_mm=plan_y,
            along_correction_mm=correction,
            arrived_at_target=room is not None and room == self.target_room,
        )

    def _match(self, floor: Floor, side: Side, edge: float, sign: float) -> Door | Opening | None:
        """The plan feature on ``side`` whose near edge (in the travel direction) is nearest."""
        best: Door | Opening | None = None
        best_gap = self.cfg.match_gate_mm
        for feature in floor.features(side):
            near = feature.at_mm - sign * feature.width_mm / 2.0
            gap = abs(near - edge)
            if gap <= best_gap:
                best, best_gap = feature, gap
        return best
