"""Drive log → inputs and measurements of the single-track estimation model (002 Sec. II, V).

Reads only the measured channels it needs (never a ``ref_`` column):
``t``, ``omega_fl`` … ``omega_rr``, ``ax``, ``ay``, ``yaw_rate`` and a steering
channel (via :func:`vestim.io.road_wheel_angles`).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import pandas as pd

from vestim.constants import CORNERS, G
from vestim.errors import LogFormatError
from vestim.estimators.stiffness.config import StiffnessConfig
from vestim.estimators.stiffness.model import (
    N_INPUT,
    N_MEAS,
    U_DELTA,
    U_DT,
    U_OMEGA_F,
    U_OMEGA_R,
    pitch_gradient,
    roll_gradient,
)
from vestim.io import road_wheel_angles
from vestim.io.vehicle import Vehicle

REQUIRED: tuple[str, ...] = ("t", *(f"omega_{c}" for c in CORNERS), "ax", "ay", "yaw_rate")
"""Columns the stiffness estimators read, besides a steering channel."""


@dataclass(frozen=True)
class StiffnessInputs:
    """Arrays for the kernels, one row per log sample.

    Attributes:
        t: (K,) s. u: (K, 4) [δ rad, ω_f rad/s, ω_r rad/s, T_s s] with δ the mean of the
            two front road-wheel angles (002 Sec. V) and ω the (low-passed) axle means.
        y: (K, 3) [a_x, a_y, ψ̇] with a_x, a_y divided by (1 + c g) (roll and pitch
            compensation, 002 Sec. II-A), m/s², m/s², rad/s.
        active: (K,) activation flags of 002 Sec. V (statistics update and forgetting).
        settled: (K,) False during the first ``settle_time`` s: bias filter frozen too.
        accel_scale: (2,) the factors (1 + c_θ g, 1 + c_φ g) dividing a_x, a_y.
        speed: (K,) m/s, R·ω of the slowest axle (initial v_x and activation).
    """

    t: np.ndarray
    u: np.ndarray
    y: np.ndarray
    active: np.ndarray
    settled: np.ndarray
    accel_scale: np.ndarray
    speed: np.ndarray


def _column(log: pd.DataFrame, name: str) -> np.ndarray:
    if name not in log.columns:
        raise LogFormatError(f"log has no column '{name}', which the stiffness estimator needs; "
                             f"required: {', '.join(REQUIRED)} and a steering channel")
    values = log[name].to_numpy(dtype=np.float64, na_value=np.nan)
    bad = np.flatnonzero(~np.isfinite(values))
    if bad.size:
        raise LogFormatError(f"column '{name}' has a non-finite value at row {bad[0]}; "
                             "the stiffness estimator needs every sample")
    return values


def lowpass(x: np.ndarray, t: np.ndarray, cutoff: float) -> np.ndarray:
    """Causal first-order low-pass (exact discretisation for each step length), Hz; 0 returns ``x``."""
    if cutoff <= 0.0:
        return x.copy()
    tau = 1.0 / (2.0 * np.pi * cutoff)
    a = 1.0 - np.exp(-np.diff(t, prepend=t[0]) / tau)
    out = np.empty_like(x)
    s = x[0]
    for k in range(x.shape[0]):
        s += a[k] * (x[k] - s)
        out[k] = s
    return out


def prepare_inputs(log: pd.DataFrame, vehicle: Vehicle, config: StiffnessConfig) -> StiffnessInputs:
    """Build :class:`StiffnessInputs` from a spec log.

    Raises:
        LogFormatError: a required column is missing or non-finite, fewer than two rows,
            or ``t`` is not strictly increasing (the message names the column).
    """
    t = _column(log, "t")
    if t.shape[0] < 2:
        raise LogFormatError("log has fewer than two rows; the stiffness estimator needs a time series")
    dt = np.diff(t)
    if np.any(dt <= 0):
        k = int(np.flatnonzero(dt <= 0)[0]) + 1
        raise LogFormatError(f"column 't' is not strictly increasing at row {k}")
    omega = np.column_stack([_column(log, f"omega_{c}") for c in CORNERS])
    ax = _column(log, "ax")
    ay = _column(log, "ay")
    yaw_rate = _column(log, "yaw_rate")
    delta = road_wheel_angles(log, vehicle.body.steering_ratio).mean(axis=1)
    if not np.all(np.isfinite(delta)):
        raise LogFormatError("steering channel has non-finite values; the stiffness estimator "
                             "needs every sample")
    om_f = lowpass(omega[:, :2].mean(axis=1), t, config.wheel_speed_cutoff)
    om_r = lowpass(omega[:, 2:].mean(axis=1), t, config.wheel_speed_cutoff)
    u = np.empty((t.shape[0], N_INPUT))
    u[:, U_DELTA] = delta
    u[:, U_OMEGA_F] = om_f
    u[:, U_OMEGA_R] = om_r
    u[:-1, U_DT] = dt
    u[-1, U_DT] = dt[-1]
    scale = np.array([1.0 + pitch_gradient(vehicle) * G, 1.0 + roll_gradient(vehicle) * G])
    y = np.empty((t.shape[0], N_MEAS))
    y[:, 0] = ax / scale[0]
    y[:, 1] = ay / scale[1]
    y[:, 2] = yaw_rate
    rw_f = vehicle.body.wheel_radius * om_f
    rw_r = vehicle.body.wheel_radius * om_r
    speed = np.minimum(rw_f, rw_r)
    slip_proxy = (rw_f - rw_r) / np.maximum(np.maximum(rw_f, rw_r), config.v_min)
    settled = t - t[0] >= config.settle_time
    active = settled & (speed >= config.v_min) & ((np.abs(delta) >= config.delta_min)
                                                  | (np.abs(slip_proxy) >= config.slip_min))
    return StiffnessInputs(t=t, u=u, y=y, active=active, settled=settled, accel_scale=scale,
                           speed=speed)
