"""Force-stage speed (issue 3): four corners × one hour at 200 Hz, after JIT warm-up.

Run:  .venv/bin/python benchmarks/bench_force.py

Targets: each longitudinal estimator < 1 s for 720 000 samples × 4 corners on one
core; the full force stage (longitudinal UKF + lateral UKF + normal) < 2 s.
Also prints how the time scales with log length.
"""

from __future__ import annotations

import time

import numpy as np
import pandas as pd

from _timing import best_of
from vestim.constants import CORNERS
from vestim.estimators.force import ForceConfig, ForceEstimator
from vestim.estimators.force.longitudinal import METHODS, LongitudinalEstimator
from vestim.io import load_vehicle
from vestim.sim import get_maneuver, simulate


def tile(log: pd.DataFrame, n: int) -> pd.DataFrame:
    reps = n // len(log) + 1
    big = pd.concat([log] * reps, ignore_index=True).iloc[:n].copy()
    big["t"] = np.arange(n) * 0.005
    return big


def main() -> None:
    veh = load_vehicle("hashemi_suv")
    log = simulate(get_maneuver("dlc_snow"), veh, seed=1)
    hour = tile(log, 720_000)
    t = hour["t"].to_numpy()
    omega = np.ascontiguousarray(hour[[f"omega_{c}" for c in CORNERS]].to_numpy())
    torque = np.ascontiguousarray(hour[[f"torque_{c}" for c in CORNERS]].to_numpy())
    print("longitudinal estimators, 720 000 samples x 4 corners:")
    for method in METHODS:
        est = LongitudinalEstimator(veh, method)
        est.advance(t[:100], omega[:100], torque[:100])  # warm-up / cache load

        def run(est=est):
            est.reset()
            est.advance(t, omega, torque)

        print(f"  {method:7s} {best_of(run)[0]:6.3f} s")
    full = ForceEstimator(veh, ForceConfig())
    full.run(log)
    print("full force stage (ukf + lateral UKF + normal), by log length:")
    for n in (72_000, 240_000, 720_000):
        part = hour.iloc[:n]
        print(f"  {n:8d} samples  {best_of(lambda part=part: full.run(part))[0]:6.3f} s")
    est = ForceEstimator(veh)
    rows = log.to_dict("records")
    est.step(rows[0])
    t0 = time.perf_counter()
    for r in rows[1:1001]:
        est.step(r)
    per_step = (time.perf_counter() - t0) / 1000
    print(f"step() per sample (all four corners, from a dict): {per_step * 1e6:.0f} us")


if __name__ == "__main__":
    main()
