"""Floor plans: the building as the robot knows it, loaded from TOML.

A floor plan is written the way one surveys a hallway with a tape measure: each floor has one
or more straight hallways, each given by its axis (start and end points in the floor frame)
and width, meeting where one's end lies on another's axis; doors and openings are placed by
their distance along their hallway's axis and the side they are on. Free-form walls cover
the rest (a tea room, an elevator lobby). The loader turns this into wall segments with
heights, which the simulator ray-casts against and the SVG renderer draws.

Frames: x, y in mm in the floor frame shared by all floors and the UWB anchors. Along a
hallway, ``s`` is the distance from its axis start and ``d`` the lateral offset, positive to
the left when looking from start to end.

- :mod:`.features`: what a plan is made of (hallways, doors, openings, walls, frames, angle
  zones, anchors, parking spots, cameras) and the error that names one;
- :mod:`.floor`: one floor, where its hallways meet, its views and its wall segments;
- :mod:`.plan`: the building (floors, rooms, pickup points, elevator cars);
- :mod:`.load`: reading a plan and every check it must pass;
- :mod:`.advice`: what a valid plan leaves the robot to do poorly.
"""

from coffeebot.floorplan.advice import PlanWarning, plan_warnings
from coffeebot.floorplan.features import (
    PLAN_MM,
    Anchor,
    AngleZone,
    Camera,
    Coordinate,
    Door,
    FloorMark,
    FloorPlanError,
    Frame,
    Hallway,
    Junction,
    Opening,
    ParkingSpot,
    Side,
    Wall,
    WallSegment,
    segment_distances,
    segments_crossed,
)
from coffeebot.floorplan.floor import Extent, Floor, Meeting
from coffeebot.floorplan.load import load_floorplan, parse_floorplan
from coffeebot.floorplan.plan import FloorPlan, RoomLocation

__all__ = [
    "PLAN_MM",
    "Anchor",
    "AngleZone",
    "Camera",
    "Coordinate",
    "Door",
    "Extent",
    "Floor",
    "FloorMark",
    "FloorPlan",
    "FloorPlanError",
    "Frame",
    "Hallway",
    "Junction",
    "Meeting",
    "Opening",
    "ParkingSpot",
    "PlanWarning",
    "RoomLocation",
    "Side",
    "Wall",
    "WallSegment",
    "load_floorplan",
    "parse_floorplan",
    "plan_warnings",
    "segment_distances",
    "segments_crossed",
]
