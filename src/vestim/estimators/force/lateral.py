"""Lateral tire forces from the handling dynamics by a UKF (001 Sec. III-B, eq. (9)–(12)).

State x = [F_yf, F_yr, F̄_yf, r]: front and rear axle lateral forces (tire
frames), the front right-minus-left difference F̄_yf = F_y,fr − F_y,fl, and the
yaw rate. 001 eq. (10) has only the three forces (Ā = 0) and measures r; we add
r to the state so that the yaw equation of eq. (9) is used as dynamics
(ṙ = M_z/I_z) instead of differentiating the gyro, which at 200 Hz and
0.003 rad/s noise gives 0.85 rad/s² of noise on ṙ. The forces are random walks.

Measurements (eq. (9) with per-wheel steering instead of 001's parallel steering):
    m f_x + F_drag = Σ_i F_xb,i,    m f_y = Σ_i F_yb,i,    r_m = r,
with F_b,i the tire forces of corner i rotated by its steering angle, the
longitudinal forces F_x,i from the longitudinal estimator, and f the road-frame
specific force (IMU rotated by the body angles, :func:`vestim.models.kinematics.road_specific_force`).
001 eq. (11) subtracts g sin(θ_v + θ_r) and g sin(φ_v + φ_r); the road-angle
part does not belong in a force balance — the tires carry the gravity
component along a grade or bank — so only the body angles are removed here.

Corner split. The front difference F̄_yf is observable only through
sin δ·t_f/2 in the yaw moment (rank drops at δ = 0, eq. (12)), so a weak
pseudo-measurement F̄_yf − ρ_f F_yf = 0 (σ = ``sigma_split``) with
ρ_f = (w_fr − w_fl)/(w_fr + w_fl) keeps it bounded and lets the yaw moment
move it when the steering makes it observable. The rear axle force is split by
w_rl : w_rr (no state resolves it: the rear wheels share one slip angle and the
yaw moment sees only the axle sum). The weights are a tire's lateral capacity,
not its normal load alone (:func:`split_weights`): w_i = F_z,i^γ · G(λ_i) with
γ < 1 for the degressive load sensitivity of real tires' cornering stiffness,
and G = 1/(1 + (λ_i/λ_0)²) taking the lateral force away from a wheel that
spins or locks (combined slip), λ_i measured against the other wheels.

Force random walk (tuning rationale). One fixed intensity cannot serve both
straight runs and steering transients: the truth F_y of a straight launch or
braking is near zero, and a walk fast enough for a 0.5 Hz sine steer
(q = 10⁶ N²/s, time constant ≈ 6 ms against the 0.07 m/s² accelerometer noise)
puts ≈ 60 N of white noise on every axle — that noise, not a bias, was the
whole F_y error of the crossplant launches/braking (x01–x03: 6.5–6.9 % of the
500 N floor). The walk is therefore innovation-matched: q_F = q_force ·
min(1 + (ν̄/ν_0)², cap), ν̄ the larger running mean (τ = ``adapt_tau``) of the
normalised lateral-balance and yaw-rate innovations, which stay ≈ 0 while the
walk keeps up and drift when a force change outruns it. q_force = 2.5·10⁵,
ν_0 = 0.15, cap 24 (6·10⁶ in transients) is one set for every log: lower
floors give quieter straight runs but lag in our own simulator's split-μ
launch and lane changes (the 0.3-point limit there), higher ones lose the
straight-run gain.

What the data cannot determine (σ stays honest): the rear left/right split
(no measurement sees it) and the front split away from large δ; their σ is
the axle σ scaled by the weight. The exponent γ is not in the vehicle file:
the crossplant PAC2002 tire has C_y ∝ F_z (γ = 1 would be better there) while
our simulator's Magic Formula is strongly degressive (γ = 1 doubles its
step-steer error), so 0.85 stays. Known residuals not removable here:
m f_y itself is off by the IMU bias plus the roll-estimate gravity leak
(20–200 N on the crossplant logs, axle totals) and by the unsprung-mass
dynamics (±0.9 kN spikes for 0.2 s at steering steps). With parallel steering
at large δ and low speed the front wheels' kinematic slip angles differ by
≈ r·t_f·sin δ/v_x; the split pseudo-measurement carries that difference with the
nominal stiffness c₀ = σ0y/κy (``split_kinematic``, see the kernel).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any, NamedTuple

import numpy as np
from numba import njit

from vestim.filters.kalman import ukf_update4
from vestim.filters.ukf import sigma_points4
from vestim.params import check_ranges

_JIT: dict[str, Any] = {"cache": True, "error_model": "numpy"}

FYF, FYR, DFYF, YAW = 0, 1, 2, 3
N_X = 4
N_Y = 4


@dataclass(frozen=True)
class LateralParams:
    """Noise settings of the lateral-force UKF.

    Attributes:
        q_force: random-walk intensity of the axle forces, N²/s.
        q_split: random-walk intensity of F̄_yf, N²/s.
        q_yaw: process noise of the yaw rate, (rad/s)²/s (model error of M_z).
        sigma_ax: one-sigma of the longitudinal balance, m/s² (IMU noise, bias, drag/pitch model).
        sigma_ay: one-sigma of the lateral balance, m/s².
        sigma_yaw: one-sigma of the yaw-rate measurement, rad/s (noise and bias).
        sigma_split: one-sigma of the front-split pseudo-measurement, N.
        load_exponent: γ of the split weights F_z^γ (1 = proportional to load).
        slip_scale: λ_0 of the split weights: slip ratio at which a wheel's share halves.
        adapt_tau: time constant of the running mean of the normalised innovations, s.
        adapt_nu: running-mean innovation at which the force random walk doubles.
        adapt_cap: largest factor on ``q_force`` (q_force·adapt_cap is the transient intensity).
        bias_tau: time constant of the running mean of f_y − r·v (the lateral balance's
            low-frequency offset, removed from m f_y), s; 0 disables it.
        bias_scale: |f_y − r v − b̂| (m/s²) at which a sample's weight in that mean halves.
        split_kinematic: use the kinematic front slip-angle difference in the split
            pseudo-measurement (nominal stiffness c₀ = σ0y/κy); False gives F̄_yf = ρ_f F_yf.
    """

    q_force: float = 2.5e5
    q_split: float = 1.0e6
    q_yaw: float = 1.0e-3
    sigma_ax: float = 0.4
    sigma_ay: float = 0.1
    sigma_yaw: float = 0.004
    sigma_split: float = 800.0
    load_exponent: float = 0.85
    slip_scale: float = 0.1
    adapt_tau: float = 0.05
    adapt_nu: float = 0.15
    adapt_cap: float = 24.0
    bias_tau: float = 0.0
    bias_scale: float = 0.1
    split_kinematic: bool = True

    def __post_init__(self) -> None:
        check_ranges(self, "force_params.lateral", positive=(
            "q_force", "q_split", "q_yaw", "sigma_ax", "sigma_ay", "sigma_yaw", "sigma_split",
            "slip_scale", "adapt_tau", "adapt_nu", "adapt_cap", "bias_scale"),
            nonnegative=("load_exponent", "bias_tau"))


def lateral_q(lp: LateralParams) -> np.ndarray:
    """The ``q`` field of :class:`LateralKernelParams`: the random walks' intensities on the
    UKF's state [q_force, q_force, q_split, q_yaw]."""
    return np.array([lp.q_force, lp.q_force, lp.q_split, lp.q_yaw])


