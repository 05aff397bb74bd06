"""Each pipeline stage's share of the time (issue 12), in ns per corner-step, against a bare
compiled 1-state UKF over four corners.

Run:  .venv/bin/python benchmarks/stage_times.py [--samples 720000]

The default pipeline runs one hour of 200 Hz (the simulator's dlc_snow tiled) with every
stage's entry point wrapped by a timer; "glue" is the rest of ``Pipeline.run`` (input
bundling, the kinematics between stages, output framing). Best of 3, one process; the
wrappers add ~1 µs per call, i.e. nothing at 65 536 samples per call.
"""

from __future__ import annotations

import argparse
import time
from collections import defaultdict
from collections.abc import Callable
from typing import Any

import numpy as np
import pandas as pd
from numba import njit

import vestim.pipeline as pl
from vestim.filters.ukf import sigma_points, ukf_weights
from vestim.io import load_vehicle
from vestim.pipeline import Pipeline
from vestim.sim import get_maneuver, simulate

STAGE_FUNCTIONS = ("corrected_log", "inputs_from_log", "wheel_health_kernel", "imu_health_kernel",
                   "axle_slip_angles", "gnss_calibration", "uncertainty", "friction_potential",
                   "validity")
"""Module-level functions of vestim.pipeline timed as stages (those present)."""


@njit(cache=True, error_model="numpy")
def bare_ukf(z: np.ndarray, q: float, r: float, wm: np.ndarray, wc: np.ndarray, tau: float,
             x: np.ndarray, P: np.ndarray, out: np.ndarray) -> None:
    """A random-walk state per corner measured directly: the UKF of 000 eq. (10)–(12) at its
    smallest (1 state, 3 sigma points), over (n, 4) measurements."""
    L = np.empty((1, 1))
    pts = np.empty((3, 1))
    xs = np.empty(1)
    Ps = np.empty((1, 1))
    for k in range(z.shape[0]):
        for c in range(4):
            xs[0] = x[c]
            Ps[0, 0] = P[c] + q
            sigma_points(xs, Ps, tau, L, pts)
            xm = 0.0
            for i in range(3):
                xm += wm[i] * pts[i, 0]
            pzz = r
            for i in range(3):
                d = pts[i, 0] - xm
                pzz += wc[i] * d * d
            pxz = pzz - r
            gain = pxz / pzz
            x[c] = xm + gain * (z[k, c] - xm)
            P[c] = Ps[0, 0] - gain * gain * pzz
            out[k, c] = x[c]


def _timed(fn: Callable[..., Any], acc: dict[str, float], name: str) -> Callable[..., Any]:
    def wrapper(*args: Any, **kwargs: Any) -> Any:
        t0 = time.perf_counter()
        try:
            return fn(*args, **kwargs)
        finally:
            acc[name] += time.perf_counter() - t0
    return wrapper


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__)
    ap.add_argument("--samples", type=int, default=720_000)
    n = ap.parse_args().samples
    veh = load_vehicle("hashemi_suv")
    log = simulate(get_maneuver("dlc_snow"), veh, seed=1)
    log = log.drop(columns=[c for c in log.columns if c.startswith("ref_")])
    big = pd.concat([log] * (n // len(log) + 1), ignore_index=True).iloc[:n].copy()
    big["t"] = np.arange(n) * 0.005

    wm, wc, tau = ukf_weights(1)
    z = np.ascontiguousarray(big[[f"omega_{c}" for c in ("fl", "fr", "rl", "rr")]].to_numpy())
    out = np.empty_like(z)
    bare = float("inf")
    for _ in range(4):
        x, P = z[0].copy(), np.ones(4)
        t0 = time.perf_counter()
        bare_ukf(z, 1e-3, 0.1, wm, wc, tau, x, P, out)
        bare = min(bare, time.perf_counter() - t0)
    bare_ns = bare / (4 * n) * 1e9

    pipe = Pipeline(veh)
    pipe.run(log)  # compile / load the kernels
    best: dict[str, float] | None = None
    total = float("inf")
    for _ in range(3):
        acc: dict[str, float] = defaultdict(float)
        saved = {name: getattr(pl, name) for name in STAGE_FUNCTIONS if hasattr(pl, name)}
        for name, fn in saved.items():
            setattr(pl, name, _timed(fn, acc, name))
        stages = {"force": pipe.force, "reference filter": pipe.reference,
                  "fused filter": pipe.fused, "corner observers": pipe.corner}
        methods = {label: obj.advance for label, obj in stages.items() if obj is not None}
        for label, obj in stages.items():
            if obj is not None:
                obj.advance = _timed(obj.advance, acc, label)  # type: ignore[method-assign]
        try:
            t0 = time.perf_counter()
            pipe.run(big)
            elapsed = time.perf_counter() - t0
        finally:
            for name, fn in saved.items():
                setattr(pl, name, fn)
            for label, obj in stages.items():
                if obj is not None:
                    obj.advance = methods[label]  # type: ignore[method-assign]
        if elapsed < total:
            total, best = elapsed, dict(acc)
    assert best is not None
    best["glue (the rest of run)"] = total - sum(best.values())
    print(f"default pipeline, {n} samples: {total:.3f} s = {total / (4 * n) * 1e9:.0f} ns per "
          f"corner-step; bare 1-state UKF {bare_ns:.1f} ns per corner-step")
    print("| stage | s | share | ns per corner-step | × bare UKF |")
    print("|---|---|---|---|---|")
    for name, sec in sorted(best.items(), key=lambda kv: -kv[1]):
        ns = sec / (4 * n) * 1e9
        print(f"| {name} | {sec:.3f} | {sec / total:.0%} | {ns:.0f} | {ns / bare_ns:.0f} |")


if __name__ == "__main__":
    main()
