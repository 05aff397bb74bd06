"""LPV corner models (vestim.models.lpv) against the LuGre equations and the papers' forms.

References: the nonlinear average lumped LuGre model of 004 eq. (6)–(8)
(``vestim.models.tire.lugre_zdot``), 001 eq. (22)–(26), (36)–(39), 004 eq. (12)–(16),
(20) and 000 eq. (19).
"""

from __future__ import annotations

import numpy as np
import pytest

from vestim.io.vehicle import load_vehicle
from vestim.models import lpv
from vestim.models.tire import lugre_zdot

VEH = load_vehicle("hashemi_suv")
AX = lpv.longitudinal_axis(VEH)
AY = lpv.lateral_axis(VEH)
T = VEH.tire
OMEGAS = np.array([0.0, 3.0, 45.0, 120.0, 180.0])


def _lugre_x(z: float, vr: float, omega: float, theta: float) -> tuple[float, float]:
    """(ż, μ) of the nonlinear LuGre model, pure longitudinal slip (004 eq. (6)–(7))."""
    dz, _ = lugre_zdot(z, 0.0, vr, 0.0, VEH.body.wheel_radius * abs(omega), theta,
                       T.sigma0_x, T.sigma0_y, T.kappa_x, T.kappa_y, T.mu_s, T.mu_c, T.v_s,
                       T.alpha)
    return dz, T.sigma0_x * z + T.sigma1_x * dz + T.sigma2_x * vr


def _jacobian(z: float, vr: float, omega: float, theta: float, h: float = 1e-7) -> np.ndarray:
    """Central finite differences of (ż, μ) w.r.t. (z, v_r): rows ż, μ."""
    jac = np.empty((2, 2))
    for j, (dz, dv) in enumerate(((h, 0.0), (0.0, h))):
        fp = np.array(_lugre_x(z + dz, vr + dv, omega, theta))
        fm = np.array(_lugre_x(z - dz, vr - dv, omega, theta))
        jac[:, j] = (fp - fm) / (2 * h)
    return jac


@pytest.mark.parametrize("omega", OMEGAS)
@pytest.mark.parametrize("theta", [0.1, 1.0])
def test_matrices_equal_linearisation_of_lugre_at_zero_slip(omega: float, theta: float) -> None:
    # At z = 0, v_r = 0 the friction term σ0|v_r|z/(θg) is second order, so the Jacobian of
    # the full LuGre model equals A(ω) (ż row) and C(ω) (μ row) for any road θ (001 eq. (20)-(23)).
    # Central differences of a quadratic-at-worst term are exact up to rounding: 1e-6 relative.
    jac = _jacobian(0.0, 0.0, omega, theta)
    a = lpv.state_matrix(omega, AX)
    c = lpv.output_matrix(omega, AX)
    np.testing.assert_allclose(jac[0], a[0], rtol=1e-6, atol=1e-6)
    np.testing.assert_allclose(jac[1], c[0], rtol=1e-6, atol=1e-4)


def test_matrices_equal_linearisation_without_friction_term_anywhere() -> None:
    # With θ → ∞ the road term Ω_z vanishes and the LuGre model *is* the LPV model
    # (001 eq. (20), (23)), at any state. Tolerance: finite-difference rounding, 1e-6 relative.
    rng = np.random.default_rng(1)
    for _ in range(5):
        z, vr, w = rng.uniform(-2e-3, 2e-3), rng.uniform(-3, 3), rng.uniform(0, 180)
        jac = _jacobian(z, vr, w, 1e12)
        np.testing.assert_allclose(jac[0], lpv.state_matrix(w, AX)[0], rtol=1e-6, atol=1e-6)
        np.testing.assert_allclose(jac[1], lpv.output_matrix(w, AX)[0], rtol=1e-6, atol=1e-4)


def test_output_equals_c_plus_c_prime_a() -> None:
    # 001 eq. (23) = 004 eq. (14): C_x(ω) = C + C′A(ω), exact algebra.
    c, cp = lpv.output_matrices_derivative_form(AX)
    np.testing.assert_allclose(lpv.output_matrix(OMEGAS, AX), c + cp @ lpv.state_matrix(OMEGAS, AX),
                               rtol=1e-14)


def test_innovation_and_output_derivative_forms_give_the_same_error_dynamics() -> None:
    # 004 eq. (16) with gains L̃ equals 001 eq. (25) with L = L̃/(1 + σ1 L̃1) (the
    # "Lp = L/(1+L1 S1)" of 001 Fig. 3-4). Both sides computed independently: 1e-12.
    l1t, l2t = 0.65, 197.0
    c, cp = lpv.output_matrices_derivative_form(AX)
    lt = np.array([[l1t], [l2t]])
    inv = np.linalg.inv(np.eye(2) + lt @ cp)
    ae_004 = inv @ (lpv.state_matrix(OMEGAS, AX) - lt @ c)
    ae, be = lpv.error_dynamics(OMEGAS, l1t, l2t, AX, form="output_derivative")
    np.testing.assert_allclose(ae, ae_004, rtol=1e-12, atol=1e-9)
    np.testing.assert_allclose(be[0], inv, rtol=1e-12, atol=1e-12)
    l1, l2 = lpv.output_derivative_to_innovation(l1t, l2t, AX.sigma1)
    ae_001, _ = lpv.error_dynamics(OMEGAS, l1, l2, AX)
    np.testing.assert_allclose(ae_001, ae_004, rtol=1e-12, atol=1e-9)


