"""Kalman measurement updates of vestim.filters.kalman against the textbook closed forms.

References are written independently in NumPy (np.linalg.solve, no Joseph form):
K = P Hᵀ S⁻¹, x + K ν, P − K S Kᵀ. On well-conditioned random SPD matrices the Joseph
form equals them to round-off; the tolerances (1e-9 relative to the matrix scale) leave
room for a few hundred ulps of the 3–6 state sums and the 1e-12 Cholesky floor.
"""

import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st

from vestim.filters.kalman import (
    _joseph,
    direct_update,
    direct_update21,
    kalman_update,
    kalman_update_scalar,
    kalman_update_scalar3,
    ukf_update,
    ukf_update3_select02,
    ukf_update4,
    ukf_update_scalar2,
)
from vestim.filters.ukf import sigma_points, ukf_weights, weighted_cross, weighted_mean

_case = st.tuples(st.integers(1, 6), st.integers(1, 3), st.integers(0, 2**32 - 1))


def _spd(rng: np.random.Generator, n: int) -> np.ndarray:
    """A random SPD matrix with eigenvalues spread over three decades."""
    q, _ = np.linalg.qr(rng.standard_normal((n, n)))
    return (q * 10.0 ** rng.uniform(-1.5, 1.5, n)) @ q.T


def _textbook(x, P, H, R, nu):
    S = H @ P @ H.T + R
    K = np.linalg.solve(S, H @ P).T
    return x + K @ nu, P - K @ S @ K.T


def _assert_psd_symmetric(P: np.ndarray) -> None:
    np.testing.assert_array_equal(P, P.T)  # exactly: the kernels mirror the upper triangle
    assert np.linalg.eigvalsh(P).min() >= -1e-12 * np.abs(P).max()


def _assert_textbook(xk: np.ndarray, Pk: np.ndarray, xr: np.ndarray, Pr: np.ndarray,
                     P0: np.ndarray) -> None:
    """The kernel's (xk, Pk) equal the textbook (xr, Pr) to round-off of the prior P0's scale,
    and Pk is exactly symmetric and PSD."""
    np.testing.assert_allclose(xk, xr, rtol=1e-9, atol=1e-9 * np.abs(xr).max())
    np.testing.assert_allclose(Pk, Pr, rtol=0, atol=1e-9 * np.abs(P0).max())
    _assert_psd_symmetric(Pk)


@settings(max_examples=200, deadline=None)
@given(_case)
def test_scalar_update_is_the_textbook_update(case):
    """S = hᵀPh + r, k = Ph/S, x + kν, P − k S kᵀ; P leaves exactly symmetric and PSD."""
    n, _, seed = case
    rng = np.random.default_rng(seed)
    P = _spd(rng, n)
    h = rng.standard_normal(n) * 10.0 ** rng.uniform(-3, 3, n)  # badly scaled rows too
    r = 10.0 ** rng.uniform(-3, 2)
    x = rng.standard_normal(n)
    nu = float(rng.standard_normal())
    xr, Pr = _textbook(x, P, h[None, :], np.array([[r]]), np.array([nu]))
    xk, Pk = x.copy(), P.copy()
    s = kalman_update_scalar(xk, Pk, h, r, nu, np.empty(n), np.empty(n), np.empty((n, n)))
    assert np.isclose(s, h @ P @ h + r, rtol=1e-12)
    _assert_textbook(xk, Pk, xr, Pr, P)


@settings(max_examples=200, deadline=None)
@given(_case)
def test_vector_update_is_the_textbook_update(case):
    """m measurements with a full SPD R: the Joseph form equals P − K S Kᵀ to round-off."""
    n, m, seed = case
    rng = np.random.default_rng(seed)
    P = _spd(rng, n)
    R = _spd(rng, m)
    H = rng.standard_normal((m, n))
    x = rng.standard_normal(n)
    nu = rng.standard_normal(m)
    xr, Pr = _textbook(x, P, H, R, nu)
    xk, Pk = x.copy(), P.copy()
    S = np.empty((m, m))
    K = np.empty((n, m))
    assert kalman_update(xk, Pk, H, R, nu, np.empty((n, m)), S, np.empty((m, m)), K,
                         np.empty((n, n)))
    np.testing.assert_allclose(S, H @ P @ H.T + R, rtol=1e-12)
    np.testing.assert_allclose(K, np.linalg.solve(H @ P @ H.T + R, H @ P).T, rtol=1e-8,
                               atol=1e-10 * np.abs(K).max())
    _assert_textbook(xk, Pk, xr, Pr, P)


