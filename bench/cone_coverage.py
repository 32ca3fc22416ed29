"""Where the ToF cones look: the robot's layout against the seed's, from the robot description.

    python bench/cone_coverage.py              # the table, for docs/safety.md
    python bench/cone_coverage.py --json       # one JSON object
    python bench/cone_coverage.py --svg DIR    # also draw each layout's coverage map into DIR

The baseline is the seed's layout (every front sensor straight ahead), computed in the same
run. ``corridor full from`` is how far ahead of the front face every point of the body's
corridor is inside some cone; ``blind in 1 m`` the corridor's area within 1 m that no cone
sees; ``warning`` how long a person crossing at 1600 mm/s (ISO 13855's walking speed) from
the hallway's side is seen before they reach the corridor, by how far ahead they cross.
Cones are nominal (``perception/coverage.py``): the simulated sensor's response tapers off
around them (docs/sensor-model.md).
"""

from __future__ import annotations

import argparse
import json
from pathlib import Path

from coffeebot.config import RobotConfig, TofSensorConfig, load_robot_config
from coffeebot.perception.coverage import coverage, layout_figures, svg

ROOT = Path(__file__).resolve().parents[1]
CROSSINGS_MM = (500.0, 1000.0, 1500.0)


def layouts(config: RobotConfig) -> dict[str, list[TofSensorConfig]]:
    straight = [
        s.model_copy(update={"yaw_deg": 0.0}) if s.face == "front" else s
        for s in config.tof.sensors
    ]
    return {"seed (front straight ahead)": straight, config.name: list(config.tof.sensors)}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--json", action="store_true")
    parser.add_argument("--svg", type=Path, help="write <layout>.svg coverage maps here")
    parser.add_argument("--board", type=Path, default=ROOT / "boards" / "coffeebot-v1.toml")
    args = parser.parse_args()
    config = load_robot_config(args.board)
    g = config.geometry
    results = {
        name: layout_figures(sensors, g.length_mm, g.width_mm, crossings_mm=CROSSINGS_MM)
        for name, sensors in layouts(config).items()
    }
    if args.svg is not None:
        args.svg.mkdir(parents=True, exist_ok=True)
        for name, sensors in layouts(config).items():
            slug = "seed" if name.startswith("seed") else name
            cov = coverage(sensors, g.length_mm, g.width_mm, extent_mm=(2000.0, 1200.0, 400.0))
            (args.svg / f"coverage-{slug}.svg").write_text(svg(cov))
    if args.json:
        print(json.dumps(results))
        return
    base = results["seed (front straight ahead)"]
    header = ["layout", "corridor full from", "blind in 1 m"]
    header += [f"warning {side} {d:.0f} mm" for side in ("left", "right") for d in CROSSINGS_MM]
    print("| " + " | ".join(header) + " |")
    print("|" + "---|" * len(header))
    for name, r in results.items():
        warnings = r["warning_s"]
        assert isinstance(warnings, dict)
        cells = [
            name,
            f"{r['corridor_full_from_mm']:.0f} mm",
            f"{r['corridor_blind_m2_within_1m']:.3f} m2",
        ]
        for key, value in warnings.items():
            seed = base["warning_s"][key]  # type: ignore[index]
            ratio = f" ({value / seed:.1f}x)" if seed else ""
            cells.append(f"{value:.2f} s{ratio}")
        print("| " + " | ".join(cells) + " |")


if __name__ == "__main__":
    main()
