"""Step-invariant discretisation of the corner velocity models against SciPy (000 Sec. III-B).

A_k = e^{A h} and B_k = ∫_0^h e^{Aτ} B dτ (000 text before eq. (21), 003 Appendix),
checked against ``scipy.linalg.expm`` and ``scipy.integrate.quad_vec`` on the
model matrices of :func:`vestim.models.lpv.kalman_model` (an independent source for
A and B). Tolerance 1e-10 relative: the closed forms are exact, so only round-off
(~1e-14, see ``decay_functions``) and the quadrature's own tolerance (1e-13) remain.
"""

import numpy as np
import pytest
from hypothesis import example, given, settings
from hypothesis import strategies as st
from scipy.integrate import quad_vec
from scipy.linalg import expm

from vestim.estimators.velocity.corner_discrete import (
    decay_functions,
    expm2,
    kf_transition_matrices,
)
from vestim.io import load_vehicle
from vestim.models.lpv import kalman_model, longitudinal_axis

SUV = load_vehicle("hashemi_suv")
AXIS = longitudinal_axis(SUV)


def scipy_discretisation(a: np.ndarray, b: np.ndarray, h: float) -> tuple[np.ndarray, np.ndarray]:
    """Reference: e^{Ah} by Padé (scipy) and ∫ e^{Aτ} B dτ by adaptive quadrature."""
    ak = expm(a * h)
    bk, _ = quad_vec(lambda tau: expm(a * tau) @ b, 0.0, h, epsabs=1e-16, epsrel=1e-13)
    return ak, bk


def rel_err(x: np.ndarray, ref: np.ndarray) -> float:
    return float(np.max(np.abs(x - ref)) / np.max(np.abs(ref)))


@pytest.mark.parametrize(("omega", "omega_dot", "h"), [
    (0.0, 0.0, 0.005),      # standstill: a = 0, the series branch at x = 0
    (1e-4, 3.0, 0.005),     # x ≈ 1e-6: series branch, cancellation-prone closed form
    (30.0, -120.0, 0.005),  # x ≈ 0.41: closed-form branch just above the switch
    (140.0, 800.0, 0.005),  # |ω| and |ω̇| at 001's operating-region bounds
    (20.0, 50.0, 0.0125),   # irregular, longer step
    (-50.0, 40.0, 0.005),   # reversing: |ω| and d|ω|/dt = sign(ω) ω̇
])
def test_kf_transition_equals_expm_and_quadrature(omega: float, omega_dot: float, h: float) -> None:
    """000 eq. (19)–(20) discretised by step invariance: closed form == expm / quad_vec to 1e-10."""
    a, b, _ = kalman_model(omega, omega_dot, AXIS)
    ak_ref, bk_ref = scipy_discretisation(a, b[:, 0], h)
    kr = AXIS.decay_per_omega
    rho_dot = -omega_dot if omega < 0 else omega_dot
    ak, bk = kf_transition_matrices(kr * abs(omega), kr * rho_dot, h)
    assert rel_err(ak, ak_ref) < 1e-10
    assert rel_err(bk, bk_ref) < 1e-10


@settings(max_examples=60, deadline=None)
@given(omega=st.floats(0.0, 250.0), omega_dot=st.floats(-2000.0, 2000.0),
       h=st.floats(1e-4, 0.05))
def test_kf_transition_property(omega: float, omega_dot: float, h: float) -> None:
    """Random operating points: the closed form matches SciPy to 1e-10 (relative to the largest entry).

    B_k from Van Loan's block exponential e^{[[A, B], [0, 0]] h} = [[A_k, B_k], [0, 1]]
    (quadrature, as above, is too slow for many examples).
    """
    a, b, _ = kalman_model(omega, omega_dot, AXIS)
    aug = np.zeros((4, 4))
    aug[:3, :3] = a * h
    aug[:3, 3] = b[:, 0] * h
    big = expm(aug)
    ak_ref, bk_ref = big[:3, :3], big[:3, 3]
    kr = AXIS.decay_per_omega
    ak, bk = kf_transition_matrices(kr * omega, kr * omega_dot, h)
    assert rel_err(ak, ak_ref) < 1e-10
    assert rel_err(bk, bk_ref) < 1e-10


