"""Sensor calibration of ``vestim calibrate``: wheel radii, IMU biases, scale and mounting,
steering ratio, offset and understeer, identified from ordinary drive logs.

Only measured channels are read (never a ``ref_`` column). Every value is an
:class:`~vestim.io.calibration.Identified` with a one-σ uncertainty and the data it
came from, or "not excited" with the vehicle file's value kept.

Uncertainties: a mean or least-squares fit over n samples has its white-noise σ inflated by
√((1 + ρ)/(1 − ρ)) for the residuals' lag-1 autocorrelation ρ (an AR(1) effective sample
count), so slowly varying model error is not counted as n independent samples.
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass

import numpy as np
import pandas as pd
from scipy.signal import butter, filtfilt

from vestim.constants import CORNERS, G
from vestim.errors import LogFormatError
from vestim.estimators.velocity.reference import (
    RadiusParams,
    gnss_calibration,
    new_radius_state,
    radius_params,
)
from vestim.io.calibration import Identified
from vestim.io.channel_map import (
    AUTO_STEADY_DOMEGA,
    AUTO_STRAIGHT_YAW_RATE,
    _roll_from_gravity,
    mounting_matrix,
    wheel_travel_angles,
)
from vestim.io.vehicle import Vehicle

WHEELS = tuple(f"omega_{c}" for c in CORNERS)
TORQUES = tuple(f"torque_{c}" for c in CORNERS)

LOWPASS_HZ = 0.5
"""Hz; zero-phase low-pass (2nd-order Butterworth) for selecting samples (free rolling,
straight, standstill) and the slow accelerations the roll/pitch-rate fits use."""
REGRESSOR_HZ = 2.0
"""Hz; low-pass of the regressors built from wheel speeds and gyros (their noise would bias
a slope toward zero); the fitted signal is left raw so its noise stays white."""
FREE_MIN_SPEED = 5.0
"""m/s; free rolling for the radii: faster than this (slow wheels quantise coarsely)."""
FREE_MAX_AY = 0.5
"""m/s²; free rolling: |ay| below this (load transfer changes the radii)."""
FREE_MAX_YAW_RATE = AUTO_STRAIGHT_YAW_RATE
"""rad/s; free rolling: straight (each wheel then travels at the same speed)."""
FREE_MAX_ACCEL = 0.3
"""m/s²; free rolling: |dv/dt| of the wheels below this (and |ax| when no torque is logged)."""
FREE_MAX_TORQUE = 0.04
"""|torque| / (static corner load × radius) below which a wheel counts as free rolling
(0.04 of the load as force; with a slip stiffness of ~20 loads per unit slip it slips 0.2 %)."""
STAND_MAX_SPEED = 0.05
"""m/s; standstill: every wheel's R·ω (low-passed) below this."""
STAND_MIN_TIME = 1.0
"""s; a standstill counts when it lasts this long (0.25 s trimmed at each end)."""
DRIVE_MIN_SPEED = 1.0
"""m/s; driving samples for the gyro, ay and ax biases."""
DRIVE_MAX_AY = 4.0
"""m/s²; the bias fits use the linear range of the tires."""
AXLE_SLIP = 0.02
"""An axle's wheel speed counts for the yaw rate when its mean is within this fraction of the
other axle's (no spinning or locking wheel)."""
STEER_MIN_SPEED = 5.0
"""m/s; steering fits: faster than this."""
STEER_MAX_AY = 2.5
"""m/s²; steering fits: the linear range (r = vδ/(L + K v²))."""
STEER_SPREAD = 1.5
"""v_max/v_min (10th–90th percentile) needed to separate the ratio from the understeer."""
COUPLING_PRIOR_SIGMA = 0.05
"""rad per m/s²; prior one-σ of the body's roll/pitch angle per m/s² of lateral/longitudinal
acceleration, which the roll/pitch gyros see through the yaw rate (q ≈ θ̇ + r·φ)."""
RADIUS_LOAD_PRIOR_SIGMA = 0.005
"""rad/s per (m/s² · m/s); prior one-σ of the wheel-speed yaw rate's error ∝ ay·v from the
load transfer's change of the left/right rolling radii (≈ 0.003 for 1.3 µm/N, 530 N per m/s²,
1.55 m track)."""
RADIUS_SPLIT_PRIOR_SIGMA = 0.002
"""1/m; prior one-σ of (R_right − R_left)/(R·track) without identified radii (0.3 % over
1.5 m)."""
GAIN_MIN_EXCITATION = 0.3
"""m/s²; a regressor (dv/dt, r·v) varying less than this has its gain held at 1."""
ACCEL_FIT_HZ = 0.5
"""Hz; ax and ay are fitted low-passed, with their regressors low-passed alike."""
TILT_GAIN_REL_SIGMA = 0.3
"""Relative one-σ of the body's tilt per m/s² as found from the accelerometer's gain (the
gain also holds other effects; on the crossplant logs it is within 30 % of the plant's)."""
GYRO_COUPLING = True
"""Fit the roll/pitch gyros with r·ax, r·ay terms too (the body's pitch/roll angle seen
through the yaw rate: q ≈ θ̇ + r·φ); halves the pitch-rate error on the crossplant turns."""
MIN_SAMPLES = 200
"""Fewest samples a fit uses."""
MOUNT_CHUNKS = 5
"""Jackknife chunks for the mounting angles' σ."""
SCALE_PRIOR_SIGMA = 0.1
"""Prior one-σ of the accelerometer's gain on dv/dt and r·v (body pitch and roll under load
add g·(dθ/da) ≈ 0.02–0.1 to it); keeps the bias fits determined when the speed hardly changes."""


# --- helpers ------------------------------------------------------------------------------------


@dataclass
class _Log:
    name: str
    df: pd.DataFrame
    t: np.ndarray
    rate: float
    omega: np.ndarray  # (n, 4) rad/s


def _name(df: pd.DataFrame, i: int) -> str:
    for key in ("name", "log", "source"):
        v = df.attrs.get(key)
        if isinstance(v, str) and v:
            return v
    return f"log {i + 1}"


def _prepare(logs: Sequence[pd.DataFrame], need: Sequence[str]) -> list[_Log]:
    if len(logs) == 0:
        raise LogFormatError("calibrate: no logs given; pass at least one drive log")
    out = []
    for i, df in enumerate(logs):
        name = _name(df, i)
        missing = [c for c in ("t", *WHEELS, *need) if c not in df.columns]
        if missing:
            raise LogFormatError(f"calibrate: {name} lacks column(s) {', '.join(missing)}; "
                                 "the sensor calibration needs them (see the log format)")
        t = df["t"].to_numpy(dtype=float)
        if len(t) < 16 or not np.all(np.diff(t) > 0):
            raise LogFormatError(f"calibrate: {name} column t must increase strictly over at "
                                 "least 16 rows")
        omega = df[list(WHEELS)].to_numpy(dtype=float)
        if not np.all(np.isfinite(omega)):
            row = int(np.argwhere(~np.isfinite(omega))[0, 0])
            raise LogFormatError(f"calibrate: {name} has a non-finite wheel speed at row {row}; "
                                 "fill or trim it")
        out.append(_Log(name, df, t, 1.0 / float(np.median(np.diff(t))), omega))
    return out


