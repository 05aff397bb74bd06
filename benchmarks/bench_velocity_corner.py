"""Corner velocity observers (issue 4): speed, and the accuracy table of docs/results.md.

Run:  .venv/bin/python benchmarks/bench_velocity_corner.py           # speed
      .venv/bin/python benchmarks/bench_velocity_corner.py --table   # accuracy (~3 min)

Speed target: each method < 1 s for 720 000 samples × 4 corners on one core. The
inputs are a simulated double lane change (force stage and corner inputs computed
once, outside the timing) tiled to one hour; only ``CornerVelocityEstimator.run`` is
timed (best of 3, wall clock and process CPU time). Also reports the per-sample
``advance`` cost (online use).

Accuracy: per-corner NRMS of v_xt (000 Sec. IV), worst corner, for every maneuver
of :data:`TABLE_MANEUVERS` on both tire plants (seed 0, force stage in the loop,
measured channels only), for each method, the free-rolling guess R·ω, and the KF /
LPV with LuGre parameters fitted (:func:`~vestim.design.calibration.fit_lugre`,
calibration from ground truth) on :data:`FIT_SET` of the same plant.
"""

from __future__ import annotations

import dataclasses
import sys
import time
from functools import partial

import numpy as np
import pandas as pd

from _timing import best_of
from vestim.constants import CORNERS
from vestim.design.calibration import fit_lugre
from vestim.estimators.force import ForceEstimator
from vestim.estimators.velocity.corner import (
    METHODS,
    CornerVelocityEstimator,
    CornerVelocityInput,
    KFParams,
    LPVParams,
)
from vestim.estimators.velocity.corner_inputs import corner_inputs
from vestim.io import load_vehicle
from vestim.io.vehicle import Vehicle
from vestim.models.kinematics import to_tire_frame
from vestim.sim import get_maneuver, simulate

N_HOUR = 720_000


def tile(inp: CornerVelocityInput, n: int) -> CornerVelocityInput:
    """Repeat a chunk to n samples with a continuous 5 ms time axis."""
    reps = n // len(inp) + 1

    def rep(a: np.ndarray) -> np.ndarray:
        return np.concatenate([a] * reps)[:n]

    return CornerVelocityInput(
        t=np.arange(n) * 0.005, omega=rep(inp.omega), mu_x=rep(inp.mu_x), a_xt=rep(inp.a_xt),
        delta=rep(inp.delta), yaw_rate=rep(inp.yaw_rate), mu_y=rep(inp.mu_y), a_yt=rep(inp.a_yt))


def speed() -> None:
    veh = load_vehicle("hashemi_suv")
    log = simulate(get_maneuver("dlc_snow", tire="lugre"), veh, seed=1)
    forces = ForceEstimator(veh).run(log)
    base = corner_inputs(log, forces, veh)
    hour = tile(base, N_HOUR)
    variants: list[tuple[str, str, LPVParams | None]] = [(m, m, None) for m in METHODS]
    variants += [("lpv (004 const.)", "lpv", LPVParams.paper_004()),
                 ("lpv (004 eq. 35)", "lpv", LPVParams.paper_004_scheduled()),
                 ("lpv (no lateral)", "lpv", LPVParams(lateral=None))]
    print(f"corner velocity observers, {N_HOUR} samples x 4 corners (best of 3):")
    for label, method, params in variants:
        est = CornerVelocityEstimator(veh, method, params)
        est.run(base.slice(0, 100))  # warm-up / cache load
        wall, cpu = best_of(partial(est.run, hour))
        flag = "ok" if wall < 1.0 else "SLOW"
        print(f"  {label:18s} {wall:6.3f} s wall, {cpu:6.3f} s CPU  "
              f"({1e9 * wall / (4 * N_HOUR):4.0f} ns per corner-sample) {flag}")
    print("per-sample advance (online), 2 000 calls:")
    for method in METHODS:
        est = CornerVelocityEstimator(veh, method)
        est.reset()
        one = [base.slice(k, k + 1) for k in range(2000)]
        t0 = time.perf_counter()
        for chunk in one:
            est.advance(chunk)
        print(f"  {method:18s} {1e6 * (time.perf_counter() - t0) / 2000:6.1f} µs per call")


TABLE_MANEUVERS: tuple[tuple[str, bool | None], ...] = (
    ("coast", None), ("accel_brake", None), ("dlc_snow", None), ("lc_wet", None), ("oval", None),
    ("ait_dry", None), ("ait_004_dry", None), ("ait_slippery", None), ("bit_slippery", None),
    ("step_steer", None), ("launch_split_mu", None), ("launch_ice", False))