def test_decay_functions_continuous_at_series_switch() -> None:
    """The series (x < 0.25) and closed-form branches agree at the switch to round-off (1e-13)."""
    lo = np.array(decay_functions(np.nextafter(0.25, 0.0)))
    hi = np.array(decay_functions(0.25))
    assert np.max(np.abs(lo - hi) / np.abs(hi)) < 1e-13
    assert decay_functions(0.0) == pytest.approx((1.0, 0.5, 0.5, 1.0 / 6.0), rel=1e-15)


def _augmented(m: np.ndarray, h: float) -> np.ndarray:
    """Φ = ∫_0^h e^{Mτ} dτ from the exponential of [[M, I], [0, 0]] h (Van Loan)."""
    aug = np.zeros((4, 4))
    aug[:2, :2] = m * h
    aug[:2, 2:] = np.eye(2) * h
    return expm(aug)[:2, 2:]


@settings(max_examples=200, deadline=None)
@given(entries=st.lists(st.floats(-1.0, 1.0), min_size=4, max_size=4),
       log_scale=st.floats(-3.0, 3.0), h=st.floats(1e-4, 0.02))
@example(entries=[-1.0, 0.0, 0.0, -1.0], log_scale=3.0, h=0.0195)  # e^{Mh} ≈ 3e-9 I: was 9.4e-9
def test_expm2_equals_scipy(entries: list[float], log_scale: float, h: float) -> None:
    """Closed-form 2×2 e^{Mh} and Φ (Cayley–Hamilton) == scipy expm (Padé) on random matrices.

    Covers real, complex and (nearly) repeated eigenvalues and ‖M‖h from 1e-7 to 20.
    Tolerance 1e-10: Φ = M⁻¹(e^{Mh} − I) loses about cond(M)·ε of relative precision,
    so nearly singular M (relative det ≤ 1e-6, including a det that underflows to 0, for
    which the kernel documents Φ = NaN) and matrices with cond(M) > 1e5 (ε·cond > 2e-11;
    the det filter alone let cond 7.5e5 through: M = diag(1.2e-7, −0.09), error 1.2e-10)
    are outside the domain. The LPV observers have det M = L2(σ0 + σ2κR|ω|) > 0, far from
    singular.
    """
    m = np.array(entries).reshape(2, 2) * 10.0**log_scale
    if np.max(np.abs(m)) * h < 1e-7:  # below the stated ‖M‖h domain (M = 3.5e-159·I gave 5e-8)
        return
    if abs(np.linalg.det(m)) <= 1e-6 * np.max(np.abs(m)) ** 2:
        return
    if not np.isfinite(np.linalg.cond(m)) or np.linalg.cond(m) > 1e5:
        return
    e, phi = expm2(m, h)
    assert rel_err(e, expm(m * h)) < 1e-10
    assert rel_err(phi, _augmented(m, h)) < 1e-10


def test_expm2_on_paper_observer_matrix() -> None:
    """001 eq. (25)–(26) error matrix at ω = 50 rad/s with L = [0.68, 183.1]: complex poles (|·|h ≈ 1.8)."""
    kr = AXIS.decay_per_omega
    c1 = AXIS.sigma0 - AXIS.sigma1 * kr * 50.0
    c2 = AXIS.sigma1 + AXIS.sigma2
    m = np.array([[-kr * 50.0 - 0.68 * c1, 1.0 - 0.68 * c2], [-183.1 * c1, -183.1 * c2]])
    e, phi = expm2(m, 0.005)
    assert rel_err(e, expm(m * 0.005)) < 1e-12
    assert rel_err(phi, _augmented(m, 0.005)) < 1e-12