def _col(log: _Log, name: str) -> np.ndarray:
    x = log.df[name].to_numpy(dtype=float)
    if not np.all(np.isfinite(x)):
        row = int(np.argwhere(~np.isfinite(x))[0, 0])
        raise LogFormatError(f"calibrate: {log.name} column {name} is not finite at row {row}; "
                             "fill or trim it")
    return x


def _lp(x: np.ndarray, rate: float, hz: float = LOWPASS_HZ) -> np.ndarray:
    if rate / 2 <= hz or len(x) < 16:
        return x
    b, a = butter(2, hz / (rate / 2))
    return np.asarray(filtfilt(b, a, x, axis=0))


def _ar1_factor(res: np.ndarray) -> float:
    """√((1 + ρ)/(1 − ρ)) for the lag-1 autocorrelation ρ of ``res`` (clipped to [0, 0.995])."""
    if len(res) < 3:
        return 1.0
    r = res - res.mean()
    den = float(r @ r)
    rho = float(r[1:] @ r[:-1]) / den if den > 0 else 0.0
    rho = min(max(rho, 0.0), 0.995)
    return math.sqrt((1 + rho) / (1 - rho))


def _fit(x: np.ndarray, y: np.ndarray, prior: Mapping[int, tuple[float, float]] | None = None
         ) -> tuple[np.ndarray, np.ndarray]:
    """Least squares y ≈ x·c with optional Gaussian priors {column: (mean, σ)}; (c, cov(c)).

    The residual variance and the AR(1) factor (squared) scale the covariance; a prior
    weighs against the data's effective (AR(1)) sample count."""
    n, k = x.shape
    xtx = x.T @ x
    xty = x.T @ y
    coef0, *_ = np.linalg.lstsq(x, y, rcond=None)
    res0 = y - x @ coef0
    # the data's information is X'X / (s² f²) with f the AR(1) factor (effective samples)
    s2 = float(res0 @ res0) / max(n - k, 1) * _ar1_factor(res0) ** 2
    if prior:
        for j, (m, sd) in prior.items():
            w = s2 / sd**2
            xtx[j, j] += w
            xty[j] += w * m
    coef = np.linalg.solve(xtx, xty)
    res = y - x @ coef
    s2 = float(res @ res) / max(n - k, 1)
    cov = np.linalg.inv(xtx) * s2 * _ar1_factor(res) ** 2
    return coef, cov


def _gain_fit(y: np.ndarray, reg: np.ndarray, others: np.ndarray) -> tuple[float, float]:
    """Intercept (and σ) of y = c₀ + k·reg + others·c with the gain k ≈ 1 (prior 1 ± 0.1).

    ``others`` starts with the column of ones. When ``reg`` hardly varies (std below
    GAIN_MIN_EXCITATION) its variation is mostly sensor noise, which would pull a fitted k
    toward zero and the intercept with it (errors in variables): k is then held at 1 and
    its prior σ times |mean reg| is added to the intercept's σ."""
    if float(np.std(reg)) < GAIN_MIN_EXCITATION:
        c, cov = _fit(others, y - reg)
        extra = SCALE_PRIOR_SIGMA * abs(float(reg.mean()))
        return float(c[0]), math.hypot(math.sqrt(cov[0, 0]), extra)
    x = np.column_stack([others, reg])
    c, cov = _fit(x, y, prior={x.shape[1] - 1: (1.0, SCALE_PRIOR_SIGMA)})
    return float(c[0]), float(math.sqrt(cov[0, 0]))


def _mean_sigma(x: np.ndarray) -> tuple[float, float]:
    return float(x.mean()), float(x.std(ddof=1) / math.sqrt(len(x)) * _ar1_factor(x))


def _combine(values: Sequence[tuple[float, float]]) -> tuple[float, float]:
    """Inverse-variance mean of (value, σ) pairs; σ widened by the Birge ratio when the
    values scatter more than their σ (e.g. a bias that differs between logs)."""
    v = np.array([a for a, _ in values])
    s = np.array([max(b, 1e-12) for _, b in values])
    w = 1 / s**2
    m = float((w * v).sum() / w.sum())
    sig = float(1 / math.sqrt(w.sum()))
    if len(v) > 1:
        chi2 = float((w * (v - m) ** 2).sum()) / (len(v) - 1)
        sig *= math.sqrt(max(chi2, 1.0))
    return m, sig


def _static_corner_loads(vehicle: Vehicle) -> np.ndarray:
    b = vehicle.body
    front = b.mass * G * b.lr / b.wheelbase / 2
    rear = b.mass * G * b.lf / b.wheelbase / 2
    return np.array([front, front, rear, rear])


def _free_wheels(log: _Log, vehicle: Vehicle) -> np.ndarray:
    """(n, 4) bool: the wheel rolls freely (|torque| small); all True without torque columns."""
    if not all(c in log.df.columns for c in TORQUES):
        return np.ones(log.omega.shape, dtype=bool)
    tq = _lp(np.column_stack([_col(log, c) for c in TORQUES]), log.rate)
    limit = FREE_MAX_TORQUE * _static_corner_loads(vehicle) * vehicle.body.wheel_radius
    return np.abs(tq) < limit[None, :]


def _ranges(logs: Sequence[_Log], masks: Sequence[np.ndarray], speeds: Sequence[np.ndarray]
            ) -> str:
    """Evidence text: which logs, how many seconds, over which speed range."""
    names = [lg.name for lg, m in zip(logs, masks, strict=True) if m.any()]
    secs = sum(float(m.sum()) / lg.rate for lg, m in zip(logs, masks, strict=True))
    vs = np.concatenate([v[m] for v, m in zip(speeds, masks, strict=True)]) if names else None
    if vs is None or len(vs) == 0:
        return "no samples"
    return (f"{', '.join(names)}: {secs:.0f} s at {float(vs.min()):.0f}-{float(vs.max()):.0f} "
            "m/s")


# --- wheels -------------------------------------------------------------------------------------


