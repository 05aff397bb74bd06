"""Reference-speed filter on synthetic signals whose truth is known in closed form."""

from __future__ import annotations

from dataclasses import fields, replace
from typing import Any

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from vestim.estimators.velocity.reference import (
    ReferenceFilter,
    ReferenceKernelParams,
    ReferenceParams,
    StiffnessParams,
    reference_params,
    stiffness_params,
)

R = 0.37
XW = np.array([1.4, 1.4, -1.6, -1.6])
YW = np.array([0.8, -0.8, 0.8, -0.8])
FS = 200.0


def _inputs(vx: np.ndarray, f_x: np.ndarray, f_y: np.ndarray, r: np.ndarray,
            axle_slip: np.ndarray) -> dict[str, np.ndarray]:
    n = vx.shape[0]
    # Free-rolling wheels on a straight road: R ω_i = v_x − r y_i.
    omega = (vx[:, None] - r[:, None] * YW[None, :]) / R
    return {"t": np.arange(n) / FS, "omega": np.ascontiguousarray(omega),
            "torque": np.zeros((n, 4)), "mu_x": np.zeros((n, 4)),
            "axle_slip": np.ascontiguousarray(axle_slip), "f_x": f_x, "f_y": f_y,
            "yaw_rate": r, "delta": np.zeros((n, 4))}


def _run(inp: dict[str, np.ndarray], params: ReferenceParams | None = None,
         chunks: int = 1) -> dict[str, np.ndarray]:
    filt = ReferenceFilter(R, 1.4, 1.6, XW, YW, params)
    parts = []
    for idx in np.array_split(np.arange(inp["t"].shape[0]), chunks):
        parts.append(filt.advance(**{k: np.ascontiguousarray(v[idx]) for k, v in inp.items()}))
    out = {k: np.concatenate([p[k] for p in parts]) for k in parts[0]}
    out["P"] = filt.state.P.copy()
    return out


def test_accelerometer_biases_are_learnt_while_driving_straight() -> None:
    # 20 s at 20 m/s; the accelerometers read +0.1 (x) and −0.08 m/s² (y) of bias. The
    # wheel speeds fix v_x and the straight-road slip angles fix v_y = 0, so b_x and the
    # lumped lateral bias b_y − b_r v_x (at constant speed the two are one) are learnt.
    n = int(20 * FS)
    vx = np.full(n, 20.0)
    out = _run(_inputs(vx, np.full(n, 0.1), np.full(n, -0.08), np.zeros(n), np.zeros((n, 2))))
    b = out["bias"][-1]
    assert b[0] == pytest.approx(0.1, abs=0.02)
    assert b[1] - b[2] * 20.0 == pytest.approx(-0.08, abs=0.02)
    assert np.abs(out["v"][-200:, 0] - 20.0).max() < 0.02
    assert np.abs(out["v"][-200:, 1]).max() < 0.02


def test_gyro_bias_is_separated_when_the_speed_changes() -> None:
    # Straight road, speed 10 → 30 m/s over 40 s; the yaw gyro reads +0.002 rad/s of bias
    # and the lateral accelerometer −0.05 m/s². The gyro bias enters v̇_y scaled by v_x,
    # so a changing speed separates it from the accelerometer bias: b_r within 0.5 mrad/s.
    n = int(40 * FS)
    t = np.arange(n) / FS
    vx = 10.0 + 0.5 * t
    inp = _inputs(vx, np.full(n, 0.5), np.full(n, -0.05), np.zeros(n), np.zeros((n, 2)))
    inp["yaw_rate"] = np.full(n, 0.002)
    inp["omega"] = np.ascontiguousarray(np.repeat(vx[:, None] / R, 4, axis=1))
    b = _run(inp)["bias"][-1]
    assert b[2] == pytest.approx(0.002, abs=5e-4)
    assert b[1] == pytest.approx(-0.05, abs=0.02)


def test_the_r_coupling_lets_speed_fixes_correct_vy() -> None:
    """A slalom at 20 m/s (r = 0.3 sin(2π t/4 s) rad/s), no wheel speeds, no tire information
    (NaN slip angles), a speed fix (σ 0.1 m/s) every 0.1 s, v_y started 1 m/s off: the
    prediction's v̇_x = f_x + r v_y carries the v_y error into v_x, and the covariance's
    r-coupling (∂v̇_x/∂v_y = r) lets the fixes, which see that v_x error, correct v_y: 0.16 m/s
    off after 20 s (measured; bound 0.3). The decoupled covariance before issue 29 could not
    move v_y from a speed fix at all. (A steady turn cannot do it: a constant r v_y error is
    an a_x bias to the fixes.) P stays symmetric positive definite, v_x and v_y correlated."""
    n = int(20 * FS)
    t = np.arange(n) / FS
    r = 0.3 * np.sin(2 * np.pi * t / 4.0)
    inp = _inputs(np.full(n, 20.0), np.zeros(n), 20.0 * r, r, np.full((n, 2), np.nan))
    inp["omega"] = np.full((n, 4), np.nan)
    fix = np.where(np.arange(n) % 20 == 0, 20.0, np.nan)[:, None]
    var = np.full((n, 1), 0.01)
    filt = ReferenceFilter(R, 1.4, 1.6, XW, YW)
    filt.advance(**{k: v[:1] for k, v in inp.items()}, extra_v=fix[:1], extra_var=var[:1])
    filt.state.x[1] = 1.0
    out = filt.advance(**{k: np.ascontiguousarray(v[1:]) for k, v in inp.items()},
                       extra_v=fix[1:], extra_var=var[1:])
    assert abs(out["v"][-1, 1]) < 0.3
    P = filt.state.P
    np.testing.assert_allclose(P, P.T, atol=1e-12)
    assert np.linalg.eigvalsh(P).min() > 0.0
    assert P[0, 1] != 0.0


