"""Corner velocity observers against textbook references, equivalences and properties.

* KF (000 eq. (19)–(22)) == a textbook Kalman filter written here with SciPy's expm;
* UKF (003 Algorithm 1) == KF on this model, which is linear in the state;
* LPV kernel == literal integrations of 001 eq. (24), (38) (innovation form) and of
  004 eq. (10)–(14) (output-derivative form with C′), both with SciPy's expm;
* covariances stay symmetric positive definite (Hypothesis);
* the high-slip threshold of 000 eq. (29) stays within [λ_l, λ_u].
"""

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from scipy.linalg import expm

from tests.estimators.velocity.corner_data import NO_SWITCHING, SUV, synthetic
from vestim.estimators.velocity.corner import (
    GAINS_001_X,
    GAINS_001_Y,
    GAINS_004,
    CornerVelocityEstimator,
    CornerVelocityInput,
    GainSchedule,
    KFParams,
    LPVParams,
    gains_004_eq35,
)
from vestim.estimators.velocity.corner_slip import HighSlipParams, slip_threshold
from vestim.estimators.velocity.lpv_observer import interp_gain
from vestim.models.lpv import kalman_model, longitudinal_axis

R = SUV.body.wheel_radius
TIRE = SUV.tire


def van_loan(a: np.ndarray, b: np.ndarray, h: float) -> tuple[np.ndarray, np.ndarray]:
    """(e^{Ah}, ∫_0^h e^{Aτ} b dτ) from one block exponential (scipy Padé)."""
    n = a.shape[0]
    aug = np.zeros((n + 1, n + 1))
    aug[:n, :n] = a * h
    aug[:n, n] = b * h
    big = expm(aug)
    return big[:n, :n], big[:n, n]


def textbook_kf(inp: CornerVelocityInput, params: KFParams) -> tuple[np.ndarray, np.ndarray]:
    """Textbook predict/update KF on 000 eq. (19), step-invariant discretisation via expm.

    Same conventions as the kernel (documented in corner_common): the decay rate at the
    mean |ω| of the step, d|ω|/dt and ω̇ as differences, the acceleration held at the
    trapezoid mean; no transport term (the synthetic input has r = δ = 0). Plain
    covariance update P = (I − KC)P⁻ (the kernel uses the Joseph form).
    """
    axis = longitudinal_axis(SUV)
    c = np.array([TIRE.sigma0_x, TIRE.sigma2_x, TIRE.sigma1_x])
    q = np.diag(params.q)
    n = len(inp)
    vxt = np.empty((n, 4))
    p_last = np.empty((4, 3, 3))
    for i in range(4):
        x = np.array([inp.mu_x[0, i] / TIRE.sigma0_x, 0.0, 0.0])
        P = np.diag(params.p0)
        vxt[0, i] = R * inp.omega[0, i]
        for k in range(1, n):
            h = inp.t[k] - inp.t[k - 1]
            w0, w1 = inp.omega[k - 1, i], inp.omega[k, i]
            a, b, _ = kalman_model(0.5 * (abs(w0) + abs(w1)), (abs(w1) - abs(w0)) / h, axis)
            ak, bk = van_loan(a, b[:, 0], h)
            u = R * (w1 - w0) / h - 0.5 * (inp.a_xt[k - 1, i] + inp.a_xt[k, i])
            x = ak @ x + bk * u
            P = ak @ P @ ak.T + q * h / params.step_ref
            s = c @ P @ c + params.r
            K = P @ c / s
            x = x + K * (inp.mu_x[k, i] - c @ x)
            P = (np.eye(3) - np.outer(K, c)) @ P
            vxt[k, i] = R * w1 - x[1]
        p_last[i] = P
    return vxt, p_last