def lateral_params(lp: LateralParams, mass: float, iz: float, xw: np.ndarray, yw: np.ndarray,
                   c0: float, r_diag: np.ndarray, wm: np.ndarray, wc: np.ndarray,
                   tau: float) -> LateralKernelParams:
    """:class:`LateralKernelParams` from the config ``lp``, the car's mass (kg), yaw inertia
    (kg m²) and corner positions (m), and the measurement noise and sigma-point weights.

    ``c0``: the nominal normalised cornering stiffness C_y/F_z, 1/rad (σ0y/κy of the
    vehicle file's [tire] table), used where ``lp.split_kinematic``."""
    return LateralKernelParams(float(mass), float(iz), xw, yw, lateral_q(lp), r_diag, wm, wc,
                               float(tau), float(lp.adapt_tau), float(lp.adapt_nu),
                               float(lp.adapt_cap), float(lp.bias_tau),
                               float(c0) if lp.split_kinematic else 0.0, float(lp.bias_scale))


@njit(**_JIT)
def split_weights(fz: np.ndarray, omega: np.ndarray, torque: np.ndarray, yaw_rate: np.ndarray,
                  radius: float, yw: np.ndarray, load_exponent: float,
                  slip_scale: float) -> np.ndarray:
    """Lateral-capacity weights per corner (n, 4) for splitting axle forces (see module doc).

    A wheel's slip is measured against the others: its wheel-centre speed is
    estimated as R ω_i + r y_i (removing the yaw-rate part of the speed
    difference between corners); a driven wheel (T ≥ 0) is compared with the
    slowest wheel and a braked one with the fastest, λ_i = (v_i − v_ref)/max(|v_i|, |v_ref|, 1 m/s).
    A wheel spinning or locking while another rolls has |λ_i| ≫ λ_0; when all
    four slip alike none is singled out.
    """
    n = fz.shape[0]
    out = np.empty((n, 4))
    v = np.empty(4)
    for k in range(n):
        v_min = np.inf
        v_max = -np.inf
        for i in range(4):
            v[i] = radius * omega[k, i] + yaw_rate[k] * yw[i]
            v_min = min(v_min, v[i])
            v_max = max(v_max, v[i])
        for i in range(4):
            v_ref = v_min if torque[k, i] >= 0.0 else v_max
            lam = (v[i] - v_ref) / max(abs(v[i]), abs(v_ref), 1.0)
            out[k, i] = max(fz[k, i], 0.0) ** load_exponent / (1.0 + (lam / slip_scale) ** 2)
    return out