@settings(max_examples=100, deadline=None)
@given(_case)
def test_one_row_vector_update_equals_the_scalar_update(case):
    """kalman_update with m = 1 and kalman_update_scalar are the same update (1e-12)."""
    n, _, seed = case
    rng = np.random.default_rng(seed)
    P = _spd(rng, n)
    h = rng.standard_normal(n)
    r = 0.3
    x = rng.standard_normal(n)
    xa, Pa = x.copy(), P.copy()
    xb, Pb = x.copy(), P.copy()
    kalman_update_scalar(xa, Pa, h, r, 0.7, np.empty(n), np.empty(n), np.empty((n, n)))
    kalman_update(xb, Pb, h[None, :], np.array([[r]]), np.array([0.7]), np.empty((n, 1)),
                  np.empty((1, 1)), np.empty((1, 1)), np.empty((n, 1)), np.empty((n, n)))
    np.testing.assert_allclose(xa, xb, rtol=1e-12, atol=1e-14)
    np.testing.assert_allclose(Pa, Pb, rtol=0, atol=1e-12 * np.abs(P).max())


@settings(max_examples=100, deadline=None)
@given(_case)
def test_joseph_form_is_psd_for_any_gain(case):
    """(I − KH) P (I − KH)ᵀ + K R Kᵀ for an arbitrary (not optimal) K: equal to the matrix
    product in NumPy and PSD — the property for which the Joseph form was chosen
    (P − K S Kᵀ is indefinite for most such K)."""
    n, m, seed = case
    rng = np.random.default_rng(seed)
    P = _spd(rng, n)
    R = _spd(rng, m)
    H = rng.standard_normal((m, n))
    K = 3.0 * rng.standard_normal((n, m))
    G = np.eye(n) - K @ H
    ref = G @ P @ G.T + K @ R @ K.T
    Pk = P.copy()
    _joseph(Pk, K, H, R, P @ H.T, np.empty((n, n)))
    np.testing.assert_allclose(Pk, ref, rtol=0, atol=1e-10 * np.abs(ref).max())
    _assert_psd_symmetric(Pk)


@settings(max_examples=100, deadline=None)
@given(_case)
def test_joseph_form_error_is_second_order_in_the_gain_error(case):
    """A gain off by δK = ε K (ε = 1e-4, as from an ill-conditioned S) moves the Joseph form
    by exactly δK S δKᵀ = ε² K S Kᵀ (second order), while P − K S Kᵀ moves by the
    first-order δK S Kᵀ + K S δKᵀ + δK S δKᵀ = (2ε + ε²) K S Kᵀ: the round-off argument of
    the module docstring. Expected ratio of the two errors ε/2 = 5e-5; asserted below 1e-3."""
    n, m, seed = case
    rng = np.random.default_rng(seed)
    P = _spd(rng, n)
    R = _spd(rng, m)
    H = rng.standard_normal((m, n))
    S = H @ P @ H.T + R
    K = np.linalg.solve(S, H @ P).T
    P_opt = P - K @ S @ K.T
    dK = 1e-4 * K
    Kp = K + dK
    Pj = P.copy()
    _joseph(Pj, Kp, H, R, P @ H.T, np.empty((n, n)))
    second = dK @ S @ dK.T
    np.testing.assert_allclose(Pj - P_opt, second, rtol=0,
                               atol=1e-9 * np.abs(P).max() + 1e-6 * np.abs(second).max())
    err_short = np.abs(P - Kp @ S @ Kp.T - P_opt).max()
    assert np.abs(Pj - P_opt).max() < 1e-3 * err_short


@settings(max_examples=100, deadline=None)
@given(_case)
def test_ukf_update_with_sigma_points_equals_the_linear_kalman_update(case):
    """For a linear measurement y = H x the unscented statistics (papers' weights) are exact:
    ŷ = H x̂, P_yy = H P Hᵀ + R, P_xy = P Hᵀ, so ukf_update equals kalman_update to round-off."""
    n, m, seed = case
    rng = np.random.default_rng(seed)
    P = _spd(rng, n)
    R = _spd(rng, m)
    H = rng.standard_normal((m, n))
    x = rng.standard_normal(n)
    z = rng.standard_normal(m)
    wm, wc, tau = ukf_weights(n)
    pts = np.empty((2 * n + 1, n))
    sigma_points(x, P, tau, np.empty((n, n)), pts)
    xm = np.empty(n)
    weighted_mean(pts, wm, xm)
    np.testing.assert_allclose(xm, x, rtol=0, atol=1e-12 * (1 + np.abs(x).max()))
    ypts = pts @ H.T
    ym = np.empty(m)
    weighted_mean(ypts, wm, ym)
    Pyy = np.empty((m, m))
    Pxy = np.empty((n, m))
    weighted_cross(ypts, ym, ypts, ym, wc, Pyy)
    weighted_cross(pts, xm, ypts, ym, wc, Pxy)
    Pyy += R
    xu, Pu = x.copy(), P.copy()
    assert ukf_update(xu, Pu, Pxy, Pyy, z - ym, np.empty((m, m)), np.empty((n, m)))
    xk, Pk = x.copy(), P.copy()
    kalman_update(xk, Pk, H, R, z - H @ x, np.empty((n, m)), np.empty((m, m)),
                  np.empty((m, m)), np.empty((n, m)), np.empty((n, n)))
    scale = np.abs(P).max()
    np.testing.assert_allclose(xu, xk, rtol=1e-8, atol=1e-8 * (1 + np.abs(xk).max()))
    np.testing.assert_allclose(Pu, Pk, rtol=0, atol=1e-8 * scale)
    np.testing.assert_array_equal(Pu, Pu.T)


