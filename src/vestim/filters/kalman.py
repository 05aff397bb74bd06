"""Kalman measurement updates for compiled filter loops: one form for every linear measurement.

Two updates, both in place on caller-owned arrays and allocation-free (scratch
arrays are passed in, as in :mod:`vestim.filters.linalg`):

* :func:`kalman_update_scalar` and :func:`kalman_update` — a linear (or affine)
  measurement z = H x + h₀ + v, var(v) = R, with the innovation ν = z − H x̂ − h₀
  given by the caller: S = H P Hᵀ + R, K = P Hᵀ S⁻¹, x̂ ← x̂ + K ν and the
  **Joseph form**

      P ← (I − K H) P (I − K H)ᵀ + K R Kᵀ.

  For the optimal gain this equals P − K S Kᵀ = (I − K H) P in exact arithmetic;
  in floating point only the Joseph form is a sum of a congruence of P and a
  positive semi-definite term, so P stays symmetric positive semi-definite for
  any gain and the error it picks up from a rounded K is second order in that
  error (Bucy & Joseph 1968; Grewal & Andrews, *Kalman Filtering*).
  The estimators' measurement rows are badly scaled (the LuGre output row
  [σ0, σ2, σ1] ≈ [600, 0.002, 0.8]; force sums of 10⁴ N against a yaw rate of
  10⁻² rad/s), which is where P − K S Kᵀ loses definiteness. It costs a few
  dozen flops more per update on these small states (n ≤ 9). The LuGre KF and
  UKF corner filters, the stiffness EKF and the RLS + KF's Kalman filter use it,
  the UKF included: its measurement is linear in the state, so the sigma-point
  sums P_xy, P_yy equal P̄ Hᵀ and H P̄ Hᵀ + R exactly and the update is a
  linear one. The scalar kernel is the vector one for m = 1 without the Cholesky
  factorisation (S is a number); :func:`kalman_update_scalar3` is it for n = 3 on
  scalars, bit for bit. :func:`direct_update` is the scalar update of one component
  measured directly (h = e_i) with an innovation gate, in the form P − c cᵀ/s that the
  velocity reference filter keeps (its wheel-speed, GNSS and tire pseudo-measurements);
  :func:`direct_update21` that of a directly measured 3-state with a block-diagonal
  (2 × 2 + 1) covariance on scalars (the stiffness particle filter's per-particle bias).

* :func:`ukf_update` — the unscented update from sigma-point statistics (000
  eq. (11)–(12), 004 eq. (5)): K = P_xy P_yy⁻¹ by a Cholesky solve
  (:func:`~vestim.filters.linalg.chol_solve`), x̂ ← x̂ + K ν, P ← P − K P_xyᵀ
  (= P − K P_yy Kᵀ), symmetrised. Without H the Joseph form cannot be written;
  it is for filters that evaluate the measurement at the sigma points. The force
  stage's UKFs use fixed-size forms of it (a general update over run-time sizes made
  their kernels about twice as slow, issue 27): :func:`ukf_update4` (4 states, 4
  measurements: the lateral force UKF) in constant-size loops, bit for bit equal to
  :func:`ukf_update`; on scalars, :func:`ukf_update_scalar2` (2 states, one measurement:
  the papers' ``ukf_rw`` of :mod:`vestim.estimators.force.longitudinal`, P − k s kᵀ) and
  :func:`ukf_update3_select02` (3 states measured at components 0 and 2: the default
  longitudinal ``ukf``, P_yy⁻¹ in closed form; its measurement is linear, but it keeps
  P − K P_xyᵀ rather than the Joseph form, whose floats differ), which equal
  :func:`ukf_update` to round-off and keep the floats those kernels computed when they
  wrote the update out.

Matrices are a few rows at most; plain loops beat LAPACK calls here by an order
of magnitude. Nothing here knows about vehicles.
"""

from __future__ import annotations

from typing import Any

import numpy as np
from numba import njit

