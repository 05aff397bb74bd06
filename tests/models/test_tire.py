"""Tire models against closed forms and their defining properties."""

import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from scipy.integrate import solve_ivp

from vestim.io import load_vehicle
from vestim.models.tire import (
    lugre_peak_mu,
    lugre_small_slip_stiffness,
    lugre_steady_state,
    lugre_theta_for_mu,
    lugre_zdot,
    magic_formula,
    magic_formula_params,
    mf_stiffness,
)

SUV = load_vehicle("hashemi_suv")
TIRE = SUV.tire
MF = magic_formula_params(SUV.magic_formula)


def _lugre_args(theta: float) -> tuple[float, ...]:
    t = TIRE
    return (theta, t.sigma0_x, t.sigma0_y, t.kappa_x, t.kappa_y, t.mu_s, t.mu_c, t.v_s, t.alpha)


@pytest.mark.parametrize("vrx, vry, wr, theta", [
    (0.2, 0.0, 20.0, 1.0), (2.0, 0.0, 22.0, 0.3), (-1.0, 0.0, 15.0, 0.1),
    (0.5, -0.8, 18.0, 0.6), (5.0, 1.0, 25.0, 1.1),
])
def test_lugre_integrates_to_closed_form_steady_state(vrx, vry, wr, theta):
    """004 eq. (6) integrated at constant v_r, R|ω| settles on ż = 0 of the closed form.

    Independent path: SciPy's adaptive RK45 on the compiled right-hand side, then
    μ = σ0 z + σ1 ż + σ2 v_r (eq. (7)) with ż ≈ 0; tolerance 1e-6 is the solver's.
    """
    def rhs(_t, z):
        return lugre_zdot(z[0], z[1], vrx, vry, wr, *_lugre_args(theta))

    sol = solve_ivp(rhs, (0.0, 2.0), [0.0, 0.0], method="LSODA", rtol=1e-10, atol=1e-14)
    zx, zy = sol.y[:, -1]
    dzx, dzy = rhs(0.0, sol.y[:, -1])
    mux = TIRE.sigma0_x * zx + TIRE.sigma1_x * dzx + TIRE.sigma2_x * vrx
    muy = TIRE.sigma0_y * zy + TIRE.sigma1_y * dzy + TIRE.sigma2_y * vry
    ref_x, ref_y = lugre_steady_state(vrx, vry, wr, theta, TIRE)
    assert mux == pytest.approx(float(ref_x), abs=1e-6)
    assert muy == pytest.approx(float(ref_y), abs=1e-6)


def test_lugre_deflection_is_bounded_by_mu_s_over_sigma0():
    """Invariant set |z| ≤ μs/σ0 (004 Sec. II-B): steady deflection stays inside for θ ≤ 1."""
    vr = np.linspace(-30, 30, 601)
    mux, _ = lugre_steady_state(vr, 0.0, 20.0, 1.0, TIRE)
    z = (mux - TIRE.sigma2_x * vr) / TIRE.sigma0_x
    assert np.all(np.abs(z) <= TIRE.mu_s / TIRE.sigma0_x + 1e-12)


@given(vrx=st.floats(-20, 20), vry=st.floats(-5, 5), wr=st.floats(0.5, 50),
       theta=st.floats(0.05, 1.2))
@settings(max_examples=200, deadline=None)
def test_lugre_steady_force_is_odd_in_slip(vrx, vry, wr, theta):
    """Property: the steady-state LuGre force is odd in the relative velocity."""
    a = np.array(lugre_steady_state(vrx, vry, wr, theta, TIRE))
    b = np.array(lugre_steady_state(-vrx, -vry, wr, theta, TIRE))
    np.testing.assert_allclose(a, -b, atol=1e-12)