"""(maneuver, tc option) rows of the accuracy table; launch_ice with TC off (long all-wheel spin)."""
FIT_SET = ("ait_dry", "step_steer", "lc_wet")
"""Logs the fitted LuGre parameters are calibrated on (per plant)."""

METHOD_COLUMNS: tuple[tuple[str, str, KFParams | LPVParams | None], ...] = (
    ("KF", "lugre_kf", None), ("UKF", "lugre_ukf", None), ("KF paper Q,R", "lugre_kf", KFParams.paper()),
    ("LPV 001", "lpv", LPVParams.paper_001()), ("LPV 004", "lpv", LPVParams.paper_004()),
    ("LPV 004 (35)", "lpv", LPVParams.paper_004_scheduled()))


def _truth(log: pd.DataFrame, inp: CornerVelocityInput) -> tuple[np.ndarray, np.ndarray]:
    vx = log[[f"ref_vx_{c}" for c in CORNERS]].to_numpy()
    vy = log[[f"ref_vy_{c}" for c in CORNERS]].to_numpy()
    return to_tire_frame(vx, vy, inp.delta)


def _nrms(est: np.ndarray, ref: np.ndarray) -> float:
    """Worst-corner NRMS (RMS error / max |truth|), in %; NaN where the truth is ~0."""
    peak = np.max(np.abs(ref), axis=0)
    if np.max(peak) < 0.1:
        return float("nan")
    err = np.sqrt(np.mean((est - ref) ** 2, axis=0)) / np.where(peak > 0.1, peak, np.nan)
    return 100.0 * float(np.nanmax(err))


def table() -> None:
    veh = load_vehicle("hashemi_suv")
    cases = {}
    for tire in ("lugre", "magic"):
        for name, tc in TABLE_MANEUVERS:
            log = simulate(get_maneuver(name, tire=tire, tc=tc), veh, seed=0)
            meas = log.drop(columns=[c for c in log.columns if c.startswith("ref_")])
            cases[(name, tire)] = (log, corner_inputs(meas, ForceEstimator(veh).run(meas), veh))
    fitted: dict[str, Vehicle] = {}
    print("fitted LuGre parameters (fit_lugre on " + ", ".join(FIT_SET) + "):")
    keys = ("sigma0_x", "sigma2_x", "kappa_x", "sigma0_y", "sigma2_y", "kappa_y", "mu_s", "mu_c", "v_s")
    print("| plant | " + " | ".join(keys) + " | σ0x/κx | σ0y/κy |")
    print("|---" * (len(keys) + 3) + "|")
    nom = veh.tire
    print("| nominal | " + " | ".join(f"{getattr(nom, k):.4g}" for k in keys)
          + f" | {nom.sigma0_x / nom.kappa_x:.1f} | {nom.sigma0_y / nom.kappa_y:.1f} |")
    for tire in ("lugre", "magic"):
        ft = fit_lugre([cases[(n, tire)][0] for n in FIT_SET], veh)
        fitted[tire] = dataclasses.replace(veh, tire=ft)
        print(f"| {tire} | " + " | ".join(f"{getattr(ft, k):.4g}" for k in keys)
              + f" | {ft.sigma0_x / ft.kappa_x:.1f} | {ft.sigma0_y / ft.kappa_y:.1f} |")
    heads = ["R·ω", *(c[0] for c in METHOD_COLUMNS), "KF fitted", "LPV 001 fitted", "v_yt LPV 001"]
    print("\nv_xt NRMS, worst corner, % (last column: v_yt of the lateral LPV)")
    print("| maneuver | plant | " + " | ".join(heads) + " |")
    print("|---" * (len(heads) + 2) + "|")
    for tire in ("lugre", "magic"):
        for name, _ in TABLE_MANEUVERS:
            log, inp = cases[(name, tire)]
            vxt, vyt = _truth(log, inp)
            row = [_nrms(veh.body.wheel_radius * inp.omega, vxt)]
            for _, method, params in METHOD_COLUMNS:
                row.append(_nrms(CornerVelocityEstimator(veh, method, params).run(inp).vxt, vxt))
            row.append(_nrms(CornerVelocityEstimator(fitted[tire], "lugre_kf").run(inp).vxt, vxt))
            lpv = CornerVelocityEstimator(fitted[tire], "lpv").run(inp)
            row.append(_nrms(lpv.vxt, vxt))
            row.append(_nrms(CornerVelocityEstimator(veh, "lpv").run(inp).vyt, vyt))
            print(f"| {name} | {tire} | " + " | ".join(f"{v:.2f}" for v in row) + " |")


if __name__ == "__main__":
    if "--table" in sys.argv[1:]:
        table()
    else:
        speed()