@settings(max_examples=30, deadline=None)
@given(st.integers(0, 2**32 - 1))
def test_ukf_update4_equals_ukf_update_bit_for_bit(seed):
    """The lateral force UKF's fixed-size update (issue 27's speed) must give the numbers of
    the general one exactly, so the pipeline's outputs do not move."""
    rng = np.random.default_rng(seed)
    P = _spd(rng, 4)
    Pxy = P @ rng.standard_normal((4, 4))
    Pyy = _spd(rng, 4) + Pxy.T @ np.linalg.solve(P, Pxy)
    x, nu = rng.standard_normal(4), rng.standard_normal(4)
    xa, Pa, xb, Pb = x.copy(), P.copy(), x.copy(), P.copy()
    Ka, Kb = np.empty((4, 4)), np.empty((4, 4))
    oka = ukf_update(xa, Pa, Pxy, Pyy, nu, np.empty((4, 4)), Ka)
    okb = ukf_update4(xb, Pb, Pxy, Pyy, nu, np.empty((4, 4)), Kb)
    assert oka == okb
    assert np.array_equal(xa, xb) and np.array_equal(Pa, Pb) and np.array_equal(Ka, Kb)


@settings(max_examples=50, deadline=None)
@given(st.integers(0, 2**32 - 1), st.sampled_from([0, 1, 2]))
def test_kalman_update_scalar3_equals_the_general_one_bit_for_bit(seed, zeros):
    """The LuGre corner KF's written-out 3-state update (issue 27's speed) must give the floats
    of kalman_update_scalar exactly (signs of zero included: rows with zero entries), so the
    pipeline's outputs do not move; the row as badly scaled as the LuGre output [σ0, σ2, σ1]."""
    rng = np.random.default_rng(seed)
    d = np.diag([1e-3, 1.0, 0.1])  # the corner KF's P0 scales (z̄, v_r, ż̄)
    P = d @ _spd(rng, 3) @ d
    P = 0.5 * (P + P.T)
    h = np.array([600.0, 0.002, 0.8]) * rng.uniform(0.5, 2.0, 3)
    h[:zeros] = 0.0
    x, r, nu = rng.standard_normal(3), 10.0 ** rng.uniform(-4, 0), rng.standard_normal()
    xa, Pa = x.copy(), P.copy()
    kalman_update_scalar(xa, Pa, h, r, nu, np.empty(3), np.empty(3), np.empty((3, 3)))
    out = kalman_update_scalar3(P[0, 0], P[0, 1], P[0, 2], P[1, 1], P[1, 2], P[2, 2],
                                x[0], x[1], x[2], h[0], h[1], h[2], r, nu)
    xb = np.array(out[:3])
    Pb = np.array([[out[3], out[4], out[5]], [out[4], out[6], out[7]], [out[5], out[7], out[8]]])
    assert np.array_equal(xa, xb) and np.array_equal(Pa, Pb)
    assert np.array_equal(np.signbit(Pa), np.signbit(Pb))


def _close_to_the_general_update(xa, Pa, xb, Pb) -> None:
    """1e-12 of each result's scale: a few ulps of the 2–3 term sums and of the 1–2
    divisions, which the written-out forms round differently from the Cholesky solve."""
    np.testing.assert_allclose(xb, xa, rtol=1e-12, atol=1e-12 * np.abs(xa).max())
    np.testing.assert_allclose(Pb, Pa, rtol=1e-12, atol=1e-12 * np.abs(Pa).max())


