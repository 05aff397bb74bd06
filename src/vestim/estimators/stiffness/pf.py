"""Algorithm 1 of 002: noise-adaptive marginalised particle filter for stiffness and state.

Each particle i carries the vehicle state x^i, the NiW statistics (μ̂^i, Λ^i)
of the stiffness deviation w (002 eq. (19)–(20); γ and ν evolve identically
for all particles and are shared scalars), the mean b^i and covariance P^i of
its own bias Kalman filter (eq. (29)–(30)), the drawn deviation w^i and a log
weight. One step k of :func:`alg1_kernel`:

1. (Algorithm 1, lines 2–5) per particle: the moment-matched Student-t of the
   total measurement noise (eq. (35)) gives the weight update (eq. (36)); the
   joint t of (w, ē) conditioned on the innovation (Theorem 1, eq. (39)–(41))
   is the predictive of w_k, from which w_k^i is drawn; when the filter is
   active the statistics are updated with that draw (eq. (19)).
2. (lines 6–10) normalise, N_eff, systematic resampling when N_eff ≤ N_thr,
   copying states, statistics, biases and draws.
3. (lines 11–13) state estimate (eq. (42)), parameter estimate (eq. (26)–(27)).
4. (lines 14–20) per particle: bias update (eq. (30)), statistics prediction
   (eq. (20)), state prediction x_{k+1} = f + g w_k (eq. (9)), bias prediction (29).

Choices where the paper is silent or ambiguous (also in docs/methods_stiffness.md):

* Order. Algorithm 1 updates the statistics (line 4) before it draws w_k
  (line 17), but eq. (19e) needs the draw, and the text after Theorem 1 uses
  the same draw for eq. (19) and for the state prediction. We draw w_k^i from
  eq. (39) at line 4, use it for eq. (19) and keep it for line 18; resampling
  copies it with the statistics.
* Activation (Sec. V). On a step that is not active the statistics are
  frozen: neither eq. (19) nor the forgetting of eq. (20) is applied. Weights,
  draws, bias filter and state prediction run as usual.
* Projection (Sec. V). Draws w^i and means μ̂^i are clipped to the bounds
  [lo, hi] of the deviation after every draw and update.
* Model error (not in 002). Eq. (9) has no state noise besides w. On the
  double-track plant (load transfer, roll, Magic-Formula curvature, tire
  relaxation and carcass damping) the single-track model misses a_y by
  0.05–0.1 m/s² rms with spikes of ~1 m/s² at steering steps, and without
  state noise the particle cloud collapses (N_eff → 1) and the parameter
  statistics absorb the misfit. ``model_error`` adds white acceleration noise
  (m/s², m/s², rad/s², held over one step) to the state prediction; zero
  reproduces eq. (9) exactly.
* The χ²_ν* variable of the Student-t draw (w = μ* + L n √(ν*/χ²)) uses the
  Wilson–Hilferty approximation χ²_ν/ν ≈ (1 − 2/(9ν) + z √(2/(9ν)))³, z ~ N(0, 1),
  instead of a gamma variate (one normal instead of a rejection sampler). Its
  0.1–99.9 % quantiles are within 1.4 % of the exact ones at ν = 21 (ν* right
  after start, ν_0 = 20) and within 0.08 % at the steady ν* ≈ 100 (λ = 0.99).
* Settling (Sec. V activation). During the first ``settle_time`` of a log the
  state posterior is still converging from P_0; statistics and bias filter are
  frozen then (``settled`` = False), see :class:`~vestim.estimators.stiffness.config.StiffnessConfig`.
* Bias filter. Eq. (30) with the state uncertainty of the cloud added to S; see
  :func:`bias_update`.
* Structure used for speed. The gyro row of d is zero, and R, Q and P_0 have no
  accelerometer–gyro coupling, so every P^i stays block-diagonal (2 × 2
  accelerometer block, scalar gyro): Λ̃_ē of eq. (35) is block-diagonal and all
  inverses are 2 × 2. The joint t still has n_e = 3 (the gyro noise shares the
  t scale variable, so it enters the Mahalanobis distance and ν* = ν̃ + 3).
  Symmetric matrices are stored packed: Λ as [Λ00, Λ01, Λ02, Λ11, Λ12, Λ22], P as
  [P_xx, P_xy, P_yy, P_ψψ]. The algebra is that of :mod:`vestim.filters.niw` written out for this sparsity;
  ``tests/estimators/stiffness/test_pf.py`` checks one step against a
  composition of the generic functions.
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np
from numba import njit

from vestim.estimators.stiffness.model import (
    M_AX,
    M_AY,
    M_YAW_RATE,
    U_DELTA,
    U_DT,
    U_OMEGA_F,
    U_OMEGA_R,
    VX,
    VY,
    W_CX,
    W_CYF,
    W_CYR,
    YAW_RATE,
    terms,
)
from vestim.filters.resampling import effective_sample_size, normalize_log_weights, systematic_resample

_JIT: dict[str, Any] = {"cache": True, "error_model": "numpy"}

# Packed symmetric layouts.
L00, L01, L02, L11, L12, L22 = range(6)
"""Λ (3 × 3, w space) packed row-wise upper triangle."""
PXX, PXY, PYY, PRR = range(4)
"""P (bias covariance): accelerometer 2 × 2 block and the gyro variance."""
N_LAM = 6
N_PB = 4
N_TERMS = 14
"""Number of values returned by :func:`~vestim.estimators.stiffness.model.terms`."""

CHOL_FLOOR = 1e-12
"""Relative floor on a Cholesky pivot (round-off on a semi-definite scale matrix)."""


@njit(**_JIT)
def chol3(a00: float, a01: float, a02: float, a11: float, a12: float,
          a22: float) -> tuple[float, float, float, float, float, float]:
    """Lower Cholesky factor (l00, l10, l20, l11, l21, l22) of a symmetric 3 × 3 matrix.

    A pivot below ``CHOL_FLOOR`` times the largest diagonal entry is raised to it.
    """
    floor = CHOL_FLOOR * max(a00, a11, a22, 1e-300)
    l00 = math.sqrt(max(a00, floor))
    l10 = a01 / l00
    l20 = a02 / l00
    l11 = math.sqrt(max(a11 - l10 * l10, floor))
    l21 = (a12 - l20 * l10) / l11
    l22 = math.sqrt(max(a22 - l20 * l20 - l21 * l21, floor))
    return l00, l10, l20, l11, l21, l22


@njit(**_JIT)
def bias_update(b: np.ndarray, pb: np.ndarray, e0: float, e1: float, e2: float,
                s00: float, s01: float, s11: float, r: np.ndarray, x_unc: np.ndarray) -> None:
    """Kalman update of one particle's bias, 002 eq. (30), in place on ``b`` (3,) and ``pb`` (4,).

    Innovation (e0, e1, e2) = y − h − d μ̂_{k|k} − b_{k|k−1}; (s00, s01, s11) = d Σ̂ dᵀ
    (accelerometer block). S = P + R + d Σ̂ dᵀ + H P_x Hᵀ, K = P S⁻¹, b ← b + K e and
    P ← P − K S Kᵀ = P − P S⁻¹ P. ``r`` is R packed like ``pb``; ``x_unc`` is H P_x Hᵀ
    packed the same way.

    Two deviations from the printed eq. (30): 002 prints P − K S⁻¹ Kᵀ, which is not
    the Kalman covariance update (we use the standard form); and eq. (30) treats the
    particle's state as exact. While the particle cloud is still wide (after
    initialisation from P_0, or after a stiffness change) each particle's residual is
    dominated by its own state error, and with S = P + R + dΣ̂dᵀ the bias absorbs it
    (we saw a_y bias estimates of 1.4 m/s² against a 0.05 m/s² prior). Adding the
    posterior state covariance P_x of the cloud, mapped through H = ∂[a_x, a_y, ψ̇]/∂x
    at the weighted mean, keeps the bias filter out of the state transient and
    vanishes once the cloud has converged.
    """
    p00 = pb[PXX]
    p01 = pb[PXY]
    p11 = pb[PYY]
    prr = pb[PRR]
    a00 = p00 + r[PXX] + s00 + x_unc[PXX]
    a01 = p01 + r[PXY] + s01 + x_unc[PXY]
    a11 = p11 + r[PYY] + s11 + x_unc[PYY]
    det = a00 * a11 - a01 * a01
    i00 = a11 / det
    i01 = -a01 / det
    i11 = a00 / det
    # K = P S⁻¹ (2 × 2)
    k00 = p00 * i00 + p01 * i01
    k01 = p00 * i01 + p01 * i11
    k10 = p01 * i00 + p11 * i01
    k11 = p01 * i01 + p11 * i11
    b[M_AX] += k00 * e0 + k01 * e1
    b[M_AY] += k10 * e0 + k11 * e1
    # P − K P (= P − P S⁻¹ P, symmetric)
    pb[PXX] = p00 - (k00 * p00 + k01 * p01)
    pb[PXY] = p01 - (k00 * p01 + k01 * p11)
    pb[PYY] = p11 - (k10 * p01 + k11 * p11)
    srr = prr + r[PRR] + x_unc[PRR]
    krr = prr / srr
    b[M_YAW_RATE] += krr * e2
    pb[PRR] = prr - krr * prr


@njit(**_JIT)
def weighted_state_moments(q: np.ndarray, x: np.ndarray, mean: np.ndarray, var: np.ndarray) -> None:
    """Weighted mean and variance of each column of ``x`` (N, n) (002 eq. (42))."""
    n = x.shape[1]
    for a in range(n):
        s = 0.0
        for i in range(q.shape[0]):
            s += q[i] * x[i, a]
        mean[a] = s
        s2 = 0.0
        for i in range(q.shape[0]):
            e = x[i, a] - s
            s2 += q[i] * e * e
        var[a] = s2


@njit(**_JIT)
def state_uncertainty(q: np.ndarray, x: np.ndarray, x_mean: np.ndarray, delta: float,
                      sin_d: float, cos_d: float, om_f: float, om_r: float, ts: float,
                      p: np.ndarray, out: np.ndarray) -> None:
    """H P_x Hᵀ of the measurement [a_x, a_y, ψ̇], packed like P (see :func:`bias_update`).

    P_x is the weighted covariance of the particle states, H = ∂h/∂x at the weighted
    mean by central differences of :func:`~vestim.estimators.stiffness.model.terms`.
    """
    cov = np.zeros((3, 3))
    for i in range(q.shape[0]):
        for a in range(3):
            ea = x[i, a] - x_mean[a]
            for c in range(a + 1):
                cov[a, c] += q[i] * ea * (x[i, c] - x_mean[c])
    for a in range(3):
        for c in range(a):
            cov[c, a] = cov[a, c]
    hx = np.empty((2, 3))
    xp = np.empty(3)
    steps = (1e-3, 1e-4, 1e-5)
    for j in range(3):
        for sign in (1.0, -1.0):
            xp[0] = x_mean[0]
            xp[1] = x_mean[1]
            xp[2] = x_mean[2]
            xp[j] += sign * steps[j]
            tr = terms(xp[0], xp[1], xp[2], delta, sin_d, cos_d, om_f, om_r, ts, p)
            if sign > 0.0:
                hx[0, j] = tr[3]
                hx[1, j] = tr[4]
            else:
                hx[0, j] = (hx[0, j] - tr[3]) / (2.0 * steps[j])
                hx[1, j] = (hx[1, j] - tr[4]) / (2.0 * steps[j])
    s00 = 0.0
    s01 = 0.0
    s11 = 0.0
    for a in range(3):
        for c in range(3):
            s00 += hx[0, a] * cov[a, c] * hx[0, c]
            s01 += hx[0, a] * cov[a, c] * hx[1, c]
            s11 += hx[1, a] * cov[a, c] * hx[1, c]
    out[PXX] = s00
    out[PXY] = s01
    out[PYY] = s11
    out[PRR] = cov[YAW_RATE, YAW_RATE]


@njit(**_JIT)
def alg1_kernel(y: np.ndarray, u: np.ndarray, active: np.ndarray, bias_on: np.ndarray,
                p: np.ndarray,
                r_pk: np.ndarray, q_pk: np.ndarray, lo: np.ndarray, hi: np.ndarray,
                forgetting: float, n_thr: float, model_error: np.ndarray,
                x: np.ndarray, mu: np.ndarray, lam: np.ndarray, b: np.ndarray, pb: np.ndarray,
                w: np.ndarray, logw: np.ndarray, shared: np.ndarray, rng: np.random.Generator,
                x_hat: np.ndarray, x_var: np.ndarray, w_hat: np.ndarray, w_cov: np.ndarray,
                b_hat: np.ndarray, ess: np.ndarray) -> int:
    """Run Algorithm 1 of 002 over K steps; particle arrays are updated in place.

    Args:
        y: (K, 3) measurements [a_x, a_y, ψ̇] (m/s², m/s², rad/s; roll/pitch compensated).
        u: (K, 4) inputs [δ rad, ω_f rad/s, ω_r rad/s, T_s s]. active: (K,) bool (Sec. V).
        bias_on: (K,) bool; where False the bias filter is frozen (no eq. (29)–(30)).
        p: model parameters (``model.P_*``).
        r_pk, q_pk: R and Q of eq. (11)–(12), packed like ``pb`` (m²/s⁴, rad²/s²).
        lo, hi: (3,) bounds of the deviation w (projection, Sec. V).
        forgetting: λ of eq. (20). n_thr: N_thr of Algorithm 1, line 8 (particles).
        model_error: (3,) std of the acceleration noise added to the state prediction
            (m/s², m/s², rad/s²; see the module docstring), zeros for eq. (9) as printed.
        x: (N, 3) states x_k. mu: (N, 3), lam: (N, 6) statistics μ̂, Λ of S_{k|k−1}.
        b: (N, 3), pb: (N, 4) bias mean and covariance b_{k|k−1}, P_{k|k−1}.
        w: (N, 3) scratch for the draws w_k^i. logw: (N,) log weights.
        shared: [γ_{k|k−1}, ν_{k|k−1}], updated in place. rng: draws normals, χ², uniforms.
        x_hat, x_var: (K, 3) ← weighted mean and variance of x_k (eq. (42)).
        w_hat: (K, 3) ← μ̂_k (eq. (27a)). w_cov: (K, 3, 3) ← Σ̂_k (eq. (27b)).
        b_hat: (K, 3) ← weighted mean of b_{k|k}. ess: (K,) ← N_eff of line 7.

    Returns:
        The number of resampling events.
    """
    n_part = x.shape[0]
    q = np.empty(n_part)
    idx = np.empty(n_part, dtype=np.int64)
    x_new = np.empty_like(x)
    mu_new = np.empty_like(mu)
    lam_new = np.empty_like(lam)
    b_new = np.empty_like(b)
    pb_new = np.empty_like(pb)
    w_new = np.empty_like(w)
    x_unc = np.empty(N_PB)
    mt = np.empty((n_part, N_TERMS))
    mt_new = np.empty((n_part, N_TERMS))
    n_resampled = 0
    gamma = shared[0]
    nu = shared[1]
    me_vx = model_error[VX] > 0.0
    me_lat = model_error[VY] > 0.0 or model_error[YAW_RATE] > 0.0
    r00 = r_pk[PXX]
    r01 = r_pk[PXY]
    r11 = r_pk[PYY]
    rrr = r_pk[PRR]
    for k in range(y.shape[0]):
        delta = u[k, U_DELTA]
        sd = math.sin(delta)
        cd = math.cos(delta)
        om_f = u[k, U_OMEGA_F]
        om_r = u[k, U_OMEGA_R]
        ts = u[k, U_DT]
        y0 = y[k, M_AX]
        y1 = y[k, M_AY]
        y2 = y[k, M_YAW_RATE]
        act = active[k]
        dof = nu - 2.0              # ν̃ = ν − n_w + 1
        c1 = (1.0 + gamma) / dof    # scale of the w predictive (21); also S_w of the joint t
        c2 = (dof - 2.0) / dof      # moment matching of R + P (35)
        dof_c = dof + 3.0           # ν* = ν̃ + n_e (41)
        wh_a = 2.0 / (9.0 * dof_c)
        wh_b = math.sqrt(wh_a)
        g_post = gamma / (1.0 + gamma)
        c_upd = 1.0 / (1.0 + gamma)
        # ---- Algorithm 1, lines 2–5
        for i in range(n_part):
            vx = x[i, VX]
            vy = x[i, VY]
            r = x[i, YAW_RATE]
            tr = terms(vx, vy, r, delta, sd, cd, om_f, om_r, ts, p)
            (_, _, _, ax, ay, dxx, dxyf, dxyr, dyx, dyyf, dyyr, _, _, _) = tr
            for a in range(N_TERMS):
                mt[i, a] = tr[a]
            l00 = lam[i, L00]
            l01 = lam[i, L01]
            l02 = lam[i, L02]
            l11 = lam[i, L11]
            l12 = lam[i, L12]
            l22 = lam[i, L22]
            # rows of d Λ (accelerometer rows of d)
            a0 = dxx * l00 + dxyf * l01 + dxyr * l02
            a1 = dxx * l01 + dxyf * l11 + dxyr * l12
            a2 = dxx * l02 + dxyf * l12 + dxyr * l22
            b0 = dyx * l00 + dyyf * l01 + dyyr * l02
            b1 = dyx * l01 + dyyf * l11 + dyyr * l12
            b2 = dyx * l02 + dyyf * l12 + dyyr * l22
            # Λ̃_ē, eq. (35): c1 d Λ dᵀ + c2 (R + P)
            e00 = c1 * (a0 * dxx + a1 * dxyf + a2 * dxyr) + c2 * (r00 + pb[i, PXX])
            e01 = c1 * (a0 * dyx + a1 * dyyf + a2 * dyyr) + c2 * (r01 + pb[i, PXY])
            e11 = c1 * (b0 * dyx + b1 * dyyf + b2 * dyyr) + c2 * (r11 + pb[i, PYY])
            err = c2 * (rrr + pb[i, PRR])
            det = e00 * e11 - e01 * e01
            inv_det = 1.0 / det
            i00 = e11 * inv_det
            i01 = -e01 * inv_det
            i11 = e00 * inv_det
            m0 = mu[i, W_CX]
            m1 = mu[i, W_CYF]
            m2 = mu[i, W_CYR]
            # innovation z = ē − d μ̂ with ē = y − h − b (bias marginalised through P)
            z0 = y0 - ax - b[i, M_AX] - (dxx * m0 + dxyf * m1 + dxyr * m2)
            z1 = y1 - ay - b[i, M_AY] - (dyx * m0 + dyyf * m1 + dyyr * m2)
            z2 = y2 - r - b[i, M_YAW_RATE]
            v0 = i00 * z0 + i01 * z1
            v1 = i01 * z0 + i11 * z1
            maha = z0 * v0 + z1 * v1 + z2 * z2 / err
            # weight, eq. (36): St(z; 0, Λ̃_ē, ν̃) up to a factor common to all particles
            logw[i] += -0.5 * math.log(det * err) - 0.5 * (dof + 3.0) * math.log1p(maha / dof)
            # Theorem 1, eq. (40)–(41): S_w dᵀ = c1 (d Λ)ᵀ
            mc0 = m0 + c1 * (a0 * v0 + b0 * v1)
            mc1 = m1 + c1 * (a1 * v0 + b1 * v1)
            mc2 = m2 + c1 * (a2 * v0 + b2 * v1)
            # (d Λ)ᵀ Λ̃⁻¹ columns
            t00 = a0 * i00 + b0 * i01
            t01 = a0 * i01 + b0 * i11
            t10 = a1 * i00 + b1 * i01
            t11 = a1 * i01 + b1 * i11
            t20 = a2 * i00 + b2 * i01
            t21 = a2 * i01 + b2 * i11
            cc = (dof + maha) / (dof + 3.0) * c1
            s00 = cc * (l00 - c1 * (t00 * a0 + t01 * b0))
            s01 = cc * (l01 - c1 * (t00 * a1 + t01 * b1))
            s02 = cc * (l02 - c1 * (t00 * a2 + t01 * b2))
            s11 = cc * (l11 - c1 * (t10 * a1 + t11 * b1))
            s12 = cc * (l12 - c1 * (t10 * a2 + t11 * b2))
            s22 = cc * (l22 - c1 * (t20 * a2 + t21 * b2))
            c00, c10, c20, c11, c21, c22 = chol3(s00, s01, s02, s11, s12, s22)
            n0 = rng.standard_normal()
            n1 = rng.standard_normal()
            n2 = rng.standard_normal()
            # χ²_ν*/ν* by the Wilson–Hilferty cube of a normal (module docstring)
            wh = max(1.0 - wh_a + wh_b * rng.standard_normal(), 1e-3)
            sc = 1.0 / math.sqrt(wh * wh * wh)
            w0 = min(max(mc0 + sc * c00 * n0, lo[W_CX]), hi[W_CX])
            w1 = min(max(mc1 + sc * (c10 * n0 + c11 * n1), lo[W_CYF]), hi[W_CYF])
            w2 = min(max(mc2 + sc * (c20 * n0 + c21 * n1 + c22 * n2), lo[W_CYR]), hi[W_CYR])
            w[i, W_CX] = w0
            w[i, W_CYF] = w1
            w[i, W_CYR] = w2
            if act:
                # eq. (19) with z = w − μ̂_{k|k−1}
                z0 = w0 - m0
                z1 = w1 - m1
                z2 = w2 - m2
                lam[i, L00] = l00 + c_upd * z0 * z0
                lam[i, L01] = l01 + c_upd * z0 * z1
                lam[i, L02] = l02 + c_upd * z0 * z2
                lam[i, L11] = l11 + c_upd * z1 * z1
                lam[i, L12] = l12 + c_upd * z1 * z2
                lam[i, L22] = l22 + c_upd * z2 * z2
                mu[i, W_CX] = min(max(m0 + g_post * z0, lo[W_CX]), hi[W_CX])
                mu[i, W_CYF] = min(max(m1 + g_post * z1, lo[W_CYF]), hi[W_CYF])
                mu[i, W_CYR] = min(max(m2 + g_post * z2, lo[W_CYR]), hi[W_CYR])
        if act:
            gamma = g_post
            nu = nu + 1.0
        # ---- lines 6–10
        lse = normalize_log_weights(logw, q)
        neff = effective_sample_size(q)
        ess[k] = neff
        if neff <= n_thr:
            systematic_resample(q, rng.random(), idx)
            for i in range(n_part):
                j = idx[i]
                x_new[i] = x[j]
                mu_new[i] = mu[j]
                lam_new[i] = lam[j]
                b_new[i] = b[j]
                pb_new[i] = pb[j]
                w_new[i] = w[j]
                mt_new[i] = mt[j]
            mt[:] = mt_new
            x[:] = x_new
            mu[:] = mu_new
            lam[:] = lam_new
            b[:] = b_new
            pb[:] = pb_new
            w[:] = w_new
            q[:] = 1.0 / n_part
            logw[:] = -math.log(n_part)
            n_resampled += 1
        else:
            for i in range(n_part):
                logw[i] -= lse
        # ---- lines 11–13: eq. (42), (27)
        weighted_state_moments(q, x, x_hat[k], x_var[k])
        state_uncertainty(q, x, x_hat[k], delta, sd, cd, om_f, om_r, ts, p, x_unc)
        inv_c = 1.0 / (nu - 4.0)    # E[Σ] = Λ/(ν − n_w − 1)
        acc = np.zeros(12)
        for i in range(n_part):
            qi = q[i]
            m0 = mu[i, W_CX]
            m1 = mu[i, W_CYF]
            m2 = mu[i, W_CYR]
            acc[0] += qi * m0
            acc[1] += qi * m1
            acc[2] += qi * m2
            acc[3] += qi * (inv_c * lam[i, L00] + m0 * m0)
            acc[4] += qi * (inv_c * lam[i, L01] + m0 * m1)
            acc[5] += qi * (inv_c * lam[i, L02] + m0 * m2)
            acc[6] += qi * (inv_c * lam[i, L11] + m1 * m1)
            acc[7] += qi * (inv_c * lam[i, L12] + m1 * m2)
            acc[8] += qi * (inv_c * lam[i, L22] + m2 * m2)
        for a in range(3):
            w_hat[k, a] = acc[a]
        pos = 3
        for a in range(3):
            for c in range(a, 3):
                v = acc[pos] - acc[a] * acc[c]
                w_cov[k, a, c] = v
                w_cov[k, c, a] = v
                pos += 1
        # ---- lines 14–20: eq. (30), (20), (9), (29)
        b_hat[k, 0] = 0.0
        b_hat[k, 1] = 0.0
        b_hat[k, 2] = 0.0
        for i in range(n_part):
            vx = x[i, VX]
            vy = x[i, VY]
            r = x[i, YAW_RATE]
            f0 = mt[i, 0]
            f1 = mt[i, 1]
            f2 = mt[i, 2]
            ax = mt[i, 3]
            ay = mt[i, 4]
            dxx = mt[i, 5]
            dxyf = mt[i, 6]
            dxyr = mt[i, 7]
            dyx = mt[i, 8]
            dyyf = mt[i, 9]
            dyyr = mt[i, 10]
            grx = mt[i, 11]
            gryf = mt[i, 12]
            gryr = mt[i, 13]
            l00 = lam[i, L00]
            l01 = lam[i, L01]
            l02 = lam[i, L02]
            l11 = lam[i, L11]
            l12 = lam[i, L12]
            l22 = lam[i, L22]
            a0 = dxx * l00 + dxyf * l01 + dxyr * l02
            a1 = dxx * l01 + dxyf * l11 + dxyr * l12
            a2 = dxx * l02 + dxyf * l12 + dxyr * l22
            b0 = dyx * l00 + dyyf * l01 + dyyr * l02
            b1 = dyx * l01 + dyyf * l11 + dyyr * l12
            b2 = dyx * l02 + dyyf * l12 + dyyr * l22
            m0 = mu[i, W_CX]
            m1 = mu[i, W_CYF]
            m2 = mu[i, W_CYR]
            if bias_on[k]:
                bias_update(b[i], pb[i],
                            y0 - ax - (dxx * m0 + dxyf * m1 + dxyr * m2) - b[i, M_AX],
                            y1 - ay - (dyx * m0 + dyyf * m1 + dyyr * m2) - b[i, M_AY],
                            y2 - r - b[i, M_YAW_RATE],
                            inv_c * (a0 * dxx + a1 * dxyf + a2 * dxyr),
                            inv_c * (b0 * dxx + b1 * dxyf + b2 * dxyr),
                            inv_c * (b0 * dyx + b1 * dyyf + b2 * dyyr), r_pk, x_unc)
            qi = q[i]
            b_hat[k, 0] += qi * b[i, 0]
            b_hat[k, 1] += qi * b[i, 1]
            b_hat[k, 2] += qi * b[i, 2]
            if act:
                for a in range(N_LAM):
                    lam[i, a] *= forgetting
            w0 = w[i, W_CX]
            w1 = w[i, W_CYF]
            w2 = w[i, W_CYR]
            x[i, VX] = f0 + ts * (dxx * w0 + dxyf * w1 + dxyr * w2)
            x[i, VY] = f1 + ts * (dyx * w0 + dyyf * w1 + dyyr * w2)
            x[i, YAW_RATE] = f2 + grx * w0 + gryf * w1 + gryr * w2
            if me_vx:
                x[i, VX] += ts * model_error[VX] * rng.standard_normal()
            if me_lat:
                x[i, VY] += ts * model_error[VY] * rng.standard_normal()
                x[i, YAW_RATE] += ts * model_error[YAW_RATE] * rng.standard_normal()
            if bias_on[k]:
                for a in range(N_PB):
                    pb[i, a] += q_pk[a]
        if act:
            gamma = gamma / forgetting
            nu = forgetting * nu
    shared[0] = gamma
    shared[1] = nu
    return n_resampled