from vestim.filters.linalg import cholesky

_JIT: dict[str, Any] = {"cache": True, "error_model": "numpy"}


@njit(**_JIT)
def _joseph(P: np.ndarray, K: np.ndarray, H: np.ndarray, R: np.ndarray, PHt: np.ndarray,
            M: np.ndarray) -> None:
    """P ← (I − K H) P (I − K H)ᵀ + K R Kᵀ given P Hᵀ (n, m); M (n, n) scratch.

    (I − K H) P = P − K (P Hᵀ)ᵀ for symmetric P; the upper triangle is evaluated and
    mirrored, so P leaves exactly symmetric.
    """
    n = P.shape[0]
    m = H.shape[0]
    for i in range(n):
        for j in range(n):
            acc = P[i, j]
            for a in range(m):
                acc -= K[i, a] * PHt[j, a]
            M[i, j] = acc
    for i in range(n):
        for j in range(i, n):
            acc = 0.0
            for q in range(n):
                g = 1.0 if j == q else 0.0
                for a in range(m):
                    g -= K[j, a] * H[a, q]
                acc += M[i, q] * g
            for a in range(m):
                for b in range(m):
                    acc += K[i, a] * K[j, b] * R[a, b]
            P[i, j] = acc
            P[j, i] = acc


@njit(**_JIT)
def kalman_update_scalar(x: np.ndarray, P: np.ndarray, h: np.ndarray, r: float, nu: float,
                         ph: np.ndarray, k: np.ndarray, M: np.ndarray) -> float:
    """Joseph-form update of (x (n,), P (n, n)) by one scalar measurement with row h (n,).

    z = hᵀx + h₀ + v, var(v) = r > 0, innovation ν = z − hᵀx̂ − h₀ (the caller's).
    S = hᵀ P h + r, k = P h / S, x̂ ← x̂ + k ν, P ← (I − k hᵀ) P (I − k hᵀ)ᵀ + r k kᵀ.
    Scratch: ph, k (n,) (k holds the gain afterwards), M (n, n). Returns S.
    P must be symmetric; it leaves exactly symmetric. A measurement of one state i
    (h the i-th unit vector) is the special case S = P_ii + r, k = P[:, i]/S.
    """
    n = x.shape[0]
    for i in range(n):
        acc = 0.0
        for j in range(n):
            acc += P[i, j] * h[j]
        ph[i] = acc
    s = 0.0
    for i in range(n):
        s += h[i] * ph[i]
    s += r
    for i in range(n):
        k[i] = ph[i] / s
        x[i] += k[i] * nu
    for i in range(n):
        for j in range(n):
            M[i, j] = P[i, j] - k[i] * ph[j]
    for i in range(n):
        for j in range(i, n):
            acc = 0.0
            for q in range(n):
                acc += M[i, q] * ((1.0 if j == q else 0.0) - k[j] * h[q])
            acc += k[i] * k[j] * r
            P[i, j] = acc
            P[j, i] = acc
    return s