@njit(**_JIT)
def _yaw_moment(fyf: float, fyr: float, dfyf: float, fc: np.ndarray, fs: np.ndarray,
                cd: np.ndarray, sd: np.ndarray, rear_w: float, xw: np.ndarray,
                yw: np.ndarray) -> float:
    """Yaw moment M_z (N m) about the CG of the state's lateral forces [F_yf, F_yr, F̄_yf] and
    each corner's tire-frame F_x, rotated by its steering angle (001 eq. (9)):
    M_z = Σ_i x_i F_yb,i − y_i F_xb,i with F_xb = F_x cos δ − F_y sin δ,
    F_yb = F_x sin δ + F_y cos δ.

    ``fc``, ``fs``: F_x cos δ and F_x sin δ per corner, ``cd``, ``sd``: cos δ and sin δ
    (computed once per sample, shared by the sigma points); ``rear_w`` the rear-left share.
    """
    fy0 = 0.5 * (fyf - dfyf)
    fy1 = 0.5 * (fyf + dfyf)
    fy2 = rear_w * fyr
    fy3 = (1.0 - rear_w) * fyr
    mz = 0.0
    mz += xw[0] * (fs[0] + fy0 * cd[0]) - yw[0] * (fc[0] - fy0 * sd[0])
    mz += xw[1] * (fs[1] + fy1 * cd[1]) - yw[1] * (fc[1] - fy1 * sd[1])
    mz += xw[2] * (fs[2] + fy2 * cd[2]) - yw[2] * (fc[2] - fy2 * sd[2])
    mz += xw[3] * (fs[3] + fy3 * cd[3]) - yw[3] * (fc[3] - fy3 * sd[3])
    return mz


