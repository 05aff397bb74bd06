"""Logs shared by the report tests: one simulated step steer and an estimate of it with
known, per-corner offsets from the truth (so every error trace and score is known)."""

from __future__ import annotations

import numpy as np
import pandas as pd
import pytest

from vestim.constants import CORNERS
from vestim.sim import simulate

R = 0.33  # m, hashemi_suv wheel_radius

OFFSETS: dict[str, float] = {"vx": 0.2, "vy": -0.05}
"""Estimate − reference of the CG channels, in their unit."""
for _k, _c in enumerate(CORNERS):
    OFFSETS[f"vx_{_c}"] = 0.1
    OFFSETS[f"vy_{_c}"] = 0.02
    OFFSETS[f"fx_{_c}"] = 100.0 * (_k + 1)  # 100, 200, 300, 400 N: a different error per corner
    OFFSETS[f"fy_{_c}"] = -50.0
    OFFSETS[f"fz_{_c}"] = 200.0
    OFFSETS[f"slip_ratio_{_c}"] = 0.01
    OFFSETS[f"slip_angle_{_c}"] = -0.005


@pytest.fixture(scope="session")
def sim_log() -> pd.DataFrame:
    """8 s step steer at 200 Hz (1601 samples, below MAX_POINTS: drawn without reduction)."""
    return simulate("step_steer", "hashemi_suv", seed=0)


@pytest.fixture(scope="session")
def offset_estimate(sim_log: pd.DataFrame) -> pd.DataFrame:
    """Every report channel as truth + :data:`OFFSETS`, σ on v_x and F_x, μ_x/μ_y from the
    estimated forces, a ``valid_fl`` flag that drops to 0 for 1 s, a ``health_vx`` ramp,
    ``valid_velocity`` 0 with reason 1 (not converged) for t < 2 s and reason 2 + 8
    (standstill, high slip) for 5 s ≤ t < 5.5 s, and a road friction ``mu_fl`` that is NaN
    (not excited) on every row, ``mu_fr`` on the first half."""
    t = sim_log["t"].to_numpy()
    cols: dict[str, np.ndarray] = {"t": t}
    for name, off in OFFSETS.items():
        cols[name] = sim_log["ref_" + name].to_numpy() + off
    cols["sigma_vx"] = np.full(t.size, 0.1)
    for c in CORNERS:
        cols[f"sigma_fx_{c}"] = np.full(t.size, 150.0)
        cols[f"mu_x_{c}"] = cols[f"fx_{c}"] / cols[f"fz_{c}"]
        cols[f"mu_y_{c}"] = cols[f"fy_{c}"] / cols[f"fz_{c}"]
    cols["valid_fl"] = np.where((t > 3.0) & (t < 4.0), 0.0, 1.0)
    cols["health_vx"] = np.clip(t / t[-1], 0.0, 1.0)
    reason = np.where(t < 2.0, 1.0, np.where((t >= 5.0) & (t < 5.5), 10.0, 0.0))
    cols["valid_velocity"] = (reason == 0.0).astype(float)
    cols["reason_velocity"] = reason
    cols["mu_fl"] = np.full(t.size, np.nan)
    cols["mu_fr"] = np.where(t < t[t.size // 2], np.nan, sim_log["ref_mu_fr"].to_numpy())
    est = pd.DataFrame(cols)
    est.attrs = {"vehicle": "hashemi_suv", "velocity": "fused"}
    return est
