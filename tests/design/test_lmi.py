"""LMI certificates: stability (001 eq. (27)-(28), 004 eq. (18)) and H∞ γ (004 eq. (24)-(25)).

Every certificate is re-checked by eigenvalues on a grid ten times finer than the
solve grid; the tests check both the solver's answer and that verification.
"""

from __future__ import annotations

import numpy as np
import pytest

from vestim.design.analysis import affine_quadratic_stability, check_lyapunov, hinf_performance
from vestim.design.frequency import frozen_hinf_norm
from vestim.design.lmi import (
    Context,
    Layout,
    LPVSystem,
    ParameterBox,
    affine_basis,
    verification_grid,
)
from vestim.io.vehicle import load_vehicle
from vestim.models import lpv

AX = lpv.longitudinal_axis(load_vehicle("hashemi_suv"))
BOX = ParameterBox(0.0, 180.0, 800.0)
H = np.array([[0.0, 1.0]])


def _observer(l1: float, l2: float) -> LPVSystem:
    a0, a1, be = lpv.affine_error_dynamics(l1, l2, AX)
    return LPVSystem.from_affine(a0, a1, be, None, H)


def test_verification_grid_is_ten_times_finer() -> None:
    assert verification_grid(BOX, 21).size == 201
    assert verification_grid(BOX, 41).size == 401
    assert verification_grid(BOX, 2).size == 201  # never fewer than 201 points


def test_layout_round_trip_and_affine_basis_reproduce_the_builder() -> None:
    lay = Layout()
    lay.add("P", (2, 3, 3), symmetric=True)
    lay.add("X", (2, 3, 1))
    lay.add("g", ())
    rng = np.random.default_rng(0)
    x = rng.normal(size=lay.size)
    vals = lay.unpack(x)
    np.testing.assert_array_equal(vals["P"], np.swapaxes(vals["P"], -1, -2))
    np.testing.assert_array_equal(lay.pack(vals), x)

    def build(v: dict[str, np.ndarray], ctx: Context) -> np.ndarray:
        return v["P"][0][None] + ctx.rho[:, None, None] * v["P"][1][None] - v["g"] * np.eye(3)

    ctx = Context(np.array([0.0, 0.5, 2.0]), np.zeros(3), {})
    g0, gx = affine_basis(lay, build, ctx)
    np.testing.assert_allclose(g0 + (gx @ x).reshape(3, 3, 3), build(vals, ctx), atol=1e-12)


def test_papers_constant_gains_are_affinely_quadratically_stable() -> None:
    # 001 Sec. IV-A1: L1x = 0.68, L2x = 183.1 over |ω| ≤ 180, |ω̇| ≤ 800 are claimed stable;
    # the vertex test with multi-convexity finds P(ω) and it verifies on 201 points.
    res = affine_quadratic_stability(_observer(0.68, 183.1), BOX, method="vertex")
    assert res.feasible and res.verified, res.summary()
    assert res.min_eig > 0
    assert res.verify_grid.size == 201
    assert res.frozen_max_real < 0


@pytest.mark.parametrize("method", ["vertex", "grid"])
def test_destabilising_gains_are_reported_infeasible(method: str) -> None:
    # L1 = −1, L2 = −100: A_e(ω) has an eigenvalue with positive real part (checked below),
    # so no Lyapunov matrix exists; the result must say infeasible and not verified.
    sys_ = _observer(-1.0, -100.0)
    a, *_ = sys_.matrices(np.array([0.0, 90.0, 180.0]))
    assert np.max(np.linalg.eigvals(a).real) > 0
    res = affine_quadratic_stability(sys_, BOX, method=method, n_grid=11)  # type: ignore[arg-type]
    assert not res.feasible and not res.verified
    hinf = hinf_performance(sys_, BOX, method=method, n_grid=11)  # type: ignore[arg-type]
    assert not hinf.verified and hinf.gamma is None