def test_saturated_axle_bound_lets_the_integral_carry_vy() -> None:
    # Sliding at the limit: the true v_y falls at 0.25 m/s² for 2 s (the kinematic f_y − r v_x
    # says so) to −0.5 m/s and stays there for 10 s, while the linear-tire slip angles,
    # which under-state a saturated tire's slip, claim α = −0.01 rad (z = −0.2 m/s at
    # 20 m/s, an upper bound on v_y; the innovation 0.3 m/s is inside the 3σ gate). The
    # one-sided treatment keeps the integral (within 0.01 m/s of the truth after 10 s); a
    # symmetric treatment (side_vy → ∞) is dragged towards the bound (0.25 m/s off). The
    # mechanism is tested at a strong one-sidedness (side_vy 0.05 m/s, k_rel 1, 3σ gate);
    # the default (side_vy 1 m/s, k_rel 0.3, 6σ) is weaker, because with a nominal stiffness
    # 30 % off (the crossplant tires) the allowed side of the bound is itself uncertain.
    n = int(14 * FS)
    t = np.arange(n) / FS
    slip = np.where(t > 2.0, -0.01, 0.0)[:, None] * np.ones((1, 2))
    f_y = np.where((t > 2.0) & (t <= 4.0), -0.25, 0.0)
    inp = _inputs(np.full(n, 20.0), np.zeros(n), f_y, np.zeros(n), slip)
    strong = ReferenceParams(side_vy=0.05, k_rel=1.0, gate_vy=3.0)
    one_sided = _run(inp, strong)["v"][-1, 1]
    symmetric = _run(inp, replace(strong, side_vy=1e9))["v"][-1, 1]
    assert abs(one_sided - -0.5) < 0.01
    assert abs(symmetric - -0.5) > 0.2


def test_chunked_processing_equals_batch() -> None:
    n = int(4 * FS)
    t = np.arange(n) / FS
    vx = 10.0 + 2.0 * t
    r = 0.1 * np.sin(2 * t)
    inp = _inputs(vx, np.full(n, 2.0), vx * r, r, np.zeros((n, 2)))
    a = _run(inp)
    b = _run(inp, chunks=7)
    np.testing.assert_array_equal(a["v"], b["v"])
    np.testing.assert_array_equal(a["bias"], b["bias"])


@settings(max_examples=25, deadline=None)
@given(seed=st.integers(0, 2**31 - 1), speed=st.floats(0.0, 40.0),
       slip=st.floats(-0.5, 0.5), with_corner=st.booleans())
def test_covariance_stays_symmetric_positive_definite(seed: int, speed: float, slip: float,
                                                      with_corner: bool) -> None:
    """Whatever the wheels, torques, accelerations, slip angles and corner measurements
    (random, including wheels spinning by a factor 1 + slip and rejected updates), P stays
    symmetric positive definite, and the state stays finite."""
    rng = np.random.default_rng(seed)
    n = 400
    vx = np.full(n, speed) + np.cumsum(rng.normal(0.0, 0.02, n))
    r = rng.normal(0.0, 0.3, n)
    inp = _inputs(vx, rng.normal(0.0, 2.0, n), rng.normal(0.0, 2.0, n), r,
                  rng.normal(0.0, 0.05, (n, 2)))
    inp["omega"] = np.ascontiguousarray(inp["omega"] * (1.0 + slip * rng.random((n, 4))))
    inp["torque"] = rng.normal(0.0, 500.0, (n, 4))
    inp["mu_x"] = rng.normal(0.0, 0.3, (n, 4))
    inp["delta"][:, :2] = rng.normal(0.0, 0.1, (n, 1))
    filt = ReferenceFilter(R, 1.4, 1.6, XW, YW)
    extra = np.where(rng.random((n, 1)) < 0.3, vx[:, None] + rng.normal(0.0, 1.0, (n, 1)),
                     np.nan) if with_corner else None
    var = np.full((n, 1), 9.0) if with_corner else None
    out = filt.advance(**inp, extra_v=extra, extra_var=var)
    P = filt.state.P
    assert np.all(np.isfinite(out["v"])) and np.all(np.isfinite(P))
    np.testing.assert_allclose(P, P.T, atol=1e-12)
    assert np.linalg.eigvalsh(P).min() > 0.0


