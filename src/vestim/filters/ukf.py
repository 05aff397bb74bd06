"""Unscented Kalman filter building blocks with the papers' sigma-point scaling.

000 Sec. II-B, 001 Sec. III-B and 004 Sec. II-A all use the same unscented
transform: N states, 2N + 1 sigma points x̂ and x̂ ± τ·(columns of √P) with
ε = √(3/N), η = ε²N − N, τ = √(N + η) (= √3 for every N), weights
W_i = 1/(2(N + η)) for i ≥ 1, W_0^m = η/(N + η), W_0^c = η/(N + η) + 1 − ε² + β
with β = 2. (The papers print W_i = ½(N + η); with τ² = N + η = 3 the
weights must be 1/(2(N + η)) = 1/6 to sum to one: the printed form is a
typesetting slip and this module uses the consistent one.)

The kernels are small Numba functions on contiguous arrays so that the
estimators can call them inside their compiled time loops (no Python per
sample). A sigma-point matrix has shape (2N + 1, N).
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np
from numba import njit

from vestim.filters.linalg import cholesky

_JIT: dict[str, Any] = {"cache": True, "error_model": "numpy"}

BETA = 2.0
"""Prior-distribution parameter β of the papers (Gaussian)."""


def ukf_weights(n: int, beta: float = BETA) -> tuple[np.ndarray, np.ndarray, float]:
    """Mean weights, covariance weights (each (2N + 1,)) and spread τ for N states.

    ε = √(3/N), η = ε²N − N, τ = √(N + η) (000 eq. (10)–(11) text; 004 Sec. II-A).
    """
    if n < 1:
        raise ValueError(f"state dimension n = {n} must be >= 1")
    eps2 = 3.0 / n
    eta = eps2 * n - n
    lam = n + eta
    wm = np.full(2 * n + 1, 1.0 / (2.0 * lam))
    wc = wm.copy()
    wm[0] = eta / lam
    wc[0] = eta / lam + 1.0 - eps2 + beta
    return wm, wc, math.sqrt(lam)


@njit(**_JIT)
def sigma_points(x: np.ndarray, P: np.ndarray, tau: float, L: np.ndarray, out: np.ndarray) -> None:
    """Fill ``out`` (2N + 1, N) with x̂, x̂ + τ L_j, x̂ − τ L_j, L the Cholesky factor of P.

    P must be symmetric (the filters symmetrise after each update); a pivot lost
    to round-off is floored by :func:`vestim.filters.linalg.cholesky`. ``L`` (N, N)
    is scratch space; nothing is allocated.
    """
    n = x.shape[0]
    cholesky(P, L)
    for j in range(n):
        out[0, j] = x[j]
    for i in range(n):
        for j in range(n):
            out[1 + i, j] = x[j] + tau * L[j, i]
            out[1 + n + i, j] = x[j] - tau * L[j, i]


@njit(**_JIT)
def weighted_mean(points: np.ndarray, wm: np.ndarray, out: np.ndarray) -> None:
    """out = Σ W_i^m points_i."""
    out[:] = 0.0
    for i in range(points.shape[0]):
        for j in range(points.shape[1]):
            out[j] += wm[i] * points[i, j]


@njit(**_JIT)
def weighted_cross(a: np.ndarray, am: np.ndarray, b: np.ndarray, bm: np.ndarray,
                   wc: np.ndarray, out: np.ndarray) -> None:
    """out = Σ W_i^c (a_i − ā)(b_i − b̄)ᵀ (000 eq. (11))."""
    out[:, :] = 0.0
    for i in range(a.shape[0]):
        for r in range(a.shape[1]):
            da = a[i, r] - am[r]
            for c in range(b.shape[1]):
                out[r, c] += wc[i] * da * (b[i, c] - bm[c])
