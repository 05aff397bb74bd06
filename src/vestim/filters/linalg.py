"""Small dense linear algebra for compiled filter loops (no allocation, no LAPACK call).

Matrices here are a few rows at most (3 × 3 in the stiffness filter), where a
plain loop beats a LAPACK call by an order of magnitude. Every function works
in place on caller-owned arrays so that a particle loop allocates nothing.
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np
from numba import njit

_JIT: dict[str, Any] = {"cache": True, "error_model": "numpy"}

JITTER = 1e-12
"""Relative diagonal jitter used when a Cholesky factorisation meets a non-positive pivot."""


@njit(**_JIT)
def cholesky(a: np.ndarray, out: np.ndarray) -> bool:
    """Lower Cholesky factor of a symmetric positive-definite ``a`` (n, n) into ``out``.

    Only the lower triangle of ``a`` is read; the strict upper triangle of ``out``
    is set to zero. A pivot that is not positive (round-off on a matrix that is
    semi-definite in exact arithmetic) is replaced by ``JITTER`` times the largest
    diagonal entry and ``False`` is returned, so callers may count such events.
    """
    n = a.shape[0]
    scale = 0.0
    for i in range(n):
        scale = max(scale, abs(a[i, i]))
    floor = JITTER * scale if scale > 0.0 else JITTER
    ok = True
    for j in range(n):
        s = a[j, j]
        for k in range(j):
            s -= out[j, k] * out[j, k]
        if not s > floor:
            s = floor
            ok = False
        ljj = math.sqrt(s)
        out[j, j] = ljj
        for i in range(j + 1, n):
            t = a[i, j]
            for k in range(j):
                t -= out[i, k] * out[j, k]
            out[i, j] = t / ljj
        for i in range(j):
            out[i, j] = 0.0
    return ok


@njit(**_JIT)
def forward_solve(low: np.ndarray, b: np.ndarray, out: np.ndarray) -> None:
    """Solve L x = b for lower-triangular L (n, n); ``out`` may alias ``b``."""
    n = low.shape[0]
    for i in range(n):
        s = b[i]
        for k in range(i):
            s -= low[i, k] * out[k]
        out[i] = s / low[i, i]


@njit(**_JIT)
def chol_solve(low: np.ndarray, b: np.ndarray, out: np.ndarray) -> None:
    """Solve (L Lᵀ) x = b given the lower Cholesky factor L; ``out`` may alias ``b``."""
    n = low.shape[0]
    forward_solve(low, b, out)
    for i in range(n - 1, -1, -1):
        s = out[i]
        for k in range(i + 1, n):
            s -= low[k, i] * out[k]
        out[i] = s / low[i, i]


@njit(**_JIT)
def chol_logdet(low: np.ndarray) -> float:
    """log |L Lᵀ| from the lower Cholesky factor."""
    s = 0.0
    for i in range(low.shape[0]):
        s += math.log(low[i, i])
    return 2.0 * s
