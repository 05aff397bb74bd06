"""Opinion-dynamics fusion (003 eq. (5)–(13), Proposition 1, Algorithm 2).

Each test names the equation it checks and why its tolerance is what it is.
"""

import itertools

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from hypothesis.extra.numpy import arrays

from vestim.estimators.fusion import FusionParams, confidences, fuse
from vestim.estimators.fusion.opinion import (
    confidence_bounds,
    consensus_weights,
    eq6_confidence,
    laplacian_bar,
    solve_confidences,
    steady_state_opinions,
)

P = FusionParams()
CONF = st.floats(1e-3, 100.0)
SPEED = st.floats(-60.0, 60.0)


def test_laplacian_bar_is_eq9():
    """003 eq. (9): diagonal 3 + W_j, off-diagonal −1 (complete graph, unit edge weights)."""
    w = np.array([1.0, 2.0, 3.0, 4.0])
    expected = -np.ones((4, 4)) + np.diag(4.0 + w)
    np.testing.assert_array_equal(laplacian_bar(w), expected)
    assert np.diag(laplacian_bar(w)).tolist() == [4.0, 5.0, 6.0, 7.0]


@settings(max_examples=200, deadline=None)
@given(w=arrays(float, 4, elements=CONF), phi=arrays(float, 4, elements=SPEED))
def test_proposition1_steady_state_is_convex_combination(w, phi):
    """003 Proposition 1 / eq. (10): L̄⁻¹W is row stochastic with non-negative entries, so
    φ̄ = L̄⁻¹Wφ(0) lies in the convex hull of φ(0); the closed form (Sherman–Morrison)
    equals numpy's solve. Tolerances: L̄ has condition number ≤ (7 + 100)/λ_min ≤ ~1e5
    for W ≥ 1e-3, so solve is accurate to ~1e-11 relative; 1e-9 on the 60 m/s scale."""
    m = np.linalg.solve(laplacian_bar(w), np.diag(w))
    assert np.all(m >= -1e-12)
    np.testing.assert_allclose(m.sum(axis=1), 1.0, atol=1e-9)
    bar = steady_state_opinions(phi[None], w[None])[0]
    np.testing.assert_allclose(bar, m @ phi, atol=1e-9 * (1 + np.abs(phi).max()))
    assert np.all(bar >= phi.min() - 1e-9) and np.all(bar <= phi.max() + 1e-9)
    # the fused CG value is the mean of φ̄; its weights are the column means of L̄⁻¹W
    cw = consensus_weights(w[None])[0]
    np.testing.assert_allclose(cw, m.mean(axis=0), atol=1e-9)
    assert cw.sum() == pytest.approx(1.0, abs=1e-14)


def test_eq6_confidence_and_bounds():
    """003 eq. (6) W = k1(k2 − |λ|) with k1 = 25, k2 = 1 (003 Sec. IV); bounds are the
    band ±20 % around it, floored at 0.1; NaN slip counts as 0 (exact arithmetic here)."""
    slip = np.array([[0.0, -0.2, 0.5, np.nan], [1.0, 1.5, -0.04, 0.96]])
    np.testing.assert_allclose(eq6_confidence(slip, 25.0, 1.0),
                               [[25.0, 20.0, 12.5, 25.0], [0.0, -12.5, 24.0, 1.0]], rtol=1e-15)
    lo, hi = confidence_bounds(slip, 25.0, 1.0, 0.1, 0.2)
    np.testing.assert_allclose(lo, [[20.0, 16.0, 10.0, 20.0], [0.1, 0.1, 19.2, 0.8]], rtol=1e-15)
    np.testing.assert_allclose(hi, [[30.0, 24.0, 15.0, 30.0], [0.1, 0.1, 28.8, 1.2]], rtol=1e-15)


def test_equal_confidences_give_the_mean():
    """Equal slips → equal W → each weight c_j/Σc = 1/4: the opinion fusion is the plain mean
    (to rounding of four additions)."""
    phi = np.array([[20.0, 20.5, 19.0, 21.3], [5.0, 5.1, 4.9, 5.2]])
    slip = np.array([[0.05, -0.05, 0.05, 0.05], [0.0, 0.0, 0.0, 0.0]])
    vx, w = fuse("opinion", phi, slip)
    np.testing.assert_allclose(w, 0.25, rtol=1e-15)
    np.testing.assert_allclose(vx, phi.mean(axis=1), rtol=1e-15)


def test_heavily_slipping_corner_loses_weight():
    """Slip 0.9 at the rear-left: W_max = 1.2·25·0.1 = 3, the other corners' W_max = 30 are
    capped at γ − 4 = 25 (three of them above γ, eq. (13)). Weight of the slipping corner
    (3/7) / (3·25/29 + 3/7) = 0.1422 (closed form of the column means of L̄⁻¹W)."""
    phi = np.array([[20.0, 20.0, 26.0, 20.0]])
    slip = np.array([[0.0, 0.0, 0.9, 0.0]])
    vx, w = fuse("opinion", phi, slip)
    np.testing.assert_allclose(confidences(slip), [[25.0, 25.0, 3.0, 25.0]], rtol=1e-14)
    c_slip, c_ok = 3.0 / 7.0, 25.0 / 29.0
    assert w[0, 2] == pytest.approx(c_slip / (3 * c_ok + c_slip), rel=1e-14)
    assert w[0, 2] < 0.25 < w[0, 0]
    assert vx[0] == pytest.approx(20.0 + 6.0 * w[0, 2], rel=1e-14)
    # and the weight keeps falling with the slip (eq. (6) is decreasing in |λ|)
    ws = [fuse("opinion", phi, np.array([[0.0, 0.0, s, 0.0]]))[1][0, 2] for s in (0.2, 0.5, 0.8, 1.2)]
    assert all(a > b for a, b in itertools.pairwise(ws))


