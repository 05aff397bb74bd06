"""Friction potential (vestim.estimators.friction): the shape inversion and the excitation
logic against a tire that follows the model exactly, then against one that does not."""

from __future__ import annotations

import math
from dataclasses import fields

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from vestim.estimators.friction import (
    FrictionKernelParams,
    FrictionParams,
    friction_kernel,
    friction_params,
    invert_shape,
    new_friction_state,
)


def _mf(z: float, c: float) -> float:
    return math.sin(c * math.atan(z / c))


@settings(max_examples=300, deadline=None)
@given(mu=st.floats(0.1, 1.2), k_lin=st.floats(0.05, 3.0), c=st.floats(1.0, 1.9))
def test_inversion_recovers_mu_of_a_magic_formula_tire(mu: float, k_lin: float, c: float):
    """u = μ F(k/μ) on the rising branch (k/μ below the peak at C tan(π/2C)) inverts to μ
    exactly: y = u/μ is the one root of F(q y) = y, found to 2⁻⁴⁰ by bisection, so μ comes
    back to ~1e-9 relative."""
    z = k_lin / mu
    peak = c * math.tan(math.pi / (2 * c))
    if z >= peak or z < 1e-3:
        return
    u = mu * _mf(z, c)
    y = invert_shape(k_lin / u, c)
    assert u / y == pytest.approx(mu, rel=1e-8)


def test_linear_range_gives_no_information():
    assert invert_shape(1.0, 1.3) == 1.0
    assert invert_shape(0.7, 1.3) == 1.0


def _run(u_x, u_y, slip_ratio, slip_angle, ky=20.0, kx=20.0, sigma_u=0.01, p=None):
    n = len(u_x)
    p = p or FrictionParams()
    t = np.arange(n) * 0.005
    col = lambda v: np.repeat(np.asarray(v, float)[:, None], 4, axis=1)  # noqa: E731
    mu = np.empty((n, 4))
    smu = np.empty((n, 4))
    ex = np.empty((n, 4))
    one = np.ones((n, 4))  # F_z = 1 N: the forces are the normalised ones
    friction_kernel(friction_params(p, np.full(4, kx)), new_friction_state(), t, col(u_x),
                    col(u_y), one, col(np.full(n, sigma_u)), np.zeros((n, 4)),
                    col(slip_ratio), col(slip_angle), np.zeros(n), np.full(n, ky), mu, smu, ex)
    return mu[:, 0], smu[:, 0], ex[:, 0]


def test_saturated_tire_on_ice_is_excited_and_reads_its_friction():
    """A lateral MF tire (C = 1.3, K_y = 20/rad) at μ = 0.3 and α = −3°: k = 1.05, well past
    the linear range; the stage must flag it and read μ = 0.3 (the model is exact here)."""
    mu_true, alpha = 0.3, -math.radians(3.0)
    k_lin = 20.0 * math.tan(alpha)
    u = mu_true * _mf(abs(k_lin) / mu_true, 1.3)
    n = 20
    mu, smu, ex = _run(np.zeros(n), np.full(n, -u), np.zeros(n), np.full(n, alpha))
    assert ex[0] == 0.0  # persistence: the first sample alone is not evidence
    assert np.all(ex[2:] == 1.0)
    np.testing.assert_allclose(mu[2:], mu_true, rtol=1e-6)
    assert np.all(smu[2:] <= 0.05)


def test_linear_tire_on_dry_road_is_not_excited():
    """μ = 1.0, α = −0.5°: the tire uses 17 % of its friction and sits within 2σ of its linear
    line, so μ must be NaN (unknown), never a number near u."""
    alpha = -math.radians(0.5)
    k_lin = 20.0 * abs(math.tan(alpha))
    u = _mf(k_lin, 1.3)
    n = 20
    mu, smu, ex = _run(np.zeros(n), np.full(n, -u), np.zeros(n), np.full(n, alpha))
    assert np.all(ex == 0.0)
    assert np.all(np.isnan(mu)) and np.all(np.isnan(smu))


def test_slip_error_of_the_size_assumed_does_not_fake_saturation():
    """A linear tire (u = K κ = 0.2 at κ = 0.01) with its slip ratio read 0.015 high (the
    sigma_slip_ratio of the defaults) must not be taken for saturated: k − u = 0.29 is
    about 1σ of k (0.31), below the 2σ excess required."""
    n = 20
    _, _, ex = _run(np.full(n, 0.2), np.zeros(n), np.full(n, 0.025), np.zeros(n))
    assert np.all(ex == 0.0)


def test_params_are_validated():
    with pytest.raises(ValueError, match="shape_lateral"):
        FrictionParams(shape_lateral=2.5)
    with pytest.raises(ValueError, match="sigma_max"):
        FrictionParams(sigma_max=0.0)


def test_params_are_packed_from_the_config_and_the_stiffness() -> None:
    """Every config field the kernel reads is the config's (non-default values) and the
    corners' K_x are the ``kx`` given, by name."""
    cfg = FrictionParams(shape_lateral=1.2, shape_longitudinal=1.5, kx_nominal=25.0,
                         sigma_k=0.1, sigma_slip_ratio=0.02, sigma_slip_angle=0.004,
                         excess_sigmas=2.5, sigma_max=0.06, u_min=0.1, persist_s=0.02,
                         sigma_vy_floor=0.2)
    prm = friction_params(cfg, np.array([18.0, 19.0, 21.0, 22.0]))
    assert isinstance(prm, FrictionKernelParams)
    for f in fields(FrictionParams):
        if f.name in FrictionKernelParams._fields:
            assert getattr(prm, f.name) == getattr(cfg, f.name), f.name
    assert (prm.kx_fl, prm.kx_fr, prm.kx_rl, prm.kx_rr) == (18.0, 19.0, 21.0, 22.0)


def test_persistence_and_u_min_reach_the_kernel() -> None:
    """The saturated ice tire of the test above (u = 0.300): with persist_s = 0.05 s the
    flag waits 10 samples of 5 ms (2 with the default 0.01 s); with u_min = 0.35 (above
    u) it never comes."""
    mu_true, alpha = 0.3, -math.radians(3.0)
    u = mu_true * _mf(abs(20.0 * math.tan(alpha)) / mu_true, 1.3)
    n = 20
    args = (np.zeros(n), np.full(n, -u), np.zeros(n), np.full(n, alpha))
    _, _, ex = _run(*args, p=FrictionParams(persist_s=0.05))
    assert np.all(ex[:10] == 0.0) and np.all(ex[10:] == 1.0)
    _, _, ex = _run(*args, p=FrictionParams(u_min=0.35))
    assert np.all(ex == 0.0)
