"""The fixed-size sigma points (N = 2, 3, 4) of vestim.filters.ukf equal the general ones bit for bit.

The force stage's kernels call the written-out forms for speed (issue 27); the pipeline's
numbers stay unchanged only if every sigma point is the same float as
:func:`sigma_points` gives, including where the Cholesky pivot floor acts.
"""

import numpy as np
import pytest

from vestim.filters.ukf import sigma_points, sigma_points2, sigma_points3, sigma_points4, ukf_weights


def _general(x: np.ndarray, P: np.ndarray) -> np.ndarray:
    n = x.shape[0]
    out = np.empty((2 * n + 1, n))
    sigma_points(x, P, ukf_weights(n)[2], np.empty((n, n)), out)
    return out


@pytest.mark.parametrize("seed", range(20))
def test_sigma_points3_equals_the_general_form_bit_for_bit(seed):
    rng = np.random.default_rng(seed)
    q, _ = np.linalg.qr(rng.standard_normal((3, 3)))
    P = (q * 10.0 ** rng.uniform(-3, 6, 3)) @ q.T
    x = rng.standard_normal(3) * 10.0 ** rng.uniform(-2, 4, 3)
    x[seed % 3] = -0.0 if seed % 2 else x[seed % 3]  # a signed zero survives as in the loop
    out = np.empty((7, 3))
    sigma_points3(x[0], x[1], x[2], P[0, 0], P[1, 0], P[1, 1], P[2, 0], P[2, 1], P[2, 2],
                  ukf_weights(3)[2], out)
    ref = _general(x, P)
    assert np.array_equal(out, ref)
    assert np.array_equal(np.signbit(out), np.signbit(ref))


@pytest.mark.parametrize("P", [np.zeros((3, 3)),  # every pivot floored (scale 0)
                               np.diag([4.0, 0.0, -1e-9]),  # the 2nd and 3rd floored
                               np.ones((3, 3))])  # rank 1: round-off pivots floored
def test_sigma_points3_floors_lost_pivots_as_the_general_form(P):
    x = np.array([1.0, -2.0, 3.0])
    out = np.empty((7, 3))
    sigma_points3(x[0], x[1], x[2], P[0, 0], P[1, 0], P[1, 1], P[2, 0], P[2, 1], P[2, 2],
                  ukf_weights(3)[2], out)
    assert np.array_equal(out, _general(x, P))


@pytest.mark.parametrize("seed", range(20))
def test_sigma_points4_equals_the_general_form_bit_for_bit(seed):
    rng = np.random.default_rng(seed)
    q, _ = np.linalg.qr(rng.standard_normal((4, 4)))
    P = (q * 10.0 ** rng.uniform(-3, 6, 4)) @ q.T
    x = rng.standard_normal(4) * 10.0 ** rng.uniform(-2, 4, 4)
    x[seed % 4] = -0.0 if seed % 2 else x[seed % 4]
    out = np.empty((9, 4))
    sigma_points4(x, P, ukf_weights(4)[2], out)
    ref = _general(x, P)
    assert np.array_equal(out, ref)
    assert np.array_equal(np.signbit(out), np.signbit(ref))


@pytest.mark.parametrize("P", [np.zeros((4, 4)), np.diag([4.0, 0.0, 1.0, -1e-9]),
                               np.ones((4, 4))])
def test_sigma_points4_floors_lost_pivots_as_the_general_form(P):
    x = np.array([1.0, -2.0, 3.0, 0.5])
    out = np.empty((9, 4))
    sigma_points4(x, P, ukf_weights(4)[2], out)
    assert np.array_equal(out, _general(x, P))


@pytest.mark.parametrize("seed", range(20))
def test_sigma_points2_equals_the_general_form_bit_for_bit(seed):
    rng = np.random.default_rng(seed)
    q, _ = np.linalg.qr(rng.standard_normal((2, 2)))
    P = (q * 10.0 ** rng.uniform(-3, 6, 2)) @ q.T
    x = rng.standard_normal(2) * 10.0 ** rng.uniform(-2, 4, 2)
    x[seed % 2] = -0.0 if seed % 4 < 2 else x[seed % 2]
    out = np.empty((5, 2))
    sigma_points2(x[0], x[1], P[0, 0], P[1, 0], P[1, 1], ukf_weights(2)[2], out)
    ref = _general(x, P)
    assert np.array_equal(out, ref)
    assert np.array_equal(np.signbit(out), np.signbit(ref))


@pytest.mark.parametrize("P", [np.zeros((2, 2)), np.diag([4.0, -1e-9]), np.ones((2, 2))])
def test_sigma_points2_floors_lost_pivots_as_the_general_form(P):
    out = np.empty((5, 2))
    sigma_points2(1.0, -2.0, P[0, 0], P[1, 0], P[1, 1], ukf_weights(2)[2], out)
    assert np.array_equal(out, _general(np.array([1.0, -2.0]), P))
