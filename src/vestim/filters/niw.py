"""Normal-inverse-Wishart statistics and multivariate Student-t algebra of 002 Sec. III-B, IV-B.

Parameterisation (002 Lemma 1): NiW(γ, μ̂, Λ, ν) is the hierarchical model
μ | Σ ~ N(μ̂, γ Σ) and Σ ~ iW(ν, Λ) ∝ |Σ|^(−(ν+d+1)/2) exp(−tr(Λ Σ⁻¹)/2), i.e.
SciPy's ``invwishart(df=ν, scale=Λ)``; γ is the reciprocal of the usual κ.
St(μ, Λ, ν) is the multivariate Student-t with location μ, *scale* matrix Λ
(covariance Λ ν/(ν−2)) and ν degrees of freedom, SciPy's ``multivariate_t``.

All functions are compiled and work in place on caller-owned arrays, one
particle at a time, so that the particle filter of
:mod:`vestim.estimators.stiffness.pf` can call them in its time loop without
allocating. Random numbers are drawn by the caller (from a
``numpy.random.Generator``) and passed in.
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np
from numba import njit

from vestim.filters.linalg import forward_solve

_JIT: dict[str, Any] = {"cache": True, "error_model": "numpy"}

LOG_PI = math.log(math.pi)


@njit(**_JIT)
def niw_predict(gamma: float, nu: float, lam: np.ndarray, forgetting: float) -> tuple[float, float]:
    """Time update with exponential forgetting, 002 eq. (20).

    γ_{k|k−1} = γ_{k−1|k−1}/λ, μ̂ unchanged, ν_{k|k−1} = λ ν_{k−1|k−1} and
    Λ_{k|k−1} = λ Λ_{k−1|k−1} (``lam`` is scaled in place). ``forgetting`` is λ ∈ (0, 1].

    Returns:
        (γ_{k|k−1}, ν_{k|k−1}).
    """
    n = lam.shape[0]
    for i in range(n):
        for j in range(n):
            lam[i, j] *= forgetting
    return gamma / forgetting, forgetting * nu


@njit(**_JIT)
def niw_update(gamma: float, nu: float, mu: np.ndarray, lam: np.ndarray,
               w: np.ndarray) -> tuple[float, float]:
    """Measurement update of the statistics with one realisation ``w``, 002 eq. (19).

    z = w − μ̂_{k|k−1} (19e); γ_{k|k} = γ/(1 + γ) (19a); μ̂_{k|k} = μ̂ + γ_{k|k} z (19b);
    ν_{k|k} = ν + 1 (19c); Λ_{k|k} = Λ + z zᵀ/(1 + γ) (19d). This is the conjugate
    Bayes update of Lemma 1 (Murphy's κ_n = κ + 1 with κ = 1/γ). ``mu`` and ``lam``
    are updated in place; ``gamma`` and ``nu`` are the predicted values.

    Returns:
        (γ_{k|k}, ν_{k|k}).
    """
    n = mu.shape[0]
    g_post = gamma / (1.0 + gamma)
    c = 1.0 / (1.0 + gamma)
    for i in range(n):
        zi = w[i] - mu[i]
        for j in range(i + 1):
            zj = w[j] - mu[j]
            v = lam[i, j] + c * zi * zj
            lam[i, j] = v
            lam[j, i] = v
    for i in range(n):
        mu[i] += g_post * (w[i] - mu[i])
    return g_post, nu + 1.0


@njit(**_JIT)
def niw_expected_cov(lam: np.ndarray, nu: float, out: np.ndarray) -> None:
    """Posterior mean of Σ under iW(ν, Λ): Λ/(ν − d − 1) (002 eq. (27b), ν − 4 for d = 3)."""
    n = lam.shape[0]
    c = 1.0 / (nu - n - 1.0)
    for i in range(n):
        for j in range(n):
            out[i, j] = c * lam[i, j]


@njit(**_JIT)
def niw_predictive_scale(gamma: float, nu: float, lam: np.ndarray, out: np.ndarray) -> float:
    """Predictive Student-t of one datum under the NiW prior, 002 eq. (21).

    ``out`` ← Λ̃ = (1 + γ)/(ν − d + 1) · Λ; the predictive is St(μ̂, Λ̃, ν − d + 1).

    Returns:
        The degrees of freedom ν − d + 1.
    """
    n = lam.shape[0]
    dof = nu - n + 1.0
    c = (1.0 + gamma) / dof
    for i in range(n):
        for j in range(n):
            out[i, j] = c * lam[i, j]
    return dof


@njit(**_JIT)
def moment_matched_scale(dmat: np.ndarray, lam: np.ndarray, gamma: float, dof: float,
                         noise_cov: np.ndarray, out: np.ndarray) -> None:
    """Scale of the moment-matched Student-t of the total measurement noise, 002 eq. (35).

    ē = d w + e with w ~ St(μ̂, (1 + γ)/ν̃ Λ, ν̃) (the predictive (21), ν̃ = ν − n_w + 1)
    and Gaussian e ~ N(0, R + P) (sensor noise plus the marginalised bias, P).
    Approximation 1 keeps ν̃ and matches the covariance:

        Λ̃_ē = (1 + γ)/ν̃ · d Λ dᵀ + (ν̃ − 2)/ν̃ · (R + P),

    so that Λ̃_ē ν̃/(ν̃ − 2) = d Cov(w) dᵀ + R + P exactly.

    Args:
        dmat: d_k, shape (n_e, n_w).
        lam: Λ_{k|k−1}, shape (n_w, n_w).
        gamma: γ_{k|k−1}.
        dof: ν̃ = ν_{k|k−1} − n_w + 1 (must exceed 2).
        noise_cov: R + P_{k|k−1}, shape (n_e, n_e).
        out: Λ̃_ē, shape (n_e, n_e).
    """
    ne, nw = dmat.shape
    c1 = (1.0 + gamma) / dof
    c2 = (dof - 2.0) / dof
    for i in range(ne):
        for j in range(i + 1):
            s = 0.0
            for a in range(nw):
                da = dmat[i, a]
                if da == 0.0:
                    continue
                t = 0.0
                for b in range(nw):
                    t += lam[a, b] * dmat[j, b]
                s += da * t
            v = c1 * s + c2 * noise_cov[i, j]
            out[i, j] = v
            out[j, i] = v


@njit(**_JIT)
def mvt_log_kernel(maha: float, logdet: float, dof: float, dim: int) -> float:
    """log St density up to the terms that depend on ν and d only.

    −½ log|Λ| − (ν + d)/2 · log(1 + m/ν) with m the squared Mahalanobis distance
    (zᵀ Λ⁻¹ z). Particle weights (002 eq. (36)) share ν, so the dropped constant
    cancels on normalisation.
    """
    return -0.5 * logdet - 0.5 * (dof + dim) * math.log1p(maha / dof)


@njit(**_JIT)
def mvt_log_norm(dof: float, dim: int) -> float:
    """The ν-, d-dependent normalising constant dropped by :func:`mvt_log_kernel`."""
    return (math.lgamma(0.5 * (dof + dim)) - math.lgamma(0.5 * dof)
            - 0.5 * dim * (math.log(dof) + LOG_PI))


@njit(**_JIT)
def t_condition(mu_w: np.ndarray, scale_w: np.ndarray, dmat: np.ndarray, low_e: np.ndarray,
                z: np.ndarray, dof: float, mu_out: np.ndarray, scale_out: np.ndarray,
                v_work: np.ndarray, u_work: np.ndarray) -> tuple[float, float]:
    """Condition the joint Student-t of (w, ē) on ē: Theorem 1, 002 eq. (39)–(41).

    Joint: St([μ_w; d μ_w], [[S_w, S_w dᵀ], [d S_w, Λ̃_ē]], ν̃) with S_w = (1 + γ)/ν̃ Λ
    (``scale_w``) and Λ̃_ē of eq. (35) (its Cholesky factor ``low_e``). With the
    innovation z = ē − d μ_w and m = zᵀ Λ̃_ē⁻¹ z, eq. (41) gives

        ν* = ν̃ + n_e,
        μ* = μ_w + S_w dᵀ Λ̃_ē⁻¹ z,
        Λ* = (ν̃ + m)/(ν̃ + n_e) · (S_w − S_w dᵀ Λ̃_ē⁻¹ d S_w).

    002 eq. (40) prints ν* = ν − n_e + 1, "d Λ" for the cross-covariance and the
    unscaled Λ in the bracket; those do not type-check (d Λ is n_e × n_w) or are
    inconsistent with Λ̃_ē containing the scaled (1 + γ)/ν̃ dΛdᵀ. We use the
    conditional of the joint that eq. (35)–(36) define, which the tests check
    against the density ratio p(w, ē)/p(ē) evaluated with SciPy.

    Args:
        mu_w: μ̂_{k|k−1}, (n_w,). scale_w: S_w, (n_w, n_w). dmat: d_k, (n_e, n_w).
        low_e: lower Cholesky factor of Λ̃_ē, (n_e, n_e). z: ē − d μ̂, (n_e,).
        dof: ν̃. mu_out, scale_out: μ* (n_w,), Λ* (n_w, n_w).
        v_work: (n_e, n_w) scratch; u_work: (n_e,) scratch.

    Returns:
        (ν*, m): conditional degrees of freedom and the Mahalanobis distance m,
        which also enters the likelihood (36).
    """
    ne, nw = dmat.shape
    # V = L⁻¹ d S_w  (n_e × n_w), u = L⁻¹ z: then S_w dᵀ Λ̃⁻¹ z = Vᵀu and S_w dᵀ Λ̃⁻¹ d S_w = VᵀV.
    for a in range(nw):
        for i in range(ne):
            s = 0.0
            for b in range(nw):
                s += dmat[i, b] * scale_w[b, a]
            u_work[i] = s
        forward_solve(low_e, u_work, u_work)
        for i in range(ne):
            v_work[i, a] = u_work[i]
    forward_solve(low_e, z, u_work)
    maha = 0.0
    for i in range(ne):
        maha += u_work[i] * u_work[i]
    for a in range(nw):
        s = 0.0
        for i in range(ne):
            s += v_work[i, a] * u_work[i]
        mu_out[a] = mu_w[a] + s
    c = (dof + maha) / (dof + ne)
    for a in range(nw):
        for b in range(a + 1):
            s = 0.0
            for i in range(ne):
                s += v_work[i, a] * v_work[i, b]
            v = c * (scale_w[a, b] - s)
            scale_out[a, b] = v
            scale_out[b, a] = v
    return dof + ne, maha


@njit(**_JIT)
def mvt_draw(mu: np.ndarray, low: np.ndarray, dof: float, normals: np.ndarray, chi2: float,
             out: np.ndarray) -> None:
    """One draw of St(μ, L Lᵀ, ν): μ + L n · √(ν/χ²) with n ~ N(0, I) and χ² ~ χ²_ν given."""
    n = mu.shape[0]
    s = math.sqrt(dof / chi2)
    for i in range(n):
        acc = 0.0
        for k in range(i + 1):
            acc += low[i, k] * normals[k]
        out[i] = mu[i] + s * acc