def _relative_radii(logs: Sequence[_Log], vehicle: Vehicle
                    ) -> tuple[np.ndarray, np.ndarray, str] | None:
    """Per-wheel radius / mean radius from straight free rolling: (ratio (4,), σ (4,), text)."""
    r0 = vehicle.body.wheel_radius
    samples, masks, speeds = [], [], []
    for lg in logs:
        w = _lp(lg.omega, lg.rate)
        v = r0 * w.mean(axis=1)
        dv = np.gradient(v, lg.t)
        m = (v > FREE_MIN_SPEED) & (np.abs(dv) < FREE_MAX_ACCEL)
        m &= _free_wheels(lg, vehicle).all(axis=1)
        for c, lim in (("ay", FREE_MAX_AY), ("yaw_rate", FREE_MAX_YAW_RATE)):
            if c in lg.df.columns:
                m &= np.abs(_lp(_col(lg, c), lg.rate)) < lim
        if not any(c in lg.df.columns for c in TORQUES) and "ax" in lg.df.columns:
            m &= np.abs(_lp(_col(lg, "ax"), lg.rate) - np.median(_col(lg, "ax"))) < FREE_MAX_ACCEL
        masks.append(m)
        speeds.append(v)
        if m.any():
            om = lg.omega[m]
            samples.append(om.mean(axis=1, keepdims=True) / om)  # ∝ radius at equal speed
    n = sum(len(s) for s in samples)
    if n < MIN_SAMPLES:
        return None
    q = np.concatenate(samples)
    ratio = np.empty(4)
    sig = np.empty(4)
    for j in range(4):
        ratio[j], sig[j] = _mean_sigma(q[:, j])
    scale = ratio.mean()
    return ratio / scale, sig / scale, "straight free rolling, " + _ranges(logs, masks, speeds)


def _gnss_scale(logs: Sequence[_Log], vehicle: Vehicle, ratio: np.ndarray
                ) -> tuple[float, float, float, float, str] | None:
    """Mean radius / base radius and the receiver latency from ``gnss_speed``:
    (scale, σ, latency s, σ, text), or None without usable fixes.

    Uses :func:`vestim.estimators.velocity.reference.gnss_calibration` (fix = s·(v_w − L·v̇_w))
    with no forgetting and a negligible prior, per log; the logs are then combined."""
    r0 = vehicle.body.wheel_radius
    prm_obj = RadiusParams(prior_fixes=1e-4, tau=1e12)
    prm = radius_params(prm_obj, r0)
    per_s, per_l, names, n_fix = [], [], [], 0
    for lg in logs:
        if "gnss_speed" not in lg.df.columns:
            continue
        g = lg.df["gnss_speed"].to_numpy(dtype=float)
        om = lg.omega / ratio[None, :]  # each wheel brought to the mean radius
        srt = np.sort(om, axis=1)
        v_w = 0.5 * r0 * (srt[:, 1] + srt[:, 2])
        use = ~np.isnan(g) & (v_w > prm_obj.v_min)
        if int(use.sum()) < 20:
            continue
        n = len(lg.t)
        st = new_radius_state()
        out_s, out_l, out_v = np.empty(n), np.empty(n), np.empty(n)
        gnss_calibration(prm, st, lg.t, np.ascontiguousarray(om), g, out_s, out_l, out_v)
        s, lat = float(out_s[-1]), float(out_l[-1])
        res = out_v[use] - s * v_w[use]
        # covariance of (s, c = s·L) from the fit's normal equations [Σvv, −Σva; −Σva, Σaa]:
        # while the speed changes at a steady rate the latency and the scale trade off
        m = np.array([[st.s_vv[0], -st.s_va[0]], [-st.s_va[0], st.s_aa[0]]])
        s2 = float(np.var(res, ddof=2)) * _ar1_factor(res) ** 2
        cov = np.linalg.pinv(m) * s2
        sig_s = math.sqrt(max(float(cov[0, 0]), 0.0))
        sig_l = math.sqrt(max(float(cov[1, 1]), 0.0)) / s
        per_s.append((s, sig_s))
        per_l.append((lat, sig_l))
        names.append(lg.name)
        n_fix += int(use.sum())
    if not per_s:
        return None
    s, sig_s = _combine(per_s)
    lat, sig_l = _combine(per_l)
    return s, sig_s, lat, sig_l, f"{', '.join(names)}: {n_fix} GNSS fixes above 3 m/s"


def identify_wheels(logs: Sequence[pd.DataFrame], vehicle: Vehicle) -> dict[str, Identified]:
    """Effective rolling radius of each wheel (m), plus ``radius_scale`` (–, mean radius / the
    file's ``wheel_radius``) and ``gnss_latency`` (s).

    Relative radii come from straight free rolling (speed > 5 m/s, |ay| < 0.5 m/s², |yaw
    rate| < 0.02 rad/s, |dv/dt| < 0.3 m/s², every wheel's |torque| < 0.04 of its static load
    × radius when torques are logged): each wheel's ω̄/ω_i, normalised to mean 1. The absolute
    scale needs ``gnss_speed`` (fit of the fixes to the wheel speed with a receiver latency);
    without it the scale is not excited and the mean radius stays the file's, each wheel's
    radius = base × its ratio to the mean.
    """
    lgs = _prepare(logs, ())
    r0 = vehicle.body.wheel_radius
    rel = _relative_radii(lgs, vehicle)
    ratio = rel[0] if rel is not None else np.ones(4)
    gn = _gnss_scale(lgs, vehicle, ratio)
    out: dict[str, Identified] = {}
    if gn is None:
        why = ("no gnss_speed fixes above 3 m/s: the absolute radius is not observable from "
               "wheel speeds and an IMU; the mean radius is the vehicle file's")
        out["radius_scale"] = Identified.not_excited(1.0, why, "-")
        out["gnss_latency"] = Identified.not_excited(0.0, "no gnss_speed fixes", "s")
        s, sig_s, scale_text = 1.0, 0.0, "mean radius kept at the file's (no gnss_speed)"
    else:
        s, sig_s, lat, sig_l, scale_text = gn
        out["radius_scale"] = Identified(s, sig_s, True, scale_text, "-")
        out["gnss_latency"] = Identified(lat, sig_l, True, scale_text, "s")
        scale_text = "scale from " + scale_text
    for j, c in enumerate(CORNERS):
        key = f"radius_{c}"
        if rel is None and gn is None:
            out[key] = Identified.not_excited(
                r0, "no straight free rolling above 5 m/s and no gnss_speed", "m")
            continue
        if rel is None:
            out[key] = Identified(r0 * s, r0 * sig_s, True,
                                  f"{scale_text}; relative radii not excited (no straight "
                                  "free rolling), taken equal", "m")
            continue
        q, sq = rel[0][j], rel[1][j]
        sigma = r0 * math.hypot(q * sig_s, s * sq)
        out[key] = Identified(r0 * s * q, sigma, True, f"ratio from {rel[2]}; {scale_text}", "m")
    return out


# --- IMU ----------------------------------------------------------------------------------------


