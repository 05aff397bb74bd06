"""Longitudinal tire force per corner from the wheel dynamics, without road friction.

Wheel dynamics (000 eq. (1), 001 eq. (1), 004 eq. (1), bearing damping neglected):
    I_w ω̇ = T − R_e F_x.
Three interchangeable methods, each a compiled kernel that advances a state
array over a chunk of samples (so ``run`` over a whole log and ``step`` per
sample execute the same code and give identical results):

* ``ukf``  — UKF with the papers' sigma-point scaling (000 eq. (10)–(12), 004 eq. (1)–(5))
  and covariance switching on high wheel acceleration (004 Sec. II-A), whose random-walk
  parameter is the wheel acceleration ω̇ rather than F_x, with the torque filtered as a
  state: x = [ω, ω̇, T], F̂_x = (T̂ − I_w ω̇̂)/R_e. It is the papers' estimator with the
  force's process model F_{k+1} = F_k + ΔT/R_e + ϱ (a torque step moves the force one
  to one unless the wheel accelerates), which removes the lag of a pure random walk.
  Its ω and T noise variances are estimated online from the log (second differences),
  and a torque-innovation switch follows limiter chops where ω resolves them quickly.
* ``ukf_rw`` — the papers' form exactly: x = [ω, F_x], F_x a random walk.
* ``pid``  — PID observer of 001 eq. (2)–(5) (gains η1 = 1.8, η2 = 11.4, η3 = 50.6).
* ``uio``  — unknown-input observer of 000 eq. (2)–(3).

Plus ``naive``, the finite-difference floor F_x = (T − I_w Δω/Δt)/R_e.

Arrays have a trailing corner axis (fl, fr, rl, rr). Units: ω rad/s, T N m, F N.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any, NamedTuple

import numpy as np
from numba import njit

from vestim.estimators.registry import register, registered
from vestim.filters.kalman import ukf_update3_select02, ukf_update_scalar2
from vestim.filters.ukf import sigma_points2, sigma_points3, ukf_weights
from vestim.io.vehicle import Vehicle
from vestim.params import check_ranges, pack

_JIT: dict[str, Any] = {"cache": True, "error_model": "numpy"}


# ----------------------------------------------------------------------------- UKF
# state per corner: [ω, F]; scratch per call
W, F = 0, 1


@dataclass(frozen=True)
class UKFParams:
    """Noise settings of the UKF force estimators (one set for every maneuver).

    Attributes:
        r_omega: wheel-speed measurement variance, (rad/s)² — 000 Sec. IV-A's 0.18 (for
            ``ukf`` with ``noise_online`` the prior of the online estimate).
        r_torque: wheel-torque measurement variance, (N m)² — 000 Sec. IV-A's 32 (likewise).
        q_acc: random-walk intensity of ω̇ in normal driving, (rad/s²)²/s (``ukf``).
        q_acc_high: the same while the wheel accelerates hard (004's switching).
        q_torque: random-walk intensity of the true torque, (N m)²/s (``ukf``).
        q_force: random-walk intensity of F_x, N²/s, in normal driving (``ukf_rw``).
        q_force_high: the same under the switching (``ukf_rw``).
        omega_dot_high: |ω̇| threshold of the switching, rad/s² (1.3 g at the SUV tire periphery).
        omega_dot_window: samples spanned by the ω̇ difference used for switching (and Δt).
        q_acc_innov: ω̇ intensity while the wheel-speed innovations are inconsistent (``ukf``):
            the innovation-driven switch, (rad/s²)²/s.
        innov_alpha: weight of the newest normalised ω innovation in its running mean.
        innov_mean: threshold of |running mean| in units of its white-noise standard deviation.
        innov_one: threshold of one normalised ω innovation.
        p0_acc: initial variance of ω̇, (rad/s²)².
        p0_force: initial variance of F_x, N² (``ukf_rw``).
        noise_online: estimate the ω and T noise variances from the log (``ukf``; see
            :func:`ukf_kernel`); r_omega and r_torque are then the prior.
        noise_prior_n: weight of that prior, in samples.
        noise_gain_min: floor of the noise trackers' gain (memory ≈ 2.33/gain samples).
        sigma_omega_min, sigma_torque_min: floors of the online noise levels, rad/s and N m.
        q_torque_innov: torque intensity while the torque-innovation switch is on, (N m)²/s.
        innov_torque_one: threshold of one normalised torque innovation.
        innov_torque_mean: threshold of their running mean, in its white-noise σ.
        innov_torque_share: share of a switched torque step put along "F_x held".
        resolve_time: the torque switch is enabled only while a one-σ torque step shows in
            ω within this time, s (τ = √(2 σ_ω I_w/σ_T)).
        q_torque_switched: torque intensity outside the switch while it is enabled, (N m)²/s
            (otherwise q_torque scaled by r̂_T/r_torque, see :func:`ukf_kernel`).
    """

    r_omega: float = 0.18
    r_torque: float = 32.0
    q_acc: float = 1.0e2
    q_acc_high: float = 3.0e4
    q_torque: float = 1.0e3
    q_force: float = 1.0e5
    q_force_high: float = 1.0e6
    omega_dot_high: float = 40.0
    omega_dot_window: int = 10
    q_acc_innov: float = 1.0e4
    innov_alpha: float = 0.2
    innov_mean: float = 3.0
    innov_one: float = 4.0
    p0_acc: float = 100.0
    p0_force: float = 1.0e6
    noise_online: bool = True
    noise_prior_n: float = 10.0
    noise_gain_min: float = 2.0e-3
    sigma_omega_min: float = 1.0e-3
    sigma_torque_min: float = 0.1
    q_torque_innov: float = 1.0e5
    innov_torque_one: float = 4.0
    innov_torque_mean: float = 3.0
    innov_torque_share: float = 0.5
    resolve_time: float = 0.2
    q_torque_switched: float = 200.0

    def __post_init__(self) -> None:
        check_ranges(self, "force_params.ukf", positive=(
            "r_omega", "r_torque", "q_acc", "q_acc_high", "q_torque", "q_force", "q_force_high",
            "omega_dot_high", "omega_dot_window", "q_acc_innov", "innov_alpha", "innov_mean",
            "innov_one", "p0_acc", "p0_force", "noise_gain_min", "sigma_omega_min",
            "sigma_torque_min", "q_torque_innov", "innov_torque_one", "innov_torque_mean",
            "resolve_time", "q_torque_switched"), nonnegative=("noise_prior_n",
                                                              "innov_torque_share"))
        if not self.innov_alpha <= 1.0 or not self.innov_torque_share <= 1.0:
            raise ValueError("force_params.ukf innov_alpha and innov_torque_share must be <= 1")


@njit(**_JIT)
def ukf_rw_kernel(p: LongitudinalParams, s: LongitudinalState, t: np.ndarray, omega: np.ndarray,
                  torque: np.ndarray, fx: np.ndarray, sigma: np.ndarray,
                  high: np.ndarray) -> None:
    """Advance the four corner UKFs over a chunk of samples (in place on the state arrays).

    State arrays: x (4, 2) = [ω, F] per corner, P (4, 2, 2), hist_t (m,) and
    hist_w (m, 4) the last m sample times and wheel speeds (for the ω̇ switch and
    Δt), prev_torque (4,) the torque held over the coming interval. ``hist_t[0]``
    NaN means "not started": the first sample initialises ω from the measurement.

    The prediction uses the torque of the previous sample (zero-order hold) and
    Δt from the time stamps; the measurement is the wheel speed. The sigma
    points are redrawn from the predicted (x̂, P̄ + Q) before the update (000
    eq. (11) reuses the propagated points, which leaves Q out of P_zz; redrawing
    is the standard, consistent form).
    """
    iw, radius, r_omega, r_torque = p.iw, p.radius, p.r_omega, p.r_torque
    q_force, q_force_high, omega_dot_high = p.q_force, p.q_force_high, p.omega_dot_high
    p0_force, wm, wc, tau = p.p0_force, p.wm, p.wc, p.tau
    x, P, hist_t, hist_w, prev_torque = s.x, s.P, s.hist_t, s.hist_w, s.prev_torque
    n = t.shape[0]
    m = hist_t.shape[0]
    pts = np.empty((5, 2))
    xm = np.empty(2)
    Pm = np.empty((2, 2))
    for k in range(n):
        if np.isnan(hist_t[0]):
            for c in range(4):
                x[c, W] = omega[k, c]
                x[c, F] = 0.0
                P[c, 0, 0] = r_omega
                P[c, 0, 1] = 0.0
                P[c, 1, 0] = 0.0
                P[c, 1, 1] = p0_force
                fx[k, c] = 0.0
                sigma[k, c] = np.sqrt(p0_force)
                high[k, c] = False
                prev_torque[c] = torque[k, c]
            _fill_history(hist_t, hist_w, t[k], omega[k])
            continue
        dt = t[k] - hist_t[m - 1]
        for c in range(4):
            is_high = abs(_omega_dot(hist_t, hist_w, t[k], omega[k, c], c)) > omega_dot_high
            q_f = q_force_high if is_high else q_force
            # Prediction through the wheel dynamics: sigma points of (x, P).
            sigma_points2(x[c, W], x[c, F], P[c, 0, 0], P[c, 1, 0], P[c, 1, 1], tau, pts)
            for i in range(5):
                pts[i, W] = pts[i, W] + dt / iw * (prev_torque[c] - radius * pts[i, F])
            xm[0] = 0.0
            xm[1] = 0.0
            for i in range(5):
                xm[0] += wm[i] * pts[i, W]
                xm[1] += wm[i] * pts[i, F]
            Pm[:, :] = 0.0
            for i in range(5):
                d0 = pts[i, W] - xm[0]
                d1 = pts[i, F] - xm[1]
                Pm[0, 0] += wc[i] * d0 * d0
                Pm[0, 1] += wc[i] * d0 * d1
                Pm[1, 1] += wc[i] * d1 * d1
            Pm[1, 0] = Pm[0, 1]
            Pm[0, 0] += (dt / iw) ** 2 * r_torque
            Pm[1, 1] += q_f * dt
            # Measurement update with the wheel speed.
            sigma_points2(xm[0], xm[1], Pm[0, 0], Pm[1, 0], Pm[1, 1], tau, pts)
            zhat = 0.0
            for i in range(5):
                zhat += wm[i] * pts[i, W]
            pzz = r_omega
            pxz0 = 0.0
            pxz1 = 0.0
            for i in range(5):
                dz = pts[i, W] - zhat
                pzz += wc[i] * dz * dz
                pxz0 += wc[i] * (pts[i, W] - xm[0]) * dz
                pxz1 += wc[i] * (pts[i, F] - xm[1]) * dz
            w_c, f_c, p00, p01, p11 = ukf_update_scalar2(
                xm[0], xm[1], Pm[0, 0], Pm[0, 1], Pm[1, 1], pxz0, pxz1, pzz,
                omega[k, c] - zhat)
            x[c, W] = w_c
            x[c, F] = f_c
            P[c, 0, 0] = p00
            P[c, 0, 1] = p01
            P[c, 1, 0] = p01
            P[c, 1, 1] = p11
            fx[k, c] = f_c
            sigma[k, c] = np.sqrt(max(p11, 0.0))
            high[k, c] = is_high
            prev_torque[c] = torque[k, c]
        _push(hist_t, hist_w, t, omega, k)


@njit(**_JIT)
def _fill_history(hist_t: np.ndarray, hist_w: np.ndarray, tk: float, wk: np.ndarray) -> None:
    """Start the (time, ω) history with the first sample repeated."""
    for j in range(hist_t.shape[0]):
        hist_t[j] = tk
        for c in range(4):
            hist_w[j, c] = wk[c]


@njit(**_JIT)
def _omega_dot(hist_t: np.ndarray, hist_w: np.ndarray, tk: float, wk: float, c: int) -> float:
    """Wheel acceleration of corner c over the history window, rad/s² (004's switching signal)."""
    span = tk - hist_t[0]
    return (wk - hist_w[0, c]) / span if span > 0 else 0.0


@njit(**_JIT)
def _push(hist_t: np.ndarray, hist_w: np.ndarray, t: np.ndarray, omega: np.ndarray,
          k: int) -> None:
    """Shift the (time, ω) history by one sample and append sample k of t (n,), omega (n, 4)
    (indexed here: a row view per sample costs a reference count)."""
    m = hist_t.shape[0]
    for j in range(m - 1):
        hist_t[j] = hist_t[j + 1]
        for c in range(4):
            hist_w[j, c] = hist_w[j + 1, c]
    hist_t[m - 1] = t[k]
    for c in range(4):
        hist_w[m - 1, c] = omega[k, c]


# ---------------------------------------------------- UKF on [ω, ω̇, T] (default)
A_W, A_A, A_T = 0, 1, 2
# Columns of the ukf state array x (4, UKF_COLS) after the filter state [ω, ω̇, T]:
X_MEAN, X_SW = 3, 4          # running mean of the normalised ω innovation; ω̇ switch flag
X_LW, X_LT = 5, 6            # log of the online noise scales σ̂_ω, σ̂_T
X_W1, X_W2, X_T1, X_T2 = 7, 8, 9, 10   # previous two wheel speeds and torques
X_N, X_TSW = 11, 12          # samples seen by the noise trackers; torque switch flag
X_TMEAN = 13                 # running mean of the normalised torque innovation
UKF_COLS = 14
# Median of |second difference| of white noise of unit σ: 0.6745 √6; the tracker's gain
# 1/f(median) of log|N(0, 1)| (its density at the median, 0.4287), for 1/k convergence.
_D2_MEDIAN = 0.6744897501960817 * 2.449489742783178
_LOG_GAIN = 1.0 / 0.4287


class UKFKernelParams(NamedTuple):
    """Parameters of :func:`ukf_kernel`: the wheel's I_w (kg m²) and R (m) and the
    :class:`UKFParams` fields it reads (units there), made by :func:`ukf_params`."""

    iw: float
    radius: float
    r_omega: float
    r_torque: float
    q_acc: float
    q_acc_high: float
    q_torque: float
    omega_dot_high: float
    p0_acc: float
    q_acc_innov: float
    innov_alpha: float
    innov_mean: float
    innov_one: float
    noise_online: bool
    noise_prior_n: float
    noise_gain_min: float
    sigma_omega_min: float
    sigma_torque_min: float
    q_torque_innov: float
    innov_torque_one: float
    innov_torque_mean: float
    innov_torque_share: float
    resolve_time: float
    q_torque_switched: float


def ukf_params(params: UKFParams, iw: float, radius: float) -> UKFKernelParams:
    """:class:`UKFKernelParams` from the validated :class:`UKFParams` and the wheel."""
    return pack(UKFKernelParams, params, iw=iw, radius=radius)


@njit(**_JIT)
def ukf_kernel(t: np.ndarray, omega: np.ndarray, torque: np.ndarray, prm: UKFKernelParams,
               wm: np.ndarray, wc: np.ndarray, tau: float, x: np.ndarray, P: np.ndarray,
               hist_t: np.ndarray, hist_w: np.ndarray, fx: np.ndarray, sigma: np.ndarray,
               high: np.ndarray) -> None:
    """Advance the four corner UKFs on x = [ω, ω̇, T] over a chunk (in place on x (4, UKF_COLS), P (4, 3, 3)).

    Process: ω_{k+1} = ω_k + Δt ω̇_k + ½Δt² … (ω̇ held), ω̇ and T random walks with
    intensities q_acc (q_acc_high while |Δω/Δt| over the history window exceeds
    ``omega_dot_high``: 004's switching) and q_torque. Measurements: ω (variance
    r_omega) and T (variance r_torque). Output F̂_x = (T̂ − I_w ω̇̂)/R_e with its
    one-sigma from the covariance. ``hist_t``/``hist_w`` as in :func:`ukf_rw_kernel`.

    Innovation-driven switching (in addition to 004's |ω̇| switch): with
    ν_k = (ω_k − ω̂_k|k−1)/√S_ωω the normalised wheel-speed innovation and
    m_k = (1 − α) m_{k−1} + α ν_k its running mean, the ω̇ intensity is raised to
    ``q_acc_innov`` for the update of sample k when |m_k| > c_m √(α/(2 − α)) (a
    persistent one-sided innovation: ω̇ has moved, e.g. a torque chop at a saturated
    tire) or |ν_k| > c_1 (one outlier). The switch decided at k also sets the
    prediction intensity of k + 1.

    Online sensor noise (``noise_online``; deviation from 000 Sec. IV-A and 004 eq. (4)–(5),
    whose measurement covariance R is a fixed, known constant): the measurement variances
    004 eq. (5) adds to P_zz are estimated from the log itself, per corner and channel,
    as σ̂² with σ̂ = median|Δ²z|/(0.6745 √6), Δ²z_k = z_k − 2 z_{k−1} + z_{k−2} (white noise
    of σ gives Δ²z ~ N(0, 6σ²); the signal's own second difference, Δt² z̈, is far below
    it except at torque steps, which a median ignores while they are a minority). The
    median is tracked recursively in the log with gain max(2.33/(k + n₀), γ_min)
    (1/k-optimal stochastic approximation; ``r_omega``/``r_torque`` are its prior worth
    n₀ = ``noise_prior_n`` samples; γ_min keeps it adaptive, ≈ 1/γ_min samples), floored at
    ``sigma_omega_min``/``sigma_torque_min``. Without it r_omega/r_torque are used as given.

    Torque-innovation switch (also a deviation from 004): with ν_T the normalised torque
    innovation and m_T its running mean (weight α as for ω), |ν_T| > ``innov_torque_one``
    means the torque stepped (a limiter chopping it within a sample) and
    |m_T| > ``innov_torque_mean`` √(α/(2 − α)) that it ramps faster than the random walk
    follows; either raises the torque intensity to
    ``q_torque_innov`` for this update and the next prediction; the share
    ``innov_torque_share`` of that step is put along "F_x held" (ΔT = I_w Δω̇, the
    saturated-tire case), the rest on T alone. It lets T̂ follow the chop at once, which
    pays only if the wheel speed resolves the matching change of ω̇ quickly: a step ΔT
    moves ω by ½(ΔT/I_w)τ² after τ, which exceeds the ω noise for a step of one torque σ
    after τ = √(2 σ̂_ω I_w/σ̂_T). The switch is enabled only while τ ≤ ``resolve_time``
    (crossplant sensors: τ ≈ 0.08 s; our simulator's σ_ω 0.42 rad/s: τ ≈ 0.5 s, off).

    ``x[:, :3]`` is the state; the other columns are the X_* bookkeeping above.
    """
    iw, radius, r_omega, r_torque = prm.iw, prm.radius, prm.r_omega, prm.r_torque
    q_acc, q_acc_high, q_torque = prm.q_acc, prm.q_acc_high, prm.q_torque
    omega_dot_high, p0_acc, q_acc_innov = prm.omega_dot_high, prm.p0_acc, prm.q_acc_innov
    innov_alpha, innov_mean, innov_one = prm.innov_alpha, prm.innov_mean, prm.innov_one
    noise_online, noise_prior_n, noise_gain_min = (prm.noise_online, prm.noise_prior_n,
                                                   prm.noise_gain_min)
    sigma_omega_min, sigma_torque_min = prm.sigma_omega_min, prm.sigma_torque_min
    q_torque_innov, innov_torque_one = prm.q_torque_innov, prm.innov_torque_one
    innov_torque_mean, innov_torque_share = prm.innov_torque_mean, prm.innov_torque_share
    resolve_time, q_torque_switched = prm.resolve_time, prm.q_torque_switched
    n = t.shape[0]
    m = hist_t.shape[0]
    # Work arrays, once per call: the 7 sigma points (propagated), their deviations from
    # the predicted mean, the predicted mean and covariance.
    pts = np.empty((7, 3))
    dev = np.empty((7, 3))
    xm = np.empty(3)
    Pm = np.empty((3, 3))
    # exp of each corner's tracked log scales x[c, X_LW], x[c, X_LT], refreshed whenever
    # those change: each is then evaluated once per sample, not twice.
    e_w = np.empty(4)
    e_t = np.empty(4)
    for c in range(4):
        e_w[c] = np.exp(x[c, X_LW])
        e_t[c] = np.exp(x[c, X_LT])
    sd_mean = np.sqrt(innov_alpha / (2.0 - innov_alpha))
    log_w_min = np.log(_D2_MEDIAN * sigma_omega_min)
    log_t_min = np.log(_D2_MEDIAN * sigma_torque_min)
    for k in range(n):
        if np.isnan(hist_t[0]):
            for c in range(4):
                x[c, A_W] = omega[k, c]
                x[c, A_A] = 0.0
                x[c, A_T] = torque[k, c]
                x[c, X_MEAN] = 0.0
                x[c, X_SW] = 0.0
                x[c, X_LW] = np.log(_D2_MEDIAN * np.sqrt(r_omega))
                x[c, X_LT] = np.log(_D2_MEDIAN * np.sqrt(r_torque))
                e_w[c] = np.exp(x[c, X_LW])
                e_t[c] = np.exp(x[c, X_LT])
                x[c, X_W1] = omega[k, c]
                x[c, X_W2] = omega[k, c]
                x[c, X_T1] = torque[k, c]
                x[c, X_T2] = torque[k, c]
                x[c, X_N] = 0.0
                x[c, X_TSW] = 0.0
                x[c, X_TMEAN] = 0.0
                P[c, :, :] = 0.0
                P[c, A_W, A_W] = r_omega
                P[c, A_A, A_A] = p0_acc
                P[c, A_T, A_T] = r_torque
                fx[k, c] = torque[k, c] / radius
                sigma[k, c] = np.sqrt(r_torque + iw * iw * p0_acc) / radius
                high[k, c] = False
            _fill_history(hist_t, hist_w, t[k], omega[k])
            continue
        dt = t[k] - hist_t[m - 1]
        for c in range(4):
            # Online noise levels from second differences (needs two previous samples):
            # each log scale log m moves up by gain/2 when |Δ²z| > m and down by gain/2
            # otherwise, so it settles where half the samples lie above: the median,
            # unmoved by a minority of large values (stochastic approximation).
            seen = x[c, X_N] + 1.0
            x[c, X_N] = seen
            if noise_online and seen >= 2.0:
                half = 0.5 * max(_LOG_GAIN / (seen - 1.0 + noise_prior_n), noise_gain_min)
                d_w = omega[k, c] - 2.0 * x[c, X_W1] + x[c, X_W2]
                x[c, X_LW] = max(x[c, X_LW] + (half if abs(d_w) > e_w[c] else -half),
                                 log_w_min)
                e_w[c] = np.exp(x[c, X_LW])
                d_t = torque[k, c] - 2.0 * x[c, X_T1] + x[c, X_T2]
                x[c, X_LT] = max(x[c, X_LT] + (half if abs(d_t) > e_t[c] else -half),
                                 log_t_min)
                e_t[c] = np.exp(x[c, X_LT])
            x[c, X_W2] = x[c, X_W1]
            x[c, X_W1] = omega[k, c]
            x[c, X_T2] = x[c, X_T1]
            x[c, X_T1] = torque[k, c]
            if noise_online:
                s_w = e_w[c] / _D2_MEDIAN
                s_t = e_t[c] / _D2_MEDIAN
                r_w = s_w * s_w
                r_t = s_t * s_t
            else:
                r_w = r_omega
                r_t = r_torque
                s_w = np.sqrt(r_w)
                s_t = np.sqrt(r_t)
            torque_switch = (q_torque_innov > q_torque_switched
                             and 2.0 * s_w * iw <= resolve_time * resolve_time * s_t)
            # Without the switch the random walk alone follows the torque: its bandwidth
            # (steady gain ≈ √(q Δt/r)) is held at the tuned one by scaling q with r̂/r.
            # With it, steps and ramps are the switch's, the walk only the slow drift.
            q_t = q_torque_switched if torque_switch else q_torque * r_t / r_torque
            is_high = abs(_omega_dot(hist_t, hist_w, t[k], omega[k, c], c)) > omega_dot_high
            # Prediction by the sigma points of (x, P) (000 eq. (10)–(11)): ω += Δt ω̇.
            sigma_points3(x[c, A_W], x[c, A_A], x[c, A_T], P[c, 0, 0], P[c, 1, 0],
                          P[c, 1, 1], P[c, 2, 0], P[c, 2, 1], P[c, 2, 2], tau, pts)
            for i in range(7):
                pts[i, A_W] += dt * pts[i, A_A]
            for j in range(3):
                acc = 0.0
                for i in range(7):
                    acc += wm[i] * pts[i, j]
                xm[j] = acc
            for i in range(7):
                for j in range(3):
                    dev[i, j] = pts[i, j] - xm[j]
            for r in range(3):
                for q in range(3):
                    acc = 0.0
                    for i in range(7):
                        acc += wc[i] * dev[i, r] * dev[i, q]
                    Pm[r, q] = acc
            q_a = q_acc_high if is_high else q_acc
            was_innov = x[c, X_SW] > 0.5
            if was_innov:
                q_a = max(q_a, q_acc_innov)
            # ω integrates ω̇: a white ω̇ increment over Δt adds Δt³/3 to var(ω).
            _add_acc_noise(Pm, q_a, dt)
            was_torque = torque_switch and x[c, X_TSW] > 0.5
            if was_torque:
                _add_torque_step(Pm, q_torque_innov * dt, innov_torque_share, iw)
            else:
                Pm[A_T, A_T] += q_t * dt
            # Innovation-driven switch: test this sample's normalised ω innovation.
            nu = (omega[k, c] - xm[A_W]) / np.sqrt(Pm[A_W, A_W] + r_w)
            x[c, X_MEAN] = (1.0 - innov_alpha) * x[c, X_MEAN] + innov_alpha * nu
            now_innov = abs(x[c, X_MEAN]) > innov_mean * sd_mean or abs(nu) > innov_one
            if now_innov and not was_innov and q_acc_innov > q_a:
                _add_acc_noise(Pm, q_acc_innov - q_a, dt)
            x[c, X_SW] = 1.0 if now_innov else 0.0
            # Torque-innovation switch: a torque step (see the docstring).
            now_torque = False
            if torque_switch:
                nu_t = (torque[k, c] - xm[A_T]) / np.sqrt(Pm[A_T, A_T] + r_t)
                x[c, X_TMEAN] = (1.0 - innov_alpha) * x[c, X_TMEAN] + innov_alpha * nu_t
                now_torque = (abs(nu_t) > innov_torque_one
                              or abs(x[c, X_TMEAN]) > innov_torque_mean * sd_mean)
                if now_torque and not was_torque:
                    Pm[A_T, A_T] -= q_t * dt
                    _add_torque_step(Pm, q_torque_innov * dt, innov_torque_share, iw)
            x[c, X_TSW] = 1.0 if now_torque else 0.0
            # Update with z = [ω, T]. The measurement selects state components, so the
            # sigma-point sums of 000 eq. (11) equal the blocks of P̄ exactly
            # (Σ W^c (χ − x̄)(χ − x̄)ᵀ = P̄ for these weights): ẑ = [ω̄, T̄],
            # P_zz = P̄[{ω, T}, {ω, T}] + R, P_xz = P̄[:, {ω, T}], inverted in closed form;
            # P = P̄ − K P_xzᵀ (= P̄ − K P_zz Kᵀ), symmetrised.
            w_c, a_c, t_c, p00, p01, p02, p11, p12, p22 = ukf_update3_select02(
                xm[A_W], xm[A_A], xm[A_T], Pm[0, 0], Pm[0, 1], Pm[0, 2], Pm[1, 0], Pm[1, 1],
                Pm[1, 2], Pm[2, 0], Pm[2, 1], Pm[2, 2], r_w, r_t, omega[k, c] - xm[A_W],
                torque[k, c] - xm[A_T])
            x[c, A_W] = w_c
            x[c, A_A] = a_c
            x[c, A_T] = t_c
            P[c, 0, 0] = p00
            P[c, 0, 1] = p01
            P[c, 0, 2] = p02
            P[c, 1, 0] = p01
            P[c, 1, 1] = p11
            P[c, 1, 2] = p12
            P[c, 2, 0] = p02
            P[c, 2, 1] = p12
            P[c, 2, 2] = p22
            fx[k, c] = (t_c - iw * a_c) / radius
            var = (p22 - 2.0 * iw * p12 + iw * iw * p11)
            sigma[k, c] = np.sqrt(max(var, 0.0)) / radius
            high[k, c] = is_high or now_innov or now_torque
        _push(hist_t, hist_w, t, omega, k)


@njit(**_JIT)
def _add_torque_step(Pm: np.ndarray, q: float, share: float, iw: float) -> None:
    """Add a torque random-walk variance q to P̄, the share ``share`` of it along
    "F_x held" (ΔT = I_w Δω̇: var(Δω̇) = q/I_w², cov(Δω̇, ΔT) = q/I_w), the rest on T alone."""
    Pm[A_T, A_T] += q
    Pm[A_A, A_A] += share * q / (iw * iw)
    Pm[A_A, A_T] += share * q / iw
    Pm[A_T, A_A] += share * q / iw


@njit(**_JIT)
def _add_acc_noise(Pm: np.ndarray, q: float, dt: float) -> None:
    """Add a white-ω̇ random walk of intensity q over Δt to the [ω, ω̇] block of P̄."""
    Pm[A_W, A_W] += q * dt**3 / 3.0
    Pm[A_W, A_A] += q * dt**2 / 2.0
    Pm[A_A, A_W] += q * dt**2 / 2.0
    Pm[A_A, A_A] += q * dt


# ----------------------------------------------------------------- PID observer
@dataclass(frozen=True)
class PIDParams:
    """Gains of the PID observer, 001 Sec. V: η1 (N per rad/s), η2 (N m per rad/s), η3 (1/s)."""

    eta1: float = 1.8
    eta2: float = 11.4
    eta3: float = 50.6

    def __post_init__(self) -> None:
        check_ranges(self, "force_params.pid", positive=("eta1", "eta2", "eta3"))


class ObserverState(NamedTuple):
    """The PID and UIO observers' state per corner (in place), each field (4,);
    :func:`new_observer_state` makes a fresh one.

    Attributes:
        omega_hat: the observer's wheel speed ω̂, rad/s.
        force: the PID observer's integral part F_c, N (the UIO has none).
        started: 1.0 once the corner's first sample started the observer.
    """

    omega_hat: np.ndarray
    force: np.ndarray
    started: np.ndarray


def new_observer_state() -> ObserverState:
    """A fresh :class:`ObserverState` (the next sample starts every corner)."""
    return ObserverState(np.zeros(4), np.zeros(4), np.zeros(4))


class PreviousSample(NamedTuple):
    """The previous sample per corner, each field (4,), held by the PID, UIO and naive
    kernels; :func:`new_previous_sample` makes a fresh one.

    Attributes:
        t: its time, s (NaN before the first sample: the naive kernel's "none").
        omega: its wheel speed, rad/s.
        torque: its net wheel torque, N m.
    """

    t: np.ndarray
    omega: np.ndarray
    torque: np.ndarray


def new_previous_sample() -> PreviousSample:
    """A fresh :class:`PreviousSample` (``t`` NaN: no previous sample)."""
    return PreviousSample(np.full(4, np.nan), np.zeros(4), np.zeros(4))


@njit(**_JIT)
def pid_kernel(t: np.ndarray, omega: np.ndarray, torque: np.ndarray, iw: float, radius: float,
               eta1: float, eta2: float, eta3: float, obs: ObserverState, prev: PreviousSample,
               fx: np.ndarray) -> None:
    """PID observer of 001 eq. (2)–(5), advanced in place over a chunk of samples.

    001 prints the observer in a garbled extraction; we use the form whose error
    dynamics are those the paper analyses (eq. (3)–(8)), with e_ω = ω − ω̂:
        I_w dω̂/dt = T − R_e F̂ + η2 e_ω                      (speed observer, eq. (4))
        F̂ = F_c − η1 e_ω                                     (proportional part)
        dF_c/dt = η3 (F_m − F̂),  F_m = (T − I_w Δω/Δt)/R_e  (integral part, eq. (2)),
    F_m being "the updated measurement at the current time step" of 001 Sec. III-A.
    Then e_F = F − F̂ obeys ė_F = −η3 e_F + Ω̇_f once e_ω has settled (eq. (8)).

    ``obs``: ω̂, F_c and the started flags (:class:`ObserverState`); ``prev`` the previous
    sample (:class:`PreviousSample`).
    """
    n = t.shape[0]
    w_hat, f_c, started = obs.omega_hat, obs.force, obs.started
    t_prev, w_prev, tq_prev = prev.t, prev.omega, prev.torque
    for k in range(n):
        for c in range(4):
            if started[c] == 0.0:
                w_hat[c] = omega[k, c]
                f_c[c] = 0.0
                started[c] = 1.0
                fx[k, c] = 0.0
            else:
                dt = t[k] - t_prev[c]
                f_meas = (tq_prev[c] - iw * (omega[k, c] - w_prev[c]) / dt) / radius
                e_prev = w_prev[c] - w_hat[c]
                f_hat = f_c[c] - eta1 * e_prev
                w_hat[c] += dt / iw * (tq_prev[c] - radius * f_hat + eta2 * e_prev)
                f_c[c] += dt * eta3 * (f_meas - f_hat)
                fx[k, c] = f_c[c] - eta1 * (omega[k, c] - w_hat[c])
            t_prev[c] = t[k]
            w_prev[c] = omega[k, c]
            tq_prev[c] = torque[k, c]


# ------------------------------------------------------------ unknown-input observer
@dataclass(frozen=True)
class UIOParams:
    """UIO of 000 eq. (2): proportional gain K_p (N m per rad/s) and nominal force f0 (N).

    000 does not give K_p; 42 N m s/rad puts the error pole (eq. (3), 𝒦 = K_p/I_w)
    at 25 rad/s for the SUV's I_w = 1.68 kg m², the bandwidth of the UKF.
    """

    kp: float = 42.0
    f0: float = 0.0

    def __post_init__(self) -> None:
        check_ranges(self, "force_params.uio", positive=("kp",), finite=True)


@njit(**_JIT)
def uio_kernel(t: np.ndarray, omega: np.ndarray, torque: np.ndarray, iw: float, radius: float,
               kp: float, f0: float, obs: ObserverState, prev: PreviousSample,
               fx: np.ndarray) -> None:
    """Unknown-input observer of 000 eq. (2)–(3), advanced in place over a chunk.

    Virtual wheel speed I_w dω̂/dt = T − R_e f0 + K_p ω̃ with ω̃ = ω − ω̂, and
    F̂ = f0 − K_p ω̃ / R_e (eq. (2)). Its error obeys eq. (3), ė = −(K_p/I_w) e − R_e(F − f0)/I_w,
    so in steady state K_p e = −R_e(F − f0) and F̂ = F. The ω̂ update is the exact
    solution over Δt with T held and ω interpolated linearly between samples
    (for ω̂̇ = −a(ω̂ − g(t)), g = g0 + s t: ω̂(Δt) = g(Δt) − s/a + (ω̂0 − g0 + s/a) e^{−aΔt}),
    so a constant force is recovered exactly.

    ``obs``: ω̂ and the started flags (:class:`ObserverState`; ``force`` unused); ``prev`` the
    previous sample (:class:`PreviousSample`).
    """
    n = t.shape[0]
    a = kp / iw
    w_hat, started = obs.omega_hat, obs.started
    t_prev, w_prev, tq_prev = prev.t, prev.omega, prev.torque
    for k in range(n):
        for c in range(4):
            if started[c] == 0.0:
                w_hat[c] = omega[k, c]
                started[c] = 1.0
            else:
                dt = t[k] - t_prev[c]
                offset = (tq_prev[c] - radius * f0) / kp
                g0 = w_prev[c] + offset
                slope = (omega[k, c] - w_prev[c]) / dt
                g1 = omega[k, c] + offset
                decay = np.exp(-a * dt)
                w_hat[c] = g1 - slope / a + (w_hat[c] - g0 + slope / a) * decay
            fx[k, c] = f0 - kp * (omega[k, c] - w_hat[c]) / radius
            t_prev[c] = t[k]
            tq_prev[c] = torque[k, c]
            w_prev[c] = omega[k, c]


# ----------------------------------------------------------------------- naive floor
@njit(**_JIT)
def naive_kernel(t: np.ndarray, omega: np.ndarray, torque: np.ndarray, iw: float, radius: float,
                 prev: PreviousSample, fx: np.ndarray) -> None:
    """The floor to beat: F_x = (T − I_w Δω/Δt)/R_e with a backward difference, in place.

    ``prev``: the previous sample (:class:`PreviousSample`; ``t`` NaN before the first
    sample, which gets the torque alone).
    """
    t_prev, w_prev, tq_prev = prev.t, prev.omega, prev.torque
    for k in range(t.shape[0]):
        for c in range(4):
            if np.isnan(t_prev[c]):
                fx[k, c] = torque[k, c] / radius
            else:
                dt = t[k] - t_prev[c]
                fx[k, c] = (tq_prev[c] - iw * (omega[k, c] - w_prev[c]) / dt) / radius
            t_prev[c] = t[k]
            tq_prev[c] = torque[k, c]
            w_prev[c] = omega[k, c]

# The methods, registered with their kernels in the order that gives their codes.
register("force", "ukf", "UKF on the wheel dynamics with the torque filtered as a state and "
         "covariance switching on high wheel acceleration", default=True,
         cite="000 eq. (10)–(12), 004 eq. (1)–(5), Sec. II-A", tables=("force_params",),
         outputs=("sigma_fx",), params=UKFParams)(ukf_kernel)
register("force", "ukf_rw", "the papers' UKF exactly: x = [ω, F_x], F_x a random walk",
         cite="000 eq. (10)–(12), 004 eq. (1)–(5)", tables=("force_params",),
         outputs=("sigma_fx",), params=UKFParams)(ukf_rw_kernel)
register("force", "pid", "PID observer of the wheel dynamics", cite="001 eq. (2)–(5)",
         tables=("force_params",), params=PIDParams)(pid_kernel)
register("force", "uio", "unknown-input observer of the wheel dynamics", cite="000 eq. (2)–(3)",
         tables=("force_params",), params=UIOParams)(uio_kernel)
register("force", "naive", "finite-difference floor F_x = (T − I_w Δω/Δt)/R_e")(naive_kernel)
_REGISTERED = registered("force")
METHODS: tuple[str, ...] = tuple(_REGISTERED)
"""The methods' names, in the registry's order."""
UKF, UKF_RW, PID, UIO, NAIVE = (_REGISTERED[name].code
                                for name in ("ukf", "ukf_rw", "pid", "uio", "naive"))
"""The methods' registry codes (what :func:`longitudinal_rows` dispatches on)."""


class LongitudinalParams(NamedTuple):
    """Every longitudinal method's parameters, whole (SI), and which one runs: ``method`` its
    registry code (:data:`UKF` …, what :func:`longitudinal_rows` dispatches on)."""

    method: int
    iw: float  # wheel inertia, kg m²
    radius: float  # effective radius, m
    ukf: UKFKernelParams
    r_omega: float  # ukf_rw's noise and random-walk parameters (UKFParams)
    r_torque: float
    q_force: float
    q_force_high: float
    omega_dot_high: float
    p0_force: float
    eta1: float  # pid's gains (PIDParams)
    eta2: float
    eta3: float
    kp: float  # uio's gain and nominal force (UIOParams)
    f0: float
    wm: np.ndarray  # the UKFs' sigma-point weights
    wc: np.ndarray
    tau: float


class LongitudinalState(NamedTuple):
    """The longitudinal methods' states: the UKFs' ``x``, ``P`` and ω̇ window (``hist_t``,
    ``hist_w``), ukf_rw's previous torque, the PID and UIO observers' ``observer`` and the
    previous sample ``prev`` of the PID, UIO and naive kernels."""

    x: np.ndarray
    P: np.ndarray
    hist_t: np.ndarray
    hist_w: np.ndarray
    prev_torque: np.ndarray
    observer: ObserverState
    prev: PreviousSample


@njit(**_JIT)
def longitudinal_rows(p: LongitudinalParams, s: LongitudinalState, t: np.ndarray,
                      omega: np.ndarray, torque: np.ndarray, fx: np.ndarray,
                      sigma: np.ndarray) -> None:
    """The method ``p.method`` over a chunk: t (n,), omega, torque (n, 4) → ``fx`` (n, 4) N and
    its one-sigma ``sigma`` (left as given, NaN, by the methods without one); ``s`` is
    advanced in place."""
    m = p.method
    if m == UKF:
        ukf_kernel(t, omega, torque, p.ukf, p.wm, p.wc, p.tau, s.x, s.P, s.hist_t, s.hist_w, fx,
                   sigma, np.empty(fx.shape, dtype=np.bool_))
    elif m == UKF_RW:
        ukf_rw_kernel(p, s, t, omega, torque, fx, sigma, np.empty(fx.shape, dtype=np.bool_))
    elif m == PID:
        pid_kernel(t, omega, torque, p.iw, p.radius, p.eta1, p.eta2, p.eta3, s.observer, s.prev,
                   fx)
    elif m == UIO:
        uio_kernel(t, omega, torque, p.iw, p.radius, p.kp, p.f0, s.observer, s.prev, fx)
    else:
        naive_kernel(t, omega, torque, p.iw, p.radius, s.prev, fx)


class LongitudinalEstimator:
    """One longitudinal method for the four corners, with its state (online or batch).

    Args:
        vehicle: uses [vehicle] wheel_inertia and wheel_radius.
        method: one of :data:`METHODS`.
        ukf, pid, uio: parameters of the respective methods.
    """

    def __init__(self, vehicle: Vehicle, method: str = "ukf", ukf: UKFParams | None = None,
                 pid: PIDParams | None = None, uio: UIOParams | None = None) -> None:
        if method not in METHODS:
            raise ValueError(f"longitudinal force method {method!r}: use one of {', '.join(METHODS)}")
        self.method = method
        self.code = _REGISTERED[method].code
        """The method's registry code."""
        self.iw = vehicle.body.wheel_inertia
        self.radius = vehicle.body.wheel_radius
        self.ukf = ukf or UKFParams()
        self.kernel_params = ukf_params(self.ukf, self.iw, self.radius)
        self.pid = pid or PIDParams()
        self.uio = uio or UIOParams()
        dim = 3 if self.code == UKF else 2
        wm, wc, tau = ukf_weights(dim)
        u, pid, uio = self.ukf, self.pid, self.uio
        self.params = LongitudinalParams(
            self.code, float(self.iw), float(self.radius), self.kernel_params,
            float(u.r_omega), float(u.r_torque), float(u.q_force), float(u.q_force_high),
            float(u.omega_dot_high), float(u.p0_force), float(pid.eta1), float(pid.eta2),
            float(pid.eta3), float(uio.kp), float(uio.f0), wm, wc, float(tau))
        self.reset()

    def reset(self) -> None:
        """Forget the state; the next sample initialises it."""
        window = self.ukf.omega_dot_window
        dim = 3 if self.code == UKF else 2
        # ukf: columns 3.. of x hold the switches' and noise trackers' state (X_* constants)
        self.state = LongitudinalState(
            x=np.zeros((4, UKF_COLS if self.code == UKF else dim)),
            P=np.zeros((4, dim, dim)), hist_t=np.full(window, np.nan),
            hist_w=np.zeros((window, 4)), prev_torque=np.zeros(4),
            observer=new_observer_state(), prev=new_previous_sample())

    def advance(self, t: np.ndarray, omega: np.ndarray,
                torque: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Process a chunk: t (n,), omega, torque (n, 4) → F_x (n, 4) in N and its one-sigma (NaN if none)."""
        n = t.shape[0]
        fx = np.empty((n, 4))
        sigma = np.full((n, 4), np.nan)
        longitudinal_rows(self.params, self.state, t, omega, torque, fx, sigma)
        return fx, sigma
