"""Fusion of the corner velocities (issue 6): per-sample cost of each method.

Run:  .venv/bin/python benchmarks/bench_fusion.py

One hour at 200 Hz (720 000 samples × 4 corners) of synthetic opinions and slip
ratios: corner speeds around 20 m/s, slips ~N(0, 0.15) with a heavily slipping
corner every 9th sample and NaN (standstill) rows, so every branch of the eq. (13)
solver is visited (all four corners capped at γ, one lone confident corner, W_max
feasible). ``fuse`` is timed end to end (validation, allocation, Numba kernel;
for "opinion" the eq. (13) optimisation of every sample included), best of 3,
after a warm-up call that loads the compiled kernels. Target: < 20 µs per sample.
Also reports ``fuse`` on one sample (online use, Python call overhead dominates)
and the batch eq. (13) solver alone.
"""

from __future__ import annotations

import time

import numpy as np

from _timing import best_of
from vestim.estimators.fusion import FUSION_METHODS, FusionParams, confidence_bounds, fuse, solve_confidences

N_HOUR = 720_000
TARGET_US = 20.0


def inputs(n: int, seed: int = 0) -> tuple[np.ndarray, np.ndarray]:
    rng = np.random.default_rng(seed)
    phi = 20.0 + rng.normal(0.0, 0.3, (n, 4))
    slip = rng.normal(0.0, 0.15, (n, 4))
    slip[::9, 2] = 0.9
    slip[::11, 1:] = 0.9  # three slipping corners: the confident one rises above the cap
    slip[::200] = np.nan
    return phi, slip


def main() -> None:
    phi, slip = inputs(N_HOUR)
    params = FusionParams()
    print(f"fusion, {N_HOUR} samples x 4 corners (best of 3):")
    for method in FUSION_METHODS:
        fuse(method, phi[:8], slip[:8], params)  # warm-up: load the cached kernels
        wall, cpu = best_of(lambda m=method: fuse(m, phi, slip, params))
        us = 1e6 * wall / N_HOUR
        flag = "ok" if us < TARGET_US else "ABOVE TARGET"
        print(f"  {method:9s} {wall:6.3f} s wall, {cpu:6.3f} s CPU  {us:7.3f} µs/sample  ({flag}, "
              f"target < {TARGET_US:g})")
    lo, hi = confidence_bounds(slip, params.k1, params.k2, params.w_floor, params.band)
    solve_confidences(lo[:8], hi[:8], params.gamma)
    wall, _ = best_of(lambda: solve_confidences(lo, hi, params.gamma))
    print(f"  eq. (13) solver alone: {1e6 * wall / N_HOUR:7.3f} µs/sample")
    print("per-sample fuse (online), 20 000 calls:")
    for method in FUSION_METHODS:
        t0 = time.perf_counter()
        for i in range(20_000):
            fuse(method, phi[i:i + 1], slip[i:i + 1], params)
        print(f"  {method:9s} {1e6 * (time.perf_counter() - t0) / 20_000:7.2f} µs per call")


if __name__ == "__main__":
    main()