def _radii(vehicle: Vehicle, radii: Mapping[str, float | Identified] | None) -> np.ndarray:
    """Per-wheel radii (m): the given ones (floats or :class:`Identified` from
    :func:`identify_wheels`), else the file's ``wheel_radius`` for all four."""
    if radii is None:
        return np.full(4, vehicle.body.wheel_radius)
    vals = [radii[f"radius_{c}"] for c in CORNERS]
    return np.array([v.value if isinstance(v, Identified) else float(v) for v in vals])


def _split_prior(vehicle: Vehicle, radii: Mapping[str, float | Identified] | None
                 ) -> tuple[float, float]:
    """Prior (mean, σ) of ε = (R_right − R_left)/(R·track) (1/m), the mean of the two axles.

    The wheel-speed yaw rate is computed with each axle's mean radius; a left/right split
    then adds ε·v to it. From :class:`Identified` radii the split and its σ (their σ include
    the common scale's, so this σ is conservative); from plain floats the split with
    RADIUS_SPLIT_PRIOR_SIGMA; without radii 0 ± RADIUS_SPLIT_PRIOR_SIGMA."""
    b = vehicle.body
    if radii is None:
        return 0.0, RADIUS_SPLIT_PRIOR_SIGMA
    eps, var = [], []
    for (left, right), track in ((("fl", "fr"), b.track_f), (("rl", "rr"), b.track_r)):
        lv, rv = radii[f"radius_{left}"], radii[f"radius_{right}"]
        lval = lv.value if isinstance(lv, Identified) else float(lv)
        rval = rv.value if isinstance(rv, Identified) else float(rv)
        mean = 0.5 * (lval + rval)
        eps.append((rval - lval) / (mean * track))
        if (isinstance(lv, Identified) and isinstance(rv, Identified) and lv.excited
                and rv.excited):
            var.append((math.hypot(lv.sigma, rv.sigma) / (mean * track)) ** 2)
        else:
            var.append(RADIUS_SPLIT_PRIOR_SIGMA**2)
    return float(np.mean(eps)), max(math.sqrt(sum(var)) / 2, 1e-6)


def _standstill(lg: _Log, radii: np.ndarray) -> np.ndarray:
    v = np.abs(_lp(lg.omega, lg.rate)) * radii[None, :]
    still = (v < STAND_MAX_SPEED).all(axis=1)
    out = np.zeros_like(still)
    trim = round(0.25 * lg.rate)
    edges = np.flatnonzero(np.diff(np.r_[0, still.astype(np.int8), 0]))
    for a, b in zip(edges[::2], edges[1::2], strict=True):
        if (b - a) / lg.rate >= STAND_MIN_TIME:
            out[a + trim:b - trim] = True
    return out


@dataclass
class _Imu:
    """One log's IMU in body axes (after the identified mounting) and wheel-derived signals."""

    lg: _Log
    acc: np.ndarray  # (n, 3) or with NaN columns when absent
    gyro: np.ndarray  # (n, 3): roll, pitch, yaw rate
    v: np.ndarray  # reference speed, m/s (NaN where no wheel counts)
    still: np.ndarray
    r_wheel: np.ndarray  # yaw rate from the wheel speeds, rad/s (NaN where unusable)


def _reference_speed(lg: _Log, vehicle: Vehicle, radii: np.ndarray) -> np.ndarray:
    """Mean R·ω of the free-rolling wheels (|torque| small; without torques, those within 2 %
    of the median wheel), m/s; NaN where none rolls freely."""
    vw = lg.omega * radii[None, :]
    ok = _free_wheels(lg, vehicle)
    if not all(c in lg.df.columns for c in TORQUES):  # no torques: drop the odd wheel out
        med = np.median(vw, axis=1, keepdims=True)
        ok &= np.abs(vw - med) <= AXLE_SLIP * np.maximum(np.abs(med), 1.0)
    cnt = ok.sum(axis=1)
    v = np.where(cnt > 0, (vw * ok).sum(axis=1) / np.maximum(cnt, 1), np.nan)
    return np.asarray(v)


def _wheel_yaw_rate(lg: _Log, vehicle: Vehicle, radii: np.ndarray) -> np.ndarray:
    """Yaw rate from each axle's left/right wheel-speed difference with the axle's mean radius
    (front: over track·cos δ,
    |δ| < 0.03 rad), averaged over the axles whose mean agrees with the other's; rad/s."""
    b = vehicle.body
    sym = np.repeat([radii[:2].mean(), radii[2:].mean()], 2)  # split: see _split_prior
    vw = lg.omega * sym[None, :]
    free = _free_wheels(lg, vehicle)
    rear = (vw[:, 3] - vw[:, 2]) / b.track_r
    if "delta_fl" in lg.df.columns and "delta_fr" in lg.df.columns:
        delta = 0.5 * (_col(lg, "delta_fl") + _col(lg, "delta_fr"))
    elif "delta" in lg.df.columns:
        delta = _col(lg, "delta")
    else:
        delta = None
    front = (vw[:, 1] - vw[:, 0]) / (b.track_f * np.cos(delta if delta is not None else 0.0))
    vf, vr = vw[:, :2].mean(axis=1), vw[:, 2:].mean(axis=1)
    if all(c in lg.df.columns for c in TORQUES):
        agree = np.ones(len(vf), dtype=bool)  # the torques tell which wheels roll freely
    else:
        agree = np.abs(vf - vr) <= AXLE_SLIP * np.maximum(np.abs(vr), 1.0)
    ok_r = free[:, 2:].all(axis=1) & agree
    ok_f = free[:, :2].all(axis=1) & agree & (delta is not None)
    if delta is not None:
        ok_f &= np.abs(delta) < 0.03
    both = np.where(ok_r & ok_f, 0.5 * (rear + front), np.nan)
    r = np.where(ok_r & ~ok_f, rear, both)
    r = np.where(ok_f & ~ok_r, front, r)
    return np.asarray(r)


