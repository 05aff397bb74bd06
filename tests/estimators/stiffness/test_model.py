"""The single-track estimation model (002 eq. (1)–(12)) against closed forms and its own structure."""

import math
from dataclasses import replace

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from vestim.constants import G
from vestim.estimators.stiffness.model import (
    N_INPUT,
    U_DELTA,
    U_DT,
    U_OMEGA_F,
    U_OMEGA_R,
    VX,
    VY,
    YAW_RATE,
    SingleTrackParams,
    model_terms,
    pitch_gradient,
    roll_gradient,
    simulate,
    slips,
)
from vestim.io import load_vehicle

SUV = load_vehicle("hashemi_suv")
NOMINAL = (220e3, 215e3, 140e3, 135e3)


def _params(drivetrain: str = "fwd", drag: float = 0.0) -> SingleTrackParams:
    p = SingleTrackParams.from_vehicle(SUV.with_drivetrain(drivetrain), NOMINAL)
    return replace(p, drag=drag)


def _terms(params: SingleTrackParams, x, u):
    f = np.empty(3)
    g = np.empty((3, 3))
    h = np.empty(3)
    d = np.empty((3, 3))
    model_terms(np.asarray(x, float), np.asarray(u, float), params.pack(), f, g, h, d)
    return f, g, h, d


def test_steady_state_cornering_matches_the_linear_bicycle_model():
    """Steady state of eq. (1b)–(1c) with (2), (4) at constant v_x and λ = 0.

    Closed form (Rajamani, 002 ref. [27]): ψ̇/δ = v/(L + K v²) with understeer gradient
    K = m (l_r C_r − l_f C_f)/(L C_f C_r), and v_y = (l_r − m l_f v²/(L C_r)) ψ̇. The
    model keeps eq. (1)'s cos δ on the front force, i.e. C_f → C_f cos δ in the closed
    form. The Euler map's fixed point is the continuous steady state, so the match is
    to round-off (1e-10 after 30 s of iteration, the slowest mode has decayed).
    """
    params = _params()
    m, lf, lr = params.mass, params.lf, params.lr
    cr = NOMINAL[3]
    big_l = lf + lr
    for v in (10.0, 22.0, 35.0):
        delta = 0.004
        u = np.zeros(N_INPUT)
        u[U_DELTA] = delta
        u[U_OMEGA_F] = u[U_OMEGA_R] = v / params.wheel_radius
        u[U_DT] = 0.005
        x = np.array([v, 0.0, 0.0])
        for _ in range(6000):
            f, _, _, _ = _terms(params, x, u)
            x = np.array([v, f[VY], f[YAW_RATE]])  # v_x held, as the closed form assumes
        cf = NOMINAL[2] * math.cos(delta)
        k_us = m * (lr * cr - lf * cf) / (big_l * cf * cr)
        r_ss = v * delta / (big_l + k_us * v**2)
        vy_ss = (lr - m * lf * v**2 / (big_l * cr)) * r_ss
        assert x[YAW_RATE] == pytest.approx(r_ss, rel=1e-10)
        assert x[VY] == pytest.approx(vy_ss, rel=1e-9, abs=1e-12)


@settings(max_examples=60, deadline=None)
@given(st.floats(5.0, 40.0), st.floats(-1.0, 1.0), st.floats(-0.5, 0.5), st.floats(-0.05, 0.05),
       st.floats(-0.05, 0.05), st.floats(-0.05, 0.05), st.sampled_from(["fwd", "rwd", "awd"]),
       st.floats(-0.5, 0.5), st.floats(-0.5, 0.5), st.floats(-0.5, 0.5))
def test_affine_in_the_stiffness_deviation(vx, vy, r, delta, sf, sr, dt, a, b, c):
    """002 eq. (9), (12): f + g w and h + d w equal the model evaluated at C_n + ΔC (eq. (7)).

    The deviation w is mapped to axle stiffness with ``deviation_to_axles``; the model
    is linear in C, so the identity is exact (1e-9 relative: round-off).
    """
    params = _params(dt, drag=0.6)
    w = np.array([a * NOMINAL[0], b * NOMINAL[2], c * NOMINAL[3]])
    u = [delta, (1 + sf) * vx / params.wheel_radius, (1 + sr) * vx / params.wheel_radius, 0.005]
    x = [vx, vy, r]
    f, g, h, d = _terms(params, x, u)
    shifted = replace(params, nominal=tuple(params.deviation_to_axles(w)))
    f2, _, h2, _ = _terms(shifted, x, u)
    np.testing.assert_allclose(f + g @ w, f2, rtol=1e-9, atol=1e-9)
    np.testing.assert_allclose(h + d @ w, h2, rtol=1e-9, atol=1e-9)


def test_d_is_the_acceleration_sensitivity_not_ts_times_g():
    """002 eq. (12) prints d = [T_s g_1; T_s g_2; 0]; with g = T_s ∂ẋ/∂w (eq. (10)) the physical
    acceleration sensitivity is g/T_s. Rows a_x, a_y of d times T_s are the v_x, v_y rows of g,
    and the gyro row is zero (exact)."""
    params = _params()
    _, g, h, d = _terms(params, [20.0, 0.3, 0.1], [0.02, 62.0, 61.0, 0.005])
    np.testing.assert_allclose(d[0] * 0.005, g[VX], rtol=1e-15)
    np.testing.assert_allclose(d[1] * 0.005, g[VY], rtol=1e-15)
    np.testing.assert_array_equal(d[2], 0.0)
    assert h[2] == 0.1


