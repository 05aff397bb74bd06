"""Kinematics kernels of vestim.models.kinematics."""

import numpy as np
from hypothesis import given
from hypothesis import strategies as st

from vestim.models.kinematics import euler_rates, yaw_acceleration_kernel


def test_yaw_acceleration_kernel_carries_across_chunks_and_zeroes_nan():
    """ṙ by backward differences: one call over a ramp r = 0.5 t (ṙ = 0.5 rad/s² after the
    first sample, 0 there with no previous sample) equals two calls over its halves with the
    carried [t, r]; a NaN rate gives 0, not NaN."""


    t = np.arange(10) * 0.005
    r = 0.5 * t
    whole = np.empty(10)
    yaw_acceleration_kernel(t, r, np.array([np.nan, 0.0]), whole)
    assert whole[0] == 0.0 and np.allclose(whole[1:], 0.5, rtol=1e-9)
    prev, parts = np.array([np.nan, 0.0]), np.empty(10)
    yaw_acceleration_kernel(t[:4], r[:4], prev, parts[:4])
    yaw_acceleration_kernel(t[4:], r[4:], prev, parts[4:])
    np.testing.assert_array_equal(parts, whole)
    assert prev[0] == t[-1] and prev[1] == r[-1]
    r[5] = np.nan
    out = np.empty(10)
    yaw_acceleration_kernel(t, r, np.array([np.nan, 0.0]), out)
    assert out[5] == 0.0 and out[6] == 0.0 and np.isfinite(out).all()


_angle = st.floats(-0.5, 0.5)
_rate = st.floats(-2.0, 2.0)


@given(_angle, _angle, _rate, _rate, _rate)
def test_euler_rates_invert_the_body_rates_of_a_zyx_rotation(roll: float, pitch: float,
                                                             droll: float, dpitch: float,
                                                             dyaw: float) -> None:
    """Body rates of Euler rates (φ̇, θ̇, ψ̇), p = φ̇ − ψ̇ sin θ, q = θ̇ cos φ + ψ̇ cos θ sin φ,
    r = ψ̇ cos θ cos φ − θ̇ sin φ (the crossplant plant's IMU, mbplant.py), map back to the
    same φ̇, θ̇ to rounding; a steady turn at a fixed roll (θ̇ = 0, q = ψ̇ cos θ sin φ ≠ 0)
    has no pitch rate."""
    sp, cp, sth, cth = np.sin(roll), np.cos(roll), np.sin(pitch), np.cos(pitch)
    p = droll - dyaw * sth
    q = dpitch * cp + dyaw * cth * sp
    r = dyaw * cth * cp - dpitch * sp
    phi_dot, theta_dot = euler_rates(p, q, r, roll, pitch)
    assert abs(phi_dot - droll) <= 1e-9
    assert abs(theta_dot - dpitch) <= 1e-9
