"""Weights, effective sample size, systematic resampling and the small Cholesky helpers."""

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from hypothesis.extra import numpy as hnp

from vestim.filters.linalg import chol_logdet, chol_solve, cholesky
from vestim.filters.resampling import effective_sample_size, normalize_log_weights, systematic_resample

_logw = hnp.arrays(np.float64, st.integers(1, 60), elements=st.floats(-1e4, 10.0))


@settings(max_examples=100, deadline=None)
@given(_logw)
def test_weights_are_normalised_softmax(logw):
    """002 Algorithm 1, line 6: q = exp(ℓ)/Σ exp(ℓ), summing to one even for ℓ ≈ −1e4 (no underflow)."""
    q = np.empty_like(logw)
    lse = normalize_log_weights(logw, q)
    assert q.sum() == pytest.approx(1.0, abs=1e-12)
    assert np.all(q >= 0)
    ref = np.exp(logw - logw.max())
    np.testing.assert_allclose(q, ref / ref.sum(), rtol=1e-12, atol=1e-300)
    assert lse == pytest.approx(logw.max() + np.log(np.exp(logw - logw.max()).sum()), rel=1e-12)


def test_weights_all_minus_infinity_reset_to_uniform():
    q = np.empty(4)
    assert normalize_log_weights(np.full(4, -np.inf), q) == -np.inf
    np.testing.assert_allclose(q, 0.25)


@settings(max_examples=100, deadline=None)
@given(_logw)
def test_ess_is_between_one_and_n(logw):
    """N_eff = 1/Σq² (line 7) lies in [1, N]; uniform weights give N."""
    q = np.empty_like(logw)
    normalize_log_weights(logw, q)
    ess = effective_sample_size(q)
    assert 1.0 - 1e-9 <= ess <= q.size + 1e-9
    assert effective_sample_size(np.full(7, 1 / 7)) == pytest.approx(7.0)


@settings(max_examples=80, deadline=None)
@given(_logw, st.floats(0.0, 1.0, exclude_max=True))
def test_systematic_counts_are_floor_or_ceil(logw, u):
    """Each ancestor gets ⌊N q_i⌋ or ⌈N q_i⌉ offspring (the defining property of systematic resampling)."""
    q = np.empty_like(logw)
    normalize_log_weights(logw, q)
    idx = np.empty(q.size, dtype=np.int64)
    systematic_resample(q, u, idx)
    assert np.all(np.diff(idx) >= 0)
    counts = np.bincount(idx, minlength=q.size)
    nq = q.size * q
    assert np.all(counts >= np.floor(nq - 1e-9)) and np.all(counts <= np.ceil(nq + 1e-9))


@settings(max_examples=40, deadline=None)
@given(hnp.arrays(np.float64, st.integers(2, 30), elements=st.floats(-20.0, 2.0)),
       hnp.arrays(np.float64, 30, elements=st.floats(-5.0, 5.0)))
def test_resampling_preserves_the_weighted_mean_in_expectation(logw, values):
    """E_u[mean of resampled values] = Σ q_i x_i: the average over a uniform grid of 2000
    offsets u equals the weighted mean to 1/2000 of the value range (the grid's quadrature error)."""
    x = values[: logw.size]
    q = np.empty_like(logw)
    normalize_log_weights(logw, q)
    idx = np.empty(q.size, dtype=np.int64)
    grid = (np.arange(2000) + 0.5) / 2000
    means = []
    for u in grid:
        systematic_resample(q, u, idx)
        means.append(x[idx].mean())
    spread = np.ptp(x) + 1e-12
    assert np.mean(means) == pytest.approx(float(q @ x), abs=spread / 2000 + 1e-12)


@st.composite
def _spd(draw):
    n = draw(st.integers(1, 4))
    a = draw(hnp.arrays(np.float64, (n, n), elements=st.floats(-10, 10)))
    return a @ a.T + draw(st.floats(1e-3, 10.0)) * np.eye(n)


@settings(max_examples=80, deadline=None)
@given(_spd())
def test_cholesky_and_solve_match_numpy(a):
    """The allocation-free helpers agree with LAPACK to round-off."""
    n = a.shape[0]
    low = np.empty_like(a)
    assert cholesky(a, low)
    np.testing.assert_allclose(low @ low.T, a, rtol=1e-10, atol=1e-10 * np.abs(a).max())
    b = np.arange(1.0, n + 1.0)
    x = np.empty(n)
    chol_solve(low, b, x)
    np.testing.assert_allclose(a @ x, b, rtol=1e-8, atol=1e-8 * np.abs(b).max())
    assert chol_logdet(low) == pytest.approx(np.linalg.slogdet(a)[1], abs=1e-9)


def test_cholesky_floors_a_semidefinite_pivot():
    a = np.array([[1.0, 1.0], [1.0, 1.0]])
    low = np.empty_like(a)
    assert not cholesky(a, low)
    assert np.all(np.isfinite(low)) and low[1, 1] > 0

