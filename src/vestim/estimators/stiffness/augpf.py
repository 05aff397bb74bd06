"""State-augmented particle filter (AUGPF), the baseline of 002 Sec. VI-A.

Each particle carries the vehicle state x (3), the mean m (3) and the variance s
(3, diagonal) of the stiffness deviation w, i.e. x ∈ R⁹ as in 002, plus the same
per-particle bias Kalman filter as Algorithm 1 so that both filters see the same
measurement model. Artificial dynamics (002 Sec. VI-A):

* m_{k+1} = m_k + N(0, diag(σ_m²)), σ_m a fraction of the nominal stiffness;
* s_{k+1} | s_k ~ iW(α, β) per component (an inverse-gamma in 1-D) with mean s_k
  and relative one-sigma ρ: α = 2 + 1/ρ², β = s_k (α − 1).

Per step (SIR with the prior as proposal): weight by
y_k ~ N(h + d m + b, R + P + d diag(s) dᵀ), i.e. with w_k and the bias marginalised
given the particle's (m, s); resample when N_eff ≤ N_thr; estimates (weighted
means; the stiffness covariance is the analogue of eq. (27b),
Σ q (diag(s) + (m − m̂)(m − m̂)ᵀ)); bias update as eq. (30) with (m, diag(s)) in
place of (μ̂, Σ̂); then draw w_k ~ N(m, diag(s)) and predict x_{k+1} = f + g w_k
(+ the same model-error noise as Algorithm 1) and the artificial dynamics.
Projection to [lo, hi] as in Algorithm 1. Unlike Algorithm 1 the draw of w_k does
not see y_k: the dependence of process and measurement noise (002 eq. (13)) is
ignored, which is the point of the comparison. (Weighting with a sampled w_k and
covariance R, the textbook bootstrap, collapsed to N_eff ≈ 1 and diverged in every
run at 200 Hz: a 5 % stiffness draw moves a_y by 0.12 m/s², 2.5 σ of the sensor.)
"""

from __future__ import annotations

import math
from typing import Any, NamedTuple

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
from vestim.estimators.stiffness.pf import (
    PRR,
    PXX,
    PXY,
    PYY,
    Estimates,
    SeriesInputs,
    bias_update,
    state_uncertainty,
    weighted_state_moments,
)
from vestim.filters.resampling import effective_sample_size, normalize_log_weights, systematic_resample

_JIT: dict[str, Any] = {"cache": True, "error_model": "numpy"}


class AugPFParams(NamedTuple):
    """What :func:`augpf_kernel` holds fixed over a run (packed by
    :meth:`~vestim.estimators.stiffness.estimator.AugmentedPF.kernel_params`).

    Attributes:
        p, r_pk, q_pk, lo, hi, n_thr, model_error: as in
            :class:`~vestim.estimators.stiffness.pf.PFParams`.
        mean_walk: (3,) one-sigma of the random walk of m per step (N per unit slip, N/rad, N/rad).
        var_shape: α of the inverse-gamma step of s (≥ 2; mean-preserving).
    """

    p: np.ndarray
    r_pk: np.ndarray
    q_pk: np.ndarray
    lo: np.ndarray
    hi: np.ndarray
    mean_walk: np.ndarray
    var_shape: float
    n_thr: float
    model_error: np.ndarray


class AugPFState(NamedTuple):
    """What :func:`augpf_kernel` advances in place, one row per particle.

    Attributes:
        x: (N, 3) states [v_x, v_y, ψ̇] (m/s, m/s, rad/s).
        m, s: (N, 3) means and variances of w (N per unit slip, N/rad, N/rad and squares).
        b: (N, 3) bias means (m/s², m/s², rad/s). pb: (N, 4) bias covariances, packed like
            P (``pf.PXX`` …). logw: (N,) log weights.
    """

    x: np.ndarray
    m: np.ndarray
    s: np.ndarray
    b: np.ndarray
    pb: np.ndarray
    logw: np.ndarray