def test_kernel_params_take_every_tuning_field_from_the_config() -> None:
    # Every ReferenceParams field reaches the kernel by name but five: window (the rows of
    # the ω history, the state's shape), q_vx_speed (the speed mode's q_vx), sigma_gnss
    # and sigma_vehicle_speed (the pipeline's extra measurements), torque_dead_mu (a share
    # of the wheel load that raises torque_dead where the mass is given). Each field gets its own
    # value (index + 0.5) so that a field packed from another one would show.
    values: dict[str, Any] = {f.name: i + 0.5 for i, f in enumerate(fields(ReferenceParams))
                              if f.name != "window"}
    cfg = ReferenceParams(**values)
    kp = reference_params(cfg, R, 1.4, 1.6, XW, YW)
    tuning = {f.name for f in fields(ReferenceParams)}
    assert tuning - set(ReferenceKernelParams._fields) == {
        "window", "q_vx_speed", "sigma_gnss", "sigma_vehicle_speed", "torque_dead_mu"}
    for name in tuning & set(kp._fields):
        assert getattr(kp, name) == getattr(cfg, name), name
        assert type(getattr(kp, name)) is float, name  # one Numba type for every config
    assert kp.kin_fx is False
    assert (kp.radius, kp.lf, kp.lr) == (R, 1.4, 1.6)
    speed = reference_params(cfg, R, 1.4, 1.6, XW, YW, fx_from_speed=True)
    assert speed.kin_fx is True
    assert speed.q_vx == cfg.q_vx_speed
    assert speed.slip_sign == np.inf
    back = speed._replace(kin_fx=False, q_vx=cfg.q_vx, slip_sign=cfg.slip_sign)
    assert back[:-2] == kp[:-2]  # all but the arrays xw, yw
    # With the mass, the dead zone is the larger of the floor and the load share R·m g/4.
    heavy = reference_params(cfg, R, 1.4, 1.6, XW, YW, mass=2000.0)
    assert heavy.torque_dead == pytest.approx(cfg.torque_dead_mu * R * 2000.0 * 9.81 / 4.0)
    assert heavy.torque_dead > cfg.torque_dead


def test_a_changed_gate_reaches_the_kernel() -> None:
    # Free rolling at 20 m/s with the rr wheel reading 1.5 m/s high: its innovation is
    # 1.5 m/s against σ = √(r_wheel) = 0.22 m/s, i.e. 6.7σ. At the default gate (5σ) it is
    # rejected in every sample and v_x stays at 20 m/s (within 1e-5 m/s). At twice the gate
    # it is accepted: without the soft gate with the others' weight, so v_x reads their
    # mean, 20.375 m/s; with it (beyond 2σ while three wheels agree) as a slipping wheel,
    # σ raised to 0.75 m/s with the excess as persistent slip (τ_wheel/T_s = 200): its weight
    # is then ≈ 1/1000 of the other three's and v_x stays within 2 mm/s of 20.
    n = int(10 * FS)
    inp = _inputs(np.full(n, 20.0), np.zeros(n), np.zeros(n), np.zeros(n), np.zeros((n, 2)))
    inp["omega"][:, 3] += 1.5 / R
    p = ReferenceParams()
    tight = _run(inp, p)
    wide = _run(inp, replace(p, gate=2.0 * p.gate, soft_gate=1e9))
    soft = _run(inp, replace(p, gate=2.0 * p.gate))
    assert np.all(np.isinf(tight["trust"][:, 3]))
    assert np.all(np.isfinite(wide["trust"][:, 3]))
    assert np.all(np.isfinite(soft["trust"][:, 3]))
    assert np.abs(tight["v"][-200:, 0] - 20.0).max() < 1e-5
    assert np.abs(wide["v"][-200:, 0] - 20.375).max() < 1e-3
    assert np.abs(soft["v"][-200:, 0] - 20.0).max() < 2e-3


def test_stiffness_params_derive_the_prior_from_c0() -> None:
    # c₀ = 15 /rad: prior compliance 1/15 rad and weight (σ_κ c₀/prior_sd)² =
    # (0.01·15/0.3)² = 0.25; the other fields are the config's.
    cfg = StiffnessParams()
    kp = stiffness_params(15.0, cfg, R, 3.0)
    assert kp.w0 == pytest.approx(1.0 / 15.0)
    assert kp.prior_weight == pytest.approx(0.25)
    for name in set(kp._fields) - {"w0", "prior_weight", "radius", "wheelbase"}:
        assert getattr(kp, name) == getattr(cfg, name), name
    assert (kp.radius, kp.wheelbase) == (R, 3.0)