def _mount(imus_raw: Sequence[tuple[_Log, np.ndarray, np.ndarray]], vehicle: Vehicle,
           radii: np.ndarray) -> tuple[np.ndarray, np.ndarray, str] | None:
    """Mounting (roll, pitch, yaw) rad and σ of IMU channels in the sensor's axes, from gravity
    on straight, steady samples and the accelerometer's response to the wheels' dv/dt
    (:func:`vestim.io.channel_map.wheel_travel_angles`, the channel map's ``mounting = "auto"``
    without a pose); σ by a jackknife over chunks of the data."""
    parts = []
    for lg, acc, gyro in imus_raw:
        v = _lp(lg.omega * radii[None, :], lg.rate).mean(axis=1)
        w = v / vehicle.body.wheel_radius
        dw = np.gradient(w, lg.t)
        acc_f = _lp(acc, lg.rate)
        r = _lp(gyro[:, 2], lg.rate)
        steady = (np.abs(dw) < AUTO_STEADY_DOMEGA) & (np.abs(r) < AUTO_STRAIGHT_YAW_RATE)
        parts.append((acc_f, w, dw, r, steady))
    cat = [np.concatenate([p[i] for p in parts]) for i in range(5)]
    acc_f, w, dw, r, steady = cat
    if int(steady.sum()) < MIN_SAMPLES or float(np.std(dw)) < 0.05 / vehicle.body.wheel_radius:
        return None

    def angles(idx: np.ndarray) -> np.ndarray:
        gravity = acc_f[idx][steady[idx]].mean(axis=0)
        pitch, yaw = wheel_travel_angles(acc_f[idx], gravity, w[idx], dw[idx], r[idx])
        roll = _roll_from_gravity(gravity, pitch, yaw)
        return np.radians([roll, pitch, yaw])

    n = len(w)
    full = angles(np.arange(n))
    chunks = np.array_split(np.arange(n), MOUNT_CHUNKS)
    jack = []
    for k in range(MOUNT_CHUNKS):
        idx = np.concatenate([c for i, c in enumerate(chunks) if i != k])
        if int(steady[idx].sum()) >= MIN_SAMPLES:
            jack.append(angles(idx))
    if len(jack) < 2:
        return None
    ja = np.array(jack)
    kk = len(ja)
    sig = np.sqrt((kk - 1) / kk * ((ja - ja.mean(axis=0)) ** 2).sum(axis=0))
    text = (f"{int(steady.sum())} straight, steady samples of {n}: gravity and the "
            "accelerometer's response to the wheels' dv/dt")
    return full, sig, text


def _fit_wheels(lg: _Log, vehicle: Vehicle, rad: np.ndarray) -> np.ndarray:
    """R·ω (m/s) of one fixed set of wheels: those free rolling ≥ 90 % of the log when
    torques are logged (the undriven axle), else all four."""
    use = _free_wheels(lg, vehicle).mean(axis=0) >= 0.9
    if not use.any():
        use[:] = True
    return np.asarray((lg.omega * rad[None, :])[:, use])


def _accel_signals(u: _Imu, vehicle: Vehicle, rad: np.ndarray, b_r: float
                   ) -> tuple[np.ndarray, ...]:
    """(v, dv/dt, r, dr/dt, ax, ay, mask) for the ax/ay fits, all low-passed at ACCEL_FIT_HZ.

    The speed comes from one fixed set of wheels (a switch between sets would step it):
    those free rolling ≥ 90 % of the log when torques are logged (the undriven axle), else
    all four; the mask leaves out 1 s around samples where one of them spins or locks
    (> 5 % off their median). Signal and regressors are low-passed alike (the fit stays
    exact for a linear model; noise in a regressor would bias its slope toward zero)."""
    lg = u.lg
    vw = _fit_wheels(lg, vehicle, rad)
    med = np.median(vw, axis=1)
    v_f = _lp(vw.mean(axis=1), lg.rate, ACCEL_FIT_HZ)
    dv = np.gradient(v_f, lg.t)
    r_f = _lp(u.gyro[:, 2], lg.rate, ACCEL_FIT_HZ) - b_r
    dr = np.gradient(r_f, lg.t)
    ay_f = _lp(u.acc[:, 1], lg.rate, ACCEL_FIT_HZ)
    ax_f = _lp(u.acc[:, 0], lg.rate, ACCEL_FIT_HZ)
    valid = np.abs(vw - med[:, None]).max(axis=1) <= 0.05 * np.maximum(np.abs(med), 1.0)
    near_gap = np.convolve(~valid, np.ones(round(lg.rate)), mode="same") > 0
    vv = np.nan_to_num(u.v)
    msk = (vv > DRIVE_MIN_SPEED) & (np.abs(ay_f) < DRIVE_MAX_AY) & ~near_gap
    return v_f, dv, r_f, dr, ax_f, ay_f, msk


def _tilt_gain(u: _Imu, vehicle: Vehicle, rad: np.ndarray, b_r: float, axis: str
               ) -> tuple[float, float] | None:
    """Body tilt per m/s² from the accelerometer's gain: (k, σ) rad per m/s², or None.

    A body rolled by φ = k·ay reads ay(1 + g·k) (gravity tips into y); pitched by θ = −k·ax
    (nose down under braking) it reads ax(1 + g·k). The gain comes from the ay fit on r·v
    (``axis = "roll"``) or the ax fit on dv/dt (``"pitch"``) when that regressor varies."""
    v_f, dv, r_f, dr, _ax, ay_f, msk = _accel_signals(u, vehicle, rad, b_r)
    if msk.sum() < MIN_SAMPLES:
        return None
    n = int(msk.sum())
    if axis == "roll":
        reg, y = (r_f * v_f)[msk], ay_f[msk]
        x = np.column_stack([np.ones(n), dr[msk], dv[msk], reg])
    else:
        reg, y = dv[msk], _ax[msk]
        x = np.column_stack([np.ones(n), reg])
    if float(np.std(reg)) < GAIN_MIN_EXCITATION:
        return None
    c, cov = _fit(x, y)
    return (float(c[-1]) - 1.0) / G, math.sqrt(float(cov[-1, -1])) / G


