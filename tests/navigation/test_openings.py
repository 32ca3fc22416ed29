"""Slow zones at the floor plan's openings: where they cap the speed, and that the cap lets
the robot stand before someone stepping out of the opening at 1600 mm/s reaches it."""

from __future__ import annotations

import math

import pytest
from helpers import CONFIG, PLAN

from coffeebot.navigation.openings import OpeningZones

FLOOR = PLAN.floor(2)
HALL = next(o for o in FLOOR.openings if o.id == "north hall")
"""The side hallway, on the left (+d) of the main hallway, 1.7 m wide."""
HALF_WIDTH = FLOOR.hallway.width_mm / 2
LANE = HALF_WIDTH - CONFIG.motion.wall_distance_mm - CONFIG.geometry.width_mm / 2
"""How far right of the centre line the keep-right lane is (295 mm)."""
FRONT = CONFIG.geometry.length_mm / 2
CRUISE = CONFIG.motion.cruise_speed_mm_s
ZONES = OpeningZones(
    CONFIG.openings,
    CONFIG.collision,
    CONFIG.tof.sensors,
    CONFIG.geometry.width_mm,
    CONFIG.geometry.length_mm,
)


def towards_plus(front_before_mm: float) -> tuple[float, float, float]:
    """(s, d, direction) of a robot in the keep-right lane driving towards +s whose front is
    ``front_before_mm`` short of the side hallway's mouth: the mouth is across the hallway,
    on its left."""
    return HALL.span[0] - front_before_mm - FRONT, -LANE, 1.0


def towards_minus(front_before_mm: float) -> tuple[float, float, float]:
    """The same driving back: the mouth is beside its lane, on its right."""
    return HALL.span[1] + front_before_mm + FRONT, LANE, -1.0


def test_the_speed_is_capped_near_an_opening_and_not_elsewhere() -> None:
    assert ZONES.limit(FLOOR, 16500.0, -LANE, 1.0, CRUISE) is None  # plain walls both sides
    assert ZONES.limit(FLOOR, *towards_plus(5000.0), CRUISE) is None  # far before it
    near = ZONES.limit(FLOOR, *towards_plus(500.0), CRUISE)
    assert near is not None and near.opening == "north hall" and near.speed_mm_s < CRUISE
    beside = ZONES.limit(FLOOR, *towards_plus(-1000.0), CRUISE)
    assert beside is not None and beside.speed_mm_s == pytest.approx(near.speed_mm_s)
    # Once the front is past the mouth's far edge, nobody stepping out can be ahead of it.
    s, d, direction = towards_plus(-HALL.width_mm - 10.0)
    assert ZONES.limit(FLOOR, s, d, direction, CRUISE) is None
    assert ZONES.limit(FLOOR, s - 20.0, d, direction, CRUISE) is not None


def test_the_cap_rises_with_the_distance_to_the_mouth() -> None:
    caps = [ZONES.limit(FLOOR, *towards_minus(ahead), CRUISE) for ahead in (2000, 1500, 1000)]
    speeds = [c.speed_mm_s for c in caps if c is not None]
    assert len(speeds) == 3 and speeds[0] > speeds[1] > speeds[2]


def test_an_opening_beside_the_lane_is_slower_than_one_across_the_hallway() -> None:
    """Keeping right, a mouth on the right is 300 mm from the body and the outer front cone
    meets its wall line 0.58 m ahead; one on the left is 890 mm off and seen from 1.47 m."""
    near_side = ZONES.limit(FLOOR, *towards_minus(0.0), CRUISE)
    far_side = ZONES.limit(FLOOR, *towards_plus(0.0), CRUISE)
    assert near_side is not None and far_side is not None
    assert ZONES.sight_mm(-1.0, HALF_WIDTH - LANE) == pytest.approx(578, abs=5)
    assert ZONES.sight_mm(1.0, HALF_WIDTH + LANE) == pytest.approx(1469, abs=5)
    assert near_side.speed_mm_s == pytest.approx(117, abs=3)
    assert far_side.speed_mm_s == pytest.approx(371, abs=3)


@pytest.mark.parametrize("place", [towards_minus, towards_plus])
def test_at_the_cap_the_robot_stands_before_someone_stepping_out_reaches_it(place) -> None:
    """Someone steps out where the cones first see the mouth and walks straight at the front
    at 1600 mm/s; the robot brakes after its reaction latency at the deceleration it can rely
    on. Stepped through in time, the gap between them never closes below the margin; 10 %
    faster than the cap, it does."""
    zone = ZONES.limit(FLOOR, *place(0.0), CRUISE)
    assert zone is not None
    collision = CONFIG.collision
    walker = CONFIG.openings.walking_speed_mm_s

    def least_gap(speed: float) -> float:
        gap, v, t, dt = zone.distance_mm, speed, 0.0, 0.001
        while v > 0:
            if t >= collision.reaction_latency_s:
                v = max(0.0, v - collision.braking_mm_s2 * dt)
            gap -= (v + walker) * dt
            t += dt
        return gap

    assert least_gap(zone.speed_mm_s) >= collision.margin_mm - 2.0
    assert least_gap(zone.speed_mm_s * 1.1) < collision.margin_mm


def test_off_the_hallway_there_is_no_zone() -> None:
    """In an office, the tea room or the elevator car the cones see the room's walls."""
    s, _, direction = towards_plus(0.0)
    assert ZONES.limit(FLOOR, s, HALF_WIDTH + 500.0, direction, CRUISE) is None


def test_slow_zones_can_be_switched_off() -> None:
    off = OpeningZones(
        CONFIG.openings.model_copy(update={"slow_zones": False}),
        CONFIG.collision,
        CONFIG.tof.sensors,
        CONFIG.geometry.width_mm,
        CONFIG.geometry.length_mm,
    )
    assert off.limit(FLOOR, *towards_minus(0.0), CRUISE) is None
    assert math.isfinite(ZONES.sight_mm(1.0, 1000.0))
