"""Where the default pipeline's time goes (issue 27), in ns per corner-step, against a bare
compiled 1-state UKF over four corners measured in the same process.

Run:  .venv/bin/python benchmarks/stage_times.py [--samples 720000]

One hour of 200 Hz (the simulator's dlc_snow tiled), best of 3. Every stage runs inside the
one compiled composition (``vestim.pipeline.rows.pipeline_rows``), so a stage's cost is read
by difference between configurations of that composition on the same log, each the same
call with one stage swapped for a cheaper one:

- longitudinal force UKF: force ``ukf`` against ``naive`` (a finite difference);
- reference filter: velocity ``reference`` against ``kinematic`` (an integrator);
- corner observers and their fusion: velocity ``kf`` against ``reference``;
- the fused filter's second reference filter: ``fused`` against ``kf`` (on dlc_snow the
  corners rarely all slip, so this is mostly the copy of the plain filter's state);
- the rest of the composition (attitude, normal loads, lateral force UKF, the cornering
  stiffness, GNSS calibration, friction, validity, uncertainty): ``kinematic`` with force
  ``naive``;
- the health stages and the input/output framing of ``Pipeline.run`` around the call:
  measured directly.
"""

from __future__ import annotations

import argparse
import time
from collections.abc import Callable
from typing import Any

import numpy as np
import pandas as pd
from numba import njit

from vestim.estimators.health import imu_health_kernel, wheel_health_kernel
from vestim.filters.ukf import sigma_points, ukf_weights
from vestim.io import load_vehicle
from vestim.pipeline import Pipeline, PipelineConfig
from vestim.sim import get_maneuver, simulate


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


def best_of(fn: Callable[[], Any], repeats: int = 3) -> float:
    """The shortest of ``repeats`` wall times of ``fn()``, s."""
    best = float("inf")
    for _ in range(repeats):
        t0 = time.perf_counter()
        fn()
        best = min(best, time.perf_counter() - t0)
    return best


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__)
    ap.add_argument("--samples", type=int, default=720_000)
    n = ap.parse_args().samples
    veh = load_vehicle("hashemi_suv")
    log = simulate(get_maneuver("dlc_snow"), veh, seed=1)
    log = log.drop(columns=[c for c in log.columns if c.startswith("ref_")])
    big = pd.concat([log] * (n // len(log) + 1), ignore_index=True).iloc[:n].copy()
    big["t"] = np.arange(n) * 0.005
    steps = 4.0 * n  # corner-steps

    z = np.ascontiguousarray(big[["omega_fl", "omega_fr", "omega_rl", "omega_rr"]].to_numpy())
    wm, wc, tau = ukf_weights(1)
    out = np.empty_like(z)

    def bare() -> None:
        bare_ukf(z, 0.1, 0.2, wm, wc, tau, np.zeros(4), np.ones(4), out)

    bare()
    t_bare = best_of(bare) / steps * 1e9

    times: dict[str, float] = {}
    for name, cfg in (("default", PipelineConfig()),
                      ("fused", PipelineConfig(velocity="fused")),
                      ("kf", PipelineConfig(velocity="kf")),
                      ("reference", PipelineConfig(velocity="reference")),
                      ("kinematic", PipelineConfig(velocity="kinematic")),
                      ("kinematic+naive", PipelineConfig(velocity="kinematic", force="naive"))):
        pipe = Pipeline(veh, cfg)
        pipe.run(big.iloc[:2000])  # compile
        times[name] = best_of(lambda pipe=pipe: pipe.run(big)) / steps * 1e9

    pipe = Pipeline(veh)
    u_omega = np.ascontiguousarray(z)
    t_ = big["t"].to_numpy()
    delta = np.zeros((n, 4))
    delta[:, 0] = big["delta_fl"].to_numpy()
    delta[:, 1] = big["delta_fr"].to_numpy()
    omega_out, health = np.empty_like(u_omega), np.empty_like(u_omega)
    imu, imu_health = np.empty((3, n)), np.empty((n, 3))
    from vestim.estimators.health import new_imu_state
    from vestim.estimators.health import new_state as new_health_state

    def health_stages() -> None:
        wheel_health_kernel(pipe._health_prm, new_health_state(), t_, u_omega, omega_out, health)
        imu_health_kernel(pipe._imu_prm, new_imu_state(), t_, big["ax"].to_numpy(),
                          big["ay"].to_numpy(), big["yaw_rate"].to_numpy(), omega_out, delta,
                          imu[0], imu[1], imu[2], imu_health)

    health_stages()
    t_health = best_of(health_stages) / steps * 1e9

    rows = [
        ("longitudinal force UKF (ukf − naive)",
         times["kinematic"] - times["kinematic+naive"]),
        ("reference filter (reference − kinematic)", times["reference"] - times["kinematic"]),
        ("corner observers + fusion (kf − reference)", times["kf"] - times["reference"]),
        ("fused filter (fused − kf)", times["fused"] - times["kf"]),
        ("health stages (wheel, IMU)", t_health),
        ("the rest (kinematic + naive, less the health stages)",
         times["kinematic+naive"] - t_health),
    ]
    total = times["default"]
    print(f"default Pipeline.run, {n} samples: {total * steps / 1e9:.3f} s = {total:.0f} ns "
          f"per corner-step = {total / t_bare:.0f}x the bare 1-state UKF ({t_bare:.1f} ns)")
    print("| stage | ns per corner-step | share | × bare UKF |")
    print("|---|---|---|---|")
    for name, ns in rows:
        print(f"| {name} | {ns:.0f} | {100 * ns / total:.0f} % | {ns / t_bare:.1f} |")


if __name__ == "__main__":
    main()
