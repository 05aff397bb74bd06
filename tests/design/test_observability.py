"""Observability tests: rank (000 eq. (24), 001 eq. (12), 004 eq. (15)), Gramians (000 (A1)-(A2)),
stochastic observability with uncertain initial covariance (000 eq. (26)-(27), (A6)-(A7))."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pandas as pd
import pytest
from scipy.linalg import (
    expm,
    solve_continuous_lyapunov,
    solve_discrete_are,
    solve_discrete_lyapunov,
)

from vestim.design.observability import (
    analyze_observability,
    controllability_gramian,
    discretize,
    expm_batched,
    gramian_rank,
    kalman_observability,
    lateral_force_observability,
    ltv_observability_matrix,
    lugre_observability,
    observability_gramian,
    stochastic_observability,
)
from vestim.errors import LogFormatError
from vestim.io.vehicle import load_vehicle
from vestim.models import lpv

VEH = load_vehicle("hashemi_suv")
AX = lpv.longitudinal_axis(VEH)


def test_ltv_matrix_reduces_to_kalman_matrix_for_lti() -> None:
    # Constant A, C: O_n = [C; CA; CA²] exactly.
    rng = np.random.default_rng(0)
    a, c = rng.normal(size=(3, 3)), rng.normal(size=(1, 3))
    o = ltv_observability_matrix(a[None], c[None])
    np.testing.assert_allclose(o, np.vstack([c, c @ a, c @ a @ a]), rtol=1e-12)


def test_ltv_matrix_uses_the_time_derivative_of_c() -> None:
    # A = 0, C(t) = [1, t]: τ1 = C = [1, t0], τ2 = Ċ = [0, 1] (000 eq. (24)), full rank
    # although CA = 0 — time variation alone makes the pair observable.
    t0 = 0.7
    o = ltv_observability_matrix(np.zeros((1, 2, 2)), np.array([[[1.0, t0]], [[0.0, 1.0]]]))
    np.testing.assert_allclose(o, [[1.0, t0], [0.0, 1.0]])


def test_lugre_observability_determinant_has_the_closed_form() -> None:
    # 004 eq. (15) by hand: τ1 = [c0, p1] with c0 = σ0 − σ1κRω, τ2 = [−c0κRω − σ1κRω̇, c0],
    # det = c0² + p1(c0κRω + σ1κRω̇). Over |ω| ≤ 180, |ω̇| ≤ 800 it stays positive (004 Fig. 5);
    # the minimum is at ω = 180, ω̇ = −800 (exact algebra: 1e-10).
    w, wd = np.meshgrid(np.linspace(0, 180, 37), np.linspace(-800, 800, 33), indexing="ij")
    kr, s0, s1, p1 = AX.decay_per_omega, AX.sigma0, AX.sigma1, AX.sigma1 + AX.sigma2
    c0 = s0 - s1 * kr * w
    _, det, rank = lugre_observability(w, wd, AX)
    np.testing.assert_allclose(det, c0**2 + p1 * (c0 * kr * w + s1 * kr * wd), rtol=1e-10)
    assert np.all(det > 0) and np.all(rank == 2)
    i = np.unravel_index(np.argmin(det), det.shape)
    assert (w[i], wd[i]) == (180.0, -800.0)


def test_three_state_kalman_model_is_unobservable_at_standstill() -> None:
    # 000 eq. (19) at ω = ω̇ = ω̈ = 0: C = [σ0, σ2, σ1], CA = [0, σ0, 0], CA² = 0 → rank 2
    # (000 Fig. 1: launches lack full rank while the wheels stand still); spinning → rank 3.
    _, r0 = kalman_observability(0.0, 0.0, 0.0, AX)
    _, r1 = kalman_observability(50.0, 100.0, 0.0, AX)
    assert int(r0) == 2 and int(r1) == 3


def test_lateral_force_model_rank() -> None:
    # 001 eq. (12): rank 3 for δ ≠ 0; at δ = 0 rank(C̄) = 2 and, with δ̇ = 0 too, rank(O_3) = 2
    # (the paper's exception). With δ = 0 but δ̇ ≠ 0 the derivative block restores rank 3.
    body = VEH.body
    assert int(lateral_force_observability(0.05, 0.0, 0.0, body)[1]) == 3
    assert int(lateral_force_observability(0.0, 0.0, 0.0, body)[1]) == 2
    assert int(lateral_force_observability(0.0, 0.2, 0.0, body)[1]) == 3


def test_observability_gramian_of_a_stable_lti_system_is_the_lyapunov_solution() -> None:
    # 000 (A1) summed to convergence equals X = AᵀXA + CᵀC (scipy). Eigenvalues 0.9 and 0.5,
    # 600 steps: truncation 0.9^1200 ≈ 1e-55, so agreement to 1e-10 relative.
    a = np.array([[0.9, 0.2], [0.0, 0.5]])
    c = np.array([[1.0, 0.3]])
    n = 600
    v = observability_gramian(np.broadcast_to(a, (n, 2, 2)), np.broadcast_to(c, (n, 1, 2)))
    np.testing.assert_allclose(v[-1], solve_discrete_lyapunov(a.T, c.T @ c), rtol=1e-10)


def test_controllability_gramian_of_a_stable_lti_system_is_the_lyapunov_solution() -> None:
    # 000 (A2): W = AWAᵀ + BBᵀ at convergence (scipy), 1e-10 relative.
    a = np.array([[0.9, 0.2], [0.0, 0.5]])
    b = np.array([[0.0], [1.0]])
    n = 600
    w = controllability_gramian(np.broadcast_to(a, (n, 2, 2)), np.broadcast_to(b, (n, 2, 1)))
    np.testing.assert_allclose(w[-1], solve_discrete_lyapunov(a, b @ b.T), rtol=1e-10)


def test_sampled_gramian_approaches_the_continuous_one() -> None:
    # T_s Σ φᵀCᵀCφ → ∫ e^{Aᵀt}CᵀCe^{At}dt = solve_continuous_lyapunov(Aᵀ, −CᵀC) as T_s → 0;
    # the left-rectangle rule errs by about T_s·‖A‖/2 ≈ 2.5e-3 relative here, so tolerance 5e-3.
    ac = np.array([[0.0, 1.0], [-4.0, -1.0]])
    c = np.array([[1.0, 0.0]])
    ts = 1e-3
    ad = expm(ac * ts)
    n = 30000
    v = observability_gramian(np.broadcast_to(ad, (n, 2, 2)), np.broadcast_to(c, (n, 1, 2)))
    ref = solve_continuous_lyapunov(ac.T, -c.T @ c)
    np.testing.assert_allclose(ts * v[-1], ref, rtol=5e-3)


def test_gramian_rank_of_unobservable_pair_is_deficient() -> None:
    a = np.eye(2)
    c = np.array([[1.0, 0.0]])
    rank, _ = gramian_rank(observability_gramian(np.broadcast_to(a, (50, 2, 2)),
                                                 np.broadcast_to(c, (50, 1, 2))))
    assert np.all(rank == 1)


def test_expm_batched_and_discretize_match_scipy() -> None:
    # Scaling-and-squaring Taylor vs scipy's Padé: both accurate to ~1e-13 here.
    rng = np.random.default_rng(4)
    m = rng.normal(size=(20, 3, 3)) * 4
    ref = np.stack([expm(x) for x in m])
    np.testing.assert_allclose(expm_batched(m), ref, rtol=1e-10, atol=1e-12)
    a = lpv.state_matrix(120.0, AX)
    b = lpv.input_matrix()
    ad, bd = discretize(a, b, 0.005)
    big = expm(np.block([[a, b], [np.zeros((1, 3))]]) * 0.005)
    np.testing.assert_allclose(ad, big[:2, :2], rtol=1e-12)
    np.testing.assert_allclose(bd, big[:2, 2:], rtol=1e-12)


def _kalman_large_psi(a: np.ndarray, c: np.ndarray, q: float, r: float, psi: float, n: int
                      ) -> np.ndarray:
    """Standard Kalman predicted covariances with P(0|−1) = ψI (000 eq. (22))."""
    p = psi * np.eye(a.shape[0])
    out = []
    for _ in range(n):
        s = c @ p @ c.T + r
        k = p @ c.T / s
        p = (np.eye(a.shape[0]) - k @ c) @ p
        p = a @ p @ a.T + q * np.eye(a.shape[0])
        out.append(p)
    return np.array(out)


def test_stochastic_observability_of_an_observable_system() -> None:
    # Double integrator with position measured: after two measurements the initial state is
    # pinned (test 1: M = 0 from k_f = 1) and N stays bounded (test 2): it starts near the
    # two-point velocity variance 2R/T_s² ≈ 200 and settles to the stationary Riccati
    # solution (scipy's solve_discrete_are, 1e-8). N equals the Kalman covariance with
    # P(0|−1) = ψI, ψ → ∞: with ψ = 1e6 they agree to 1e-4 relative (O(1/ψ) plus rounding
    # of the ψ-sized cancellation).
    ts = 0.01
    a = np.array([[1.0, ts], [0.0, 1.0]])
    c = np.array([[1.0, 0.0]])
    n = 3000
    res = stochastic_observability(np.broadcast_to(a, (n, 2, 2)), np.broadcast_to(c, (n, 1, 2)),
                                   q=1e-4, r=1e-2, bound=1e3)
    assert res.test1 and res.k_f == 1 and res.test2 and res.observable
    assert np.all(res.lam_m[1:] == 0) and res.lam_m[0] > 0
    assert res.lam_n[1] == pytest.approx(2e-2 / ts**2, rel=0.01)
    stationary = solve_discrete_are(a.T, c.T, 1e-4 * np.eye(2), np.array([[1e-2]]))
    assert res.lam_n[-1] == pytest.approx(np.linalg.eigvalsh(stationary)[-1], rel=1e-8)
    p = _kalman_large_psi(a, c, 1e-4, 1e-2, 1e6, n)
    lam = np.linalg.eigvalsh(p)[:, -1]
    np.testing.assert_allclose(res.lam_n[5:], lam[5:], rtol=1e-4)


def test_stochastic_observability_of_an_unobservable_system() -> None:
    # Two decoupled random walks, only the first measured: the second initial state is never
    # observed, so M_k = e2 e2ᵀ ≠ 0 for ever (test 1 fails).
    a = np.eye(2)
    c = np.array([[1.0, 0.0]])
    n = 100
    res = stochastic_observability(np.broadcast_to(a, (n, 2, 2)), np.broadcast_to(c, (n, 1, 2)),
                                   q=1e-4, r=1e-2)
    assert not res.test1 and not res.observable and res.k_f is None
    assert np.all(res.diffuse_rank == 1)
    np.testing.assert_allclose(res.lam_m, 1.0)


def test_first_step_reproduces_000_A6() -> None:
    # (A6): Σ0 = C0ᵀΞ0⁻¹, N1 = Q0 + A0Σ0((Σ0ᵀΣ0)⁺)²Σ0ᵀA0ᵀ, M1 = A0X0X0ᵀA0ᵀ (exact).
    a = np.array([[1.0, 0.1], [0.2, 0.9]])
    c = np.array([[2.0, 1.0]])
    q, r = 1e-3, 4e-2
    res = stochastic_observability(a[None], c[None], q=q, r=r)
    sig = c.T / np.sqrt(r)
    pinv = 1.0 / (sig.T @ sig).item()
    n1 = q * np.eye(2) + a @ sig * pinv**2 @ sig.T @ a.T
    phi = np.eye(2) - sig @ sig.T * pinv
    m1 = a @ phi @ a.T
    assert res.lam_n[0] == pytest.approx(np.linalg.eigvalsh(n1)[-1], rel=1e-10)
    assert res.lam_m[0] == pytest.approx(np.linalg.eigvalsh(m1)[-1], rel=1e-10)


def test_analyze_observability_writes_figures_and_summary(tmp_path: Path) -> None:
    t = np.arange(0, 0.4, 0.005)
    log = pd.DataFrame({"t": t, **{f"omega_{c}": 10 + 100 * t for c in ("fl", "fr", "rl", "rr")}})
    rep = analyze_observability(log, VEH, tmp_path, corners=("fl",))
    names = sorted(p.name for p in rep.figures)
    assert names == ["observability_gramian.png", "observability_region.png",
                     "observability_test1.png", "observability_test2.png"]
    assert all(p.stat().st_size < 300_000 for p in rep.figures)
    data = json.loads((tmp_path / "observability.json").read_text())
    assert data["region"]["full_rank"] is True
    lug = next(r for r in rep.results if r.model == "lugre_x")
    assert lug.gramian_full_rank_from is not None and lug.stochastic_test1
    assert "| fl | lugre_x |" in (tmp_path / "observability.md").read_text()


def test_analyze_observability_names_a_missing_column(tmp_path: Path) -> None:
    log = pd.DataFrame({"t": [0.0, 0.005, 0.01], "omega_fl": [1.0, 1.0, 1.0]})
    with pytest.raises(LogFormatError, match="omega_fr"):
        analyze_observability(log, VEH, tmp_path)