class LateralKernelParams(NamedTuple):
    """:func:`lateral_kernel`'s parameters (SI), made by :func:`lateral_params`: the car's
    mass (kg) and yaw inertia (kg m²), the corner positions ``xw`` ahead of and ``yw`` left
    of the CG (4,) m, the random walks ``q`` (:func:`lateral_q`) and the measurement noise
    ``r_diag`` (4,), the sigma-point weights and scale, and the :class:`LateralParams` of the
    innovation-matched random walk, the f_y offset and the kinematic split."""

    mass: float
    iz: float
    xw: np.ndarray
    yw: np.ndarray
    q: np.ndarray
    r_diag: np.ndarray
    wm: np.ndarray
    wc: np.ndarray
    tau: float
    adapt_tau: float  # s, the innovation means' averaging time (0: no adaptation)
    adapt_nu: float  # ν_0, the normalised innovation mean that doubles the force walk
    adapt_cap: float  # the most factor on the force walk
    bias_tau: float  # s, the f_y offset's longest memory (0: no offset)
    split_c0: float  # c₀ of the kinematic front split, 1/rad (0: none)
    bias_scale: float  # m/s², the offset's Cauchy scale


class LateralState(NamedTuple):
    """:func:`lateral_kernel`'s state (in place); :func:`new_lateral_state` makes a fresh one.

    Attributes:
        x: (:data:`N_X`,) the UKF's state [F_yf, F_yr, ΔF_yf, r] (N, N, N, rad/s).
        P: (N_X, N_X) its covariance.
        t_prev: (1,) time of the previous sample, s.
        started: (1,) 1.0 once the first sample started the filter.
        fx_prev: (4,) F_x of the previous sample, N, and ``delta_prev`` (4,) its road-wheel
            angles, rad: held over the interval.
        nu_balance, nu_yaw: (1,) the running means ν̄ of the normalised lateral-balance and
            yaw-rate innovations.
        walk_factor: (1,) the factor on the force random walk (1 + (ν̄/ν_0)², capped).
        fy_offset: (1,) the offset b̂ of f_y, m/s².
        elapsed: (1,) time since the start, s.
    """

    x: np.ndarray
    P: np.ndarray
    t_prev: np.ndarray
    started: np.ndarray
    fx_prev: np.ndarray
    delta_prev: np.ndarray
    nu_balance: np.ndarray
    nu_yaw: np.ndarray
    walk_factor: np.ndarray
    fy_offset: np.ndarray
    elapsed: np.ndarray


def new_lateral_state() -> LateralState:
    """A fresh :class:`LateralState` (the next sample initialises the filter)."""
    return LateralState(np.zeros(N_X), np.zeros((N_X, N_X)), np.zeros(1), np.zeros(1),
                        np.zeros(4), np.zeros(4), np.zeros(1), np.zeros(1), np.zeros(1),
                        np.zeros(1), np.zeros(1))