def test_printed_lyapunov_of_001_eq29_fails_eq28_but_satisfies_the_dual_form() -> None:
    # 001 eq. (29) against eq. (28) as printed (AᵀP + PA + ω̇P1 ≺ 0): violated, worst at ω = 0,
    # ω̇ = −800 with λ_max ≈ +9.28e9. Read as Q(ω) of A Q + Q Aᵀ − ω̇Q1 ≺ 0 (MATLAB pdlstab's
    # form, V = eᵀQ⁻¹e) it holds with λ_max ≈ −361.7 on 1801 points. Tolerance 1 %: the paper
    # prints 5 significant digits.
    p = np.array([[[1.2176, 115.35], [115.35, 80379.0]], [[-0.0011, -0.2227], [-0.2227, -67.969]]])
    sys_ = _observer(0.68, 183.1)
    primal = check_lyapunov(sys_, BOX, p, form="primal", n_verify=1801)
    dual = check_lyapunov(sys_, BOX, p, form="dual", n_verify=1801)
    assert not primal.verified
    assert -primal.checks[1].min_eig == pytest.approx(9.278e9, rel=1e-2)
    assert dual.verified
    assert dual.checks[1].min_eig == pytest.approx(361.7, rel=1e-2)
    assert dual.checks[1].worst_rho == 0.0


def test_gamma_of_an_lti_system_equals_its_hinf_norm() -> None:
    # Lightly damped oscillator ẍ + 2ζw ẋ + w²x = u, z = x (ζ = 0.1, w = 3): the H∞ norm is
    # 1/(2ζ√(1−ζ²) w²) = 0.5583. With ρ̇ = 0 and ρ-independent matrices, the LMI optimum γ* is
    # that norm (bounded real lemma is exact for LTI); the frequency sweep gives it
    # independently. Tolerance 1e-4: solver accuracy ~1e-8 and a 2000-point sweep.
    zeta, wn = 0.1, 3.0
    a = np.array([[0.0, 1.0], [-wn**2, -2 * zeta * wn]])
    sys_ = LPVSystem.from_affine(a, np.zeros((2, 2)), np.array([[0.0], [1.0]]), None,
                                 np.array([[1.0, 0.0]]))
    box = ParameterBox(0.0, 1.0, 0.0)
    exact = 1 / (2 * zeta * np.sqrt(1 - zeta**2) * wn**2)
    sweep, _ = frozen_hinf_norm(sys_, np.array([0.5]), np.linspace(0, 10, 20001))
    res = hinf_performance(sys_, box, method="vertex")
    assert sweep[0] == pytest.approx(exact, rel=1e-4)
    assert res.gamma_opt == pytest.approx(exact, rel=1e-4)
    assert res.verified and res.gamma is not None and res.gamma >= exact


def test_lpv_gamma_bounds_every_frozen_hinf_norm() -> None:
    # The LPV γ covers all parameter trajectories, so it is at least the worst frozen H∞ norm
    # (a frequency sweep at each ω), here ≈ 1.0 from the DC coupling Ω_z → e_vr.
    sys_ = _observer(0.68, 183.1)
    res = hinf_performance(sys_, BOX, method="vertex")
    frozen, _ = frozen_hinf_norm(sys_, np.linspace(0, 180, 19))
    assert res.verified and res.gamma is not None
    assert res.gamma >= frozen.max() * (1 - 1e-9)
    assert frozen.max() >= 1.0


def test_grid_method_with_quadratic_p_verifies() -> None:
    res = affine_quadratic_stability(_observer(0.68, 183.1), BOX, method="grid", degree=2,
                                     n_grid=11)
    assert res.verified and res.lyapunov is not None and res.lyapunov.shape == (3, 2, 2)


def test_vertex_method_needs_an_affine_system() -> None:
    sys_ = LPVSystem(evaluate=_observer(0.68, 183.1).evaluate)
    with pytest.raises(ValueError, match="affine"):
        affine_quadratic_stability(sys_, BOX, method="vertex")


def test_parameter_box_validation() -> None:
    with pytest.raises(ValueError, match="lower < upper"):
        ParameterBox(1.0, 1.0, 0.0)
    with pytest.raises(ValueError, match="rate"):
        ParameterBox(0.0, 1.0, -1.0)