def test_slip_signs_follow_the_log_spec():
    """Eq. (3) with the spec's sign: traction (Rω > v_x) gives λ > 0; eq. (4): a left-steered
    front wheel in straight motion has α_f = δ > 0 (force to the left)."""
    p = _params().pack()
    lam_f, lam_r, af, ar = slips(20.0, 0.0, 0.0, 0.01, 21.0 / 0.33, 19.0 / 0.33, p)
    assert lam_f == pytest.approx(1 / 21) and lam_r == pytest.approx(-1 / 20)
    assert af == pytest.approx(0.01) and ar == 0.0


def test_drag_enters_a_x():
    """Aerodynamic drag −c v|v|/m in eq. (1a) (not in 002's Assumption 4)."""
    u = [0.0, 20.0 / 0.33, 20.0 / 0.33, 0.005]
    _, _, h0, _ = _terms(_params(drag=0.0), [20.0, 0.0, 0.0], u)
    _, _, h1, _ = _terms(_params(drag=0.66), [20.0, 0.0, 0.0], u)
    assert h1[0] - h0[0] == pytest.approx(-0.66 * 400.0 / SUV.body.mass)


def test_longitudinal_ties():
    """FWD/AWD: w_x is ΔC_f^x and ΔC_r^x = w_x C_{r,n}^x/C_{f,n}^x (the same relative change);
    RWD: w_x is ΔC_r^x and ΔC_f^x = w_x C_{f,n}^x/C_{r,n}^x. The cornering stiffnesses do not
    enter the longitudinal ones."""
    cxf, cxr, cyf, cyr = NOMINAL
    w = np.array([10e3, -14e3, -13.5e3])
    fwd = _params("fwd").deviation_to_axles(w)
    np.testing.assert_allclose(fwd, [cxf + 10e3, cxr * (1.0 + 10e3 / cxf), cyf - 14e3, cyr - 13.5e3])
    rwd = _params("rwd").deviation_to_axles(w)
    np.testing.assert_allclose(rwd, [cxf * (1.0 + 10e3 / cxr), cxr + 10e3, cyf - 14e3, cyr - 13.5e3])
    back = _params("rwd").axles_to_deviation(rwd)
    np.testing.assert_allclose(back, w)
    np.testing.assert_allclose(_params("fwd").axles_to_deviation(fwd), w)


def test_simulate_is_the_euler_recursion():
    params = _params(drag=0.5)
    k = 50
    u = np.tile([0.01, 65.0, 64.0, 0.005], (k, 1))
    w = np.tile([5e3, -3e3, 2e3], (k, 1))
    x, y = simulate(np.array([21.0, 0.1, 0.02]), u, w, params)
    f, g, h, d = _terms(params, x[10], u[10])
    np.testing.assert_allclose(x[11], f + g @ w[10], rtol=1e-13)
    np.testing.assert_allclose(y[10], h + d @ w[10], rtol=1e-13)
    with pytest.raises(ValueError, match="u must be"):
        simulate(np.zeros(3), u[:, :3], w, params)


def test_invalid_parameters_are_named():
    with pytest.raises(ValueError, match="mass"):
        SingleTrackParams(mass=-1, yaw_inertia=1, lf=1, lr=1, wheel_radius=0.3, nominal=NOMINAL)
    with pytest.raises(ValueError, match="drivetrain"):
        SingleTrackParams(1, 1, 1, 1, 0.3, NOMINAL, drivetrain="4wd")
    with pytest.raises(ValueError, match="nominal"):
        SingleTrackParams(1, 1, 1, 1, 0.3, (1.0, 2.0, -3.0, 4.0))


def test_roll_and_pitch_gradients_match_the_simulator(study_log_ideal):
    """a_y,IMU = a_y (1 + c_φ g) and a_x,IMU = a_x (1 + c_θ g) (002 Sec. II-A, roll; pitch alike).

    The simulator's sprung body is a damped second-order mode, so the regression of the
    measured roll on the measured a_y over the square-wave maneuver sees its dynamics too;
    5 % (roll) and 12 % (pitch, whose 1.5 Hz mode is excited by the torque steps) cover it.
    """
    log = study_log_ideal
    s = log["t"].to_numpy() > 2.0
    ay = log["ay"].to_numpy()[s]
    ax = log["ax"].to_numpy()[s]
    c_phi = np.polyfit(ay / (1 + roll_gradient(SUV) * G), log["ref_roll"].to_numpy()[s], 1)[0]
    c_theta = -np.polyfit(ax / (1 + pitch_gradient(SUV) * G), log["ref_pitch"].to_numpy()[s], 1)[0]
    assert c_phi == pytest.approx(roll_gradient(SUV), rel=0.05)
    assert c_theta == pytest.approx(pitch_gradient(SUV), rel=0.12)
    assert math.isfinite(c_phi)