@njit(**_JIT)
def lateral_kernel(p: LateralKernelParams, s: LateralState, t: np.ndarray, fx: np.ndarray,
                   delta: np.ndarray, weights: np.ndarray, f_x: np.ndarray, f_y: np.ndarray,
                   yaw_rate: np.ndarray, noise: np.ndarray, drag: np.ndarray, fz: np.ndarray,
                   speed: np.ndarray, fy_out: np.ndarray, sig_out: np.ndarray) -> None:
    """Advance the lateral-force UKF over a chunk (in place on ``s``, :class:`LateralState`).

    Inputs per sample: fx (n, 4) tire-frame longitudinal forces, delta (n, 4)
    road-wheel angles (rear 0), weights (n, 4) lateral-capacity weights of
    :func:`split_weights`, f_x, f_y road-frame
    specific force (m/s²), yaw_rate (rad/s), noise (4, n) the measured noise variances of
    f_x, f_y, f_z ((m/s²)²) and the yaw rate ((rad/s)²; f_z's unused), which raise the measurement noise above
    ``r_diag`` where they exceed it (the log's own sensors, e.g. a vibrating IMU or a gyro
    noisier than the configured one), drag (N), fz (n, 4) normal loads (N), speed
    (n,) a wheel-speed reference of v_x (m/s).
    Outputs: fy_out (n, 4) tire-frame lateral force per corner, sig_out (n, 4) one-sigma.
    """
    mass, iz, xw, yw, q, r_diag = p.mass, p.iz, p.xw, p.yw, p.q, p.r_diag
    wm, wc, tau = p.wm, p.wc, p.tau
    x, P = s.x, s.P
    t_prev, started, fx_prev, delta_prev = s.t_prev, s.started, s.fx_prev, s.delta_prev
    nu_balance, nu_yaw, walk_factor = s.nu_balance, s.nu_yaw, s.walk_factor
    fy_offset, elapsed = s.fy_offset, s.elapsed
    n = t.shape[0]
    npts = 2 * N_X + 1
    # Work arrays, once per call.
    pts = np.empty((npts, N_X))
    dev = np.empty((npts, N_X))
    xm = np.empty(N_X)
    ym = np.empty(N_Y)
    Pm = np.empty((N_X, N_X))
    Pyy = np.empty((N_Y, N_Y))
    Pxy = np.empty((N_X, N_Y))
    Ly = np.empty((N_Y, N_Y))
    K = np.empty((N_X, N_Y))
    H = np.empty((N_Y, N_X))
    cd_now = np.empty(4)
    sd_now = np.empty(4)
    cd_prev = np.cos(delta_prev)  # cos and sin of the held angles, carried from sample to sample
    sd_prev = np.sin(delta_prev)
    fc_prev = np.empty(4)  # the held F_x times cos δ and sin δ
    fs_prev = np.empty(4)
    y = np.empty(N_Y)
    for k in range(n):
        wr_sum = weights[k, 2] + weights[k, 3]
        rear_w = weights[k, 2] / wr_sum if wr_sum > 0 else 0.5
        wf_sum = weights[k, 0] + weights[k, 1]
        rho = (weights[k, 1] - weights[k, 0]) / wf_sum if wf_sum > 0 else 0.0
        fresh = started[0] == 0.0
        if fresh:
            x[:] = 0.0
            x[YAW] = yaw_rate[k]
            P[:, :] = 0.0
            P[FYF, FYF] = 1.0e6
            P[FYR, FYR] = 1.0e6
            P[DFYF, DFYF] = 1.0e5
            P[YAW, YAW] = r_diag[2]
            started[0] = 1.0
            nu_balance[0] = 0.0
            nu_yaw[0] = 0.0
            walk_factor[0] = 1.0
            fy_offset[0] = 0.0
            elapsed[0] = 0.0
        else:
            dt = t[k] - t_prev[0]
            elapsed[0] += dt
            # Prediction: forces random walk, yaw rate by the yaw moment (001 eq. (9)).
            sigma_points4(x, P, tau, pts)
            for i in range(4):
                fc_prev[i] = fx_prev[i] * cd_prev[i]
                fs_prev[i] = fx_prev[i] * sd_prev[i]
            for i in range(npts):
                mz = _yaw_moment(pts[i, FYF], pts[i, FYR], pts[i, DFYF], fc_prev, fs_prev,
                                 cd_prev, sd_prev, rear_w, xw, yw)
                pts[i, YAW] += dt * mz / iz
            for j in range(N_X):  # 000 eq. (11): the weighted mean and covariance
                acc = 0.0
                for i in range(npts):
                    acc += wm[i] * pts[i, j]
                xm[j] = acc
            for i in range(npts):
                for j in range(N_X):
                    dev[i, j] = pts[i, j] - xm[j]
            for r in range(N_X):
                for c2 in range(N_X):
                    acc = 0.0
                    for i in range(npts):
                        acc += wc[i] * dev[i, r] * dev[i, c2]
                    Pm[r, c2] = acc
            for j in range(N_X):
                Pm[j, j] += q[j] * dt * (walk_factor[0] if j < 2 else 1.0)
            # Update with [m f_x + drag, m f_y, r, 0]. The measurement is affine in
            # the state, y = H x + h0, so the sigma-point sums of the update equal
            # H P̄ Hᵀ and P̄ Hᵀ exactly; they are evaluated in that closed form.
            for i in range(4):
                cd_now[i] = np.cos(delta[k, i])
                sd_now[i] = np.sin(delta[k, i])
            H[:, :] = 0.0
            H[0, FYF] = -0.5 * (sd_now[0] + sd_now[1])
            H[0, DFYF] = 0.5 * (sd_now[0] - sd_now[1])
            H[0, FYR] = -(rear_w * sd_now[2] + (1.0 - rear_w) * sd_now[3])
            H[1, FYF] = 0.5 * (cd_now[0] + cd_now[1])
            H[1, DFYF] = 0.5 * (cd_now[1] - cd_now[0])
            H[1, FYR] = rear_w * cd_now[2] + (1.0 - rear_w) * cd_now[3]
            H[2, YAW] = 1.0
            H[3, DFYF] = 1.0
            H[3, FYF] = -rho
            h0x = 0.0
            h0y = 0.0
            for i in range(4):
                h0x += fx[k, i] * cd_now[i]
                h0y += fx[k, i] * sd_now[i]
            for r in range(N_Y):
                acc = 0.0
                for j in range(N_X):
                    acc += H[r, j] * xm[j]
                ym[r] = acc
            ym[0] += h0x
            ym[1] += h0y
            for r in range(N_X):  # Pxy = P̄ Hᵀ
                for c2 in range(N_Y):
                    acc = 0.0
                    for j in range(N_X):
                        acc += Pm[r, j] * H[c2, j]
                    Pxy[r, c2] = acc
            for r in range(N_Y):  # Pyy = H P̄ Hᵀ + R
                for c2 in range(N_Y):
                    acc = 0.0
                    for j in range(N_X):
                        acc += H[r, j] * Pxy[j, c2]
                    Pyy[r, c2] = acc
            Pyy[0, 0] += max(r_diag[0], mass * mass * noise[0, k])
            Pyy[1, 1] += max(r_diag[1], mass * mass * noise[1, k])
            Pyy[2, 2] += max(r_diag[2], noise[3, k])
            Pyy[3, 3] += r_diag[3]
            y[0] = mass * f_x[k] + drag[k] - ym[0]
            y[1] = mass * (f_y[k] - fy_offset[0]) - ym[1]
            y[2] = yaw_rate[k] - ym[2]
            y[3] = -ym[3]
            if p.split_c0 > 0.0:
                # Kinematic front split: the outer front wheel runs faster, so with one
                # steering angle the slip angles differ by r t_f sin δ/v_x; Ackermann
                # geometry (δ_fl ≠ δ_fr) takes that back. Linear tires C_i = c₀ F_z,i
                # then move F̄_yf from ρ F_yf by (1 − ρ²) C_f Δα/2 with
                # Δα = δ_fr − δ_fl + r t_f sin δ̄/v_x. Bounded by |F_yf| (neither wheel
                # reverses its force).
                v = max(speed[k], 3.0)
                c_f = p.split_c0 * (max(fz[k, 0], 0.0) + max(fz[k, 1], 0.0))
                d_kin = 0.5 * (1.0 - rho * rho) * c_f * (
                    delta[k, 1] - delta[k, 0] + xm[YAW] * (yw[0] - yw[1])
                    * np.sin(0.5 * (delta[k, 0] + delta[k, 1])) / v)
                # Off the linear range the secant stiffness falls: the term fades with the
                # axle's lateral utilisation μ_f = |F_yf|/F_z,f (half at μ_f = 0.2).
                mu_f = abs(xm[FYF]) / max(c_f / p.split_c0, 1.0)
                d_kin /= 1.0 + (mu_f / 0.2) ** 2
                lim = abs(xm[FYF])
                y[3] += min(max(d_kin, -lim), lim)
            # Innovation-matched force random walk: the running means of the
            # normalised lateral-balance and yaw-rate innovations are ~0 while the
            # random walk keeps up; a force change the walk lags behind makes them
            # drift, and the intensity grows as 1 + (ν̄/ν_0)² (capped) for the next step.
            if p.adapt_tau > 0.0:
                a_nu = min(dt / p.adapt_tau, 1.0)
                nu_balance[0] += a_nu * (y[1] / np.sqrt(Pyy[1, 1]) - nu_balance[0])
                nu_yaw[0] += a_nu * (y[2] / np.sqrt(Pyy[2, 2]) - nu_yaw[0])
                nu2 = max(nu_balance[0] * nu_balance[0], nu_yaw[0] * nu_yaw[0])
                walk_factor[0] = min(1.0 + nu2 / (p.adapt_nu * p.adapt_nu), p.adapt_cap)
            x[:] = xm
            P[:, :] = Pm
            ukf_update4(x, P, Pxy, Pyy, y, Ly, K)  # K = Pxy Pyy⁻¹, x̂ += K ν, P −= K Pxyᵀ
        if p.bias_tau > 0.0:
            # Offset of the lateral balance: f_y − r v_x is the sideslip acceleration v̇_y,
            # zero on average, plus what the attitude filter leaks into f_y at low
            # frequency (roll-gyro bias times its crossover time, accelerometer bias);
            # its running mean (memory min(max(elapsed, 1 s), bias_tau)) is removed.
            # A slide (sustained v̇_y) or a spinning wheel in the speed reference makes
            # f_y − r v large: a Cauchy weight (scale ``bias_scale``) leaves such samples out.
            mem = min(max(elapsed[0], 1.0), p.bias_tau)
            g_b = min((t[k] - t_prev[0]) / mem if elapsed[0] > 0.0 else 0.0, 1.0)
            e_b = f_y[k] - yaw_rate[k] * speed[k] - fy_offset[0]
            fy_offset[0] += g_b * e_b / (1.0 + (e_b / p.bias_scale) ** 2)
        t_prev[0] = t[k]
        for i in range(4):  # held over the next interval
            fx_prev[i] = fx[k, i]
            delta_prev[i] = delta[k, i]
            if fresh:
                cd_prev[i] = np.cos(delta[k, i])
                sd_prev[i] = np.sin(delta[k, i])
            else:  # this sample's, computed for its update
                cd_prev[i] = cd_now[i]
                sd_prev[i] = sd_now[i]
        fy_out[k, 0] = 0.5 * (x[FYF] - x[DFYF])
        fy_out[k, 1] = 0.5 * (x[FYF] + x[DFYF])
        fy_out[k, 2] = rear_w * x[FYR]
        fy_out[k, 3] = (1.0 - rear_w) * x[FYR]
        var_f = P[FYF, FYF]
        var_d = P[DFYF, DFYF]
        cov_fd = P[FYF, DFYF]
        sig_out[k, 0] = 0.5 * np.sqrt(max(var_f + var_d - 2 * cov_fd, 0.0))
        sig_out[k, 1] = 0.5 * np.sqrt(max(var_f + var_d + 2 * cov_fd, 0.0))
        sig_out[k, 2] = rear_w * np.sqrt(max(P[FYR, FYR], 0.0))
        sig_out[k, 3] = (1.0 - rear_w) * np.sqrt(max(P[FYR, FYR], 0.0))
