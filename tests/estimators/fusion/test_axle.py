"""Axle weightings: fixed η1 = η2 = 0.5 (000 Sec. III, 004 Sec. III) and adaptive
(001 eq. (34)–(35) longitudinal, (42)–(45) lateral).

Each test names the equation it checks and why its tolerance is what it is.
"""

import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from hypothesis.extra.numpy import arrays

from vestim.estimators.fusion import FusionParams, fuse
from vestim.estimators.fusion.axle import AxleWeightParams, adaptive_axle_weights, fuse_lateral_adaptive

A = AxleWeightParams()


def _w_low(lam_am: float, a: AxleWeightParams = A) -> float:
    """001 eq. (34) written out: W_i = W_s + (W̄_ub − W̄_lb)/π · atan(ρ (λ_am − λ_th))."""
    return a.w_s + (a.w_ub - a.w_lb) / math.pi * math.atan(a.rho * (lam_am - a.threshold))


def test_fixed_weights_are_axle_means():
    """000 / 004: V_x = η1 (v_fL + v_fR)/2 + η2 (v_rL + v_rR)/2; η1 = η2 = 0.5 gives 1/4 per
    corner; η1 = 0.7 gives 0.35 / 0.15 (exact in binary to rounding of one product)."""
    phi = np.array([[20.0, 21.0, 19.0, 18.0]])
    vx, w = fuse("axle", phi, np.zeros((1, 4)))
    np.testing.assert_array_equal(w, [[0.25, 0.25, 0.25, 0.25]])
    assert vx[0] == pytest.approx(19.5, rel=1e-15)
    vx, w = fuse("axle", phi, np.zeros((1, 4)), FusionParams(eta_front=0.7))
    np.testing.assert_allclose(w, [[0.35, 0.35, 0.15, 0.15]], rtol=1e-15)
    assert vx[0] == pytest.approx(0.7 * 20.5 + 0.3 * 18.5, rel=1e-15)


def test_adaptive_favours_the_less_slipping_axle():
    """001 eq. (34)–(35): rear axle Σ_r = |0.5| + |−0.5| = 1 ≥ Σ_f = 0.02, so λ_am = 1 and the
    front axle gets W_s + W̄ atan(50·0.9) = 0.8972, the rear 0.1028 (formula to rounding)."""
    phi = np.array([[20.0, 20.0, 25.0, 25.0]])
    slip = np.array([[0.01, -0.01, 0.5, -0.5]])
    vx, w = fuse("adaptive", phi, slip)
    wf = _w_low(1.0)
    assert wf == pytest.approx(0.8972, abs=1e-4)
    np.testing.assert_allclose(w, [[wf / 2, wf / 2, (1 - wf) / 2, (1 - wf) / 2]], rtol=1e-14)
    assert vx[0] == pytest.approx(wf * 20.0 + (1 - wf) * 25.0, rel=1e-14)
    # the mirror image swaps the roles of the axles
    _, w2 = fuse("adaptive", phi, slip[:, [2, 3, 0, 1]])
    np.testing.assert_allclose(w2, w[:, [2, 3, 0, 1]], rtol=1e-14)


def test_adaptive_near_equal_in_calm_driving_and_tie():
    """Below the threshold (λ_am = 0.03 < λ_th = 0.1) the less-slipping axle weighs
    W_s + W̄ atan(50(0.03 − 0.1)) = 0.535, close to the fixed 0.5; an exact tie (and NaN
    slip at standstill, counted as 0) gives 0.5 / 0.5."""
    w = adaptive_axle_weights(np.array([[0.01, 0.0, 0.02, 0.01], [0.02, 0.0, 0.01, 0.01],
                                        [np.nan, np.nan, np.nan, np.nan]]))
    assert w[0, 0] == pytest.approx(_w_low(0.03), rel=1e-14)
    assert w[0, 0] == pytest.approx(0.535, abs=1e-3)
    np.testing.assert_array_equal(w[1:], [[0.5, 0.5], [0.5, 0.5]])


@settings(max_examples=200, deadline=None)
@given(slip=arrays(float, (1, 4), elements=st.floats(-2.0, 2.0)))
def test_adaptive_weights_bounded_and_ordered(slip):
    """001 eq. (34): the weights are complementary, the less-slipping axle's weight lies in
    [W̄_lb, W̄_ub] = [0.5, 0.9], so it never weighs less than the other axle."""
    w = adaptive_axle_weights(slip)[0]
    assert w.sum() == pytest.approx(1.0, abs=1e-15)
    sf, sr = np.abs(slip[0, :2]).sum(), np.abs(slip[0, 2:]).sum()
    low = w[0] if sf <= sr else w[1]
    assert A.w_lb - 1e-15 <= low <= A.w_ub + 1e-15
    assert low >= 1.0 - low


def test_lateral_rigid_body_is_recovered_for_any_weights():
    """001 eq. (43): corners of a rigid body have v_y,ij = V_y + r x_i (x_f = L_f, x_r = −L_r);
    the axle values −r L_f + mean(front) and r L_r + mean(rear) both equal V_y, so the
    fused value is V_y whatever the slip-angle weights (to rounding)."""
    rng = np.random.default_rng(2)
    n, lf, lr = 200, 1.42, 1.43
    vy_cg = rng.normal(0.0, 1.0, n)
    r = rng.normal(0.0, 0.5, n)
    vy = np.column_stack([vy_cg + r * lf, vy_cg + r * lf, vy_cg - r * lr, vy_cg - r * lr])
    alpha = rng.normal(0.0, 0.1, (n, 4))
    out, w = fuse_lateral_adaptive(vy, r, lf, lr, alpha)
    np.testing.assert_allclose(out, vy_cg, atol=1e-14)
    np.testing.assert_allclose(w.sum(axis=1), 1.0, rtol=1e-15)
    assert np.any(np.abs(w[:, 0] - 0.5) > 0.1)  # the weights did vary


def test_axle_params_validation():
    with pytest.raises(ValueError, match="w_s"):
        AxleWeightParams(w_s=0.9)
    with pytest.raises(ValueError, match="w_lb"):
        AxleWeightParams(w_lb=0.95)
    with pytest.raises(ValueError, match="rho"):
        AxleWeightParams(rho=0.0)