def identify_imu(logs: Sequence[pd.DataFrame], vehicle: Vehicle, *,
                 radii: Mapping[str, float | Identified] | None = None,
                 sensor_axes: bool = False) -> dict[str, Identified]:
    """IMU biases (``bias_ax``/``ay``/``az`` m/s², ``bias_yaw_rate``/``roll_rate``/
    ``pitch_rate`` rad/s), ``accel_scale`` (–) and mounting ``mount_roll``/``pitch``/``yaw`` (rad).

    Args:
        logs: drive logs of one car with one IMU (the biases are taken common to all logs;
            if they scatter between logs beyond their σ, σ is widened by the Birge ratio).
        vehicle: its vehicle file (radii, tracks, wheelbase, mass for the free-rolling test).
        radii: per-wheel radii ``radius_fl`` … (m), e.g. from :func:`identify_wheels`
            (their σ bound the left/right split the wheel-speed yaw rate needs); default:
            the file's ``wheel_radius`` scaled by the logs' own relative radii from straight
            free rolling (equal radii when there is none).
        sensor_axes: the IMU channels are in the sensor's own axes (frame converted, mounting
            not applied). Then the mounting is identified (gravity on straight, steady driving
            gives roll and pitch; the accelerometer's response to the wheels' dv/dt gives yaw,
            as the channel map's ``mounting = "auto"`` without a pose) and the IMU is rotated
            into body axes before the biases; ``bias_ax``/``bias_ay`` are then not separable
            from the mount's pitch/roll (0.05 m/s² of bias reads as 0.29°) and are reported
            not excited. Default False: the channels are in body axes (the log format's); the
            mount's roll and pitch are then folded into the ax/ay biases (reported not
            excited) and a residual yaw is fitted (ay's response to dv/dt) and reported, not
            excited: the log format defines those axes as the body's.

    Method: gyro biases from standstill (≥ 1 s, every wheel below 0.05 m/s) when there is
    one, else from driving: yaw rate − the wheel-speed yaw rate (fitted with a term in ay for
    load-dependent radii); roll/pitch rate means (a bounded angle's rate averages to zero),
    with terms r·ax, r·ay for the body's pitch/roll seen through the yaw rate. ``bias_ay``:
    ay = b + k·r·v + c·dr/dt (+ mount yaw·dv/dt), ``bias_ax``: ax = b + k·dv/dt (k prior
    1 ± 0.1: body pitch under load), both on a level road on average (on a real road the mean
    grade enters bias_ax as g·sin(grade)). ``accel_scale`` = |specific force| / g at
    standstill; ``bias_az`` = mean az − g when there is no standstill (else it is one number
    with the scale at 1 g and reported not excited).
    """
    lgs = _prepare(logs, ("ax", "ay", "yaw_rate"))
    if radii is None:
        # the logs' own straight free rolling gives the relative radii (the mean stays the
        # file's); their ratio σ, free of any scale σ, bounds the left/right split
        rel = _relative_radii(lgs, vehicle)
        base = vehicle.body.wheel_radius
        rel_radii: dict[str, float | Identified] | None = None
        if rel is not None:
            rel_radii = {f"radius_{c}": Identified(base * q, base * sq, True, rel[2], "m")
                         for c, q, sq in zip(CORNERS, rel[0], rel[1], strict=True)}
        rad = _radii(vehicle, rel_radii)
        split = _split_prior(vehicle, rel_radii)
    else:
        rad = _radii(vehicle, radii)
        split = _split_prior(vehicle, radii)
    raw = []
    for lg in lgs:
        acc = np.column_stack([_col(lg, c) if c in lg.df.columns else np.full(len(lg.t), np.nan)
                               for c in ("ax", "ay", "az")])
        gyro = np.column_stack([_col(lg, c) if c in lg.df.columns else np.full(len(lg.t), np.nan)
                                for c in ("roll_rate", "pitch_rate", "yaw_rate")])
        raw.append((lg, acc, gyro))
    out: dict[str, Identified] = {}
    if sensor_axes:
        if any(np.isnan(a).any() or np.isnan(g).any() for _, a, g in raw):
            raise LogFormatError("calibrate: sensor_axes needs all of ax, ay, az, roll_rate, "
                                 "pitch_rate, yaw_rate to rotate the IMU into body axes")
        m = _mount(raw, vehicle, rad)
        if m is None:
            for k in ("mount_roll", "mount_pitch", "mount_yaw"):
                out[k] = Identified.not_excited(
                    0.0, "too few straight, steady samples or no change of speed", "rad")
            rot = np.eye(3)
        else:
            ang, sigs, text = m
            for k, a, s in zip(("mount_roll", "mount_pitch", "mount_yaw"), ang, sigs,
                               strict=True):
                out[k] = Identified(float(a), float(s), True, text, "rad")
            rot = mounting_matrix(*np.degrees(ang))
        raw = [(lg, a @ rot.T, g @ rot.T) for lg, a, g in raw]
    imus = []
    for lg, acc, gyro in raw:
        imus.append(_Imu(lg, acc, gyro, _reference_speed(lg, vehicle, rad),
                         _standstill(lg, rad), _wheel_yaw_rate(lg, vehicle, rad)))
    still_n = sum(int(u.still.sum()) for u in imus)
    still_text = (f"{', '.join(u.lg.name for u in imus if u.still.any())}: "
                  f"{sum(float(u.still.sum()) / u.lg.rate for u in imus):.0f} s of standstill")

    # gyro biases
    gyro_b: dict[str, tuple[float, float, str] | None] = {}
    b_r, s_br = 0.0, 0.0
    for j, name in ((2, "yaw_rate"), (0, "roll_rate"), (1, "pitch_rate")):
        if any(np.isnan(u.gyro[:, j]).all() for u in imus):
            gyro_b[name] = None
            continue
        if still_n >= MIN_SAMPLES:
            per = [_mean_sigma(u.gyro[u.still, j]) for u in imus if u.still.sum() >= 16]
            val, sig = _combine(per)
            gyro_b[name] = (val, sig, still_text)
            if name == "yaw_rate":
                b_r, s_br = val, sig
            continue
        per, masks, speeds = [], [], []
        for u in imus:
            lg = u.lg
            ay_f = _lp(u.acc[:, 1], lg.rate, REGRESSOR_HZ)
            ax_f = _lp(u.acc[:, 0], lg.rate, REGRESSOR_HZ)
            r_f = _lp(u.gyro[:, 2], lg.rate, REGRESSOR_HZ) - b_r
            vv = np.nan_to_num(u.v)
            base = (vv > DRIVE_MIN_SPEED) & (np.abs(ay_f) < DRIVE_MAX_AY)
            if name == "yaw_rate":
                # load transfer changes the radii left/right: an error ∝ ay·v (prior
                # 0 ± RADIUS_LOAD_PRIOR_SIGMA)
                msk = base & np.isfinite(u.r_wheel)
                y = u.gyro[msk, 2] - u.r_wheel[msk]
                # and a left/right radius split an error ε·v (prior from the radii)
                x = np.column_stack([np.ones(int(msk.sum())), (ay_f * vv)[msk], vv[msk]])
                prior = {1: (0.0, RADIUS_LOAD_PRIOR_SIGMA), 2: split}
            else:
                # the body's angle follows the acceleration (θ ≈ k·ax, φ ≈ k·ay), so the
                # mean of its rate is k·Δa/T: a term in d(a)/dt (prior 0 ± 0.05 rad per m/s²)
                msk = base
                y = u.gyro[msk, j]
                slow = _lp(u.acc[:, 0 if name == "pitch_rate" else 1], lg.rate)
                x = np.column_stack([np.ones(int(msk.sum())), np.gradient(slow, lg.t)[msk]])
                prior = {1: (0.0, COUPLING_PRIOR_SIGMA)}
                if GYRO_COUPLING:
                    # q = θ̇ + r·φ, p = φ̇ − r·θ with φ = k_φ·ay, θ = −k_θ·ax: terms r·ay,
                    # r·ax whose k is taken from the accelerometer's own gain (the fit
                    # alone confuses it with other pitch/roll motion correlated with r·a)
                    other = ax_f if name == "roll_rate" else ay_f
                    x = np.column_stack([x, (r_f * other)[msk]])
                    tilt = _tilt_gain(u, vehicle, rad, b_r,
                                      "roll" if name == "pitch_rate" else "pitch")
                    if tilt is None:
                        prior[2] = (0.0, COUPLING_PRIOR_SIGMA)
                    else:
                        k_t, s_t = tilt
                        prior[2] = (k_t, max(s_t, TILT_GAIN_REL_SIGMA * abs(k_t), 1e-4))
            masks.append(msk)
            speeds.append(vv)
            if int(msk.sum()) >= MIN_SAMPLES:
                c, cov = _fit(x, y, prior=prior)
                per.append((float(c[0]), float(math.sqrt(cov[0, 0]))))
        if not per:
            gyro_b[name] = None
            continue
        val, sig = _combine(per)
        how = ("yaw rate − wheel-speed yaw rate" if name == "yaw_rate"
               else f"mean {name} while driving")
        gyro_b[name] = (val, sig, f"{how}, " + _ranges([u.lg for u in imus], masks, speeds))
        if name == "yaw_rate":
            b_r, s_br = val, sig
    for name, res in gyro_b.items():
        key = f"bias_{name}"
        if res is None:
            out[key] = Identified.not_excited(
                0.0, f"no {name} channel, or no standstill and too little driving above "
                f"{DRIVE_MIN_SPEED} m/s", "rad/s")
        else:
            out[key] = Identified(res[0], res[1], True, res[2], "rad/s")

    # accelerometer scale and az
    have_az = all(not np.isnan(u.acc[:, 2]).all() for u in imus)
    if still_n >= MIN_SAMPLES and have_az:
        per = []
        for u in imus:
            if u.still.sum() >= 16:
                f = u.acc[u.still]
                norm = np.linalg.norm(f, axis=1) / G
                per.append(_mean_sigma(norm))
        val, sig = _combine(per)
        out["accel_scale"] = Identified(val, sig, True, still_text + ": |specific force| / g",
                                        "-")
        out["bias_az"] = Identified.not_excited(
            0.0, "at 1 g an az bias and the accelerometer's scale are one number: reported as "
            "accel_scale", "m/s^2")
    else:
        out["accel_scale"] = Identified.not_excited(
            1.0, "no standstill of 1 s or more (or no az): |specific force| / g needs one",
            "-")
        if have_az:
            per, masks, speeds = [], [], []
            for u in imus:
                msk = np.nan_to_num(u.v) > DRIVE_MIN_SPEED
                masks.append(msk)
                speeds.append(np.nan_to_num(u.v))
                if msk.sum() >= MIN_SAMPLES:
                    # the rolled/pitched body (φ ∝ ay, θ ∝ ax) reads −φ·ay and θ·ax of the
                    # turn and the acceleration in z, and the pitch moves the sensor: terms
                    # in (r·v)², (dv/dt)², dv/dt from the gyro and wheels (not from ay, ax,
                    # whose own bias would make ay² nearly constant on a straight road)
                    # (squared before the low-pass: the mean of a square is what counts)
                    lg = u.lg
                    v_f = _lp((lg.omega * rad[None, :]).mean(axis=1), lg.rate, REGRESSOR_HZ)
                    dv = np.gradient(v_f, lg.t)
                    lat = (_lp(u.gyro[:, 2], lg.rate, REGRESSOR_HZ) - b_r) * v_f
                    x = np.column_stack([np.ones(int(msk.sum()))] + [
                        _lp(q, lg.rate, ACCEL_FIT_HZ)[msk] for q in (lat**2, dv**2, dv)])
                    c, cov = _fit(x, _lp(u.acc[:, 2], lg.rate, ACCEL_FIT_HZ)[msk] - G)
                    per.append((float(c[0]), float(math.sqrt(cov[0, 0]))))
            if per:
                val, sig = _combine(per)
                out["bias_az"] = Identified(
                    val, sig, True, "mean az − g while driving (level road on average), "
                    + _ranges([u.lg for u in imus], masks, speeds), "m/s^2")
        if "bias_az" not in out:
            out["bias_az"] = Identified.not_excited(0.0, "no az channel or no driving", "m/s^2")

    # ax, ay biases (and the residual mount yaw in body axes)
    per_x, per_y, per_yaw, masks, speeds = [], [], [], [], []
    for u in imus:
        lg = u.lg
        vv = np.nan_to_num(u.v)
        v_f, dv, r_f, dr, ax_f, ay_f, msk = _accel_signals(u, vehicle, rad, b_r)
        masks.append(msk)
        speeds.append(vv)
        if msk.sum() < MIN_SAMPLES:
            continue
        n = int(msk.sum())
        one = np.ones((n, 1))
        per_x.append(_gain_fit(ax_f[msk], dv[msk], one))
        lat = np.column_stack([one, dr[msk], dv[msk]])
        c0, s0 = _gain_fit(ay_f[msk], (r_f * v_f)[msk], lat)
        # the yaw-rate bias's own σ enters ay's intercept through r·v
        per_y.append((c0, math.hypot(s0, s_br * float(v_f[msk].mean()))))
        if float(np.std(dv[msk])) > 0.1:
            x = np.column_stack([lat, (r_f * v_f)[msk]])
            c, cov = _fit(x, ay_f[msk], prior={3: (1.0, SCALE_PRIOR_SIGMA)})
            per_yaw.append((-float(c[2]), float(math.sqrt(cov[2, 2]))))
    text = _ranges([u.lg for u in imus], masks, speeds)
    if sensor_axes:
        why = ("the IMU is in sensor axes: at 1 g an ax/ay bias is one number with the mount's "
               "pitch/roll, reported as mount_pitch/mount_roll")
        out["bias_ax"] = Identified.not_excited(0.0, why, "m/s^2")
        out["bias_ay"] = Identified.not_excited(0.0, why, "m/s^2")
    else:
        for key, per, how in (("bias_ax", per_x, "ax − dv/dt of the free wheels"),
                              ("bias_ay", per_y, "ay − r·v")):
            if per:
                val, sig = _combine(per)
                out[key] = Identified(val, sig, True, f"{how} while driving (level road on "
                                      f"average), {text}", "m/s^2")
            else:
                out[key] = Identified.not_excited(
                    0.0, f"too little driving above {DRIVE_MIN_SPEED} m/s", "m/s^2")
        why = ("IMU taken in body axes: a mount roll/pitch reads as an ay/ax bias at 1 g "
               "(reported there)")
        out["mount_roll"] = Identified.not_excited(0.0, why, "rad")
        out["mount_pitch"] = Identified.not_excited(0.0, why, "rad")
        if per_yaw:
            # Logs in body axes are aligned by the log format, so the residual yaw is a
            # finding, not a correction: on the aligned crossplant IMUs it read 2.2° ± 1.2°
            # and 4.9° ± 1.8° (confounded by sideslip and ABS), and rotating by it moved
            # 4–9 % of a_x into a_y. A misaligned sensor is imported through a channel map's
            # mounting, or calibrated with sensor_axes=True.
            val, sig = _combine(per_yaw)
            out["mount_yaw"] = Identified.not_excited(
                0.0, f"logs in body axes are aligned by the log format; residual "
                f"{math.degrees(val):.2f}° ± {math.degrees(sig):.2f}° found from ay's response "
                f"to dv/dt ({text}): if real, import the raw log with a channel map's mounting",
                "rad")
        else:
            out["mount_yaw"] = Identified.not_excited(
                0.0, "the speed hardly changes (std dv/dt < 0.1 m/s²)", "rad")
    return out