@njit(**_JIT)
def augpf_kernel(prm: AugPFParams, st: AugPFState, inp: SeriesInputs, rng: np.random.Generator,
                 out: Estimates) -> int:
    """Run the AUGPF over the K steps of ``inp`` (``inp.active`` is not read); ``st`` is
    updated in place.

    Args:
        prm: the run's parameters (:class:`AugPFParams`).
        st: the particles (:class:`AugPFState`).
        inp: y, u, bias_on as in :func:`~vestim.estimators.stiffness.pf.alg1_kernel`.
        rng: draws every random number.
        out: ← the estimates of each step, as in Algorithm 1.

    Returns:
        The number of resampling events.
    """
    y, u, bias_on = inp.y, inp.u, inp.bias_on
    p, r_pk, q_pk, lo, hi = prm.p, prm.r_pk, prm.q_pk, prm.lo, prm.hi
    mean_walk, var_shape, n_thr, model_error = prm.mean_walk, prm.var_shape, prm.n_thr, prm.model_error
    x, m, s, b, pb, logw = st.x, st.m, st.s, st.b, st.pb, st.logw
    x_hat, x_var, w_hat, w_cov, b_hat, ess = out.x_hat, out.x_var, out.w_hat, out.w_cov, out.b_hat, out.ess
    n_part = x.shape[0]
    q = np.empty(n_part)
    idx = np.empty(n_part, dtype=np.int64)
    x_new = np.empty_like(x)
    m_new = np.empty_like(m)
    s_new = np.empty_like(s)
    b_new = np.empty_like(b)
    pb_new = np.empty_like(pb)
    x_unc = np.empty(4)
    n_resampled = 0
    has_model_error = model_error[VX] > 0.0 or model_error[VY] > 0.0 or model_error[YAW_RATE] > 0.0
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
        for i in range(n_part):
            (_, _, _, ax, ay, dxx, dxyf, dxyr, dyx, dyyf, dyyr, _, _, _) = terms(
                x[i, VX], x[i, VY], x[i, YAW_RATE], delta, sd, cd, om_f, om_r, ts, p)
            m0 = m[i, W_CX]
            m1 = m[i, W_CYF]
            m2 = m[i, W_CYR]
            s0 = s[i, W_CX]
            s1 = s[i, W_CYF]
            s2 = s[i, W_CYR]
            # y_k ~ N(h + d m + b, R + P + d diag(s) dᵀ): w marginalised given (m, s)
            z0 = y0 - ax - b[i, M_AX] - (dxx * m0 + dxyf * m1 + dxyr * m2)
            z1 = y1 - ay - b[i, M_AY] - (dyx * m0 + dyyf * m1 + dyyr * m2)
            z2 = y2 - x[i, YAW_RATE] - b[i, M_YAW_RATE]
            e00 = r_pk[PXX] + pb[i, PXX] + dxx * dxx * s0 + dxyf * dxyf * s1 + dxyr * dxyr * s2
            e01 = r_pk[PXY] + pb[i, PXY] + dxx * dyx * s0 + dxyf * dyyf * s1 + dxyr * dyyr * s2
            e11 = r_pk[PYY] + pb[i, PYY] + dyx * dyx * s0 + dyyf * dyyf * s1 + dyyr * dyyr * s2
            err = r_pk[PRR] + pb[i, PRR]
            det = e00 * e11 - e01 * e01
            maha = (e11 * z0 * z0 - 2.0 * e01 * z0 * z1 + e00 * z1 * z1) / det + z2 * z2 / err
            logw[i] += -0.5 * math.log(det * err) - 0.5 * maha
        lse = normalize_log_weights(logw, q)
        neff = effective_sample_size(q)
        ess[k] = neff
        if neff <= n_thr:
            systematic_resample(q, rng.random(), idx)
            for i in range(n_part):
                j = idx[i]
                x_new[i] = x[j]
                m_new[i] = m[j]
                s_new[i] = s[j]
                b_new[i] = b[j]
                pb_new[i] = pb[j]
            x[:] = x_new
            m[:] = m_new
            s[:] = s_new
            b[:] = b_new
            pb[:] = pb_new
            q[:] = 1.0 / n_part
            logw[:] = -math.log(n_part)
            n_resampled += 1
        else:
            for i in range(n_part):
                logw[i] -= lse
        weighted_state_moments(q, x, x_hat[k], x_var[k])
        state_uncertainty(q, x, x_hat[k], delta, sd, cd, om_f, om_r, ts, p, x_unc)
        for a in range(3):
            acc = 0.0
            for i in range(n_part):
                acc += q[i] * m[i, a]
            w_hat[k, a] = acc
        for a in range(3):
            for c in range(3):
                acc = 0.0
                for i in range(n_part):
                    v = (m[i, a] - w_hat[k, a]) * (m[i, c] - w_hat[k, c])
                    if a == c:
                        v += s[i, a]
                    acc += q[i] * v
                w_cov[k, a, c] = acc
        b_hat[k, 0] = 0.0
        b_hat[k, 1] = 0.0
        b_hat[k, 2] = 0.0
        for i in range(n_part):
            (f0, f1, f2, ax, ay, dxx, dxyf, dxyr, dyx, dyyf, dyyr, grx, gryf, gryr) = terms(
                x[i, VX], x[i, VY], x[i, YAW_RATE], delta, sd, cd, om_f, om_r, ts, p)
            m0 = m[i, W_CX]
            m1 = m[i, W_CYF]
            m2 = m[i, W_CYR]
            if bias_on[k]:
                s0 = s[i, W_CX]
                s1 = s[i, W_CYF]
                s2 = s[i, W_CYR]
                bias_update(b[i], pb[i],
                            y0 - ax - (dxx * m0 + dxyf * m1 + dxyr * m2) - b[i, M_AX],
                            y1 - ay - (dyx * m0 + dyyf * m1 + dyyr * m2) - b[i, M_AY],
                            y2 - x[i, YAW_RATE] - b[i, M_YAW_RATE],
                            dxx * dxx * s0 + dxyf * dxyf * s1 + dxyr * dxyr * s2,
                            dxx * dyx * s0 + dxyf * dyyf * s1 + dxyr * dyyr * s2,
                            dyx * dyx * s0 + dyyf * dyyf * s1 + dyyr * dyyr * s2, r_pk, x_unc)
                for a in range(4):
                    pb[i, a] += q_pk[a]
            # bootstrap draw of the process noise for the state prediction
            w0 = min(max(m0 + math.sqrt(s[i, W_CX]) * rng.standard_normal(), lo[0]), hi[0])
            w1 = min(max(m1 + math.sqrt(s[i, W_CYF]) * rng.standard_normal(), lo[1]), hi[1])
            w2 = min(max(m2 + math.sqrt(s[i, W_CYR]) * rng.standard_normal(), lo[2]), hi[2])
            b_hat[k, 0] += q[i] * b[i, 0]
            b_hat[k, 1] += q[i] * b[i, 1]
            b_hat[k, 2] += q[i] * b[i, 2]
            x[i, VX] = f0 + ts * (dxx * w0 + dxyf * w1 + dxyr * w2)
            x[i, VY] = f1 + ts * (dyx * w0 + dyyf * w1 + dyyr * w2)
            x[i, YAW_RATE] = f2 + grx * w0 + gryf * w1 + gryr * w2
            if has_model_error:
                x[i, VX] += ts * model_error[VX] * rng.standard_normal()
                x[i, VY] += ts * model_error[VY] * rng.standard_normal()
                x[i, YAW_RATE] += ts * model_error[YAW_RATE] * rng.standard_normal()
            for a in range(3):
                m[i, a] = min(max(m[i, a] + mean_walk[a] * rng.standard_normal(), lo[a]), hi[a])
                # inverse-gamma step with mean s: s' = β/G, G ~ Gamma(α), β = s (α − 1)
                s[i, a] = s[i, a] * (var_shape - 1.0) / rng.standard_gamma(var_shape)
    return n_resampled
