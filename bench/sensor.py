"""The simulated VL53L1X's answers for standard scenes, beside what is published of the chip.

    python bench/sensor.py            # tables, for docs/benchmarks.md
    python bench/sensor.py --json     # {"scenes": [{"scene", "kind", "near_mm", ...}, ...]}

Every scene is ranged ``--rangings`` times through the simulated chip's model (the robot's
setup: long mode, 20 ms, the ULD's default thresholds, full ROI; the ``walls`` scenes also at
100 ms, the budget the datasheet's range figures use). Each row gives the mean and standard
deviation of the valid readings and the share of each status. The baseline, measured in the
same run on the same scene, is the nearest surface along the cone's axis (what a ray caster
reports); ``mean / nearest`` shows how a blended reading differs from it. The ``published``
column is what ST or a user measured on the real part (docs/sensor-model.md has the sources).

Walls and the edge are ranged from a tripod (1.5 m up, as a datasheet measurement would be:
no floor in the cone); poles and bottles from the robot's 250 mm, floor included.
"""

from __future__ import annotations

import argparse
import json
import time
from collections.abc import Iterator
from dataclasses import dataclass

import numpy as np

from coffeebot.hardware.vl53l1x import FULL_ROI, SpadRoi
from coffeebot.messages import ReadingStatus
from coffeebot.sim.world import materials
from coffeebot.sim.world.geometry import Surfaces
from coffeebot.sim.world.tof import (
    DEFAULT_SETUP,
    ConeOptics,
    RangingNoise,
    RangingSetup,
    SensorArray,
    SensorMount,
    range_once,
)

TRIPOD = SensorMount(x_mm=0, y_mm=0, yaw_deg=0, height_mm=1500)
ROBOT = SensorMount(x_mm=0, y_mm=0, yaw_deg=0, height_mm=250)
STRONG_AMBIENT_MCPS = 40.0
STATUSES = (
    ReadingStatus.VALID,
    ReadingStatus.SIGMA_FAIL,
    ReadingStatus.SIGNAL_FAIL,
    ReadingStatus.OUT_OF_BOUNDS,
)


@dataclass(frozen=True)
class Scene:
    scene: str
    kind: str
    surfaces: Surfaces
    mount: SensorMount
    near_mm: float | None
    far_mm: float | None
    published: str = ""
    ambient_mcps: float | None = None
    budget_ms: int = 20
    roi: SpadRoi = FULL_ROI


def wall(distance: float, reflectance: float, y0: float = -6000, y1: float = 6000) -> Surfaces:
    row = [[distance, y0, distance, y1, 0.0, 5000.0]]
    return Surfaces(np.array(row), ("wall",), np.zeros((0, 5)), (), np.array([reflectance]))


def pole(distance: float, diameter: float, reflectance: float, top: float = 2000) -> Surfaces:
    r = diameter / 2
    row = [[distance + r, 0.0, r, 0.0, top]]
    reflect = np.array([reflectance])
    return Surfaces(np.zeros((0, 6)), (), np.array(row), ("pole",), np.zeros(0), reflect)


def scenes() -> Iterator[Scene]:
    facts = {
        (3600, materials.WHITE, 100): "dark: range limit 3.6 m (88 %, long mode)",
        (1500, materials.GREY, 100): "dark: range limit ~1.7 m (17 %, long mode)",
        (400, materials.WHITE, 100): "a table at 415 mm: 397 +/- 1.3 mm",
        (100, materials.WHITE, 20): "a hand at 100 / 150 / 200 mm: 80 / 136 / 192",
        (200, materials.WHITE, 20): "a hand at 100 / 150 / 200 mm: 80 / 136 / 192",
        (700, materials.WHITE, 100): "strong sunlight: a white target lost beyond ~0.7 m",
        (1000, materials.WHITE, 20): "accuracy +/-20 mm dark, +/-25 mm strong ambient",
    }
    for ambient, light in ((0.0, "dark"), (STRONG_AMBIENT_MCPS, "sunlight")):
        for budget in (20, 100):
            targets = ((materials.WHITE, "white 88 %"), (materials.GREY, "grey 17 %"))
            for reflectance, name in targets:
                for d in (100, 200, 400, 700, 1000, 1500, 2000, 3000, 3600, 4000):
                    fact = facts.get((d, reflectance, budget), "")
                    if (light == "dark" and "sunlight" in fact) or (
                        light != "dark" and ("dark" in fact or "table" in fact)
                    ):
                        fact = ""
                    yield Scene(
                        f"wall {name} at {d} mm, {light}, {budget} ms",
                        "wall",
                        wall(d, reflectance),
                        TRIPOD,
                        d,
                        None,
                        fact,
                        ambient_mcps=ambient,
                        budget_ms=budget,
                    )
    for near, far in ((500, 1500), (1000, 1500), (2000, 3500)):
        yield Scene(
            f"pole 30 mm at {near} mm before a wall at {far} mm",
            "pole",
            wall(far, materials.WALL) + pole(near, 30, 0.5),
            ROBOT,
            near,
            far,
            "reads between the two, pulled towards the wall (ST forum)",
        )
    for kind, reflectance in (("bottle_white", materials.WHITE), ("bottle_black", materials.BLACK)):
        for d in (300, 600, 1000, 1500):
            yield Scene(
                f"{kind.replace('_', ' ')} 70 mm at {d} mm, open space",
                kind,
                pole(d, 70, reflectance, top=250 + 150),
                ROBOT,
                d,
                None,
            )
    for offset in (-300, -150, 0, 150, 300):
        # A wall at 800 mm on the left of the axis and at 1800 mm on the right: the edge at
        # ``offset`` mm to the left of where the axis meets it.
        edge = wall(800, materials.WALL, y0=offset, y1=6000) + wall(
            1800, materials.WALL, y0=-6000, y1=offset
        )
        yield Scene(
            f"edge 800 / 1800 mm, {offset:+d} mm from the axis",
            "edge",
            edge,
            TRIPOD,
            800,
            1800,
            "a recess edge ramps instead of jumping",
        )
    for roi in (FULL_ROI, SpadRoi(4, 4)):
        yield Scene(
            f"pole 30 mm at 1000 mm before a wall at 1500 mm, ROI {roi.width}x{roi.height}",
            "pole",
            wall(1500, materials.WALL) + pole(1000, 30, 0.5),
            ROBOT,
            1000,
            1500,
            "a narrower ROI weighs the centre more",
            roi=roi,
        )
    yield Scene("nothing in view (floor only)", "nothing", Surfaces.empty(), ROBOT, None, None)


