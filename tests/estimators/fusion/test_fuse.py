"""Conformance of fuse() for every method: shapes, convex weights, chunking invariance,
inputs untouched, missing samples, errors (issue 6 API contract)."""

import itertools

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from hypothesis.extra.numpy import arrays

from vestim.estimators.fusion import FUSION_METHODS, FusionParams, fuse


def _data(n: int, seed: int = 0) -> tuple[np.ndarray, np.ndarray]:
    rng = np.random.default_rng(seed)
    phi = 15.0 + rng.normal(0.0, 0.5, (n, 4))
    slip = rng.normal(0.0, 0.15, (n, 4))
    slip[::9, 2] = 0.9
    slip[::13] = np.nan
    return phi, slip


@pytest.mark.parametrize("method", FUSION_METHODS)
def test_batch_equals_per_sample_and_any_chunking(method):
    """Stateless per sample: one call on 997 rows, one call per row and uneven chunks give
    bit-identical results."""
    phi, slip = _data(997)
    vx, w = fuse(method, phi, slip)
    assert vx.shape == (997,) and w.shape == (997, 4)
    rows = [fuse(method, phi[i:i + 1], slip[i:i + 1]) for i in range(997)]
    np.testing.assert_array_equal(np.concatenate([r[0] for r in rows]), vx)
    np.testing.assert_array_equal(np.vstack([r[1] for r in rows]), w)
    cuts = [0, 1, 8, 300, 301, 997]
    parts = [fuse(method, phi[a:b], slip[a:b]) for a, b in itertools.pairwise(cuts)]
    np.testing.assert_array_equal(np.concatenate([p[0] for p in parts]), vx)


@pytest.mark.parametrize("method", FUSION_METHODS)
@settings(max_examples=100, deadline=None)
@given(phi=arrays(float, (3, 4), elements=st.floats(-60.0, 60.0)),
       slip=arrays(float, (3, 4), elements=st.floats(-3.0, 3.0) | st.just(np.nan)))
def test_weights_are_convex(method, phi, slip):
    """Every method returns non-negative weights summing to 1 (to rounding of four terms) and
    a fused value inside [min φ, max φ] (003 Proposition 1 for "opinion")."""
    vx, w = fuse(method, phi, slip)
    assert np.all(w >= 0.0)
    np.testing.assert_allclose(w.sum(axis=1), 1.0, atol=4e-15)
    np.testing.assert_allclose(vx, (w * phi).sum(axis=1), rtol=1e-15, atol=1e-13)
    assert np.all(vx >= phi.min(axis=1) - 1e-12) and np.all(vx <= phi.max(axis=1) + 1e-12)


@pytest.mark.parametrize("method", FUSION_METHODS)
def test_inputs_not_mutated_and_nan_slip_is_zero_slip(method):
    phi, slip = _data(50)
    phi0, slip0 = phi.copy(), slip.copy()
    vx, w = fuse(method, phi, slip)
    np.testing.assert_array_equal(phi, phi0)
    np.testing.assert_array_equal(slip, slip0)
    vx0, w0 = fuse(method, phi, np.nan_to_num(slip, nan=0.0))
    np.testing.assert_array_equal(vx, vx0)
    np.testing.assert_array_equal(w, w0)


@pytest.mark.parametrize("method", FUSION_METHODS)
def test_missing_opinion_drops_out(method):
    """A NaN corner velocity gets weight 0 and the others keep their ratios; a row with no
    finite corner gives NaN; empty input gives empty output."""
    phi, slip = _data(5)
    _, w_full = fuse(method, phi, slip)
    phi[1, 3] = np.nan
    phi[2, :] = np.nan
    vx, w = fuse(method, phi, slip)
    assert w[1, 3] == 0.0
    np.testing.assert_allclose(w[1, :3], w_full[1, :3] / w_full[1, :3].sum(), rtol=1e-14)
    assert vx[1] == pytest.approx((w[1, :3] * phi[1, :3]).sum(), rel=1e-14)
    assert np.isnan(vx[2]) and np.all(np.isnan(w[2]))
    assert np.all(np.isfinite(vx[[0, 3, 4]]))
    vx_e, w_e = fuse(method, np.empty((0, 4)), np.empty((0, 4)))
    assert vx_e.shape == (0,) and w_e.shape == (0, 4)


def test_rigid_body_opinions_are_returned_unchanged():
    """When all four opinions agree (a rigid body mapped to the CG, 003 eq. (5)), every method
    returns that value whatever the slips (weights sum to 1)."""
    phi = np.full((4, 4), 17.25)
    slip = np.array([[0.0, 0.3, 0.9, 1.5], [0.1] * 4, [np.nan] * 4, [-0.5, 0.0, 0.0, 0.2]])
    for method in FUSION_METHODS:
        vx, _ = fuse(method, phi, slip, FusionParams())
        np.testing.assert_allclose(vx, 17.25, rtol=1e-15)


def test_errors_name_the_problem():
    phi, slip = _data(3)
    with pytest.raises(ValueError, match="'kalman'"):
        fuse("kalman", phi, slip)
    with pytest.raises(ValueError, match="vx_corner_cg"):
        fuse("axle", phi[:, :3], slip[:, :3])
    with pytest.raises(ValueError, match="slip_ratio"):
        fuse("opinion", phi, slip[:2])