@njit(**_JIT)
def kalman_update_scalar3(p00: float, p01: float, p02: float, p11: float, p12: float,
                          p22: float, x0: float, x1: float, x2: float, h0: float, h1: float,
                          h2: float, r: float, nu: float
                          ) -> tuple[float, float, float, float, float, float, float, float, float]:
    """:func:`kalman_update_scalar` for n = 3 written out on scalars: the same operations in the
    same order (each sum from 0.0, the Joseph factor's entries as 1.0 − k h or 0.0 − k h), so
    the same floats, bit for bit, without arrays (a kernel's per-sample row views of its state
    cost reference counting).

    P = [[p00, p01, p02], [p01, p11, p12], [p02, p12, p22]] (symmetric), x = (x0, x1, x2), the
    row h = (h0, h1, h2), var(v) = r, innovation ν. Returns the updated
    (x0, x1, x2, p00, p01, p02, p11, p12, p22).
    """
    ph0 = 0.0 + p00 * h0 + p01 * h1 + p02 * h2
    ph1 = 0.0 + p01 * h0 + p11 * h1 + p12 * h2
    ph2 = 0.0 + p02 * h0 + p12 * h1 + p22 * h2
    s = 0.0 + h0 * ph0 + h1 * ph1 + h2 * ph2
    s += r
    k0 = ph0 / s
    k1 = ph1 / s
    k2 = ph2 / s
    x0 += k0 * nu
    x1 += k1 * nu
    x2 += k2 * nu
    m00 = p00 - k0 * ph0
    m01 = p01 - k0 * ph1
    m02 = p02 - k0 * ph2
    m10 = p01 - k1 * ph0
    m11 = p11 - k1 * ph1
    m12 = p12 - k1 * ph2
    m20 = p02 - k2 * ph0
    m21 = p12 - k2 * ph1
    m22 = p22 - k2 * ph2
    # column j of (I − k hᵀ)ᵀ: g_jq = δ_jq − k_j h_q
    g00 = 1.0 - k0 * h0
    g01 = 0.0 - k0 * h1
    g02 = 0.0 - k0 * h2
    g10 = 0.0 - k1 * h0
    g11 = 1.0 - k1 * h1
    g12 = 0.0 - k1 * h2
    g20 = 0.0 - k2 * h0
    g21 = 0.0 - k2 * h1
    g22 = 1.0 - k2 * h2
    n00 = 0.0 + m00 * g00 + m01 * g01 + m02 * g02 + k0 * k0 * r
    n01 = 0.0 + m00 * g10 + m01 * g11 + m02 * g12 + k0 * k1 * r
    n02 = 0.0 + m00 * g20 + m01 * g21 + m02 * g22 + k0 * k2 * r
    n11 = 0.0 + m10 * g10 + m11 * g11 + m12 * g12 + k1 * k1 * r
    n12 = 0.0 + m10 * g20 + m11 * g21 + m12 * g22 + k1 * k2 * r
    n22 = 0.0 + m20 * g20 + m21 * g21 + m22 * g22 + k2 * k2 * r
    return x0, x1, x2, n00, n01, n02, n11, n12, n22


@njit(**_JIT)
def _gain_and_state(x: np.ndarray, S: np.ndarray, C: np.ndarray, nu: np.ndarray, L: np.ndarray,
                    K: np.ndarray) -> bool:
    """K = C S⁻¹ by a Cholesky solve (C (n, m) the state-measurement cross covariance, S (m, m)
    the innovation covariance; L (m, m) its factor), then x̂ ← x̂ + K ν. Returns False when S
    needed the Cholesky pivot floor."""
    ok = cholesky(S, L)
    m = S.shape[0]
    for i in range(x.shape[0]):
        # K[i] = S⁻¹ C[i]: chol_solve's forward and back substitutions, on the rows by
        # index (a row view per state costs more than the solve at these sizes)
        for a in range(m):
            acc = C[i, a]
            for b in range(a):
                acc -= L[a, b] * K[i, b]
            K[i, a] = acc / L[a, a]
        for a in range(m - 1, -1, -1):
            acc = K[i, a]
            for b in range(a + 1, m):
                acc -= L[b, a] * K[i, b]
            K[i, a] = acc / L[a, a]
    for i in range(x.shape[0]):
        acc = x[i]
        for a in range(nu.shape[0]):
            acc += K[i, a] * nu[a]
        x[i] = acc
    return ok