def nearest_on_axis(surfaces: Surfaces) -> float | None:
    """The baseline: where the cone's axis (+x from the origin, level) first meets a surface."""
    hits = [
        float(x0) for x0, y0, _x1, y1, *_ in surfaces.segments if min(y0, y1) <= 0 <= max(y0, y1)
    ]
    hits += [float(cx - r) for cx, cy, r, *_ in surfaces.cylinders if abs(cy) <= r]
    return min(hits) if hits else None


def measure(scene: Scene, optics: ConeOptics, rangings: int, seed: int) -> dict[str, object]:
    if scene.ambient_mcps is not None:
        optics = optics.model_copy(update={"ambient_mcps": scene.ambient_mcps})
    array = SensorArray([scene.mount], optics)
    returns = array.returns(array.layers(0.0, 0.0, 0.0, scene.surfaces), 0, scene.roi)
    setup = RangingSetup(timing_budget_ms=scene.budget_ms)
    rng = np.random.default_rng(seed)
    readings = [range_once(returns, setup, RangingNoise(), rng) for _ in range(rangings)]
    valid = [r.distance_mm for r in readings if r.status is ReadingStatus.VALID]
    nearest = nearest_on_axis(scene.surfaces)
    mean = float(np.mean(valid)) if valid else None
    row: dict[str, object] = {
        "scene": scene.scene,
        "kind": scene.kind,
        "near_mm": scene.near_mm,
        "far_mm": scene.far_mm,
        "mean_mm": None if mean is None else round(mean, 1),
        "sd_mm": round(float(np.std(valid)), 1) if valid else None,
        "valid_share": round(len(valid) / rangings, 3),
    }
    for status in STATUSES[1:]:
        row[f"{status.value}_share"] = round(
            sum(r.status is status for r in readings) / rangings, 3
        )
    row["signal_mcps"] = round(returns.signal_mcps, 3)
    row["sigma_mm"] = round(float(np.median([r.sigma_mm for r in readings])), 1)
    row["nearest_mm"] = nearest
    row["mean_over_nearest"] = None if mean is None or not nearest else round(mean / nearest, 3)
    row["published"] = scene.published
    return row


def _fmt(value: object) -> str:
    if value is None:
        return "-"
    if isinstance(value, float):
        return f"{value:.3f}" if abs(value) < 10 else f"{value:.0f}"
    return str(value)


def table(rows: list[dict[str, object]], kinds: tuple[str, ...]) -> str:
    keys = [
        "scene",
        "mean_mm",
        "sd_mm",
        "valid_share",
        "sigma_fail_share",
        "signal_fail_share",
        "out_of_bounds_share",
        "signal_mcps",
        "sigma_mm",
        "nearest_mm",
        "mean_over_nearest",
        "published",
    ]
    lines = ["| " + " | ".join(k.replace("_", " ") for k in keys) + " |"]
    lines.append("|" + "---|" * len(keys))
    for row in rows:
        if row["kind"] in kinds:
            lines.append("| " + " | ".join(_fmt(row[k]) for k in keys) + " |")
    return "\n".join(lines)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--json", action="store_true")
    parser.add_argument("--rangings", type=int, default=400)
    parser.add_argument("--seed", type=int, default=1)
    args = parser.parse_args()
    started = time.perf_counter()
    optics = ConeOptics()
    rows = [measure(scene, optics, args.rangings, args.seed) for scene in scenes()]
    if args.json:
        print(json.dumps({"scenes": rows}))
        return
    print(f"{args.rangings} rangings per scene; robot setup {DEFAULT_SETUP}\n")
    print("### Walls (tripod, no floor in the cone)\n")
    print(table(rows, ("wall",)))
    print("\n### Thin things, edges, nothing (poles and bottles from the robot's 250 mm)\n")
    print(table(rows, ("pole", "bottle_white", "bottle_black", "edge", "nothing")))
    print(f"\n(elapsed {time.perf_counter() - started:.1f} s)")


if __name__ == "__main__":
    main()
