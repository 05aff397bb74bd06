"""Drive log → inputs and measurements of the single-track estimation model (002 Sec. II, V).

Reads only the measured channels it needs (never a ``ref_`` column):
``t``, ``omega_fl`` … ``omega_rr``, ``ax``, ``ay``, ``yaw_rate`` and a steering
channel (via :func:`vestim.io.road_wheel_angles`); ``roll_rate`` and ``pitch_rate``
when the log has them (roll and pitch compensation, :func:`attitude_scale`).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import pandas as pd
from scipy.signal import butter, lfilter, lfilter_zi

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

ATTITUDE_BAND_TOP = 2.0
"""Hz, upper edge of the band-pass of :func:`attitude_scale` (body roll and pitch of a car
under driver inputs lie below it; the 1.5–3 Hz suspension modes are attenuated alike on both
sides of the regression)."""

REQUIRED: tuple[str, ...] = ("t", *(f"omega_{c}" for c in CORNERS), "ax", "ay", "yaw_rate")
"""Columns the stiffness estimators read, besides a steering channel."""


@dataclass(frozen=True)
class StiffnessInputs:
    """Arrays for the kernels, one row per log sample.

    Attributes:
        t: (K,) s. u: (K, 4) [δ rad, ω_f rad/s, ω_r rad/s, T_s s] with δ the mean of the
            two front road-wheel angles (002 Sec. V) and ω the (low-passed) axle means.
        y: (K, 3) [a_x, a_y, ψ̇] with a_x, a_y divided by (1 + c g) (roll and pitch
            compensation, 002 Sec. II-A; a_y with the measured roll angle above
            ``roll_crossover`` where the log has ``roll_rate``, :func:`roll_compensated`),
            m/s², m/s², rad/s.
        active: (K,) activation flags of 002 Sec. V (statistics update and forgetting).
        settled: (K,) False during the first ``settle_time`` s: bias filter frozen too.
        accel_scale: (K, 2) the factors (1 + c_θ g, 1 + c_φ g) dividing a_x, a_y at each
            sample (:func:`attitude_scale`; constant where the log has no body rates).
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


def _integrate(t: np.ndarray, rate: np.ndarray) -> np.ndarray:
    """Trapezoidal running integral of a body rate (rad/s) from t[0]: the attitude angle, rad."""
    dt = np.diff(t, prepend=t[0])
    return np.cumsum(0.5 * (rate + np.concatenate([rate[:1], rate[:-1]])) * dt)


def attitude_scale(t: np.ndarray, rate: np.ndarray, accel: np.ndarray, sign: float,
                   c_prior: float, cutoff: float, prior_weight: float) -> np.ndarray:
    """Causal estimate of the factor 1 + c g by which a body-fixed accelerometer overreads.

    002 Sec. II-A divides the measured lateral specific force by (1 + c_φ g), with c_φ the
    steady-state roll gradient (φ = c_φ a_y); the same holds for pitch on a_x with
    c_θ = −θ/a_x (θ > 0 nose down, the IMU reads a_x − g θ): the attitude angle is
    s·c·a with s = +1 for roll and −1 for pitch. The gradient is a suspension property that a vehicle
    file may not give (the loader then fills a generic 1.5 Hz suspension, which was 12 %
    off in a_y on the cross-plant Vanagon, 8 % on the Escort). Where the log has the body
    rate, the gradient is measured instead: the attitude angle is the integral of the rate,
    the measured specific force is a(1 + c g) = a/(1 − k g) with s·k the regression
    coefficient of the angle on the *measured* specific force, and k is the running least-
    squares slope of the two signals after the same Butterworth band-pass (``cutoff`` Hz to
    :data:`ATTITUDE_BAND_TOP`), which removes the integrated gyro bias (a ramp) and the
    accelerometer bias, keeps most of the accelerometer noise out of the regression (noise
    alone pulls the slope towards 0) and leaves the slope of a static relation unchanged.
    Causal: the slope at sample k uses samples 0…k only, with the prior gradient counted as
    ``prior_weight`` s·(m/s²)² of excitation.

    Args:
        t: (K,) s. rate: (K,) body rate (rad/s). accel: (K,) measured specific force (m/s²).
        sign: +1 (roll, a_y) or −1 (pitch, a_x). c_prior: prior gradient, rad per m/s².

    Returns:
        (K,) the factor 1 + c g at each sample.
    """
    angle = _integrate(t, rate)
    ts = float(np.median(np.diff(t)))
    nyq = 0.5 / ts
    b, a = butter(2, [min(cutoff / nyq, 0.5), min(ATTITUDE_BAND_TOP / nyq, 0.99)], btype="bandpass")
    zi = lfilter_zi(b, a)
    ang_hp = lfilter(b, a, angle, zi=zi * angle[0])[0]
    acc_hp = lfilter(b, a, accel, zi=zi * accel[0])[0]
    k_prior = c_prior / (1.0 + c_prior * G)
    w0 = prior_weight / ts
    k = (sign * np.cumsum(ang_hp * acc_hp) + w0 * k_prior) / (np.cumsum(acc_hp * acc_hp) + w0)
    return 1.0 / (1.0 - k * G)