@njit(**_JIT)
def kalman_update(x: np.ndarray, P: np.ndarray, H: np.ndarray, R: np.ndarray, nu: np.ndarray,
                  PHt: np.ndarray, S: np.ndarray, L: np.ndarray, K: np.ndarray,
                  M: np.ndarray) -> bool:
    """Joseph-form update of (x (n,), P (n, n)) by m linear measurements H (m, n), R (m, m).

    ν (m,) = z − H x̂ − h₀ (the caller's). S = H P Hᵀ + R, K = P Hᵀ S⁻¹ by a Cholesky
    solve, x̂ ← x̂ + K ν, P ← (I − K H) P (I − K H)ᵀ + K R Kᵀ. Scratch (left holding the
    step's quantities, for callers that test innovations against S): PHt (n, m) = P Hᵀ,
    S (m, m), L (m, m) its Cholesky factor, K (n, m) the gain, M (n, n). Returns False
    when S needed the Cholesky pivot floor (:func:`~vestim.filters.linalg.cholesky`).
    """
    n = x.shape[0]
    m = H.shape[0]
    for i in range(n):
        for a in range(m):
            acc = 0.0
            for j in range(n):
                acc += P[i, j] * H[a, j]
            PHt[i, a] = acc
    for a in range(m):
        for b in range(m):
            acc = 0.0
            for j in range(n):
                acc += H[a, j] * PHt[j, b]
            S[a, b] = acc + R[a, b]
    ok = _gain_and_state(x, S, PHt, nu, L, K)
    _joseph(P, K, H, R, PHt, M)
    return ok


@njit(**_JIT)
def ukf_update(x: np.ndarray, P: np.ndarray, Pxy: np.ndarray, Pyy: np.ndarray, nu: np.ndarray,
               L: np.ndarray, K: np.ndarray) -> bool:
    """Unscented measurement update of (x (n,), P (n, n)) from sigma-point statistics.

    Pxy (n, m) = Σ W^c (χ − x̂)(γ − ŷ)ᵀ, Pyy (m, m) = Σ W^c (γ − ŷ)(γ − ŷ)ᵀ + R,
    ν (m,) = z − ŷ (000 eq. (11)–(12)). K = Pxy Pyy⁻¹ by a Cholesky solve, x̂ ← x̂ + K ν,
    P ← P − K Pxyᵀ, symmetrised. Scratch: L (m, m), K (n, m) (the gain afterwards).
    Returns False when Pyy needed the Cholesky pivot floor.
    """
    n = x.shape[0]
    m = Pyy.shape[0]
    ok = _gain_and_state(x, Pyy, Pxy, nu, L, K)
    for i in range(n):
        for j in range(n):
            acc = P[i, j]
            for a in range(m):
                acc -= K[i, a] * Pxy[j, a]
            P[i, j] = acc
    for i in range(n):
        for j in range(i + 1, n):
            v = 0.5 * (P[i, j] + P[j, i])
            P[i, j] = v
            P[j, i] = v
    return ok


@njit(**_JIT)
def ukf_update4(x: np.ndarray, P: np.ndarray, Pxy: np.ndarray, Pyy: np.ndarray, nu: np.ndarray,
                L: np.ndarray, K: np.ndarray) -> bool:
    """:func:`ukf_update` for 4 states and 4 measurements: the same operations in the same
    order (the same numbers, bit for bit), in loops of constant size that the compiler
    unrolls. Arguments and result as there."""
    ok = cholesky(Pyy, L)
    for i in range(4):
        for a in range(4):
            acc = Pxy[i, a]
            for b in range(a):
                acc -= L[a, b] * K[i, b]
            K[i, a] = acc / L[a, a]
        for a in range(3, -1, -1):
            acc = K[i, a]
            for b in range(a + 1, 4):
                acc -= L[b, a] * K[i, b]
            K[i, a] = acc / L[a, a]
    for i in range(4):
        acc = x[i]
        for a in range(4):
            acc += K[i, a] * nu[a]
        x[i] = acc
    for i in range(4):
        for j in range(4):
            acc = P[i, j]
            for a in range(4):
                acc -= K[i, a] * Pxy[j, a]
            P[i, j] = acc
    for i in range(4):
        for j in range(i + 1, 4):
            v = 0.5 * (P[i, j] + P[j, i])
            P[i, j] = v
            P[j, i] = v
    return ok