def test_kf_equals_textbook_kalman_filter() -> None:
    """000 eq. (21)–(22): kernel == textbook KF (expm discretisation) to 1e-9 m/s over 1.25 s.

    Tolerance: the two differ only in round-off (closed-form vs Padé discretisation,
    Joseph vs plain covariance update), which the stable filter does not amplify.
    """
    inp = synthetic(250, seed=1)
    params = KFParams(high_slip=NO_SWITCHING)
    out = CornerVelocityEstimator(SUV, "lugre_kf", params).run(inp)
    ref_vxt, ref_p = textbook_kf(inp, params)
    assert np.max(np.abs(out.vxt - ref_vxt)) < 1e-9
    est = CornerVelocityEstimator(SUV, "lugre_kf", params)
    est.run(inp)
    np.testing.assert_allclose(est.covariance, ref_p, rtol=1e-6, atol=1e-14)


@pytest.mark.parametrize("params", [KFParams(), KFParams.paper()], ids=["default", "paper"])
def test_ukf_equals_kf_on_the_linear_model(params: KFParams) -> None:
    """003 Algorithm 1 on the (state-linear) model (3): the unscented transform is exact,
    so the UKF equals the KF, high-slip switching included; 1e-7 m/s allows for the
    round-off of the Cholesky factor and the sigma-point sums over 8 s.
    """
    inp = synthetic(1600, seed=2, planar=True, jitter=0.2)
    kf = CornerVelocityEstimator(SUV, "lugre_kf", params).run(inp)
    ukf = CornerVelocityEstimator(SUV, "lugre_ukf", params).run(inp)
    np.testing.assert_array_equal(kf.high_slip, ukf.high_slip)
    assert np.max(np.abs(kf.vxt - ukf.vxt)) < 1e-7
    np.testing.assert_allclose(kf.sigma_vxt, ukf.sigma_vxt, rtol=1e-6)


def literal_lpv(inp: CornerVelocityInput, l1: float, l2: float, form: str,
                direction: str = "x") -> np.ndarray:
    """Direct integration of the printed observers, inputs and μ held over each step.

    innovation (001 eq. (24), (38)):   x̂˙ = A x̂ + B u + L (μ − C_q x̂),  C_q = [σ0 − σ1κRρ, σ1 + σ2]
    output_derivative (004 eq. (10)–(14)): x̂˙ = A x̂ + B u + L̃ (μ − C x̂ − C′ x̂˙),
        C = [σ0, σ2], C′ = [σ1, 0], solved as x̂˙ = (I + L̃C′)⁻¹[(A − L̃C)x̂ + B u + L̃μ].
    Returns v̂_r (n, 4).
    """
    s0, s1, s2, kap = ((TIRE.sigma0_x, TIRE.sigma1_x, TIRE.sigma2_x, TIRE.kappa_x) if direction == "x"
                       else (TIRE.sigma0_y, TIRE.sigma1_y, TIRE.sigma2_y, TIRE.kappa_y))
    mu = inp.mu_x if direction == "x" else inp.mu_y
    acc = inp.a_xt if direction == "x" else inp.a_yt
    L = np.array([l1, l2])
    B = np.array([0.0, 1.0])
    n = len(inp)
    vr = np.empty((n, 4))
    for i in range(4):
        x = np.array([mu[0, i] / s0, 0.0])
        vr[0, i] = 0.0
        for k in range(1, n):
            h = inp.t[k] - inp.t[k - 1]
            w0, w1 = inp.omega[k - 1, i], inp.omega[k, i]
            rho = 0.5 * (abs(w0) + abs(w1))
            a_mid = 0.5 * (acc[k - 1, i] + acc[k, i])
            u = R * (w1 - w0) / h - a_mid if direction == "x" else -a_mid
            y = 0.5 * (mu[k - 1, i] + mu[k, i])
            A = np.array([[-kap * R * rho, 1.0], [0.0, 0.0]])
            if form == "innovation":
                cq = np.array([s0 - s1 * kap * R * rho, s1 + s2])
                M = A - np.outer(L, cq)
                g = B * u + L * y
            else:
                inv = np.linalg.inv(np.eye(2) + np.outer(L, [s1, 0.0]))
                M = inv @ (A - np.outer(L, [s0, s2]))
                g = inv @ (B * u + L * y)
            e, _ = van_loan(M, np.zeros(2), h)
            _, phi_g = van_loan(M, g, h)
            x = e @ x + phi_g
            vr[k, i] = x[1]
    return vr


