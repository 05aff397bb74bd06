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


def _fixed(x: np.ndarray, P: np.ndarray) -> np.ndarray:
    """The written-out form for N = len(x), called as the kernels call it."""
    n = x.shape[0]
    out = np.empty((2 * n + 1, n))
    tau = ukf_weights(n)[2]
    if n == 2:
        sigma_points2(x[0], x[1], P[0, 0], P[1, 0], P[1, 1], tau, out)
    elif n == 3:
        sigma_points3(x[0], x[1], x[2], P[0, 0], P[1, 0], P[1, 1], P[2, 0], P[2, 1], P[2, 2],
                      tau, out)
    else:
        sigma_points4(x, P, tau, out)
    return out


@pytest.mark.parametrize("n", [2, 3, 4])
@pytest.mark.parametrize("seed", range(20))
def test_fixed_size_sigma_points_equal_the_general_form_bit_for_bit(n, seed):
    """Covariances over nine decades of eigenvalue, means over six; a signed zero in the
    mean survives as in the general loop."""
    rng = np.random.default_rng(seed)
    q, _ = np.linalg.qr(rng.standard_normal((n, n)))
    P = (q * 10.0 ** rng.uniform(-3, 6, n)) @ q.T
    x = rng.standard_normal(n) * 10.0 ** rng.uniform(-2, 4, n)
    if seed % 2:
        x[seed % n] = -0.0
    out, ref = _fixed(x, P), _general(x, P)
    assert np.array_equal(out, ref)
    assert np.array_equal(np.signbit(out), np.signbit(ref))


@pytest.mark.parametrize("n", [2, 3, 4])
@pytest.mark.parametrize("kind", ["zero", "diagonal", "rank one"])
def test_fixed_size_sigma_points_floor_lost_pivots_as_the_general_form(n, kind):
    """Every pivot floored (P = 0), a zero and a slightly negative pivot on the diagonal, and
    a rank-one P whose round-off pivots are floored."""
    P = {"zero": np.zeros((n, n)),
         "diagonal": np.diag({2: [4.0, -1e-9], 3: [4.0, 0.0, -1e-9], 4: [4.0, 0.0, 1.0, -1e-9]}[n]),
         "rank one": np.ones((n, n))}[kind]
    x = np.array([1.0, -2.0, 3.0, 0.5])[:n]
    assert np.array_equal(_fixed(x, P), _general(x, P))
