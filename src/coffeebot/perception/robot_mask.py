"""The readings another robot of the fleet may have made: the particle filter leaves them out.

The floor plan has walls, not robots. In the tea room among the fleet's parked robots most of
a robot's cones read another robot's side; weighed against the plan those readings favour
poses that put a wall where the robots stand, and the fit falling with them made the filter
inject particles, whose heaviest mode it then followed: the estimate of a robot driving from
the loading spot to its parking spot past three parked robots jumped 884 mm
(``bench/fleet.py --robots 4 --rates 10``). The dispatcher's traffic says where each other
robot stands, to a few centimetres, and the robots are all one model. So a valid reading
whose cone, from the estimate and widened by its heading uncertainty, meets such a robot's
outline (grown by ``margin_mm`` for both robots' estimates) short of its range plus that
margin is not weighed, and a scan with such a reading does not feed the recovery monitor:
what is left of it (often the front sensors' floor returns alone) says little of whether
the filter is lost. Only robots standing still, with a fresh report, count, as for the
costmap (:func:`coffeebot.navigation.others.standing_outlines`): a driving robot's report is
half a metre old at walking pace, and its readings are weighed as a person's are, through
the range model's short-reading term. A robot without a fleet gets no traffic, and nothing
changes.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from coffeebot.config import TofSensorConfig
from coffeebot.messages import RangeScan
from coffeebot.perception.cones import cones_meeting


class RobotMask:
    """The readings of a scan another robot's outline may explain."""

    def __init__(self, sensors: Sequence[TofSensorConfig], margin_mm: float) -> None:
        self.sensors = {s.id: s for s in sensors}
        self.margin_mm = margin_mm

    def masked(
        self,
        scan: RangeScan,
        pose: tuple[float, float, float],
        heading_margin_deg: float,
        outlines: Sequence[np.ndarray],
    ) -> frozenset[int]:
        """The sensors whose valid reading in ``scan``, from ``pose`` (x mm, y mm, heading
        deg) with its heading ``heading_margin_deg`` uncertain, may come from one of the
        other robots' ``outlines`` (each (4, 4) sides, grown by ``margin_mm`` already)."""
        if not outlines:
            return frozenset()
        return cones_meeting(
            self.sensors, scan, pose, heading_margin_deg, np.vstack(outlines), self.margin_mm, None
        )
