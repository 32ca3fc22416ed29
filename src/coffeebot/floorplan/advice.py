"""Warnings: what a valid plan leaves the robot to do poorly (too few UWB anchors in range,
doors it cannot see, cameras not calibrated).
"""

from __future__ import annotations

import itertools
import math
from pathlib import Path
from typing import NamedTuple

import numpy as np

from coffeebot.floorplan.floor import Floor
from coffeebot.floorplan.plan import FloorPlan

MIN_ANCHORS = 3
"""Anchors in range a UWB fix needs: the tag reports no position with fewer."""

COVERAGE_STEP_MM = 100.0
"""Spacing of the points along a hallway where anchor coverage is counted."""


class PlanWarning(NamedTuple):
    """Something a plan may contain but the robot will handle poorly, as a check reports it."""

    element: str
    problem: str

    def describe(self, path: str | Path) -> str:
        return f"{path}: {self.element}: {self.problem}"


def plan_warnings(
    plan: FloorPlan, *, uwb_range_mm: float, min_recess_mm: float
) -> list[PlanWarning]:
    """The plan's weak spots for a robot whose UWB reaches ``uwb_range_mm`` and whose door
    detector sees recesses from ``min_recess_mm``: the loader knows neither, so the plan's
    check asks for these."""
    warnings: list[PlanWarning] = []
    for floor in plan.floors:
        warnings += _uwb_coverage_gaps(floor, uwb_range_mm)
        warnings += _unseen_doors(floor, min_recess_mm)
        warnings += _unchecked_cameras(floor)
    return warnings


def _uwb_coverage_gaps(floor: Floor, uwb_range_mm: float) -> list[PlanWarning]:
    """Stretches of each hallway's centre line with fewer than three anchors in range: no
    UWB fix there. The tag is taken at floor height, so an anchor's whole height counts."""
    anchors = np.array([(a.x_mm, a.y_mm, a.z_mm) for a in floor.anchors], dtype=float)
    anchors = anchors.reshape(-1, 3)
    warnings = []
    for hallway in floor.hallways:
        length = hallway.length_mm
        along = np.linspace(0.0, length, math.ceil(length / COVERAGE_STEP_MM) + 1)
        points = np.array([hallway.from_local(float(s), 0.0) for s in along])
        distances = np.hypot(
            np.hypot(points[:, :1] - anchors[:, 0], points[:, 1:] - anchors[:, 1]), anchors[:, 2]
        )
        in_range = (distances <= uwb_range_mm).sum(axis=1)
        short = in_range < MIN_ANCHORS
        name = floor._name(hallway)
        for is_short, run in itertools.groupby(range(len(along)), key=lambda i: bool(short[i])):
            if not is_short:
                continue
            indices = list(run)
            fewest = int(in_range[indices].min())
            warnings.append(
                PlanWarning(
                    f"floor {floor.level} / {name}",
                    f"{along[indices[0]]:.0f}..{along[indices[-1]]:.0f} mm along it has "
                    f"{fewest} UWB anchor{'' if fewest == 1 else 's'} within "
                    f"{uwb_range_mm:.0f} mm, a fix needs {MIN_ANCHORS}: the robot relies on "
                    "odometry, walls and doors there",
                )
            )
    return warnings


def _unseen_doors(floor: Floor, min_recess_mm: float) -> list[PlanWarning]:
    """Closed doors too shallow for the door detector (an open one shows the room behind)."""
    return [
        PlanWarning(
            f"floor {floor.level} / door {door.id}",
            f"recess_mm: {door.recess_mm:.0f} mm is shallower than the door detector sees "
            f"({min_recess_mm:.0f} mm): the robot will not see this door and relies on UWB "
            "and odometry there",
        )
        for door in sorted(floor.doors, key=lambda d: d.at_mm)
        if not door.open and door.recess_mm < min_recess_mm
    ]


def _unchecked_cameras(floor: Floor) -> list[PlanWarning]:
    """Cameras whose calibration nothing checks: without marks the pose and lens alone place
    what the camera sees; through exactly four the homography fits them all exactly."""
    warnings = []
    for camera in floor.cameras:
        element = f"floor {floor.level} / camera {camera.id}"
        if not camera.marks:
            warnings.append(
                PlanWarning(
                    element,
                    "marks: none, so its pose and lens alone place what it sees (a bracket "
                    "one degree askew: 45 mm at 2.6 m): tape four to six marks to calibrate it",
                )
            )
        elif len(camera.marks) == 4:
            warnings.append(
                PlanWarning(
                    element,
                    "marks: 4, which the homography fits exactly: a misread one shows only "
                    "if it disagrees with the camera's pose, a fifth would check them",
                )
            )
    return warnings