def test_lpv_001_equals_printed_observers() -> None:
    """001 eq. (24) (L = [0.68, 183.1]) and eq. (38) (L = [1.11, 16.7]) integrated literally
    == kernel, to 1e-9 m/s (round-off of the closed-form 2×2 exponential)."""
    inp = synthetic(150, seed=3)
    out = CornerVelocityEstimator(SUV, "lpv", LPVParams.paper_001()).run(inp)
    vrx = literal_lpv(inp, 0.68, 183.1, "innovation", "x")
    vry = literal_lpv(inp, 1.11, 16.7, "innovation", "y")
    assert np.max(np.abs(out.v_rx - vrx)) < 1e-9
    assert np.max(np.abs(out.v_ry - vry)) < 1e-9
    np.testing.assert_allclose(out.vyt, -out.v_ry)


def test_lpv_004_output_derivative_form_equals_printed_observer() -> None:
    """004 eq. (10)–(14) with the C′ term (L̃ = [0.65, 197]) integrated literally == kernel
    (which runs the equivalent innovation gain L̃/(1 + σ1L̃1), 004 eq. (16)), to 1e-9 m/s."""
    inp = synthetic(150, seed=4)
    out = CornerVelocityEstimator(SUV, "lpv", LPVParams.paper_004()).run(inp)
    vrx = literal_lpv(inp, 0.65, 197.0, "output_derivative", "x")
    assert np.max(np.abs(out.v_rx - vrx)) < 1e-9


def test_gains_004_eq35_values() -> None:
    """004 eq. (35) at ω = 0: L̃1 = 2.83e4/2.38e4, L̃2 = 4822·7.34e4/9.51e5 (hand-evaluated)."""
    l1, l2 = gains_004_eq35(0.0)
    assert l1 == pytest.approx(2.83e4 / 2.38e4, rel=1e-12)
    assert l2 == pytest.approx(4822 * 7.34e4 / 9.51e5, rel=1e-12)
    l1, l2 = gains_004_eq35(np.array([60.0, 120.0]))
    assert np.all(l2 > 0) and np.all(np.isfinite(l1))


@settings(max_examples=50, deadline=None)
@given(rho=st.floats(-10.0, 200.0))
def test_gain_interpolation_equals_numpy_interp(rho: float) -> None:
    """Linear interpolation on the eq. (35) grid, held outside [0, 120] rad/s, == np.interp."""
    w, l1, l2 = LPVParams.paper_004_scheduled().longitudinal.innovation_gains(TIRE.sigma1_x)
    g1, g2 = interp_gain(rho, w, l1, l2)
    assert g1 == pytest.approx(np.interp(rho, w, l1), rel=1e-14)
    assert g2 == pytest.approx(np.interp(rho, w, l2), rel=1e-14)


def test_gain_schedule_forms_and_validation() -> None:
    """Output-derivative gains convert as L = L̃/(1 + σ1L̃1) (004 eq. (16)); bad schedules are refused."""
    _, l1, l2 = GAINS_004.innovation_gains(0.76)
    assert l1[0] == pytest.approx(0.65 / (1 + 0.76 * 0.65))
    assert l2[0] == pytest.approx(197.0 / (1 + 0.76 * 0.65))
    _, l1, _ = GAINS_001_X.innovation_gains(0.76)
    assert l1[0] == 0.68
    assert GAINS_001_Y.l2 == (16.7,)
    with pytest.raises(ValueError, match="strictly increasing"):
        GainSchedule((0.0, 0.0), (1.0, 1.0), (1.0, 1.0))
    with pytest.raises(ValueError, match="l2 must be > 0"):
        GainSchedule.constant(0.5, -1.0)
    with pytest.raises(ValueError, match="lengths"):
        GainSchedule((0.0, 1.0), (1.0,), (1.0, 2.0))
    with pytest.raises(ValueError, match="form"):
        GainSchedule.constant(0.5, 1.0, "derivative")  # type: ignore[arg-type]


