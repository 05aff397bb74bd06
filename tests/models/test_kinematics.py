"""Kinematics kernels of vestim.models.kinematics."""

import numpy as np

from vestim.models.kinematics import yaw_acceleration_kernel


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
