"""Simulator speed: 60 s of driving at 1 kHz, per tire plant (issue target: < 2 s on one core).

Run:  make bench   (or .venv/bin/python benchmarks/bench_sim.py)

Times the whole `simulate()` call (kernel, sensor model, DataFrame) after a
warm-up run that compiles / loads the Numba cache. The 002 study maneuver is
60 s long; the ice launch with the LuGre plant is the stiff worst case (the
kernel sub-steps while the tires slide) and is scaled to 60 s.
"""

from __future__ import annotations

import os
import time

os.environ.setdefault("NUMBA_NUM_THREADS", "1")

from vestim.sim import get_maneuver, simulate

CASES = [
    ("stiffness_study", "magic"),
    ("stiffness_study", "lugre"),
    ("dlc_snow", "magic"),
    ("dlc_snow", "lugre"),
    ("launch_ice", "magic"),
    ("launch_ice", "lugre"),
    ("launch_split_mu", "lugre"),
]


def main(repeats: int = 3) -> None:
    print(f"{'maneuver':18s} {'tire':6s} {'sim s':>6s} {'wall s':>8s} {'per 60 s':>9s}")
    for name, tire in CASES:
        m = get_maneuver(name, tire=tire)
        simulate(m)  # warm-up
        best = float("inf")
        for _ in range(repeats):
            t0 = time.perf_counter()
            simulate(m)
            best = min(best, time.perf_counter() - t0)
        print(f"{name:18s} {tire:6s} {m.duration:6.1f} {best:8.3f} {best * 60 / m.duration:9.3f}")


if __name__ == "__main__":
    main()