@settings(max_examples=20, deadline=None)
@given(seed=st.integers(0, 10_000), log_q=st.floats(-11.0, -3.0), log_r=st.floats(-5.0, 0.0),
       method=st.sampled_from(["lugre_kf", "lugre_ukf"]), jitter=st.floats(0.0, 0.5))
def test_covariance_stays_symmetric_positive_definite(seed: int, log_q: float, log_r: float,
                                                      method: str, jitter: float) -> None:
    """P stays symmetric and positive definite for any noise level, with switching and
    irregular steps (Joseph form in the KF; the UKF's factorisation never needs jitter)."""
    q = 10.0**log_q
    params = KFParams(q=(q * 1e-3, q, 10 * q), r=10.0**log_r, q_high=(q * 1e-4, q * 0.1, q),
                      r_high=10.0 ** (log_r + 2))
    est = CornerVelocityEstimator(SUV, method, params)
    inp = synthetic(300, seed=seed, planar=True, jitter=jitter)
    for start in range(0, 300, 100):
        out = est.advance(inp.slice(start, start + 100))
        P = est.covariance
        np.testing.assert_allclose(P, np.transpose(P, (0, 2, 1)), rtol=0, atol=0)
        assert np.all(np.linalg.eigvalsh(P) > 0.0)
        assert np.all(np.isfinite(out.vxt))


def test_slip_threshold_eq29_bounds() -> None:
    """000 eq. (29) (prefactor read as φ_e√(2π)): λ̄_th = λ_l at σ_e = 0, → λ_u as σ_e grows, monotone."""
    s = np.linspace(0.0, 50.0, 501)
    th = slip_threshold(0.15, 0.05, 0.005, s)
    assert th[0] == pytest.approx(0.05, abs=1e-15)
    assert th[-1] == pytest.approx(0.15, abs=1e-6)
    assert np.all(np.diff(th) >= 0)


def test_high_slip_flags_on_wheel_spin() -> None:
    """A wheel spinning up at 100 rad/s² (|ω̇| criterion) is flagged; free rolling is not."""
    inp = synthetic(400, seed=5)
    omega = inp.omega.copy()
    omega[200:, 0] = omega[199, 0] + 100.0 * (inp.t[200:] - inp.t[199])
    mu_x = inp.mu_x.copy()
    mu_x[200:, 0] = 0.1  # a driven tire transmits force
    spin = type(inp)(t=inp.t, omega=omega, mu_x=mu_x, a_xt=inp.a_xt, delta=inp.delta,
                     yaw_rate=inp.yaw_rate)
    out = CornerVelocityEstimator(SUV, "lugre_kf").run(spin)
    assert out.high_slip[215:, 0].all()
    hs = HighSlipParams()
    assert hs.lambda_lower < hs.lambda_upper


@pytest.mark.parametrize("form", ["innovation", "output_derivative"])
@pytest.mark.parametrize("omega", [0.0, 35.0, 110.0])
def test_lpv_step_matches_models_lpv_error_dynamics(omega: float, form: str) -> None:
    """With u = μ = 0 one kernel step is x ← e^{A_e h} x, A_e from models/lpv.py's
    error_dynamics (001 eq. (25), 004 eq. (16)) — the kernel's inline matrices and the
    shared corner model agree (1e-12)."""
    from vestim.estimators.velocity.lpv_observer import lpv_step
    from vestim.models.lpv import error_dynamics

    axis = longitudinal_axis(SUV)
    l1, l2 = (0.65, 197.0)
    ae, _ = error_dynamics(omega, l1, l2, axis, form)  # type: ignore[arg-type]
    g = GainSchedule.constant(l1, l2, form)  # type: ignore[arg-type]
    _, g1, g2 = g.innovation_gains(axis.sigma1)
    xs = np.array([[2e-4, 0.3]])
    lpv_step(xs, 0, axis.decay_per_omega, axis.sigma0, axis.sigma1, axis.sigma2, omega, g1[0], g2[0],
             0.0, 0.0, 0.005, np.empty((3, 3)), np.empty(3))
    expected = expm(ae * 0.005) @ np.array([2e-4, 0.3])
    np.testing.assert_allclose(xs[0], expected, rtol=1e-12, atol=1e-18)