@pytest.mark.parametrize("mu", [0.1, 0.25, 0.5, 1.0])
def test_lugre_theta_for_mu_reaches_the_requested_peak(mu):
    """θ(μ) is defined so that the steady traction peak at 20 m/s equals μ (to 1e-6)."""
    theta = lugre_theta_for_mu(mu, TIRE)
    assert lugre_peak_mu(theta, TIRE) == pytest.approx(mu, abs=1e-6)


def test_lugre_small_slip_stiffness_matches_finite_difference():
    """dμx/dλ at λ → 0 of the closed-form steady state equals σ0/κ + σ2 R|ω| (times Fz)."""
    wr, fz, lam = 20.0, 5000.0, 1e-7
    mux, muy = lugre_steady_state(lam * wr, -lam * wr, wr, 0.3, TIRE)
    cx, cy = lugre_small_slip_stiffness(fz, wr, 1.0, TIRE.sigma0_x, TIRE.sigma2_x, TIRE.kappa_x,
                                        TIRE.sigma0_y, TIRE.sigma2_y, TIRE.kappa_y)
    assert fz * float(mux) / lam == pytest.approx(cx, rel=1e-4)
    assert fz * float(-muy) / lam == pytest.approx(cy, rel=1e-4)


@given(mu=st.floats(0.05, 1.2), fz=st.floats(500, 12000), scale=st.floats(0.5, 1.5))
@settings(max_examples=60, deadline=None)
def test_magic_formula_peak_is_mu_fz(mu, fz, scale):
    """Pure-slip peaks of the Magic Formula sit at D = μ·Fz (shape factors C > 1).

    Domain: a tire softened below half its stiffness on μ > 1.2 puts the lateral
    peak beyond a 90° slip angle, where no peak can be observed.
    """
    kappa = np.linspace(0.0, 1.5, 30001)
    fx = np.array([magic_formula(k, 0.0, fz, mu, scale, *MF)[0] for k in kappa[::10]])
    alpha = np.linspace(0.0, 1.55, 15501)  # peak lies beyond 0.8 rad for soft, high-μ cases
    fy = np.array([magic_formula(0.0, a, fz, mu, scale, *MF)[1] for a in alpha])
    assert fx.max() == pytest.approx(mu * fz, rel=2e-3)
    assert -fy.min() == pytest.approx(mu * fz, rel=2e-3)


@given(k=st.floats(-1, 1), a=st.floats(-0.5, 0.5), fz=st.floats(100, 10000), mu=st.floats(0.05, 1.5))
@settings(max_examples=200, deadline=None)
def test_magic_formula_odd_and_within_friction_circle(k, a, fz, mu):
    """Property: F(−κ, −α) = −F(κ, α), and the combined force stays inside μ·Fz per axis."""
    fx, fy = magic_formula(k, a, fz, mu, 1.0, *MF)
    gx, gy = magic_formula(-k, -a, fz, mu, 1.0, *MF)
    assert fx == pytest.approx(-gx, abs=1e-9)
    assert fy == pytest.approx(-gy, abs=1e-9)
    assert abs(fx) <= mu * fz * (1 + 1e-12) and abs(fy) <= mu * fz * (1 + 1e-12)
    assert math.copysign(1, fy) != math.copysign(1, a) or fy == 0.0 or a == 0.0


def test_magic_formula_slope_at_origin_is_the_load_dependent_stiffness():
    """dFx/dκ and −dFy/dα at zero slip equal K_x, K_y of mf_stiffness (finite difference)."""
    p = SUV.magic_formula
    for fz in (2000.0, 5500.0, 9000.0):
        kx, ky = mf_stiffness(fz, 1.0, p.fz0, p.kx, p.kx_load, p.ky1, p.ky2)
        h = 1e-7
        assert magic_formula(h, 0.0, fz, 0.8, 1.0, *MF)[0] / h == pytest.approx(kx, rel=1e-5)
        assert -magic_formula(0.0, h, fz, 0.8, 1.0, *MF)[1] / h == pytest.approx(ky, rel=1e-5)