def roll_compensated(t: np.ndarray, roll_rate: np.ndarray, ay: np.ndarray, scale: np.ndarray,
                     crossover: float) -> np.ndarray:
    """Lateral specific force with the gravity through the *measured* roll angle removed, m/s².

    A body-fixed accelerometer reads a_y,m = a_y + g φ. 002 Sec. II-A takes φ at its steady
    state c_φ a_y, i.e. a_y = a_y,m/(1 + c_φ g) (``scale``, :func:`attitude_scale`). At a
    steering step the body's roll lags the lateral acceleration (the roll mode, 1–3 Hz), so
    a_y,m/(1 + c_φ g) undershoots the step for a few tenths of a second while the tire forces
    do not; Algorithm 1 learns the level of the cornering stiffness mostly from those
    transients (in a steady turn a common scaling of both axles changes v_y, which is not
    measured, and only weakly the yaw rate), and on the cross-plant x12 log the lag took
    9–10 % off the front cornering stiffness after the change. Here φ comes from a
    complementary filter: its steady-state value k a_y,m (k = (1 − 1/scale)/g, the measured
    gradient) below ``crossover`` Hz, the integrated roll rate above it (first-order pair: a
    gyro bias b leaves a constant error b/(2π crossover) in φ). In steady state the result is
    a_y,m/(1 + c_φ g) exactly.

    Args:
        t: (K,) s. roll_rate: (K,) rad/s. ay: (K,) measured lateral specific force, m/s².
        scale: (K,) 1 + c_φ g from :func:`attitude_scale`. crossover: Hz (> 0).
    """
    angle = _integrate(t, roll_rate)
    static = (1.0 - 1.0 / scale) / G * ay
    gap = angle - static
    return ay - G * (static + gap - lowpass(gap, t, crossover))


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
    scale = np.empty((t.shape[0], 2))
    for j, (rate, acc, sgn, c0) in enumerate((("pitch_rate", ax, -1.0, pitch_gradient(vehicle)),
                                               ("roll_rate", ay, 1.0, roll_gradient(vehicle)))):
        if config.attitude_from_rates and rate in log.columns:
            scale[:, j] = attitude_scale(t, _column(log, rate), acc, sgn, c0,
                                         config.attitude_cutoff, config.attitude_prior_weight)
        else:
            scale[:, j] = 1.0 + c0 * G
    y = np.empty((t.shape[0], N_MEAS))
    y[:, 0] = ax / scale[:, 0]
    y[:, 1] = ay / scale[:, 1]
    if config.attitude_from_rates and config.roll_crossover > 0.0 and "roll_rate" in log.columns:
        y[:, 1] = roll_compensated(t, _column(log, "roll_rate"), ay, scale[:, 1],
                                   config.roll_crossover)
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
