"""Where the default pipeline's time goes (issue 27), in ns per corner-step, against a bare
compiled 1-state UKF over four corners measured in the same process.

Run:  .venv/bin/python benchmarks/stage_times.py [--samples 720000] [--velocity fused]

One hour of 200 Hz (the simulator's dlc_snow tiled), best of 3. Every stage runs inside the
one compiled composition (``vestim.pipeline.rows.pipeline_rows``); here each stage's kernel
is also run alone, through its estimator's own entry point, on the same log's inputs (the
force stage's outputs feeding the velocity stages), and "composition" is what the pipeline
costs beyond the sum: the kinematics between the stages, the copies into blocks, the
output framing. ``--velocity`` times the pipeline with another velocity method (its corner
observers, where it runs them, as a stage of their own).
"""

from __future__ import annotations

import argparse
import time
from collections.abc import Callable
from dataclasses import replace
from typing import Any

import numpy as np
import pandas as pd
from numba import njit

from vestim.constants import CORNERS
from vestim.estimators import registry
from vestim.estimators.force import ForceEstimator
from vestim.estimators.friction import friction_potential, new_friction_state
from vestim.estimators.health import imu_health_kernel, new_imu_state, wheel_health_kernel
from vestim.estimators.health import new_state as new_health_state
from vestim.estimators.uncertainty import uncertainty
from vestim.estimators.validity import validity
from vestim.estimators.velocity.corner import CornerVelocityEstimator, CornerVelocityInput
from vestim.estimators.velocity.reference import (
    ReferenceFilter,
    axle_slip_angles,
    new_stiffness_state,
)
from vestim.filters.ukf import sigma_points, ukf_weights
from vestim.io import load_vehicle
from vestim.io.inputs import inputs_from_log
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
    ap.add_argument("--velocity", default=registry.default("velocity"),
                    help="the velocity method (default: the pipeline's default)")
    args = ap.parse_args()
    n, velocity = args.samples, args.velocity
    corner_method = registry.lookup("velocity", velocity).corner
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

    cfg = PipelineConfig(velocity=velocity)
    pipe = Pipeline(veh, cfg)
    pipe.run(big.iloc[:2000])  # compile
    total = best_of(lambda: pipe.run(big)) / steps * 1e9

    u = inputs_from_log(big, veh)
    delta = np.ascontiguousarray(u.delta)
    omega_out, health = np.empty_like(u.omega), np.empty_like(u.omega)
    imu, imu_health = np.empty((3, n)), np.empty((n, 3))

    def health_stages() -> None:
        wheel_health_kernel(pipe._health_prm, new_health_state(), u.t, u.omega, omega_out,
                            health)
        imu_health_kernel(pipe._imu_prm, new_imu_state(), u.t, u.ax, u.ay, u.yaw_rate,
                          omega_out, delta, imu[0], imu[1], imu[2], imu_health)

    force = ForceEstimator(veh, cfg.force_config())
    res = force.advance(replace(u))

    def force_stage() -> None:
        force.reset()
        force.advance(replace(u))

    fz = res["fz"]
    mu_x = np.ascontiguousarray(np.where(fz > 1.0, res["fx"] / fz, 0.0))
    axle, c_y = np.empty((n, 2)), np.empty(n)

    def stiffness() -> None:
        axle_slip_angles(pipe._stiff_prm, new_stiffness_state(), u.t, u.omega, u.yaw_rate,
                         delta, res["fy"], res["fz"], axle, c_y)

    stiffness()
    b = veh.body
    ref = ReferenceFilter(b.wheel_radius, b.lf, b.lr, pipe._xw, pipe._yw, cfg.reference,
                          mass=b.mass)
    vel = ref.advance(u.t, u.omega, u.torque, mu_x, axle, res["f_x"], res["f_y"], u.yaw_rate,
                      delta, fy_sd=res["fy_sd"])

    def reference_filter() -> None:
        ref.reset()
        ref.advance(u.t, u.omega, u.torque, mu_x, axle, res["f_x"], res["f_y"], u.yaw_rate,
                    delta, fy_sd=res["fy_sd"])

    est = pipe.run(big)
    corner = CornerVelocityEstimator(veh, corner_method or "lugre_kf")
    a_xt = np.repeat(res["f_x"][:, None], 4, axis=1)
    a_yt = np.repeat(res["f_y"][:, None], 4, axis=1)
    vyt = est[[f"vyt_{c}" for c in CORNERS]].to_numpy()
    mu_y = np.ascontiguousarray(np.where(fz > 1.0, res["fy"] / fz, 0.0))
    inp = CornerVelocityInput(t=u.t, omega=u.omega, mu_x=mu_x, a_xt=a_xt, delta=delta,
                              yaw_rate=u.yaw_rate, mu_y=mu_y, a_yt=a_yt, vyt=vyt)

    def corner_observers() -> None:
        corner.reset()
        corner.advance(inp)

    v = np.ascontiguousarray(vel["v"])
    sr = np.ascontiguousarray(est[[f"slip_ratio_{c}" for c in CORNERS]].to_numpy())
    sa = np.ascontiguousarray(est[[f"slip_angle_{c}" for c in CORNERS]].to_numpy())
    vxt = np.ascontiguousarray(est[[f"vxt_{c}" for c in CORNERS]].to_numpy())
    sig_a = np.full(n, 0.01)

    def friction() -> None:
        friction_potential(pipe._friction_prm, new_friction_state(), u.t, res["fx"], res["fy"],
                           res["fz"], res["sigma_fx"], res["sigma_fy"], sr, sa, sig_a, c_y)

    def sigma() -> None:
        uncertainty(u.t, v, vel["sigma"], delta, u.omega, u.ax, u.ay, res["fz"], vxt,
                    np.ascontiguousarray(vyt), sr, c_y, pipe._unc_prm)

    def flags() -> None:
        validity(u.t, float(u.t[0]), v[:, 0], sr, sa, delta[:, :2], u.ay, np.zeros(n, bool),
                 cfg.validity, vel["bias"][:, 3].copy())

    rows = []
    corners = ((f"corner observers ({corner_method})", corner_observers),) if corner_method else ()
    for name, fn in (("force stage (attitude, loads, longitudinal and lateral UKFs)",
                      force_stage), ("reference filter", reference_filter), *corners,
                     ("health stages (wheel, IMU)", health_stages),
                     ("friction potential", friction), ("uncertainty (σ)", sigma),
                     ("validity flags", flags), ("cornering stiffness", stiffness)):
        fn()
        rows.append((name, best_of(fn) / steps * 1e9))
    fused = "; the fused filter's second reference filter" if velocity == "fused" else ""
    rows.append((f"composition (the rest: kinematics, blocks, framing{fused})",
                 total - sum(ns for _, ns in rows)))
    print(f"Pipeline.run, velocity {velocity}, {n} samples: {total * steps / 1e9:.3f} s = {total:.0f} ns "
          f"per corner-step = {total / t_bare:.0f}x the bare 1-state UKF ({t_bare:.1f} ns)")
    print("| stage | ns per corner-step | share | × bare UKF |")
    print("|---|---|---|---|")
    for name, ns in rows:
        print(f"| {name} | {ns:.0f} | {100 * ns / total:.0f} % | {ns / t_bare:.1f} |")


if __name__ == "__main__":
    main()
