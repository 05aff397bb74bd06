"""LuGre-based time-varying Kalman (000) and unscented Kalman (003) corner velocity estimators.

Model per corner (000 eq. (17)–(19), 003 eq. (1)–(4)), state x = [z̄_x, v_rx, ż̄_x]
(:class:`vestim.models.lpv.KalmanState`)::

    ż̄_x = v_rx − κ_x R|ω| z̄_x + Ω_z                  (000 eq. (17); Ω_z the road-friction term)
    v̇_rx = R ω̇ − v̇_xt + Ω_a                          (000 eq. (18))
    z̄̈_x = v̇_rx − κ_x R (d|ω|/dt z̄_x + |ω| ż̄_x)        (time derivative of eq. (17))
    μ_x = σ0x z̄_x + σ2x v_rx + σ1x ż̄_x + Γ             (000 eq. (19) output)

i.e. ẋ = A(t) x + B u, A = [[−κR|ω|, 1, 0], [0, 0, 0], [−κR d|ω|/dt, 0, −κR|ω|]],
B = [0, 1, 1]ᵀ (000 eq. (19) with M⁻¹ multiplied out; 003 eq. (3)–(4) print these
A_c, B_c directly), u = R ω̇ − v̇_xt. 000 prints the input as "(R_e v)" and the
third row's input as 0 before M⁻¹; M⁻¹ = [[1,0,0],[0,1,0],[0,1,1]] moves the
input into the third row, as 003's B_c = [0 1 1]ᵀ confirms. The output matrix is
C = [σ0x, σ2x, σ1x] (003 prints it transposed, C_cᵀ; it is a row).

Discretisation by step invariance (000 text before eq. (21)): A_k = e^{A h},
B_k = ∫_0^h e^{Aτ}B dτ, in closed form (:func:`~.corner_discrete.kf_transition`).

Filters:

* ``kf`` — 000 eq. (21)–(22) in filter form: predict x⁻ = A_k x + B_k u,
  P⁻ = A_k P A_kᵀ + Q̄, then update with μ_x,k (Joseph form,
  :func:`vestim.filters.kalman.kalman_update_scalar`, so P stays symmetric positive
  definite). 000's one-step predictor (21) is the same recursion with
  the update and the prediction fused; the filter form is used so that the
  estimate at sample k already contains μ_x,k.
* ``ukf`` — 003 Algorithm 1 with the papers' sigma-point scaling (2N + 1 = 7
  points, :mod:`vestim.filters.ukf`). The sigma points are redrawn from
  (x⁻, P⁻ + Q̄) before the output is predicted: Algorithm 1 reuses the propagated
  points, which leaves Q̄ out of P_ŷŷ and P_x̂ŷ; redrawing is the consistent form
  (the force stage does the same). On this model, which is linear in the state,
  the unscented transform is exact, so the UKF equals the KF up to round-off —
  003 chose the UKF for "nonlinear and non-Gaussian characteristics", which
  system (3) as printed does not have.

Noise covariances: 000 Sec. III gives Q̄ = 2.5e-3, R̄ = 1e-3 in normal driving and
Q̄ = 3.3e-4, R̄ = 2.1e-1 while the high-slip module (:mod:`.corner_slip`) flags the
corner, as scalars. :meth:`KFParams.paper` reads them as Q̄ = q I₃ per 5 ms step
(T_s of 000 Sec. III-C); the defaults of :class:`KFParams` scale Q̄ per state and
drop the force update under high slip (reasons in its docstring). Q̄ is scaled by
h/T_s for a step h ≠ T_s.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Any

import numpy as np
from numba import njit

from vestim.estimators.velocity.corner_common import (
    H_AX,
    H_D,
    H_R,
    H_T,
    H_W,
    CornerInputs,
    CornerOutputs,
    CornerParams,
    CornerState,
    count_release,
    pick,
    store,
    transport_rate,
    vyt_no_sideslip,
)
from vestim.estimators.velocity.corner_discrete import (
    fill_transition,
    kf_transition_entries,
)
from vestim.estimators.velocity.corner_slip import (
    HighSlipParams,
    detector_step,
    is_high_slip,
    slip_ratio_estimate,
)
from vestim.filters.kalman import kalman_update_scalar3
from vestim.filters.ukf import sigma_points
from vestim.models.lpv import KalmanState

_JIT: dict[str, Any] = {"cache": True, "error_model": "numpy"}

Z, VR, ZD = int(KalmanState.Z), int(KalmanState.VR), int(KalmanState.ZDOT)
NX = 3


@dataclass(frozen=True)
class KFParams:
    """Noise settings of the LuGre Kalman/UKF corner estimators.

    Q̄ = diag(q) is the process-noise covariance per step of ``step_ref`` seconds
    (scaled by h/step_ref for a step h), state order [z̄_x (m²), v_rx ((m/s)²),
    ż̄_x ((m/s)²)]; R̄ the variance of μ_x. ``q``/``r`` apply in normal driving,
    ``q_high``/``r_high`` while the high-slip module flags the corner.

    Defaults (ours, see docs/methods.md): 000 prints scalar Q̄ = 2.5e-3 /
    3.3e-4 and R̄ = 1e-3 / 2.1e-1 (normal / high slip) without saying how Q̄ maps on
    the three states. Read as Q̄ = q I₃ in SI units (:meth:`paper`), the deflection
    z̄_x (|z̄| ≤ μ_s/σ0 ≈ 2 mm) gets a random walk of 50 mm per step, so the force is
    absorbed by z̄_x and v_rx is left to the integrated kinematics (drift from the
    accelerometer bias), and in long slip the friction-free model's huge force
    prediction still pulls v̂_xt to Rω through R̄ = 0.21. The defaults scale Q̄ to
    each state's physical range, keep 000's R̄ = 1e-3 and its high-slip ratio
    Q̄_high/Q̄ = 3.3e-4/2.5e-3, and make the high-slip R̄ infinite (no force update:
    in saturation μ_x carries no information on v_rx).

    Attributes:
        q, r: normal-driving Q̄ diagonal and R̄.
        q_high, r_high: high-slip Q̄ diagonal and R̄ (r_high = inf: no force update).
        p0: diagonal of the initial covariance P̄_{0|−1}.
        step_ref: s, the step the Q̄ values refer to (000's T_s = 0.005 s).
        high_slip: the detection module's parameters.
    """

    q: tuple[float, float, float] = (1.0e-9, 1.0e-7, 1.0e-4)
    r: float = 1.0e-3
    q_high: tuple[float, float, float] = (1.32e-10, 1.32e-8, 1.32e-5)
    r_high: float = math.inf
    p0: tuple[float, float, float] = (1.0e-6, 1.0, 1.0e-2)
    step_ref: float = 0.005
    high_slip: HighSlipParams = field(default_factory=HighSlipParams)

    @classmethod
    def paper(cls) -> KFParams:
        """000 Sec. III's values read literally: Q̄ = q I₃ (2.5e-3 / 3.3e-4), R̄ = 1e-3 / 2.1e-1,
        P̄_{0|−1} = 2.5e-3 I₃, and no μ release in the high-slip module."""
        return cls(q=(2.5e-3,) * 3, r=1.0e-3, q_high=(3.3e-4,) * 3, r_high=2.1e-1,
                   p0=(2.5e-3,) * 3, high_slip=HighSlipParams(mu_release=0.0))

    def __post_init__(self) -> None:
        for name in ("q", "q_high", "p0"):
            v = tuple(float(e) for e in getattr(self, name))
            if len(v) != NX or not all(math.isfinite(e) and e > 0.0 for e in v):
                raise ValueError(f"KFParams.{name} = {getattr(self, name)!r} must be {NX} finite "
                                 "numbers > 0 (diagonal of [z, v_r, z_dot])")
            object.__setattr__(self, name, v)
        for name in ("r", "r_high", "step_ref"):
            v = getattr(self, name)
            if not (isinstance(v, int | float) and v > 0.0) or math.isnan(v):
                raise ValueError(f"KFParams.{name} = {v!r} must be a number > 0")
        if not math.isfinite(self.r) or not math.isfinite(self.step_ref):
            raise ValueError("KFParams.r and step_ref must be finite")


@njit(**_JIT)
def _store_prediction(x: np.ndarray, P: np.ndarray, c: int, m0: float, m1: float, m2: float,
                      s00: float, s01: float, s02: float, s11: float, s12: float,
                      s22: float) -> None:
    """Corner ``c``'s predicted state (m0, m1, m2) and symmetric covariance (its upper
    triangle s00 … s22) into ``x`` (4, 3) and ``P`` (4, 3, 3)."""
    x[c, 0] = m0
    x[c, 1] = m1
    x[c, 2] = m2
    P[c, 0, 0] = s00
    P[c, 0, 1] = P[c, 1, 0] = s01
    P[c, 0, 2] = P[c, 2, 0] = s02
    P[c, 1, 1] = s11
    P[c, 1, 2] = P[c, 2, 1] = s12
    P[c, 2, 2] = s22


@njit(**_JIT)
def _kf_step(x: np.ndarray, P: np.ndarray, c: int, a00: float, a01: float, a20: float,
             a21: float, a22: float, b0: float, b1: float, b2: float, u: float, q0: float,
             q1: float, q2: float, r: float, y: float, h0: float, h1: float, h2: float) -> None:
    """One predict/update of the linear KF (000 eq. (21)–(22), filter form), in place on x[c], P[c].

    (h0, h1, h2) = C = [σ0, σ2, σ1] is the output row, (q0, q1, q2) the diagonal of Q̄. Uses
    the structure of A_k (:func:`~.corner_discrete.kf_transition`): A_k[0, 2] = 0 and row 1 =
    [0, 1, 0] (v_rx is only driven by the input); a00 … a22 are A_k's other entries, b0 … b2
    the entries of B_k. Scalars, not arrays or row views (each costs reference counting per
    corner-step; issue 27): the arithmetic of the array form, bit for bit.
    """
    x0, x1, x2 = x[c, 0], x[c, 1], x[c, 2]
    p00, p01, p02 = P[c, 0, 0], P[c, 0, 1], P[c, 0, 2]
    p10, p11, p12 = P[c, 1, 0], P[c, 1, 1], P[c, 1, 2]
    p20, p21, p22 = P[c, 2, 0], P[c, 2, 1], P[c, 2, 2]
    xp0 = a00 * x0 + a01 * x1 + b0 * u
    xp1 = x1 + b1 * u
    xp2 = a20 * x0 + a21 * x1 + a22 * x2 + b2 * u
    # T = A P, then P⁻ = T Aᵀ + Q
    t00 = a00 * p00 + a01 * p10
    t01 = a00 * p01 + a01 * p11
    t02 = a00 * p02 + a01 * p12
    t20 = a20 * p00 + a21 * p10 + a22 * p20
    t21 = a20 * p01 + a21 * p11 + a22 * p21
    t22 = a20 * p02 + a21 * p12 + a22 * p22
    s00 = t00 * a00 + t01 * a01 + q0
    s01 = t01
    s02 = t00 * a20 + t01 * a21 + t02 * a22
    s11 = p11 + q1
    s12 = p10 * a20 + p11 * a21 + p12 * a22
    s22 = t20 * a20 + t21 * a21 + t22 * a22 + q2
    if not math.isnan(y):
        # Update with μ_x = C x, C = [σ0, σ2, σ1], in the Joseph form of
        # :func:`~vestim.filters.kalman.kalman_update_scalar`: symmetric positive definite by
        # construction even when round-off makes P⁻ − K S Kᵀ lose definiteness (σ0 ≈ 600
        # against σ2 ≈ 0.002 makes C badly scaled).
        innov = y - (h0 * xp0 + h1 * xp1 + h2 * xp2)
        xp0, xp1, xp2, s00, s01, s02, s11, s12, s22 = kalman_update_scalar3(
            s00, s01, s02, s11, s12, s22, xp0, xp1, xp2, h0, h1, h2, r, innov)
    _store_prediction(x, P, c, xp0, xp1, xp2, s00, s01, s02, s11, s12, s22)


@njit(**_JIT)
def _ukf_step(x: np.ndarray, P: np.ndarray, c: int, Ak: np.ndarray, Bk: np.ndarray, u: float,
              q: np.ndarray, r: float, y: float, h: np.ndarray, wm: np.ndarray, wc: np.ndarray,
              tau: float, pts: np.ndarray, L: np.ndarray, xm: np.ndarray, Pm: np.ndarray) -> None:
    """One step of 003 Algorithm 1, in place on x[c], P[c] (xm, Pm: scratch).

    Prediction through the sigma points of (x, P) (papers' scaling). The output
    μ = C x is linear, so the sigma-point sums of the update (P_ŷŷ, P_x̂ŷ of
    Algorithm 1, over points redrawn from (x̂_m, P_m + Q̄)) equal C P_m Cᵀ + R̄ and
    P_m Cᵀ exactly: the update is the linear one of
    :func:`~vestim.filters.kalman.kalman_update_scalar` (Joseph form, as ``_kf_step``),
    which saves a second factorisation per step.
    """
    npts = pts.shape[0]
    for i in range(NX):
        xm[i] = x[c, i]
        for j in range(NX):
            Pm[i, j] = P[c, i, j]
    sigma_points(xm, Pm, tau, L, pts)
    a00, a01, a20, a21, a22 = Ak[0, 0], Ak[0, 1], Ak[2, 0], Ak[2, 1], Ak[2, 2]
    b0 = Bk[0] * u
    b1 = Bk[1] * u
    b2 = Bk[2] * u
    # One pass over the points: F(χ_i) = A_k χ_i + B_k u (A_k[0, 2] = 0, row 1 = [0, 1, 0]),
    # kept as deviations d_i = F(χ_i) − F(χ_0) from the propagated centre (no cancellation),
    # with Σ W^m d, Σ W^c d, Σ W^c and Σ W^c d dᵀ; then the mean m = F(χ_0) + Σ W^m d and
    # Σ W^c (F − m)(F − m)ᵀ = Σ W^c d dᵀ − e gᵀ − g eᵀ + (Σ W^c) e eᵀ, e = Σ W^m d, g = Σ W^c d.
    q0, q1, q2 = pts[0, 0], pts[0, 1], pts[0, 2]
    f0c = a00 * q0 + a01 * q1 + b0
    f1c = q1 + b1
    f2c = a20 * q0 + a21 * q1 + a22 * q2 + b2
    e0 = e1 = e2 = 0.0
    g0 = g1 = g2 = 0.0
    wsum = wc[0]
    s00 = s01 = s02 = s11 = s12 = s22 = 0.0
    for i in range(1, npts):
        d0 = a00 * (pts[i, 0] - q0) + a01 * (pts[i, 1] - q1)
        d1 = pts[i, 1] - q1
        d2 = a20 * (pts[i, 0] - q0) + a21 * (pts[i, 1] - q1) + a22 * (pts[i, 2] - q2)
        w = wm[i]
        e0 += w * d0
        e1 += w * d1
        e2 += w * d2
        w = wc[i]
        wsum += w
        wd0 = w * d0
        wd1 = w * d1
        g0 += wd0
        g1 += wd1
        g2 += w * d2
        s00 += wd0 * d0
        s01 += wd0 * d1
        s02 += wd0 * d2
        s11 += wd1 * d1
        s12 += wd1 * d2
        s22 += w * d2 * d2
    m0 = f0c + e0
    m1 = f1c + e1
    m2 = f2c + e2
    s00 += -2.0 * e0 * g0 + wsum * e0 * e0
    s01 += -e0 * g1 - g0 * e1 + wsum * e0 * e1
    s02 += -e0 * g2 - g0 * e2 + wsum * e0 * e2
    s11 += -2.0 * e1 * g1 + wsum * e1 * e1
    s12 += -e1 * g2 - g1 * e2 + wsum * e1 * e2
    s22 += -2.0 * e2 * g2 + wsum * e2 * e2
    s00 += q[0]
    s11 += q[1]
    s22 += q[2]
    if not math.isnan(y):
        # P_x̂ŷ = P_m Cᵀ, P_ŷŷ = C P_m Cᵀ + R̄: the linear update, in the same Joseph form as
        # the KF (Algorithm 1's P_m − K P_ŷŷ Kᵀ is equal in exact arithmetic).
        innov = y - (h[0] * m0 + h[1] * m1 + h[2] * m2)
        m0, m1, m2, s00, s01, s02, s11, s12, s22 = kalman_update_scalar3(
            s00, s01, s02, s11, s12, s22, m0, m1, m2, h[0], h[1], h[2], r, innov)
    _store_prediction(x, P, c, m0, m1, m2, s00, s01, s02, s11, s12, s22)


@njit(**_JIT)
def lugre_kf_kernel(p: CornerParams, s: CornerState, inp: CornerInputs,
                    out: CornerOutputs) -> None:
    """Advance the four corner filters over a chunk of n samples, in place on the state arrays.

    Inputs: t (n,) s; omega, mu_x, a_xt, a_yt, delta (n, 4); yaw_rate (n,); hint (n, 4)
    bool; vyt_in (n, 4) m/s (NaN: use :func:`~.corner_common.vyt_no_sideslip`).
    State: x (4, 3), P (4, 3, 3), hold (9, 4) (:mod:`.corner_common`) and the detector's rings (see
    :func:`~.corner_slip.detector_step`). Outputs (n, 4): v̂_xt = Rω − v̂_rx, its
    one-sigma √P_vr, the high-slip flag, v̂_rx, ẑ_x, ż̂_x.

    Samples with NaN t or ω give NaN outputs and leave the state untouched; NaN μ_x
    skips the update (prediction only); NaN accelerations, δ or r hold the last value.
    ``p``, ``s``, ``inp``, ``out``: :mod:`.corner_common`'s trees (``out.vyt``, ``vry``,
    ``zy`` are not written).
    """
    t, omega, mu_x, a_xt, a_yt = inp.t, inp.omega, inp.mu_x, inp.a_xt, inp.a_yt
    delta, yaw_rate, hint, vyt_in = inp.delta, inp.yaw_rate, inp.hint, inp.vyt_in
    radius, kappa, sigma0, sigma1, sigma2 = p.radius, p.kappa, p.sigma0, p.sigma1, p.sigma2
    x_corner, q, r, q_high, r_high, p0 = p.xw, p.q, p.r, p.q_high, p.r_high, p.p0
    step_ref, lam_u, lam_l, beta_e, wdot_th = p.step_ref, p.lam_u, p.lam_l, p.beta_e, p.wdot_th
    min_speed, mu_release, release_window = p.min_speed, p.mu_release, p.release_window
    use_ukf, wm, wc, tau = p.use_ukf, p.wm, p.wc, p.tau
    x, P, hold, acc_buf, stats = s.x, s.P, s.hold, s.acc, s.stats
    w_buf, t_buf, ring = s.w_buf, s.t_buf, s.ring
    out_vxt, out_sigma, out_high, out_vr = out.vxt, out.sigma, out.high, out.vrx
    out_z, out_zdot = out.zx, out.zdot
    n = t.shape[0]
    kr = kappa * radius
    Ak = np.empty((3, 3))  # the UKF's A_k, B_k (fill_transition)
    Bk = np.empty(3)
    xp = np.empty(3)
    Pp = np.empty((3, 3))
    hrow = np.array([sigma0, sigma2, sigma1])
    qn0, qn1, qn2 = q[0], q[1], q[2]
    qh0, qh1, qh2 = q_high[0], q_high[1], q_high[2]
    pts = np.empty((2 * NX + 1, NX))
    L = np.empty((NX, NX))
    wdh = np.empty(4, dtype=np.bool_)
    qk = np.empty(NX)
    for k in range(n):
        tk = t[k]
        if math.isnan(tk):
            for c in range(4):
                out_vxt[k, c] = math.nan
                out_sigma[k, c] = math.nan
                out_high[k, c] = False
                out_vr[k, c] = math.nan
                out_z[k, c] = math.nan
                out_zdot[k, c] = math.nan
            continue
        thr = detector_step(k, tk, omega, a_xt, a_yt, lam_u, lam_l, beta_e, wdot_th,
                            acc_buf, stats, w_buf, t_buf, ring, wdh)
        for c in range(4):
            wk = omega[k, c]
            if math.isnan(wk):
                out_vxt[k, c] = math.nan
                out_sigma[k, c] = math.nan
                out_high[k, c] = False
                out_vr[k, c] = math.nan
                out_z[k, c] = math.nan
                out_zdot[k, c] = math.nan
                continue
            yk = mu_x[k, c]
            high = False
            if math.isnan(hold[H_T, c]):
                # First sample: free rolling (v_r = 0), deflection from the force.
                x[c, Z] = 0.0 if math.isnan(yk) else yk / sigma0
                x[c, VR] = 0.0
                x[c, ZD] = 0.0
                P[c, :, :] = 0.0
                for i in range(NX):
                    P[c, i, i] = p0[i]
            else:
                h = tk - hold[H_T, c]
                w0 = hold[H_W, c]
                rho0 = abs(w0)
                rho1 = abs(wk)
                a = kr * 0.5 * (rho0 + rho1)
                b = kr * (rho1 - rho0) / h
                e, a01, a20, a21, b0, b1, b2 = kf_transition_entries(a, b, h)
                d_now = pick(delta[k, c], hold[H_D, c])
                r_mid = 0.5 * (pick(yaw_rate[k], hold[H_R, c]) + hold[H_R, c])
                ax_mid = 0.5 * (pick(a_xt[k, c], hold[H_AX, c]) + hold[H_AX, c])
                vyt = vyt_in[k, c]
                if math.isnan(vyt):
                    vyt = vyt_no_sideslip(r_mid, x_corner[c], radius * w0 - x[c, VR], d_now)
                vxt_dot = ax_mid + transport_rate(r_mid, d_now, hold[H_D, c], h) * vyt
                u = radius * (wk - w0) / h - vxt_dot
                # High-slip module on the prior mean (000 Sec. III): slip or |ω̇| criterion.
                # (A_k's row 1 = [0, 1, 0], B_k[1] = b1, :func:`~.corner_discrete.kf_transition`)
                vr_prior = 0.0 * x[c, Z] + 1.0 * x[c, VR] + b1 * u
                lam_k = slip_ratio_estimate(radius * wk, vr_prior, min_speed)
                rel = count_release(hold, c, yk, mu_release, release_window)
                high = is_high_slip(lam_k, thr, wdh[c], hint[k, c], rel)
                scale = h / step_ref
                rk = r_high if high else r
                y_use = math.nan if math.isinf(rk) else yk  # R̄ = ∞: prediction only
                if use_ukf:
                    for i in range(NX):
                        qk[i] = (q_high[i] if high else q[i]) * scale
                    fill_transition(e, a01, a20, a21, b0, b1, b2, Ak, Bk)
                    _ukf_step(x, P, c, Ak, Bk, u, qk, rk, y_use, hrow, wm, wc, tau, pts, L, xp,
                              Pp)
                else:
                    q0, q1, q2 = (qh0, qh1, qh2) if high else (qn0, qn1, qn2)
                    _kf_step(x, P, c, e, a01, a20, a21, e, b0, b1, b2, u, q0 * scale,
                             q1 * scale, q2 * scale, rk, y_use, sigma0, sigma2, sigma1)
            out_vxt[k, c] = radius * wk - x[c, VR]
            out_sigma[k, c] = math.sqrt(max(P[c, VR, VR], 0.0))
            out_high[k, c] = high
            out_vr[k, c] = x[c, VR]
            out_z[k, c] = x[c, Z]
            out_zdot[k, c] = x[c, ZD]
            store(hold, c, tk, wk, delta[k, c], a_xt[k, c], a_yt[k, c], yk, math.nan,
                  yaw_rate[k])
