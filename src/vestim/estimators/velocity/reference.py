"""Reference-speed Kalman filter: what an ABS/ESC team ships without a tire model.

State x = [v_x, v_y, b_x, b_y, b_r]: CG velocity in the body frame (m/s), the biases of
the longitudinal and lateral kinematic accelerations (m/s²; accelerometer bias plus
the road grade's g·sin γ or bank's g·sin β, which the IMU cannot tell apart) and the
yaw-gyro bias (rad/s). Process (000 eq. (15) with the lateral equation):
    v̇_x = f_x − b_x + (r − b_r) v_y,    v̇_y = f_y − b_y − (r − b_r) v_x,    ḃ = w_b,
with f the IMU specific force rotated to the road plane by the body angles.

Measurements, sequential scalar updates per sample:
* each wheel's speed mapped to the CG, v_i = R ω_i cos δ_i − v_yt,i sin δ_i + r y_i
  (v_yt,i from the current v_y; a NaN ω_i is no measurement: a log without wheel speeds
  runs on the extra CG-speed measurements alone, its lateral part unchanged), with a
  variance that grows with the evidence of slip of that wheel:
    - its use of friction |μ_x,i| (drive or brake force per load, from the force stage),
    - ω̇ inconsistent with the acceleration, |R ω̇_i − a_x| over a 0.1 s window,
    - innovations of the sign slip produces (positive while driving, negative
      while braking) are inflated quadratically,
  and innovation gating (rejected beyond ``gate`` standard deviations);
* optional extra CG-speed measurements (n, m) with their variances — the
  pipeline's fusion feeds the corner-based estimates here;
* each axle's slip angle from its estimated lateral force and the nominal small-slip
  cornering stiffness (α = −F_y/C_y): v_y = v_x(α_f + δ) − l_f r and v_y = v_x α_r + l_r r
  (single-track kinematics), pseudo-measurements whose σ grows with the slip angle
  (stiffness uncertainty) and the sideslip acceleration (sliding), gated at ``gate_vy``.
  The friction is unknown, so a saturated axle's slip angle is unknown too: its
  pseudo-measurement disagrees with the integral and is rejected; v_y then comes from
  the integral, whose drift b_y (learnt while the tires were linear) holds down.

A wheel whose measurement is rejected or inflated leaves the filter to the
acceleration integral, whose drift the bias state limits.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np
from numba import njit

from vestim.models.kinematics import middle_wheel_speed

_JIT: dict[str, Any] = {"cache": True, "error_model": "numpy"}

VX, VY, BX, BY, BR = 0, 1, 2, 3, 4
LON = np.array([VX, BX])
LAT = np.array([VY, BY, BR])


@dataclass(frozen=True)
class ReferenceParams:
    """Tuning of the reference filter (one set for every maneuver).

    Attributes:
        q_vx, q_vy: process intensities of v_x, v_y, (m/s)²/s (IMU noise and model error).
        q_vx_speed: q_vx where f_x is a speed's derivative (a log without ``ax``), (m/s)²/s:
            that derivative lags by 0.1 s (wheel speeds) to 0.5 s (GNSS fixes). 0.2 (10 ×
            q_vx): on the crossplant logs without ax its v_x RMSE is 0.080 (x07), 0.046 (x11)
            m/s against 0.102, 0.069 at q_vx, and 0.088 against 0.73 on x07 without wheel
            speeds either (GNSS fixes); x05, x08 without wheel speeds 0.043 against 0.033.
        q_bias: random-walk intensity of b_x, (m/s²)²/s (grade changes, bias drift).
        r_wheel: wheel-speed variance at no slip, (m/s)² (sensor noise, radius error).
        k_mu: slip-evidence gain: σ grows by k_mu·|μ_x|·|v| (m/s per unit μ_x).
        k_acc: slip-evidence gain on |R ω̇ − a_x|, s (m/s per m/s²).
        slip_sign: innovation (m/s) at which a slip-signed innovation doubles σ.
        gate: innovation gate in standard deviations.
        r_vy: variance of the axles' v_y pseudo-measurements at zero slip angle, (m/s)².
        k_vy: growth of their σ with the sideslip acceleration |f_y − b_y − r v_x|, s.
        bias_max: bound on |b_x|, m/s² (sensor bias plus a grade of about 5 %).
        q_bias_y: random-walk intensity of b_y, (m/s²)²/s.
        bias_y_max: bound on |b_y|, m/s² (sensor biases, r-gyro bias × v_x, bank of ~5 %).
        k_rel: relative error of the nominal cornering stiffness (σ of the pseudo-measurement
            grows by k_rel·|v_x α|).
        gate_vy: innovation gate of the v_y pseudo-measurements, standard deviations.
        tau_vy: correlation time of their error, s (see :func:`_lateral_update`); 0.1 s:
            with the stiffness identified online the bound is no longer off by the nominal
            stiffness for seconds at a time (1 s let v_y drift 0.06 m/s on the crossplant
            slalom, x08).
        side_vy: innovation (m/s) on the allowed side of the linear-tire bound at which its
            slip-dependent σ doubles.
        tau_wheel: correlation time of a wheel's slip error, s: the slip-evidence part of
            its σ enters with the variance inflated by τ/T_s (0: white).
        acc_dead: dead zone of the |R ω̇ − a_x| evidence, m/s² (the wheel-speed noise makes
            ω̇ over the window noisy: σ ≈ 2 m/s² for the simulator's sensors at 200 Hz).
        k_lat: slip-evidence gain on the wheel's lateral sliding speed |v_yt| (dimensionless:
            m/s of σ per m/s): a tire sliding sideways is in combined slip and rolls slower.
            0.5: with 1, a v_y estimate that is itself off (a car whose stiffness the
            file does not know) made free-rolling wheels untrusted and coupled the v_y error
            into v_x (crossplant x02 0.29 → 0.14 %, x06 0.57 → 0.47 %).
        q_gyro_bias: random-walk intensity of the yaw-gyro bias b_r, (rad/s)²/s.
        gyro_bias_sd: prior one-sigma of b_r, rad/s (automotive MEMS: ~0.002 per run).
        torque_dead: |torque| (N m) below which a wheel counts as neither driven nor braked
            for the slip-signed inflation (torque-sensor noise at standstill, σ ≈ 6 N m,
            would otherwise make the inflation one-sided at random and bias b_x).
        k_comb: slip ratio λ_c of an axle's wheels at which the v_y bound's one-sidedness
            doubles (side_vy / (1 + (λ/λ_c)²)): a tire in longitudinal slip is in combined
            slip and makes less lateral force than the linear tire says.
        alpha_lin: linear-tire slip angle |α| (rad) at which the v_y pseudo-measurements are
            half way from a value (k_rel, tau_vy, side_vy, gate_vy: the linear range, with the
            stiffness identified online) to a bound (the ``*_sat`` values: a saturating tire
            of unknown friction), blend 1/(1 + (α/α_lin)⁴).
        k_rel_sat, tau_vy_sat, side_vy_sat, gate_vy_sat: k_rel, tau_vy, side_vy, gate_vy of a
            saturating axle.
        pair_gap: gap between the front and rear linear-tire v_y (m/s) at which both are
            half way from a value to a bound (blend 1/(1 + (gap/pair_gap)²), times the
            slip-angle blend of ``alpha_lin``).
        sigma_gnss: one-sigma of a ``gnss_speed`` fix (brought forward by its latency) as a
            white CG-speed measurement, m/s (the pipeline undoes the τ_wheel/T_s inflation of
            extra measurements for it). The RAV4 log's fixes scatter by 0.077 m/s against
            the pose reference once the latency is removed.
        sigma_vehicle_speed: one-sigma of a dense CAN ``vehicle_speed`` as a CG-speed
            measurement, m/s, used only in a log without wheel speeds. Its error (the ESC's
            own reference speed: radius error, quantisation) persists like a wheel's, so it
            enters with the τ_wheel/T_s inflation of every extra measurement.
        sigma_corner_slip: one-sigma (m/s) of the fused pipeline's corner-observer CG speed,
            which enters only while ≥ 3 corners are in high slip (before the τ/T_s
            inflation). 3 m/s: with 1 m/s the corner KF's tire-model bias in moderate
            all-wheel slip cost up to 0.4 point of CG v_x NRMS over the reference filter
            alone (seeds 1–3); at 3 m/s it is within 0.13 point everywhere.
        window: samples of the ω̇ difference.
    """

    q_vx: float = 0.02
    q_vy: float = 1.0e-4
    q_bias: float = 2.0e-4
    r_wheel: float = 0.05
    k_mu: float = 1.0
    k_acc: float = 0.3
    slip_sign: float = 0.3
    gate: float = 5.0
    r_vy: float = 0.0025
    k_vy: float = 0.1
    bias_max: float = 0.5
    q_bias_y: float = 1.0e-5
    bias_y_max: float = 0.5
    k_rel: float = 0.3
    gate_vy: float = 6.0
    tau_vy: float = 0.1
    side_vy: float = 1.0
    tau_wheel: float = 1.0
    acc_dead: float = 3.0
    k_lat: float = 0.5
    q_gyro_bias: float = 1.0e-9
    gyro_bias_sd: float = 0.003
    torque_dead: float = 20.0
    k_comb: float = 0.1
    alpha_lin: float = 0.015
    k_rel_sat: float = 1.0
    tau_vy_sat: float = 1.0
    side_vy_sat: float = 0.05
    gate_vy_sat: float = 3.0
    pair_gap: float = 0.2
    window: int = 20
    sigma_corner_slip: float = 3.0
    sigma_gnss: float = 0.1
    sigma_vehicle_speed: float = 0.1
    q_vx_speed: float = 0.2


@dataclass(frozen=True)
class StiffnessParams:
    """Online normalised cornering stiffness c = C_y/ΣF_z of :func:`axle_slip_angles`.

    Attributes:
        prior_sd: relative one-sigma of the prior compliance 1/c₀ (c₀ = σ0y/κy of the
            [tire] table, which is a nominal value, not this car's tire).
        sigma_kappa: one-sigma of the slip-difference regression's error, rad (gyro noise,
            camber thrust and roll steer that the single-track kinematics leave out).
        tau: forgetting time of the regression, s (the road or tire may change).
        mu_linear: |μ_y| of either axle above which a sample is left out (off the linear
            range the secant stiffness is lower than the small-slip one).
        v_min: speed below which a sample is left out, m/s.
        c_min, c_max: physical bounds of c, 1/rad (passenger-car tires: about 10–30).
        tau_hp: time constant of the high-pass applied to both sides of the regression, s:
            it keeps the yaw transients and removes what drifts slowly with the lateral
            acceleration (camber thrust, roll steer, the onset of saturation in a ramp),
            which would otherwise be read as compliance.
        tau_lp: time constant of the low-pass applied to both sides, s: noise on the
            estimated μ_yr − μ_yf (the regressor) would bias the compliance towards 0.
        e_robust: band-passed residual (rad) at which a sample's weight is halved (Cauchy):
            the onset of saturation or of combined slip moves L r/v_x − δ where the linear
            tire does not.
    """

    prior_sd: float = 0.3
    sigma_kappa: float = 0.01
    tau: float = 20.0
    mu_linear: float = 0.3
    v_min: float = 5.0
    c_min: float = 8.0
    c_max: float = 30.0
    tau_hp: float = 1.0
    tau_lp: float = 0.1
    e_robust: float = 0.002


def stiffness_params(c0: float, p: StiffnessParams, radius: float, wheelbase: float) -> np.ndarray:
    """Parameter vector of :func:`axle_slip_angles` from the nominal c₀ (1/rad)."""
    return np.array([1.0 / c0, (p.sigma_kappa * c0 / p.prior_sd) ** 2, p.tau, p.mu_linear,
                     p.v_min, p.c_min, p.c_max, radius, wheelbase, p.tau_hp, p.tau_lp,
                     p.e_robust])


@njit(**_JIT)
def axle_slip_angles(t: np.ndarray, omega: np.ndarray, yaw_rate: np.ndarray,
                     delta: np.ndarray, fy: np.ndarray, fz: np.ndarray, prm: np.ndarray,
                     state: np.ndarray, out: np.ndarray, out_c: np.ndarray) -> None:
    """Axle slip angles α = −F_y/(c ΣF_z) (n, 2) [front, rear], rad, the linear-tire input of
    the v_y bounds, with the normalised cornering stiffness c identified online.

    The single-track kinematics fix the difference of the axle slip angles without v_y:
    α_f − α_r = L r/v_x − δ (000 eq. (16)'s slip angles, spec sign), and a linear tire
    gives α = −w μ_y with the compliance w = 1/c. So
        L r/v_x − δ = w (μ_yr − μ_yf) + b,
    a regression for w (b takes a steering offset and the gyro bias over speed) in samples
    where both axles are in their linear range. It is solved in closed form from
    exponentially forgotten sums (time constant τ) with the Gaussian prior w₀ = 1/c₀ of
    weight (σ_κ/σ_w)² (``prm`` from :func:`stiffness_params`: [w₀, prior weight, τ,
    μ_linear, v_min, c_min, c_max, R, L]). Only yaw transients excite it: in steady
    cornering μ_yf ≈ μ_yr and c stays where the last transient left it.
    ``state`` = [Σλ, Σλx, Σλy, Σλx², Σλxy, t_prev, started]; ``out_c`` (n,) the c used.
    NaN where ΣF_z ≤ 1 N (lifted axle).
    """
    w0, p0, tau, mu_lin, v_min, c_min, c_max, radius, wheelbase, tau_hp, tau_lp, e_rob = (
        prm[0], prm[1], prm[2], prm[3], prm[4], prm[5], prm[6], prm[7], prm[8], prm[9],
        prm[10], prm[11])
    for k in range(t.shape[0]):
        fzf = fz[k, 0] + fz[k, 1]
        fzr = fz[k, 2] + fz[k, 3]
        mu_f = (fy[k, 0] + fy[k, 1]) / fzf if fzf > 1.0 else np.nan
        mu_r = (fy[k, 2] + fy[k, 3]) / fzr if fzr > 1.0 else np.nan
        dt = t[k] - state[5] if state[6] == 1.0 else 0.0
        lam = np.exp(-dt / tau)
        state[5] = t[k]
        state[6] = 1.0
        state[3] *= lam
        state[4] *= lam
        v = middle_wheel_speed(omega, k, radius)
        if v > v_min and abs(mu_f) < mu_lin and abs(mu_r) < mu_lin:
            x = mu_r - mu_f
            y = wheelbase * yaw_rate[k] / v - 0.5 * (delta[k, 0] + delta[k, 1])
            if state[2] == 0.0:  # first linear sample: the band-pass starts from it
                state[0], state[1], state[2], state[7], state[8] = x, y, 1.0, x, y
            g = min(dt / tau_lp, 1.0)
            state[7] += g * (x - state[7])
            state[8] += g * (y - state[8])
            g = min(dt / tau_hp, 1.0)
            state[0] += g * (state[7] - state[0])
            state[1] += g * (state[8] - state[1])
            x = state[7] - state[0]
            y = state[8] - state[1]
            # Cauchy weight on the residual against the current compliance: the onset of
            # saturation or combined slip makes y jump where x does not, and would be read
            # as a stiff tire.
            e = (y - x * (state[4] + p0 * w0) / (state[3] + p0)) / e_rob
            wgt = 1.0 / (1.0 + e * e)
            state[3] += wgt * x * x
            state[4] += wgt * x * y
        comp = (state[4] + p0 * w0) / (state[3] + p0)
        c = min(max(1.0 / comp if comp > 0.0 else c_max, c_min), c_max)
        out_c[k] = c
        out[k, 0] = -mu_f / c
        out[k, 1] = -mu_r / c


@dataclass(frozen=True)
class RadiusParams:
    """Online wheel-radius scale and GNSS latency from a sparse ``gnss_speed``
    (:func:`gnss_calibration`).

    Attributes:
        prior_fixes: weight of the prior scale 1 (the file's wheel_radius) and latency 0, in
            fixes at ``prior_speed`` and ``prior_accel``.
        prior_speed: speed of those prior fixes, m/s.
        prior_accel: acceleration of those prior fixes, m/s² (sets the latency prior's weight).
        tau: forgetting time, s (tire wear, pressure and load change slowly).
        v_min: speed below which a fix is not used, m/s (GNSS speed noise dominates).
        a_max: |dv_w/dt| above which a fix is not used, m/s² (wheel slip).
        tau_acc: time constant of the low-pass on the wheel-speed derivative, s.
        s_min, s_max: physical bounds of the scale (a radius off by more than 8 % is a wrong
            vehicle file, not tire growth).
        latency_max: bound of the receiver latency, s.
    """

    prior_fixes: float = 20.0
    prior_speed: float = 10.0
    prior_accel: float = 1.0
    tau: float = 600.0
    v_min: float = 3.0
    a_max: float = 3.0
    tau_acc: float = 0.05
    s_min: float = 0.92
    s_max: float = 1.08
    latency_max: float = 0.5


def radius_params(p: RadiusParams, radius: float) -> np.ndarray:
    """Parameter vector of :func:`gnss_calibration`."""
    return np.array([radius, p.prior_fixes * p.prior_speed**2, p.tau, p.v_min, p.a_max,
                     p.s_min, p.s_max, p.prior_fixes * p.prior_accel**2, p.tau_acc,
                     p.latency_max])


@njit(**_JIT)
def gnss_calibration(t: np.ndarray, omega: np.ndarray, gnss: np.ndarray, prm: np.ndarray,
                     state: np.ndarray, out_scale: np.ndarray, out_latency: np.ndarray,
                     out_speed: np.ndarray) -> None:
    """Effective-radius scale s (R_eff = s R) and receiver latency L from the GNSS speed.

    A fix g_k is the speed L seconds ago: g_k ≈ s (v_w − L v̇_w) at its sample (v_w: the
    mean R ω of the two middle wheels, robust to one slipping wheel; v̇_w its derivative,
    low-passed over τ_acc). Least squares in (s, c = s L) with exponential forgetting and
    the priors s = 1, c = 0 (weights W_s in (m/s)², W_c in (m/s²)²), L clipped to
    [0, L_max], s to [s_min, s_max]. Without fixes s = 1 and L = 0. ``out_speed`` is the fix
    brought to its own sample, g + L v̇_w (NaN between fixes): the CG-speed measurement.
    The RAV4 log: s 1.0088 (its CAN wheel speeds read 0.86 % low), L 0.16 s.
    ``prm`` from :func:`radius_params`; ``state`` = [Σvv, Σva, Σaa, Σgv, Σga, t_prev,
    started, v_w prev, v̇_w].
    """
    radius, w_s, tau, v_min, a_max, s_min, s_max, w_c, tau_a, l_max = (
        prm[0], prm[1], prm[2], prm[3], prm[4], prm[5], prm[6], prm[7], prm[8], prm[9])
    for k in range(t.shape[0]):
        v_w = middle_wheel_speed(omega, k, radius)
        if state[6] == 1.0:
            dt = t[k] - state[5]
            lam = np.exp(-dt / tau)
            for j in range(5):
                state[j] *= lam
            if dt > 0:
                g_lp = min(dt / tau_a, 1.0)
                state[8] += g_lp * ((v_w - state[7]) / dt - state[8])
        state[5] = t[k]
        state[6] = 1.0
        state[7] = v_w
        a_w = state[8]
        g = gnss[k]
        if not np.isnan(g) and v_w > v_min and abs(a_w) < a_max:
            state[0] += v_w * v_w
            state[1] += v_w * a_w
            state[2] += a_w * a_w
            state[3] += g * v_w
            state[4] += g * a_w
        # Normal equations for (s, c) with regressors (v_w, −v̇_w) and the priors.
        m11 = state[0] + w_s
        m12 = -state[1]
        m22 = state[2] + w_c
        b1 = state[3] + w_s
        b2 = -state[4]
        det = m11 * m22 - m12 * m12
        sc = (b1 * m22 - m12 * b2) / det
        c = (m11 * b2 - m12 * b1) / det
        sc = min(max(sc, s_min), s_max)
        lat = min(max(c / sc, 0.0), l_max)
        out_scale[k] = sc
        out_latency[k] = lat
        out_speed[k] = g + lat * sc * a_w if not np.isnan(g) else np.nan


@njit(**_JIT)
def _block_update(x: np.ndarray, P: np.ndarray, idx: np.ndarray, z: float, r: float,
                  gate: float) -> float:
    """Kalman update of state idx[0] by a direct measurement z = x[idx[0]] + v, var(v) = r;
    returns the innovation (NaN if rejected beyond ``gate`` innovation standard deviations).

    P is block diagonal (the blocks [v_x, b_x] and [v_y, b_y, b_r], see
    :func:`reference_kernel`), so the update touches the block ``idx`` only:
    K = P[idx, i]/s, P ← P − K P[i, idx] (for the optimal gain this equals the Joseph form).
    """
    i = idx[0]
    s = P[i, i] + r
    innov = z - x[i]
    if innov * innov > gate * gate * s:
        return np.nan
    m = idx.shape[0]
    # K P[i, :] for a block of at most 3 states, without a scratch array (this runs six
    # times per sample).
    c0 = P[idx[0], i]
    c1 = P[idx[1], i] if m > 1 else 0.0
    c2 = P[idx[2], i] if m > 2 else 0.0
    for a in range(m):
        ca = c0 if a == 0 else (c1 if a == 1 else c2)
        x[idx[a]] += ca / s * innov
        for b in range(m):
            cb = c0 if b == 0 else (c1 if b == 1 else c2)
            P[idx[a], idx[b]] -= ca * cb / s
    return innov


@njit(**_JIT)
def _lateral_update(x: np.ndarray, P: np.ndarray, z: float, alpha: float, r_white: float,
                    sig_col: float, inflate: float, s_side: float, gate: float) -> float:
    """Update of v_y by an axle's linear-tire pseudo-measurement z (m/s).

    Its error has a white part (variance ``r_white``: the lateral-force noise) and a part
    that grows with the slip angle and the sliding (σ ``sig_col``) and persists for about
    a second, so it enters with the variance σ²·``inflate`` (= τ_c/T_s, the samples per
    correlation time: one sample's information per correlation time). A tire's force grows
    less than linearly with its slip angle, so the linear α = −F_y/C under-states |α|:
    z is a bound on v_y (an upper bound when α < 0), and an estimate on the bound's
    allowed side is pulled only weakly (σ_col grows with (innovation/s_side)²). The gate
    compares the innovation with the un-inflated σ. Returns the innovation (NaN if rejected).
    """
    innov = z - x[VY]
    if innov * innov > gate * gate * (P[VY, VY] + r_white + sig_col * sig_col):
        return np.nan
    if (alpha < 0.0 and innov > 0.0) or (alpha > 0.0 and innov < 0.0):
        sig_col *= 1.0 + (innov / s_side) ** 2
    return _block_update(x, P, LAT, z, r_white + sig_col * sig_col * inflate, np.inf)


@njit(**_JIT)
def reference_kernel(t: np.ndarray, omega: np.ndarray, torque: np.ndarray, mu_x: np.ndarray,
                     axle_slip: np.ndarray,
                     f_x: np.ndarray, f_y: np.ndarray, yaw_rate: np.ndarray, delta: np.ndarray,
                     extra_v: np.ndarray, extra_var: np.ndarray, radius: float, lf: float,
                     lr: float, xw: np.ndarray, yw: np.ndarray, prm: np.ndarray, x: np.ndarray,
                     P: np.ndarray, hist: np.ndarray, state: np.ndarray, out_v: np.ndarray,
                     out_sig: np.ndarray, out_bias: np.ndarray,
                     out_trust: np.ndarray) -> None:
    """Advance the reference filter over a chunk, in place on x (5,), P (5, 5), hist, state.

    ``prm`` = [q_vx, q_vy, q_bias, r_wheel, k_mu, k_acc, slip_sign, gate, r_vy, k_vy,
    bias_max, q_bias_y, bias_y_max, k_rel, gate_vy, tau_vy, s_side, tau_wheel, acc_dead, k_lat,
    q_gyro_bias, gyro_bias_sd, torque_dead, k_comb, alpha_lin, k_rel_sat, tau_vy_sat,
    side_vy_sat, gate_vy_sat, pair_gap, kinematic f_x (1: f_x is v̇_x itself, from a speed's
    derivative, so the prediction leaves out r v_y; 0: the IMU's specific force)].
    ``axle_slip`` (n, 2): front and rear axle slip angles from the lateral forces and the
    nominal cornering stiffness, rad (spec sign: atan(v_yt/v_xt)); NaN where unknown.
    ``hist`` (m, 5): last m samples of (t, ω_fl…ω_rr) for ω̇; ``state`` = [t_prev, started,
    f_x, f_y, r of the previous sample, samples with every wheel rejected, index of the
    oldest row of ``hist`` (a ring buffer)]. ``extra_v``/
    ``extra_var`` (n, m2): extra CG-speed measurements and variances, NaN where absent.
    Outputs: out_v (n, 2) [v_x, v_y], out_sig (n, 2), out_bias (n, 3) [b_x, b_y, b_r], out_trust
    (n, 4) the standard deviation used per wheel (inf where rejected).
    """
    q_vx, q_vy, q_b, r_w, k_mu, k_acc, s_sign, gate, r_vy, k_vy, bias_max = (
        prm[0], prm[1], prm[2], prm[3], prm[4], prm[5], prm[6], prm[7], prm[8], prm[9], prm[10])
    q_by, by_max, k_rel, gate_vy, tau_vy, s_side, tau_w, acc_dead, k_lat = prm[11:20]
    q_br, gyro_sd, torque_dead, k_comb = prm[20], prm[21], prm[22], prm[23]
    alpha_lin, k_rel_sat, tau_sat, side_sat, gate_sat, pair_gap = prm[24:30]
    kin_fx = prm[30] != 0.0
    m = hist.shape[0]
    nx = x.shape[0]
    wheel_v = np.empty(4)
    wheel_slip = np.zeros(4)
    for k in range(t.shape[0]):
        dt = t[k] - state[0]
        if state[1] == 0.0:
            v0 = 0.0
            n_wheels = 0
            for i in range(4):
                if not np.isnan(omega[k, i]):
                    v0 += 0.25 * radius * omega[k, i]
                    n_wheels += 1
            p_vx = 1.0
            if n_wheels == 0:
                # No wheel speeds: start from this sample's CG-speed measurement if any,
                # with a σ of 10 m/s so that the first one passes the gate.
                for j in range(extra_v.shape[1]):
                    if not np.isnan(extra_v[k, j]):
                        v0 = extra_v[k, j]
                        break
                p_vx = 100.0
            elif n_wheels < 4:
                v0 *= 4.0 / n_wheels
            x[:] = 0.0
            x[VX] = v0
            P[:, :] = 0.0
            P[VX, VX] = p_vx
            P[VY, VY] = 0.25
            P[BX, BX] = 0.25
            P[BY, BY] = 0.05**2
            P[BR, BR] = gyro_sd * gyro_sd
            state[1] = 1.0
            for j in range(m):
                hist[j, 0] = t[k]
                for i in range(4):
                    hist[j, 1 + i] = omega[k, i]
            state[6] = 0.0
        else:
            fxp, fyp = state[2], state[3]
            rp = state[4] - x[BR]
            vx, vy = x[VX], x[VY]
            # Prediction (000 eq. (15) with the lateral equation and bias states):
            # v̇x = f_x − b_x + (r − b_r) v_y,  v̇y = f_y − b_y − (r − b_r) v_x  (inputs of the
            # previous sample). The gyro bias b_r enters v_y scaled by v_x, so unlike the
            # accelerometer bias b_y it changes with speed (0.002 rad/s × 25 m/s of speed
            # change = 0.05 m/s² of v̇_y error) and is observable as the speed changes.
            if kin_fx:  # f_x is a speed's derivative: it already holds the r v_y term
                x[VX] = vx + dt * (fxp - x[BX])
            else:
                x[VX] = vx + dt * (fxp - x[BX] + rp * vy)
            x[VY] = vy + dt * (fyp - x[BY] - rp * vx)
            # The r-coupling of v_x and v_y stays out of the covariance: with a gyro bias and
            # r → 0 on a straight road it would make the lateral pseudo-measurements a
            # spurious v_x measurement (v_x ≈ (f_y − b_y)/r); [v_x, b_x] and [v_y, b_y, b_r]
            # are therefore two decoupled blocks (P stays block diagonal) whose means are
            # coupled through r. Longitudinal block: F = [[1, −dt], [0, 1]].
            pvv = P[VX, VX] - 2.0 * dt * P[VX, BX] + dt * dt * P[BX, BX]
            pvb = P[VX, BX] - dt * P[BX, BX]
            P[VX, VX] = pvv
            P[VX, BX] = pvb
            P[BX, VX] = pvb
            # Lateral block: v_y ← v_y − dt b_y + dt v_x b_r, i.e. row g = [1, −dt, dt v_x].
            g1, g2 = -dt, dt * vx
            p0 = np.empty(3)
            for a in range(3):
                p0[a] = P[LAT[a], VY] + g1 * P[LAT[a], BY] + g2 * P[LAT[a], BR]
            pyy = p0[0] + g1 * p0[1] + g2 * p0[2]
            P[VY, VY] = pyy
            for a in range(1, 3):
                P[LAT[a], VY] = p0[a]
                P[VY, LAT[a]] = p0[a]
            P[VX, VX] += q_vx * dt
            P[VY, VY] += q_vy * dt
            P[BX, BX] += q_b * dt
            P[BY, BY] += q_by * dt
            P[BR, BR] += q_br * dt
        oldest = int(state[6])  # ring buffer: the oldest row is overwritten next
        span = t[k] - hist[oldest, 0]
        r_now = yaw_rate[k] - x[BR]
        # Wheel speeds mapped to the CG, trusted by their evidence of slip.
        accepted = 0
        available = 0
        sq_rw = np.sqrt(r_w)
        inflate_w = max(tau_w / dt, 1.0) if dt > 0 else 1.0
        for i in range(4):
            if np.isnan(omega[k, i]):  # no wheel speed: no measurement (a log without them)
                out_trust[k, i] = np.inf
                wheel_v[i] = np.nan
                wheel_slip[i] = 0.0
                continue
            available += 1
            d = delta[k, i]
            c, s = (np.cos(d), np.sin(d)) if d != 0.0 else (1.0, 0.0)
            vxw = x[VX] - r_now * yw[i]
            vyw = x[VY] + r_now * xw[i]
            vyt = -vxw * s + vyw * c
            v_meas = radius * omega[k, i] * c - vyt * s + r_now * yw[i]
            omega_dot = (omega[k, i] - hist[oldest, 1 + i]) / span if span > 0 else 0.0
            acc_err = max(abs(radius * omega_dot - f_x[k] + x[BX]) - acc_dead, 0.0)
            sig = (sq_rw + k_mu * abs(mu_x[k, i]) * abs(x[VX]) + k_acc * acc_err
                   + k_lat * abs(vyt))
            innov_pred = v_meas - x[VX]
            tq = torque[k, i]
            if (tq > torque_dead and innov_pred > 0) or (tq < -torque_dead and innov_pred < 0):
                sig *= 1.0 + (innov_pred / s_sign) ** 2
            # The slip part of σ is a persistent error (a slipping wheel stays slipping), so
            # it enters with the correlation-time inflation, like the lateral model error;
            # the gate uses the plain σ.
            slip_part = sig - sq_rw
            wheel_slip[i] = abs(innov_pred) / max(abs(x[VX]), 1.0)
            if innov_pred * innov_pred > gate * gate * (P[VX, VX] + sig * sig):
                res = np.nan
            else:
                res = _block_update(x, P, LON, v_meas,
                                    r_w + slip_part * slip_part * inflate_w, np.inf)
            out_trust[k, i] = np.inf if np.isnan(res) else sig
            wheel_v[i] = v_meas
            if not np.isnan(res):
                accepted += 1
        # Recovery: every wheel rejected although none shows evidence of slip means the
        # filter, not the wheels, has drifted. After ``window`` such samples, restart v_x
        # from the median wheel speed (an ESC unit's reference-speed reset).
        state[5] = state[5] + 1.0 if accepted == 0 and available > 0 else 0.0
        if state[5] >= m:
            x[VX] = np.median(wheel_v) if available == 4 else np.nanmedian(wheel_v)
            for j in range(nx):
                P[VX, j] = 0.0
                P[j, VX] = 0.0
            P[VX, VX] = r_w
            state[5] = 0.0
        # Extra CG-speed measurements (fusion with the corner-based estimators).
        for j in range(extra_v.shape[1]):
            if not np.isnan(extra_v[k, j]):
                # A corner observer's error persists like a wheel's slip error: same inflation.
                _block_update(x, P, LON, extra_v[k, j], extra_var[k, j] * inflate_w, gate)
        # v_y from each axle's slip angle by the linear tire (front: v_y = v_x(α_f + δ) − l_f r,
        # rear: v_y = v_x α_r + l_r r). Its error grows with the slip angle (stiffness
        # uncertainty, k_rel) and with the sideslip acceleration |f_y − b_y − r v_x| (the
        # tires are off their linear range while the car slides, k_vy); innovations beyond
        # gate_vy σ are rejected: a saturated axle says nothing about v_y, and the
        # integration (its drift held by b_y, learnt while the tires were linear) carries on.
        beta_acc = abs(f_y[k] - x[BY] - r_now * x[VX])
        d_f = 0.5 * (delta[k, 0] + delta[k, 1])
        # Both axles on the linear tire with the identified stiffness give the same v_y
        # (their difference is the kinematic L r/v_x − δ): a gap between them means one is
        # saturating or sliding, whatever the friction; both are then bounds (h_pair → 0).
        # On low μ this is the only sign: the linear slip angle stays small in a slide.
        h_pair = 1.0
        if not (np.isnan(axle_slip[k, 0]) or np.isnan(axle_slip[k, 1])):
            gap = (x[VX] * (axle_slip[k, 0] + d_f - axle_slip[k, 1]) - (lf + lr) * r_now) / pair_gap
            h_pair = 1.0 / (1.0 + gap * gap)
        for a in range(2):
            alpha = axle_slip[k, a]
            if np.isnan(alpha):
                continue
            z = (x[VX] * (alpha + d_f) - lf * r_now if a == 0 else x[VX] * alpha + lr * r_now)
            # In the linear range (|α| below α_lin) the linear tire gives a value: tight σ,
            # short correlation, pulled on both sides; towards saturation (friction unknown)
            # only a bound: σ k_rel_sat |v_x α|, a second of correlation, one-sided, 3σ gate.
            # h blends the two by the slip angle itself.
            q = (alpha / alpha_lin) ** 2
            h = h_pair / (1.0 + q * q)
            sig = (k_rel_sat + h * (k_rel - k_rel_sat)) * abs(x[VX] * alpha) + k_vy * beta_acc
            tau_a = tau_sat + h * (tau_vy - tau_sat)
            inflate = max(tau_a / dt, 1.0) if dt > 0 else 1.0
            side = side_sat + h * (s_side - side_sat)
            # A wheel in longitudinal slip is in combined slip: its lateral force falls short
            # of the linear tire's, so the bound's one-sidedness sharpens with the axle's
            # larger slip ratio λ (wheel-speed innovation over speed): side/(1 + (λ/λ_c)²).
            lam = max(wheel_slip[2 * a], wheel_slip[2 * a + 1]) / k_comb
            side /= 1.0 + lam * lam
            _lateral_update(x, P, z, alpha, r_vy, sig, inflate, side,
                            gate_sat + h * (gate_vy - gate_sat))
        # The biases are physically bounded (sensor bias plus a grade or bank of at most
        # ~5 %): a larger value means slip or a sliding car is being explained away as bias.
        x[BX] = min(max(x[BX], -bias_max), bias_max)
        x[BY] = min(max(x[BY], -by_max), by_max)
        # History for ω̇, and inputs held over the next interval.
        hist[oldest, 0] = t[k]
        for i in range(4):
            hist[oldest, 1 + i] = omega[k, i]
        state[6] = float((oldest + 1) % m)
        state[0] = t[k]
        state[2] = f_x[k]
        state[3] = f_y[k]
        state[4] = yaw_rate[k]
        out_v[k, 0] = x[VX]
        out_v[k, 1] = x[VY]
        out_sig[k, 0] = np.sqrt(max(P[VX, VX], 0.0))
        out_sig[k, 1] = np.sqrt(max(P[VY, VY], 0.0))
        out_bias[k, 0] = x[BX]
        out_bias[k, 1] = x[BY]
        out_bias[k, 2] = x[BR]


class ReferenceFilter:
    """Stateful wrapper of :func:`reference_kernel` (``reset``, ``advance``).

    Args:
        radius: wheel radius R, m.
        lf, lr: CG to front / rear axle, m.
        xw, yw: corner positions from the CG (fl, fr, rl, rr), m.
        params: tuning.
    """

    def __init__(self, radius: float, lf: float, lr: float, xw: np.ndarray, yw: np.ndarray,
                 params: ReferenceParams | None = None) -> None:
        self.radius = radius
        self.lf = lf
        self.lr = lr
        self.xw = np.ascontiguousarray(xw, dtype=float)
        self.yw = np.ascontiguousarray(yw, dtype=float)
        self.params = params or ReferenceParams()
        p = self.params
        self._prm = np.array([p.q_vx, p.q_vy, p.q_bias, p.r_wheel, p.k_mu, p.k_acc, p.slip_sign,
                              p.gate, p.r_vy, p.k_vy, p.bias_max, p.q_bias_y, p.bias_y_max,
                              p.k_rel, p.gate_vy, p.tau_vy, p.side_vy, p.tau_wheel,
                              p.acc_dead, p.k_lat, p.q_gyro_bias, p.gyro_bias_sd,
                              p.torque_dead, p.k_comb, p.alpha_lin, p.k_rel_sat,
                              p.tau_vy_sat, p.side_vy_sat, p.gate_vy_sat, p.pair_gap, 0.0])
        self.reset()

    def reset(self) -> None:
        self._x = np.zeros(5)
        self._P = np.zeros((5, 5))
        self._hist = np.zeros((self.params.window, 5))
        self._state = np.zeros(7)

    def snapshot(self) -> tuple[np.ndarray, ...]:
        """Copies of the filter's state (x, P, ω history, bookkeeping), for :meth:`restore`."""
        return (self._x.copy(), self._P.copy(), self._hist.copy(), self._state.copy())

    def restore(self, snap: tuple[np.ndarray, ...]) -> None:
        """Continue from a :meth:`snapshot` (of this filter or of one with the same params)."""
        for own, saved in zip((self._x, self._P, self._hist, self._state), snap, strict=True):
            own[...] = saved

    def advance(self, t: np.ndarray, omega: np.ndarray, torque: np.ndarray, mu_x: np.ndarray,
                axle_slip: np.ndarray, f_x: np.ndarray, f_y: np.ndarray, yaw_rate: np.ndarray,
                delta: np.ndarray,
                extra_v: np.ndarray | None = None,
                extra_var: np.ndarray | None = None,
                fx_from_speed: bool = False) -> dict[str, np.ndarray]:
        """Process a chunk; returns v (n, 2) [v_x, v_y] m/s, sigma (n, 2), bias (n, 3) [b_x, b_y]
        m/s² and b_r rad/s, trust (n, 4).

        ``axle_slip`` (n, 2) holds the front and rear axle slip angles −F_y/C_y in rad (NaN
        where unknown); ``extra_v``/``extra_var`` (n, m) extra CG-speed measurements, m/s
        and (m/s)², NaN where absent. ``fx_from_speed``: ``f_x`` is the derivative of a
        speed (a log without ``ax``), i.e. v̇_x itself, not the specific force v̇_x − r v_y:
        the prediction leaves out r v_y, its process intensity is ``q_vx_speed``, and the
        slip-signed inflation is off
        (``slip_sign`` = ∞: a wheel reading below the integral while braked is no evidence of
        slip when the integral is the wheels' own, and inflating it would leave v_x to the
        integral's lag).
        """
        n = t.shape[0]
        if extra_v is None or extra_var is None:
            extra_v = np.full((n, 0), np.nan)
            extra_var = np.full((n, 0), np.nan)
        v = np.empty((n, 2))
        sig = np.empty((n, 2))
        bias = np.empty((n, 3))
        trust = np.empty((n, 4))
        prm = self._prm
        if fx_from_speed:
            prm = prm.copy()
            prm[6] = np.inf
            prm[30] = 1.0
            prm[0] = self.params.q_vx_speed
        reference_kernel(t, omega, torque, mu_x, np.ascontiguousarray(axle_slip), f_x, f_y,
                         yaw_rate, delta,
                         np.ascontiguousarray(extra_v), np.ascontiguousarray(extra_var),
                         self.radius, self.lf, self.lr, self.xw, self.yw, prm, self._x,
                         self._P, self._hist, self._state, v, sig, bias, trust)
        return {"v": v, "sigma": sig, "bias": bias, "trust": trust}