def _ukf_rw_update_as_written(x0, x1, p00, p01, p11, pxz0, pxz1, pzz, innov):
    """The papers' force UKF's update as the ukf_rw kernel wrote it out before issue 27
    moved it into filters/ (the reference for the floats the pipeline gave)."""
    k0 = pxz0 / pzz
    k1 = pxz1 / pzz
    return (x0 + k0 * innov, x1 + k1 * innov, p00 - k0 * k0 * pzz, p01 - k0 * k1 * pzz,
            p11 - k1 * k1 * pzz)


@settings(max_examples=100, deadline=None)
@given(st.integers(0, 2**32 - 1))
def test_ukf_update_scalar2_is_the_general_update_and_the_ukf_rw_kernels(seed):
    """ukf_rw's scalar update: to 1e-12 the general ukf_update (n = 2, m = 1) on a
    consistent joint covariance (P_xy = P h, P_yy = hᵀ P h + r, r between a tenth and ten
    times hᵀ P h, so P keeps ≥ 1/11 of its variance along h: no cancellation beyond a
    decade), and bit for bit the kernel's former written-out update, so ``ukf_rw``'s
    outputs do not move (issue 27)."""
    rng = np.random.default_rng(seed)
    d = np.diag([1.0, 1e3])  # ukf_rw's scales: ω in rad/s, F in N
    P = d @ _spd(rng, 2) @ d
    P = 0.5 * (P + P.T)
    h = rng.standard_normal(2)
    Pxy = P @ h
    Pyy = h @ Pxy * (1.0 + 10.0 ** rng.uniform(-1, 1))
    x = rng.standard_normal(2) * np.array([100.0, 1e3])
    nu = float(rng.standard_normal()) * np.sqrt(Pyy)
    out = ukf_update_scalar2(x[0], x[1], P[0, 0], P[0, 1], P[1, 1], Pxy[0], Pxy[1], Pyy, nu)
    xb = np.array(out[:2])
    Pb = np.array([[out[2], out[3]], [out[3], out[4]]])
    xa, Pa = x.copy(), P.copy()
    assert ukf_update(xa, Pa, Pxy[:, None].copy(), np.array([[Pyy]]), np.array([nu]),
                      np.empty((1, 1)), np.empty((2, 1)))
    _close_to_the_general_update(xa, Pa, xb, Pb)
    ref = _ukf_rw_update_as_written(x[0], x[1], P[0, 0], P[0, 1], P[1, 1], Pxy[0], Pxy[1],
                                    Pyy, nu)
    assert out == ref


def _ukf_update_as_written(xm, Pm, r_w, r_t, e0, e1):
    """The default longitudinal force UKF's update of x = [ω, ω̇, T] by z = [ω, T] as
    ukf_kernel wrote it out before issue 27 moved it into filters/ (the reference for the
    floats the pipeline gave)."""
    x = np.empty(3)
    P = np.empty((3, 3))
    s00 = Pm[0, 0] + r_w
    s01 = Pm[0, 2]
    s11 = Pm[2, 2] + r_t
    det = s00 * s11 - s01 * s01
    i00 = s11 / det
    i01 = -s01 / det
    i11 = s00 / det
    for r in range(3):
        g0 = Pm[r, 0] * i00 + Pm[r, 2] * i01
        g1 = Pm[r, 0] * i01 + Pm[r, 2] * i11
        x[r] = xm[r] + g0 * e0 + g1 * e1
        for q in range(3):
            P[r, q] = Pm[r, q] - (g0 * Pm[q, 0] + g1 * Pm[q, 2])
    for r in range(3):
        for q in range(r + 1, 3):
            v = 0.5 * (P[r, q] + P[q, r])
            P[r, q] = v
            P[q, r] = v
    return x, P