def test_gain_form_conversion_round_trip() -> None:
    l1, l2 = lpv.innovation_to_output_derivative(*lpv.output_derivative_to_innovation(
        0.65, 197.0, 0.76), 0.76)
    assert l1 == pytest.approx(0.65, rel=1e-14) and l2 == pytest.approx(197.0, rel=1e-14)
    with pytest.raises(ValueError, match="σ1·L1 = 1"):
        lpv.innovation_to_output_derivative(1 / 0.76, 1.0, 0.76)


def test_affine_form_is_001_eq26_with_corrected_entry() -> None:
    # 001 eq. (26): A_e = A0 + ωA1 with p1 = σ1+σ2, p2 = L1σ1 − 1; the (1,2) entry of A0 is
    # 1 − L1 p1 (the text prints −L1 p1). Exact algebra: 1e-12.
    l1, l2 = 0.68, 183.1
    s0, s1, s2, kr = AX.sigma0, AX.sigma1, AX.sigma2, AX.decay_per_omega
    p1, p2 = s1 + s2, l1 * s1 - 1
    a0_ref = np.array([[-l1 * s0, 1 - l1 * p1], [-l2 * s0, -l2 * p1]])
    a1_ref = np.array([[kr * p2, 0], [kr * l2 * s1, 0]])
    a0, a1, be = lpv.affine_error_dynamics(l1, l2, AX)
    np.testing.assert_allclose(a0, a0_ref, rtol=1e-12)
    np.testing.assert_allclose(a1, a1_ref, rtol=1e-12)
    np.testing.assert_allclose(be, [[1 - l1 * s1, 0], [-l2 * s1, 1]], rtol=1e-12)  # 001 eq. (25)
    ae, _ = lpv.error_dynamics(OMEGAS, l1, l2, AX)
    np.testing.assert_allclose(ae, a0 + OMEGAS[:, None, None] * a1, rtol=1e-12, atol=1e-9)


def test_affine_form_is_004_eq20_with_corrected_entry() -> None:
    # 004 eq. (20) with a1(1,1) = −κR/(1 + L1σ1) (printed: −κR). Exact algebra: 1e-12.
    l1, l2 = 0.65, 197.0
    s0, s1, s2, kr = AX.sigma0, AX.sigma1, AX.sigma2, AX.decay_per_omega
    d = 1 + l1 * s1
    a0_ref = np.array([[-l1 * s0 / d, (1 - l1 * s2) / d], [-l2 * s0 / d, -l2 * (s1 + s2) / d]])
    a1_ref = np.array([[-kr / d, 0], [l2 * kr * s1 / d, 0]])
    a0, a1, _ = lpv.affine_error_dynamics(l1, l2, AX, form="output_derivative")
    np.testing.assert_allclose(a0, a0_ref, rtol=1e-12)
    np.testing.assert_allclose(a1, a1_ref, rtol=1e-12)


def test_batched_equals_looped_and_sign_of_omega_is_ignored() -> None:
    batch = lpv.error_dynamics(OMEGAS, 0.68, 183.1, AX)[0]
    loop = np.stack([lpv.error_dynamics(w, 0.68, 183.1, AX)[0] for w in OMEGAS])
    np.testing.assert_array_equal(batch, loop)
    np.testing.assert_array_equal(lpv.state_matrix(-OMEGAS, AY), lpv.state_matrix(OMEGAS, AY))


def test_scheduled_gains_broadcast_with_omega() -> None:
    l1 = np.linspace(0.5, 0.7, OMEGAS.size)
    ae, be = lpv.error_dynamics(OMEGAS, l1, 100.0, AX)
    assert ae.shape == (OMEGAS.size, 2, 2) and be.shape == (OMEGAS.size, 2, 2)
    np.testing.assert_allclose(ae[2], lpv.error_dynamics(OMEGAS[2], l1[2], 100.0, AX)[0])


def test_kalman_model_is_000_eq19_and_keeps_the_deflection_rate_consistent() -> None:
    # 000 eq. (19): A = M⁻¹Ā, B = M⁻¹[0,1,0]ᵀ. And c = ż − v_r + κR|ω|z obeys ċ = −κR|ω|c:
    # the third state stays the deflection rate if it starts as one (exact algebra).
    w, wd = 90.0, 400.0
    kr = AX.decay_per_omega
    m = np.array([[1.0, 0, 0], [0, 1, 0], [0, -1, 1]])
    abar = np.array([[-kr * w, 1, 0], [0, 0, 0], [-kr * wd, 0, -kr * w]])
    a, b, c = lpv.kalman_model(w, wd, AX)
    np.testing.assert_allclose(a, np.linalg.solve(m, abar), rtol=1e-14)
    np.testing.assert_allclose(b, np.linalg.solve(m, [[0.0], [1.0], [0.0]]), rtol=1e-14)
    np.testing.assert_allclose(c, [[AX.sigma0, AX.sigma2, AX.sigma1]])
    x = np.array([1e-3, 0.4, -0.2])
    u = 3.0
    xd = a @ x + b[:, 0] * u
    cons = x[2] - x[1] + kr * w * x[0]
    cdot = xd[2] - xd[1] + kr * wd * x[0] + kr * w * xd[0]
    assert cdot == pytest.approx(-kr * w * cons, rel=1e-12)


def test_axis_validation_names_the_field() -> None:
    with pytest.raises(ValueError, match="sigma0"):
        lpv.LuGreAxis(0.0, 0.7, 0.0, 8.0, 0.33)
    with pytest.raises(ValueError, match="sigma2"):
        lpv.LuGreAxis(600.0, 0.7, -1.0, 8.0, 0.33)
