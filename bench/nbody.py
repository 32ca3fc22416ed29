"""The n-body program (the Computer Language Benchmarks Game's, 5 bodies, steps of 0.01):
the CPU-bound Python reference bench/cpu.py scales its Raspberry Pi 4 estimate by.

Plain Python 3 without dependencies, so any interpreter can run it, an older one too:

    python3.7 bench/nbody.py 500000     # prints the least CPU seconds of three runs

bench/cpu.py times it here in its own interpreter and, with ``--reference-python``, in the
Python the published Pi 4 figure was measured with, to tell the machine's speed from the
interpreter's.
"""

from __future__ import annotations

import math
import sys
import time

ROUNDS = 3


def nbody_seconds(steps: int) -> float:
    """CPU seconds for ``steps`` steps of the n-body program (pure Python, as published)."""
    pi = math.pi
    solar_mass = 4 * pi * pi
    days = 365.24
    bodies = [
        ([0.0, 0.0, 0.0], [0.0, 0.0, 0.0], solar_mass),
        (
            [4.84143144246472090e00, -1.16032004402742839e00, -1.03622044471123109e-01],
            [
                1.66007664274403694e-03 * days,
                7.69901118419740425e-03 * days,
                -6.90460016972063023e-05 * days,
            ],
            9.54791938424326609e-04 * solar_mass,
        ),
        (
            [8.34336671824457987e00, 4.12479856412430479e00, -4.03523417114321381e-01],
            [
                -2.76742510726862411e-03 * days,
                4.99852801234917238e-03 * days,
                2.30417297573763929e-05 * days,
            ],
            2.85885980666130812e-04 * solar_mass,
        ),
        (
            [1.28943695621391310e01, -1.51111514016986312e01, -2.23307578892655734e-01],
            [
                2.96460137564761618e-03 * days,
                2.37847173959480950e-03 * days,
                -2.96589568540237556e-05 * days,
            ],
            4.36624404335156298e-05 * solar_mass,
        ),
        (
            [1.53796971148509165e01, -2.59193146099879641e01, 1.79258772950371181e-01],
            [
                2.68067772490389322e-03 * days,
                1.62824170038242295e-03 * days,
                -9.51592254519715870e-05 * days,
            ],
            5.15138902046611451e-05 * solar_mass,
        ),
    ]
    pairs = [(bodies[i], bodies[j]) for i in range(5) for j in range(i + 1, 5)]
    dt = 0.01
    start = time.process_time()
    for _ in range(steps):
        for (r1, v1, m1), (r2, v2, m2) in pairs:
            dx, dy, dz = r1[0] - r2[0], r1[1] - r2[1], r1[2] - r2[2]
            mag = dt * ((dx * dx + dy * dy + dz * dz) ** -1.5)
            b1, b2 = m1 * mag, m2 * mag
            v1[0] -= dx * b2
            v1[1] -= dy * b2
            v1[2] -= dz * b2
            v2[0] += dx * b1
            v2[1] += dy * b1
            v2[2] += dz * b1
        for r, (vx, vy, vz), _ in bodies:
            r[0] += dt * vx
            r[1] += dt * vy
            r[2] += dt * vz
    return time.process_time() - start


def best_seconds(steps: int, rounds: int = ROUNDS) -> float:
    """The least CPU time of ``rounds`` runs: a CPU benchmark's least is the least disturbed."""
    return min(nbody_seconds(steps) for _ in range(rounds))


if __name__ == "__main__":
    print(best_seconds(int(sys.argv[1])))