@njit(**_JIT)
def ukf_update_scalar2(x0: float, x1: float, p00: float, p01: float, p11: float, c0: float,
                       c1: float, s: float, nu: float
                       ) -> tuple[float, float, float, float, float]:
    """:func:`ukf_update` for 2 states and one measurement, on scalars (no arrays: a kernel's
    per-sample views of its state cost reference counting).

    P = [[p00, p01], [p01, p11]], x = (x0, x1), P_xy = (c0, c1), P_yy = s (R included),
    ν = z − ŷ, in the units of the caller's state and measurement. k = P_xy / s, x̂ ← x̂ + k ν,
    P ← P − k s kᵀ, which is P − k P_xyᵀ (:func:`ukf_update`'s form) in exact arithmetic and
    symmetric by construction; the division is by s itself, not by its Cholesky factor twice,
    so the floats differ from :func:`ukf_update`'s by round-off. These are the operations of
    the papers' ``ukf_rw`` force UKF (:mod:`vestim.estimators.force.longitudinal`) in their
    order, so its outputs are those of its hand-written update, bit for bit. Returns the
    updated (x0, x1, p00, p01, p11).
    """
    k0 = c0 / s
    k1 = c1 / s
    return (x0 + k0 * nu, x1 + k1 * nu, p00 - k0 * k0 * s, p01 - k0 * k1 * s,
            p11 - k1 * k1 * s)


@njit(**_JIT)
def ukf_update3_select02(x0: float, x1: float, x2: float, p00: float, p01: float, p02: float,
                         p10: float, p11: float, p12: float, p20: float, p21: float,
                         p22: float, r0: float, r2: float, nu0: float, nu2: float
                         ) -> tuple[float, float, float, float, float, float, float, float,
                                    float]:
    """:func:`ukf_update` for 3 states measured by z = (x_0, x_2) + v, var(v) = diag(r0, r2),
    on scalars: P_xy = P̄[:, {0, 2}], P_yy = P̄[{0, 2}, {0, 2}] + R (the sigma-point sums of
    a measurement that selects state components equal these blocks), P_yy⁻¹ in closed form
    (2 × 2: det, then the adjugate's entries each divided by it), K = P_xy P_yy⁻¹,
    x̂ ← x̂ + K ν, P ← P̄ − K P_xyᵀ, symmetrised (the upper and lower entry averaged).

    P̄ is passed whole, (p00 … p22) row by row: a sigma-point covariance is symmetric only to
    round-off (w a b and w b a differ in the last bit), and each entry is used where the
    hand-written update of the longitudinal force UKF (:func:`~vestim.estimators.force.
    longitudinal.ukf_kernel`) used it, in its order, so its outputs are unchanged bit for bit.
    ν = (z_0 − x̂_0, z_2 − x̂_2). Units are the caller's. The closed-form inverse and the
    grouping K P_xyᵀ differ from :func:`ukf_update`'s Cholesky solve and running sums by
    round-off. Returns the updated (x0, x1, x2, p00, p01, p02, p11, p12, p22).
    """
    s00 = p00 + r0
    s01 = p02
    s11 = p22 + r2
    det = s00 * s11 - s01 * s01
    i00 = s11 / det
    i01 = -s01 / det
    i11 = s00 / det
    # gain rows (g_r0, g_r2) = P̄[r, {0, 2}] P_yy⁻¹
    g00 = p00 * i00 + p02 * i01
    g02 = p00 * i01 + p02 * i11
    g10 = p10 * i00 + p12 * i01
    g12 = p10 * i01 + p12 * i11
    g20 = p20 * i00 + p22 * i01
    g22 = p20 * i01 + p22 * i11
    x0 = x0 + g00 * nu0 + g02 * nu2
    x1 = x1 + g10 * nu0 + g12 * nu2
    x2 = x2 + g20 * nu0 + g22 * nu2
    # P̄ − K P_xyᵀ entry by entry, then (upper + lower)/2
    n00 = p00 - (g00 * p00 + g02 * p02)
    n01 = p01 - (g00 * p10 + g02 * p12)
    n02 = p02 - (g00 * p20 + g02 * p22)
    n10 = p10 - (g10 * p00 + g12 * p02)
    n11 = p11 - (g10 * p10 + g12 * p12)
    n12 = p12 - (g10 * p20 + g12 * p22)
    n20 = p20 - (g20 * p00 + g22 * p02)
    n21 = p21 - (g20 * p10 + g22 * p12)
    n22 = p22 - (g20 * p20 + g22 * p22)
    return (x0, x1, x2, n00, 0.5 * (n01 + n10), 0.5 * (n02 + n20), n11, 0.5 * (n12 + n21),
            n22)


