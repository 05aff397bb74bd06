"""Importance weights, effective sample size and systematic resampling (002 Algorithm 1, lines 6–9)."""

from __future__ import annotations

import math
from typing import Any

import numpy as np
from numba import njit

_JIT: dict[str, Any] = {"cache": True, "error_model": "numpy"}


@njit(**_JIT)
def normalize_log_weights(logw: np.ndarray, out: np.ndarray) -> float:
    """Normalised weights q_i = exp(ℓ_i)/Σ exp(ℓ_j) into ``out`` (002 Algorithm 1, line 6).

    Uses the log-sum-exp shift so that likelihoods far below the float range do
    not all underflow. ``out`` may alias ``logw``. Non-finite entries get weight 0;
    if every entry is non-finite the weights are reset to uniform.

    Returns:
        log Σ exp(ℓ_j), the log normaliser (the log marginal likelihood increment
        when ``logw`` holds previous log weights plus log likelihoods).
    """
    n = logw.shape[0]
    top = -math.inf
    for i in range(n):
        if math.isfinite(logw[i]) and logw[i] > top:
            top = logw[i]
    if top == -math.inf:
        for i in range(n):
            out[i] = 1.0 / n
        return -math.inf
    s = 0.0
    for i in range(n):
        v = math.exp(logw[i] - top) if math.isfinite(logw[i]) else 0.0
        out[i] = v
        s += v
    for i in range(n):
        out[i] /= s
    return top + math.log(s)


@njit(**_JIT)
def effective_sample_size(q: np.ndarray) -> float:
    """N_eff = 1/Σ q_i² of normalised weights (002 Algorithm 1, line 7)."""
    s = 0.0
    for i in range(q.shape[0]):
        s += q[i] * q[i]
    return 1.0 / s


@njit(**_JIT)
def systematic_resample(q: np.ndarray, u: float, idx: np.ndarray) -> None:
    """Systematic resampling: ``idx`` ← ancestors of N offspring for normalised weights ``q``.

    Offspring j takes the ancestor i with Q_{i−1} ≤ (j + u)/N < Q_i, Q the
    cumulative weights and u ~ U[0, 1) one draw for all. Each ancestor gets
    ⌊N q_i⌋ or ⌈N q_i⌉ copies and E[copies] = N q_i, so the weighted mean of any
    particle function is preserved in expectation (Doucet & Johansen, 002 ref. [17]).
    """
    n = q.shape[0]
    m = idx.shape[0]
    i = 0
    cum = q[0]
    for j in range(m):
        pos = (j + u) / m
        while pos >= cum and i < n - 1:
            i += 1
            cum += q[i]
        idx[j] = i
