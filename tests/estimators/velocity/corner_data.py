"""Shared inputs for the corner velocity observer tests: synthetic chunks and simulator logs."""

from __future__ import annotations

from functools import cache

import numpy as np
import pandas as pd

from vestim.constants import CORNERS
from vestim.estimators.force import ForceEstimator
from vestim.estimators.velocity.corner import CornerVelocityInput, HighSlipParams
from vestim.estimators.velocity.corner_inputs import corner_inputs
from vestim.io import load_vehicle
from vestim.models.kinematics import to_tire_frame
from vestim.sim import get_maneuver, simulate

SUV = load_vehicle("hashemi_suv")

NO_SWITCHING = HighSlipParams(lambda_upper=1e9, lambda_lower=1e8, omega_dot_threshold=1e12,
                              mu_release=0.0)
"""A detector that never fires: the filters run with their normal-driving Q̄, R̄ only."""


def synthetic(n: int = 400, seed: int = 0, *, planar: bool = False, h: float = 0.005,
              jitter: float = 0.0) -> CornerVelocityInput:
    """Random but smooth corner inputs: wheel speeds 10–40 rad/s with noise, μ in ±0.4.

    planar=False sets yaw rate and steering to zero (no transport term), which the
    textbook references below assume.
    """
    rng = np.random.default_rng(seed)
    t = np.cumsum(np.full(n, h) * (1.0 + jitter * rng.uniform(-1, 1, n)))
    base = 25.0 + 10.0 * np.sin(2 * np.pi * t[:, None] / 3.0 + rng.uniform(0, 6, 4))
    omega = base + rng.normal(0.0, 0.4, (n, 4))
    mu_x = 0.3 * np.sin(2 * np.pi * t[:, None] / 2.0 + rng.uniform(0, 6, 4)) + rng.normal(0, 0.02, (n, 4))
    mu_y = 0.2 * np.cos(2 * np.pi * t[:, None] / 2.5 + rng.uniform(0, 6, 4)) + rng.normal(0, 0.02, (n, 4))
    a_xt = 3.0 * np.cos(2 * np.pi * t[:, None] / 3.0) + rng.normal(0.0, 0.05, (n, 4))
    a_yt = 2.0 * np.sin(2 * np.pi * t[:, None] / 4.0) + rng.normal(0.0, 0.05, (n, 4))
    delta = np.zeros((n, 4))
    r = np.zeros(n)
    if planar:
        delta[:, :2] = 0.1 * np.sin(2 * np.pi * t / 4.0)[:, None]
        r = 0.3 * np.sin(2 * np.pi * t / 4.0)
    return CornerVelocityInput(t=t, omega=omega, mu_x=mu_x, a_xt=a_xt, delta=delta, yaw_rate=r,
                               mu_y=mu_y, a_yt=a_yt)


def without_ref(log: pd.DataFrame) -> pd.DataFrame:
    return log.drop(columns=[c for c in log.columns if c.startswith("ref_")])


@cache
def sim_case(name: str, tire: str, tc: bool | None = None) -> tuple[pd.DataFrame, CornerVelocityInput]:
    """A simulated log (seed 0) and the corner inputs built from its measured channels only."""
    log = simulate(get_maneuver(name, tire=tire, tc=tc), SUV, seed=0)
    meas = without_ref(log)
    forces = ForceEstimator(SUV).run(meas)
    return log, corner_inputs(meas, forces, SUV)


def reference_vxt(log: pd.DataFrame, inp: CornerVelocityInput) -> np.ndarray:
    """Truth v_xt (n, 4): ref_vx_*, ref_vy_* rotated into the tire frames by δ."""
    vx = log[[f"ref_vx_{c}" for c in CORNERS]].to_numpy()
    vy = log[[f"ref_vy_{c}" for c in CORNERS]].to_numpy()
    return to_tire_frame(vx, vy, inp.delta)[0]


def nrms(est: np.ndarray, ref: np.ndarray) -> np.ndarray:
    """Per-corner NRMS of 000 Sec. IV: RMS error over max |truth|, shape (4,)."""
    return np.sqrt(np.mean((est - ref) ** 2, axis=0)) / np.max(np.abs(ref), axis=0)
