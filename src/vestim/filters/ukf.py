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

from vestim.filters.linalg import JITTER, cholesky

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
def _pivot_floor(scale: float) -> float:
    """The Cholesky pivot floor of :func:`vestim.filters.linalg.cholesky` for the largest
    |diagonal| ``scale`` of P."""
    return JITTER * scale if scale > 0.0 else JITTER


@njit(**_JIT)
def _root(s: float, floor: float) -> float:
    """√ of the pivot ``s``, floored as :func:`vestim.filters.linalg.cholesky` floors it (a
    pivot not above ``floor``, NaN included, becomes ``floor``)."""
    if not s > floor:
        s = floor
    return math.sqrt(s)


@njit(**_JIT)
def sigma_points2(x0: float, x1: float, p00: float, p10: float, p11: float, tau: float,
                  out: np.ndarray) -> None:
    """:func:`sigma_points` for N = 2 written out, as :func:`sigma_points3` (the same
    numbers bit for bit). ``out`` (5, 2)."""
    scale = max(max(0.0, abs(p00)), abs(p11))
    floor = _pivot_floor(scale)
    l00 = _root(p00, floor)
    l10 = p10 / l00
    l11 = _root(p11 - l10 * l10, floor)
    a00, a10, a11 = tau * l00, tau * l10, tau * l11
    zero = tau * 0.0
    out[0, 0], out[0, 1] = x0, x1
    out[1, 0], out[1, 1] = x0 + a00, x1 + a10
    out[2, 0], out[2, 1] = x0 + zero, x1 + a11
    out[3, 0], out[3, 1] = x0 - a00, x1 - a10
    out[4, 0], out[4, 1] = x0 - zero, x1 - a11


@njit(**_JIT)
def sigma_points3(x0: float, x1: float, x2: float, p00: float, p10: float, p11: float,
                  p20: float, p21: float, p22: float, tau: float, out: np.ndarray) -> None:
    """:func:`sigma_points` for N = 3 from the state's components and P's lower triangle,
    written out: the same operations in the same order (so the same numbers, bit for bit:
    the Cholesky factor of :func:`vestim.filters.linalg.cholesky` with its pivot floor, the
    zero entries of L added as +0.0), without the loops over a run-time size or the views of
    a state array. ``out`` (7, 3)."""
    scale = max(max(max(0.0, abs(p00)), abs(p11)), abs(p22))
    floor = _pivot_floor(scale)
    l00 = _root(p00, floor)
    l10 = p10 / l00
    l20 = p20 / l00
    l11 = _root(p11 - l10 * l10, floor)
    l21 = (p21 - l20 * l10) / l11
    l22 = _root(p22 - l20 * l20 - l21 * l21, floor)
    a00, a10, a20 = tau * l00, tau * l10, tau * l20
    a11, a21, a22 = tau * l11, tau * l21, tau * l22
    zero = tau * 0.0
    out[0, 0], out[0, 1], out[0, 2] = x0, x1, x2
    out[1, 0], out[1, 1], out[1, 2] = x0 + a00, x1 + a10, x2 + a20
    out[2, 0], out[2, 1], out[2, 2] = x0 + zero, x1 + a11, x2 + a21
    out[3, 0], out[3, 1], out[3, 2] = x0 + zero, x1 + zero, x2 + a22
    out[4, 0], out[4, 1], out[4, 2] = x0 - a00, x1 - a10, x2 - a20
    out[5, 0], out[5, 1], out[5, 2] = x0 - zero, x1 - a11, x2 - a21
    out[6, 0], out[6, 1], out[6, 2] = x0 - zero, x1 - zero, x2 - a22


@njit(**_JIT)
def sigma_points4(x: np.ndarray, P: np.ndarray, tau: float, out: np.ndarray) -> None:
    """:func:`sigma_points` for N = 4 written out, as :func:`sigma_points3`: the same numbers
    bit for bit from x (4,) and P's lower triangle (4, 4), without a factor array or loops
    over a run-time size. ``out`` (9, 4)."""
    p00, p11, p22, p33 = P[0, 0], P[1, 1], P[2, 2], P[3, 3]
    scale = max(max(max(max(0.0, abs(p00)), abs(p11)), abs(p22)), abs(p33))
    floor = _pivot_floor(scale)
    l00 = _root(p00, floor)
    l10 = P[1, 0] / l00
    l20 = P[2, 0] / l00
    l30 = P[3, 0] / l00
    l11 = _root(p11 - l10 * l10, floor)
    l21 = (P[2, 1] - l20 * l10) / l11
    l31 = (P[3, 1] - l30 * l10) / l11
    l22 = _root(p22 - l20 * l20 - l21 * l21, floor)
    l32 = (P[3, 2] - l30 * l20 - l31 * l21) / l22
    l33 = _root(p33 - l30 * l30 - l31 * l31 - l32 * l32, floor)
    x0, x1, x2, x3 = x[0], x[1], x[2], x[3]
    a00, a10, a20, a30 = tau * l00, tau * l10, tau * l20, tau * l30
    a11, a21, a31 = tau * l11, tau * l21, tau * l31
    a22, a32, a33 = tau * l22, tau * l32, tau * l33
    zero = tau * 0.0
    out[0, 0], out[0, 1], out[0, 2], out[0, 3] = x0, x1, x2, x3
    out[1, 0], out[1, 1], out[1, 2], out[1, 3] = x0 + a00, x1 + a10, x2 + a20, x3 + a30
    out[2, 0], out[2, 1], out[2, 2], out[2, 3] = x0 + zero, x1 + a11, x2 + a21, x3 + a31
    out[3, 0], out[3, 1], out[3, 2], out[3, 3] = x0 + zero, x1 + zero, x2 + a22, x3 + a32
    out[4, 0], out[4, 1], out[4, 2], out[4, 3] = x0 + zero, x1 + zero, x2 + zero, x3 + a33
    out[5, 0], out[5, 1], out[5, 2], out[5, 3] = x0 - a00, x1 - a10, x2 - a20, x3 - a30
    out[6, 0], out[6, 1], out[6, 2], out[6, 3] = x0 - zero, x1 - a11, x2 - a21, x3 - a31
    out[7, 0], out[7, 1], out[7, 2], out[7, 3] = x0 - zero, x1 - zero, x2 - a22, x3 - a32
    out[8, 0], out[8, 1], out[8, 2], out[8, 3] = x0 - zero, x1 - zero, x2 - zero, x3 - a33


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