@settings(max_examples=100, deadline=None)
@given(st.integers(0, 2**32 - 1))
def test_ukf_update3_select02_is_the_general_update_and_the_ukf_kernels(seed):
    """The default longitudinal UKF's update by z = (x_0, x_2): to 1e-12 the general
    ukf_update (P_xy = P̄[:, {0, 2}], P_yy = P̄[{0, 2}, {0, 2}] + R, R's variances between a
    tenth and ten times P̄'s, so no entry cancels beyond a decade or two), and bit for bit
    the kernel's former written-out update, P̄ also asymmetric in its last bits as the
    sigma-point sums leave it, so ``ukf``'s outputs do not move (issue 27)."""
    rng = np.random.default_rng(seed)
    d = np.diag([1.0, 10.0, 100.0])  # ukf's scales: ω rad/s, ω̇ rad/s², T N m
    P = d @ _spd(rng, 3) @ d
    P = 0.5 * (P + P.T)
    r0, r2 = P[0, 0] * 10.0 ** rng.uniform(-1, 1), P[2, 2] * 10.0 ** rng.uniform(-1, 1)
    x = rng.standard_normal(3) * np.array([100.0, 10.0, 500.0])
    nu = rng.standard_normal(2) * np.sqrt([P[0, 0] + r0, P[2, 2] + r2])
    sel = [0, 2]
    xa, Pa = x.copy(), P.copy()
    assert ukf_update(xa, Pa, P[:, sel].copy(), P[np.ix_(sel, sel)] + np.diag([r0, r2]), nu,
                      np.empty((2, 2)), np.empty((3, 2)))

    def written_out(P):
        out = ukf_update3_select02(x[0], x[1], x[2], *P.ravel(), r0, r2, nu[0], nu[1])
        return np.array(out[:3]), np.array([[out[3], out[4], out[5]], [out[4], out[6], out[7]],
                                            [out[5], out[7], out[8]]])

    xb, Pb = written_out(P)
    _close_to_the_general_update(xa, Pa, xb, Pb)
    P_lower = P * (1.0 + np.tril(rng.choice([-1.0, 0.0, 1.0], (3, 3)), -1) * 2.0**-52)
    for Pm in (P, P_lower):  # symmetric, and off by an ulp below the diagonal
        xb, Pb = written_out(Pm)
        xr, Pr = _ukf_update_as_written(x, Pm, r0, r2, nu[0], nu[1])
        assert np.array_equal(xb, xr) and np.array_equal(Pb, Pr)


@settings(max_examples=100, deadline=None)
@given(_case)
def test_direct_update_is_the_textbook_update_of_one_component(case):
    """direct_update of component i is the textbook update with H = e_i (to round-off, as
    the Joseph form above: it keeps P − c cᵀ/s), returns the innovation, and a measurement
    beyond the gate (ν² > gate²·s) is rejected: NaN, state and covariance untouched."""
    n, _, seed = case
    rng = np.random.default_rng(seed)
    P = _spd(rng, n)
    x = rng.standard_normal(n)
    i = int(rng.integers(n))
    r = 0.3
    z = x[i] + 0.7
    H = np.zeros((1, n))
    H[0, i] = 1.0
    xr, Pr = _textbook(x, P, H, np.array([[r]]), np.array([0.7]))
    xk, Pk = x.copy(), P.copy()
    assert direct_update(xk, Pk, i, z, r, np.inf, np.empty((1, n))) == z - x[i]
    np.testing.assert_allclose(xk, xr, rtol=1e-9, atol=1e-9 * np.abs(xr).max())
    np.testing.assert_allclose(Pk, Pr, rtol=0, atol=1e-9 * np.abs(P).max())
    gate = 0.7 / np.sqrt(P[i, i] + r) * 0.99  # just inside |ν| = 0.7: rejected
    xg, Pg = x.copy(), P.copy()
    assert np.isnan(direct_update(xg, Pg, i, z, r, gate, np.empty((1, n))))
    np.testing.assert_array_equal(xg, x)
    np.testing.assert_array_equal(Pg, P)


@settings(max_examples=100, deadline=None)
@given(st.integers(0, 2**32 - 1))
def test_direct_update21_is_the_textbook_update_of_a_block_diagonal_state(seed):
    """direct_update21 is the textbook update with H = I of a 3-state whose P and S are
    block diagonal (2 × 2 + 1; S = P + R, R of the same blocks), to round-off."""
    rng = np.random.default_rng(seed)
    P = np.zeros((3, 3))
    R = np.zeros((3, 3))
    P[:2, :2], R[:2, :2] = _spd(rng, 2), _spd(rng, 2)
    P[2, 2], R[2, 2] = 10.0 ** rng.uniform(-1.5, 1.5, 2)
    S = P + R
    b, e = rng.standard_normal(3), rng.standard_normal(3)
    xr, Pr = _textbook(b, P, np.eye(3), R, e)
    out = direct_update21(b[0], b[1], b[2], P[0, 0], P[0, 1], P[1, 1], P[2, 2],
                          S[0, 0], S[0, 1], S[1, 1], S[2, 2], e[0], e[1], e[2])
    Pk = np.array([[out[3], out[4], 0.0], [out[4], out[5], 0.0], [0.0, 0.0, out[6]]])
    np.testing.assert_allclose(out[:3], xr, rtol=1e-9, atol=1e-9 * np.abs(xr).max())
    np.testing.assert_allclose(Pk, Pr, rtol=0, atol=1e-9 * np.abs(P).max())