@njit(**_JIT)
def direct_update(x: np.ndarray, P: np.ndarray, i: int, z: float, r: float, gate: float,
                  work: np.ndarray) -> float:
    """Kalman update of state ``i`` by a direct measurement z = x[i] + v, var(v) = r
    (units of x[i]); returns the innovation (NaN if rejected beyond ``gate`` innovation
    standard deviations, the state untouched).

    :func:`kalman_update_scalar` for h = e_i, written as K = P[:, i]/s, P ← P − c cᵀ/s
    (c = P[:, i], s = P[i, i] + r) over the full state rather than the Joseph form: equal
    for the optimal gain, and the floats the velocity reference filter has always kept
    (its r-coupled prediction makes a v_x measurement inform v_y and the other way round).
    ``work`` (≥ 1 row of the state's length) is scratch space.
    """
    s = P[i, i] + r
    innov = z - x[i]
    if innov * innov > gate * gate * s:
        return np.nan
    n = x.shape[0]
    c = work[0]
    for a in range(n):
        c[a] = P[a, i]
    for a in range(n):
        x[a] += c[a] / s * innov
        for b in range(n):
            P[a, b] -= c[a] * c[b] / s
    return innov


@njit(**_JIT)
def direct_update21(b0: float, b1: float, b2: float, p00: float, p01: float, p11: float,
                    p22: float, s00: float, s01: float, s11: float, s22: float, e0: float,
                    e1: float, e2: float) -> tuple[float, float, float, float, float, float,
                                                  float]:
    """Kalman update of a 3-state b measured directly (H = I) whose covariance P is block
    diagonal, a 2 × 2 block (p00, p01, p11) and p22, on scalars: the innovation ``e`` and its
    covariance S (the same blocks: s00, s01, s11 and s22, P plus the measurement noise and
    whatever else the caller adds). K = P S⁻¹, b ← b + K e and P ← P − K P (= P − P S⁻¹ P,
    the optimal gain's form), S⁻¹ in closed form with one division for both blocks. The
    stiffness particle filter's per-particle bias update (002 eq. (30)).

    Returns:
        (b0, b1, b2, p00, p01, p11, p22) after the update.
    """
    det = s00 * s11 - s01 * s01
    inv_all = 1.0 / (det * s22)  # one division for the 2 × 2 block and the scalar
    inv_det = s22 * inv_all
    i00 = s11 * inv_det
    i01 = -s01 * inv_det
    i11 = s00 * inv_det
    # K = P S⁻¹ (2 × 2 block)
    k00 = p00 * i00 + p01 * i01
    k01 = p00 * i01 + p01 * i11
    k10 = p01 * i00 + p11 * i01
    k11 = p01 * i01 + p11 * i11
    k22 = p22 * det * inv_all
    return (b0 + k00 * e0 + k01 * e1, b1 + k10 * e0 + k11 * e1, b2 + k22 * e2,
            p00 - (k00 * p00 + k01 * p01), p01 - (k00 * p01 + k01 * p11),
            p11 - (k10 * p01 + k11 * p11), p22 - k22 * p22)