# --- steering -----------------------------------------------------------------------------------


def identify_steering(logs: Sequence[pd.DataFrame], vehicle: Vehicle, *,
                      radii: Mapping[str, float | Identified] | None = None,
                      yaw_rate_bias: float = 0.0) -> dict[str, Identified]:
    """``steering_ratio`` (–), ``steering_offset`` (rad) and ``understeer_gradient`` (rad per
    m/s²) from the steady yaw response r = v (c·δ − δ₀) / (L + K v²).

    δ is the log's road-wheel angle (``delta`` or the mean of ``delta_fl``/``delta_fr``, which
    the log states as steering_wheel_angle / the file's ratio), or
    ``steering_wheel_angle`` / the file's ratio when only that is given. Fit (samples above
    5 m/s, |ay| < 2.5 m/s², slowly changing yaw rate from the gyro minus ``yaw_rate_bias``,
    speed from the free-rolling wheels, else all four): L·r/v = c·δ − δ₀' − K·r·v, with the
    noisy yaw rate on the left (as a regressor its noise would bias c toward zero). c is a
    correction factor on δ: the ratio is only identifiable relative to the wheelbase L.

    - ``steering_ratio`` = the file's ratio / c (with only road-wheel angles given it is the
      ratio that would reproduce the corrected δ from the steering wheel);
    - ``steering_offset`` = δ₀'/c, the log's δ when driving straight (rad);
    - ``understeer_gradient`` = K, excited only when the speed spreads by ≥ 1.5× (10th–90th
      percentile); otherwise the K term is not fitted and the ratio is the effective one at
      the logs' speeds (ratio × (1 + K v²/L)), with understeer reported not excited.
    """
    lgs = _prepare(logs, ("yaw_rate",))
    b = vehicle.body
    rad = _radii(vehicle, radii)
    rows_d, rows_r, rows_v, masks, speeds = [], [], [], [], []
    source = None
    for lg in lgs:
        cols = lg.df.columns
        if "delta_fl" in cols and "delta_fr" in cols:
            d = 0.5 * (_col(lg, "delta_fl") + _col(lg, "delta_fr"))
            source = source or "road-wheel angles delta_fl/delta_fr"
        elif "delta" in cols:
            d = _col(lg, "delta")
            source = source or "road-wheel angle delta"
        elif "steering_wheel_angle" in cols:
            d = _col(lg, "steering_wheel_angle") / b.steering_ratio
            source = source or "steering_wheel_angle / the file's ratio"
        else:
            raise LogFormatError(f"calibrate: {lg.name} has no steering column (delta, "
                                 "delta_fl/delta_fr or steering_wheel_angle)")
        v = _lp(_fit_wheels(lg, vehicle, rad).mean(axis=1), lg.rate, REGRESSOR_HZ)
        r = _lp(_col(lg, "yaw_rate") - yaw_rate_bias, lg.rate, REGRESSOR_HZ)
        ay = _lp(_col(lg, "ay"), lg.rate) if "ay" in cols else r * v
        dr = np.gradient(_lp(r, lg.rate), lg.t)
        # steady: the yaw rate changes slowly against its own size (0.2 s time scale)
        msk = (v > STEER_MIN_SPEED) & (np.abs(ay) < STEER_MAX_AY) & (np.abs(dr) < 0.05 + 0.5 *
                                                                      np.abs(r))
        masks.append(msk)
        speeds.append(v)
        rows_d.append(d[msk])
        rows_r.append(r[msk])
        rows_v.append(v[msk])
    d = np.concatenate(rows_d)
    r = np.concatenate(rows_r)
    v = np.concatenate(rows_v)
    text = f"{source}; " + _ranges(lgs, masks, speeds)
    out: dict[str, Identified] = {}
    if len(d) < MIN_SAMPLES or float(np.std(r / np.maximum(v, 1.0))) < 1e-4:
        why = "no steady turning above 5 m/s (yaw rate / speed never varies)"
        out["steering_ratio"] = Identified.not_excited(b.steering_ratio, why, "-")
        out["steering_offset"] = Identified.not_excited(0.0, why, "rad")
        out["understeer_gradient"] = Identified.not_excited(0.0, why, "rad/(m/s^2)")
        return out
    lo, hi = np.percentile(v, [10, 90])
    spread = hi / lo >= STEER_SPREAD
    L = b.wheelbase
    # L·r/v = c·δ − δ₀' − K·r·v: the noisy yaw rate on the left (a noisy regressor would
    # bias c toward zero), δ (a clean sensor) and the low-passed r·v on the right
    y = L * r / v
    x = np.column_stack([d, np.ones(len(d)), r * v] if spread else [d, np.ones(len(d))])
    c, cov = _fit(x, y)
    corr, s_c = float(c[0]), math.sqrt(cov[0, 0])
    if not (math.isfinite(corr) and corr > 0.2):
        why = f"the yaw response does not follow δ (fitted gain c = {corr:.3g})"
        out["steering_ratio"] = Identified.not_excited(b.steering_ratio, why, "-")
        out["steering_offset"] = Identified.not_excited(0.0, why, "rad")
        out["understeer_gradient"] = Identified.not_excited(0.0, why, "rad/(m/s^2)")
        return out
    if spread:
        out["understeer_gradient"] = Identified(-float(c[2]), math.sqrt(cov[2, 2]), True, text,
                                                "rad/(m/s^2)")
    else:
        out["understeer_gradient"] = Identified.not_excited(
            0.0, f"speeds {lo:.0f}-{hi:.0f} m/s (10th-90th percentile) spread < "
            f"{STEER_SPREAD}x: the understeer is folded into an effective steering_ratio",
            "rad/(m/s^2)")
    ratio = b.steering_ratio / corr
    out["steering_ratio"] = Identified(ratio, ratio * s_c / corr, True,
                                       text + ("" if spread else "; effective ratio"), "-")
    # δ at straight driving (r = 0): −e/c, σ by the delta method
    e = float(c[1])
    off = -e / corr
    var = (cov[1, 1] / corr**2 + e**2 * cov[0, 0] / corr**4 - 2 * e * cov[0, 1] / corr**3)
    out["steering_offset"] = Identified(off, math.sqrt(max(float(var), 0.0)), True, text, "rad")
    return out