def test_lone_confident_corner_rises_above_the_cap():
    """eq. (13) with three corners at slip 0.9 (W_max = 3, d = 7) and one at 0 (W_max = 30):
    the confident corner may exceed γ while λ_max(L̄) = γ, up to
    c_s = γ + 1/(1 + 3/(γ − 7)) = 29 + 22/25, i.e. W = 25.88; λ_max is then exactly γ."""
    slip = np.array([[0.0, 0.9, 0.9, 0.9]])
    w = confidences(slip)
    np.testing.assert_allclose(w, [[25.88, 3.0, 3.0, 3.0]], rtol=1e-14)
    assert np.linalg.eigvalsh(laplacian_bar(w[0]))[-1] == pytest.approx(P.gamma, rel=1e-14)


def test_wmax_is_optimal_when_feasible():
    """λ_min(L̄) increases in every W_j, so with a loose γ the optimum of eq. (13) is W_max."""
    rng = np.random.default_rng(0)
    lo = rng.uniform(0.1, 10.0, (50, 4))
    hi = lo + rng.uniform(0.0, 10.0, (50, 4))
    w, feasible = solve_confidences(lo, hi, 4.0 + hi.max() + 1e-9)
    assert feasible.all()
    np.testing.assert_array_equal(w, hi)


def test_no_feasible_box_point_beats_the_exact_optimum():
    """Independent of any solver: of 4000 random points per box (half uniform, half within
    ~0.05 of the optimum), those with λ_max ≤ γ never reach a larger λ_min than the
    closed-form optimum (margin 1e-12: eigvalsh rounding on O(50) entries)."""
    rng = np.random.default_rng(11)
    for _ in range(100):
        gamma = rng.uniform(10.0, 40.0)
        hi = gamma - 4.0 + rng.uniform(-6.0, 6.0, 4)
        lo = np.maximum(0.01, np.minimum(hi - rng.uniform(0.0, 8.0, 4), gamma - 4.0 - 0.01))
        hi = np.maximum(hi, lo)
        w, feasible = solve_confidences(lo[None], hi[None], gamma)
        assert feasible[0]
        best = np.linalg.eigvalsh(laplacian_bar(w[0]))[0]
        uniform = lo + rng.uniform(0.0, 1.0, (2000, 4)) * (hi - lo)
        near = np.clip(w[0] + rng.normal(0.0, 0.05, (2000, 4)), lo, hi)  # local optimality
        pts = np.vstack([lo, uniform, near])
        ev = np.linalg.eigvalsh(laplacian_bar(pts))
        ok = ev[:, -1] <= gamma
        assert ok.any()
        assert ev[ok, 0].max() <= best + 1e-12


def test_infeasible_instances_are_flagged():
    """Two lower bounds above γ − 4 (at most one eigen-direction may exceed γ), or one more
    than 1 above: infeasible, W = W_min returned."""
    lo = np.array([[30.0, 30.0, 1.0, 1.0], [26.5, 1.0, 1.0, 1.0]])
    hi = lo + 1.0
    w, feasible = solve_confidences(lo, hi, 29.0)
    assert not feasible.any()
    np.testing.assert_array_equal(w, lo)


def test_solve_confidences_rejects_bad_bounds():
    with pytest.raises(ValueError, match="w_lo <= w_hi"):
        solve_confidences(np.array([[2.0, 1.0, 1.0, 1.0]]), np.ones((1, 4)), 29.0)
    with pytest.raises(ValueError, match="gamma"):
        solve_confidences(np.ones((1, 4)), np.ones((1, 4)), 3.0)
    with pytest.raises(ValueError, match=r"\(n, 4\)"):
        solve_confidences(np.ones((1, 3)), np.ones((1, 3)), 29.0)


def test_confidences_match_the_fusion_kernel():
    """confidences() (numpy bounds + batch solver) gives the W the fusion kernel uses: its
    consensus weights reproduce fuse()'s weights to rounding."""
    rng = np.random.default_rng(5)
    slip = rng.normal(0.0, 0.3, (500, 4))
    phi = 20.0 + rng.normal(0.0, 1.0, (500, 4))
    _, w = fuse("opinion", phi, slip)
    np.testing.assert_allclose(w, consensus_weights(confidences(slip)), rtol=1e-14)


def test_params_validation():
    with pytest.raises(ValueError, match="gamma"):
        FusionParams(gamma=20.0)
    with pytest.raises(ValueError, match="band"):
        FusionParams(band=1.0)
    with pytest.raises(ValueError, match="k1"):
        FusionParams(k1=-1.0)
    FusionParams(gamma=24.5)  # just above 4 + 0.8·25
