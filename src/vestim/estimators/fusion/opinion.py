"""Opinion-dynamics fusion of the corner velocities (003 Sec. II–III, eq. (5)–(13), Algorithm 2).

The four corners are the nodes of a complete graph with unit edge weights (003
eq. (9)). Each corner's opinion φ_j is its longitudinal velocity mapped to the CG
(003 eq. (5), φ = v_x + (r/2)·T with T = [−T_f, T_f, −T_r, T_r]; the caller maps),
and its self-confidence W_j > 0 falls with its slip ratio (003 eq. (6)). The
opinions evolve by 003 eq. (8), φ̇ = −L̄φ + Wφ(0) with L̄ = L + W, and settle at
φ̄ = L̄⁻¹Wφ(0) (003 eq. (10)), a convex combination of the initial opinions
(003 Proposition 1). The confidences are chosen per sample by the convex problem
003 eq. (13), solved here exactly in closed form (:func:`solve_confidences`).

Closed forms used throughout (L = 4I − 11ᵀ, D = diag(d), d_j = 4 + W_j, so
L̄ = D − 11ᵀ, a diagonal minus a rank-one matrix; Sherman–Morrison):

    L̄⁻¹ = D⁻¹ + D⁻¹11ᵀD⁻¹ / (1 − Σ_j 1/d_j),      1 − Σ_j 1/d_j = Σ_j W_j / (4 d_j),

    φ̄_k = (W_k φ_k + 4 φ*) / (4 + W_k),     φ* = Σ_j c_j φ_j / Σ_j c_j,   c_j = W_j / (4 + W_j).

Each steady-state opinion blends the corner's own opinion with the network value
φ*, and the mean of the four steady-state opinions is exactly φ* (sum φ̄_k over k
and use Σ_k 4/(4 + W_k) + Σ_k c_k = 4). vestim's fused CG velocity is that mean, (1/4)·1ᵀφ̄ = φ*: the
per-corner weights are the column means of L̄⁻¹W, c_j / Σc.

Everything here is stateless per sample; the kernels loop over samples in Numba.
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np
from numba import njit

from vestim.estimators.fusion.axle import weighted_average_row

_JIT: dict[str, Any] = {"cache": True, "error_model": "numpy"}

N_CORNERS = 4
"""Nodes of the complete graph (003 Fig. 1a): fl, fr, rl, rr (:data:`vestim.constants.CORNERS`)."""

DEGREE = 3.0
"""Degree of every node of the complete graph on four nodes (diagonal of L, 003 eq. (9))."""

SHIFT = DEGREE + 1.0
"""L = 4I − 11ᵀ on the complete graph with unit edge weights, so L̄ = diag(4 + W) − 11ᵀ."""


# --------------------------------------------------------------------------- confidences (eq. (6))


def eq6_confidence(slip_ratio: np.ndarray, k1: float, k2: float) -> np.ndarray:
    """Slip-based confidence of 003 eq. (6), W_j = k1·(k2 − |λ_j|), dimensionless.

    ``slip_ratio`` is λ̄_j (any shape); NaN (standstill, undefined slip) counts as
    zero slip, i.e. full confidence k1·k2. The value is *not* floored here: it is
    negative for |λ| > k2 (:func:`confidence_bounds` floors it).
    """
    lam = np.nan_to_num(np.asarray(slip_ratio, dtype=float), nan=0.0)
    return k1 * (k2 - np.abs(lam))


@njit(**_JIT)
def _bounds_row(slip: np.ndarray, i: int, k1: float, k2: float, w_floor: float, band: float,
                lo: np.ndarray, hi: np.ndarray) -> None:
    """Bounds [W_min, W_max] of 003 eq. (13) for sample i (see :func:`confidence_bounds`)."""
    for j in range(N_CORNERS):
        lam = slip[i, j]
        if lam != lam:  # NaN: standstill, no slip information -> no slip
            lam = 0.0
        w6 = k1 * (k2 - abs(lam))
        lo[j] = max(w_floor, (1.0 - band) * w6)
        hi[j] = max(w_floor, (1.0 + band) * w6)


def confidence_bounds(slip_ratio: np.ndarray, k1: float, k2: float, w_floor: float,
                      band: float) -> tuple[np.ndarray, np.ndarray]:
    """Per-corner bounds [W_j,min, W_j,max] of 003 eq. (13) from the slip ratio, (n, 4) each.

    003 says only that the bounds "are determined based on the slip condition of the
    corresponding corner and (6)". Our rule (a choice): a relative band of
    half-width ``band`` around the eq. (6) value, floored at ``w_floor`` > 0 (003
    requires W_j > 0, and eq. (6) is ≤ 0 for |λ| ≥ k2)::

        W6_j = k1 (k2 − |λ_j|),   W_j,min = max(w_floor, (1 − band) W6_j),
                                  W_j,max = max(w_floor, (1 + band) W6_j).

    The band is the freedom eq. (13) trades for robustness: the optimum takes
    W_j,max unless the delay constraint λ_max(L̄) ≤ γ caps it (see
    :func:`solve_confidences`).
    """
    slip = np.ascontiguousarray(slip_ratio, dtype=float)
    if slip.ndim != 2 or slip.shape[1] != N_CORNERS:
        raise ValueError(f"slip_ratio must have shape (n, 4) with columns fl, fr, rl, rr; got {slip.shape}")
    lo = np.empty_like(slip)
    hi = np.empty_like(slip)
    _bounds_kernel(slip, k1, k2, w_floor, band, lo, hi)
    return lo, hi


@njit(**_JIT)
def _bounds_kernel(slip: np.ndarray, k1: float, k2: float, w_floor: float, band: float,
                   lo: np.ndarray, hi: np.ndarray) -> None:
    row_lo = np.empty(N_CORNERS)
    row_hi = np.empty(N_CORNERS)
    for i in range(slip.shape[0]):
        _bounds_row(slip, i, k1, k2, w_floor, band, row_lo, row_hi)
        for j in range(N_CORNERS):
            lo[i, j] = row_lo[j]
            hi[i, j] = row_hi[j]


# --------------------------------------------------------------------------- eq. (13), exact


@njit(**_JIT)
def _copy4(src: np.ndarray, dst: np.ndarray) -> None:
    for j in range(N_CORNERS):
        dst[j] = src[j]


@njit(**_JIT)
def _solve_row(lo_w: np.ndarray, hi_w: np.ndarray, gamma: float, out: np.ndarray,
               bp: np.ndarray) -> bool:
    """Exact solution of 003 eq. (13) for one sample (derivation in :func:`solve_confidences`).

    ``lo_w``, ``hi_w``: bounds on W (4,); ``out`` (4,) receives W; ``bp`` (≥ 7,)
    scratch. Returns False (and W = W_min, the point of least λ_max in the box)
    when the problem is infeasible.
    """
    g = gamma
    n_hi_above = 0  # corners whose upper bound exceeds γ (in d = 4 + W)
    k_hi = -1
    n_lo_above = 0  # corners whose lower bound exceeds γ: they must sit above γ
    k_lo = -1
    for j in range(N_CORNERS):
        if SHIFT + hi_w[j] > g:
            n_hi_above += 1
            k_hi = j
        if SHIFT + lo_w[j] > g:
            n_lo_above += 1
            k_lo = j
    if n_lo_above >= 2:  # at most one corner may exceed γ (step 2 of the derivation)
        _copy4(lo_w, out)
        return False
    if n_hi_above == 0:  # W_max feasible: λ_max ≤ max d ≤ γ
        _copy4(hi_w, out)
        return True
    k = k_lo if n_lo_above == 1 else k_hi
    # Candidate: the others at their upper bounds, the top corner k up to c_s
    # (λ_max = γ exactly); admissible when the others all stay below γ.
    others_below = True
    s_inv = 0.0
    for j in range(N_CORNERS):
        if j != k:
            dj = SHIFT + hi_w[j]
            if dj >= g:
                others_below = False
            else:
                s_inv += 1.0 / (g - dj)
    if others_below:
        c_s = g + 1.0 / (1.0 + s_inv)
        if c_s >= SHIFT + lo_w[k]:
            _copy4(hi_w, out)
            out[k] = min(hi_w[k], c_s - SHIFT)
            return True
    if n_lo_above == 0:  # two or more upper bounds reach γ: clip them all at γ
        for j in range(N_CORNERS):
            out[j] = min(hi_w[j], g - SHIFT)
        return True
    # Forced top (its lower bound exceeds γ): it stays at its lower bound c, and the
    # others share one level ℓ < γ, clipped to their boxes, fixed by λ_max = γ:
    # G(ℓ) = Σ_{j≠k} 1/(γ − clip_j(ℓ)) = R = 1/(c − γ) − 1.
    c = SHIFT + lo_w[k]
    if c - g >= 1.0:
        _copy4(lo_w, out)
        return False
    r = 1.0 / (c - g) - 1.0
    g0 = 0.0
    for j in range(N_CORNERS):
        if j != k:
            g0 += 1.0 / (g - (SHIFT + lo_w[j]))
    if g0 > r:
        _copy4(lo_w, out)
        return False
    # breakpoints of the piecewise G, sorted (insertion sort of ≤ 7 values)
    nb = 0
    for j in range(N_CORNERS):
        if j != k:
            bp[nb] = SHIFT + lo_w[j]
            bp[nb + 1] = min(SHIFT + hi_w[j], g)
            nb += 2
    bp[nb] = g
    nb += 1
    for a in range(1, nb):
        v = bp[a]
        b = a - 1
        while b >= 0 and bp[b] > v:
            bp[b + 1] = bp[b]
            b -= 1
        bp[b + 1] = v
    level = g  # reached only by rounding: G(γ⁻) ≤ R means c_s ≥ c, handled above
    prev = bp[0]  # G = g0 ≤ R left of the first breakpoint
    for a in range(1, nb):
        right = bp[a]
        if right <= prev:
            continue
        mid = 0.5 * (prev + right)
        m = 0
        bsum = 0.0
        for j in range(N_CORNERS):
            if j != k:
                lo_d = SHIFT + lo_w[j]
                hi_d = SHIFT + hi_w[j]
                if mid < lo_d:
                    bsum += 1.0 / (g - lo_d)
                elif mid >= hi_d:
                    bsum += 1.0 / (g - hi_d)
                else:
                    m += 1
        if m > 0 and r > bsum:  # on this piece G = m/(γ − ℓ) + B
            cand = g - m / (r - bsum)
            if cand <= right:
                level = max(cand, prev)
                break
        prev = right
    for j in range(N_CORNERS):
        if j != k:
            out[j] = min(max(level - SHIFT, lo_w[j]), hi_w[j])  # clip in W: bounds held exactly
    out[k] = lo_w[k]
    return True


@njit(**_JIT)
def _solve_kernel(w_lo: np.ndarray, w_hi: np.ndarray, gamma: float, out: np.ndarray,
                  feasible: np.ndarray) -> None:
    bp = np.empty(2 * N_CORNERS)
    lo = np.empty(N_CORNERS)
    hi = np.empty(N_CORNERS)
    w = np.empty(N_CORNERS)
    for i in range(w_lo.shape[0]):
        for j in range(N_CORNERS):
            lo[j] = w_lo[i, j]
            hi[j] = w_hi[i, j]
        feasible[i] = _solve_row(lo, hi, gamma, w, bp)
        for j in range(N_CORNERS):
            out[i, j] = w[j]


def solve_confidences(w_lo: np.ndarray, w_hi: np.ndarray, gamma: float) -> tuple[np.ndarray, np.ndarray]:
    r"""Exact solution of 003 eq. (13) for each row: maximise λ_min(L̄) s.t. λ_max(L̄) ≤ γ, W ∈ box.

    Args:
        w_lo, w_hi: (n, 4) bounds W_j,min ≤ W_j,max (> 0 in 003), dimensionless.
        gamma: γ, bound on λ_max(L̄) (1/s in the units of 003 eq. (8); 003 Lemma 2
            ties it to the tolerable delay, τ_max = π/(2γ)).

    Returns:
        ``(W, feasible)``: (n, 4) confidences and (n,) bool. Infeasible rows get
        W = W_min (the box point of least λ_max, λ_max being monotone in each W_j).

    Derivation (unit edge weights, 003 eq. (9)). Write d_j = 4 + W_j, so
    L̄ = D − 11ᵀ.

    1. *Eigenvalues.* By the matrix determinant lemma μ ∉ {d_j} is an eigenvalue iff
       the secular equation f(μ) = Σ_j 1/(d_j − μ) = 1 holds, and the eigenvalues
       interlace with the sorted d: λ_1 < d_(1) ≤ λ_2 ≤ d_(2) ≤ λ_3 ≤ d_(3) ≤ λ_4 ≤ d_(4).
    2. *Constraints as secular inequalities.* λ_1 ≥ t ⇔ D − tI ⪰ 11ᵀ ⇔ d_j > t and
       f(t) ≤ 1. λ_4 ≤ γ ⇔ (γI − D) + 11ᵀ ⪰ 0 ⇔ either every d_j ≤ γ, or exactly one
       d_k > γ and 1/(d_k − γ) ≥ 1 + Σ_{j≠k} 1/(γ − d_j) (a diagonal with one negative
       entry plus 11ᵀ is PSD iff its determinant is ≥ 0; two negative entries leave
       e_a − e_b ⟂ 1 with a negative quadratic form). So at most one corner may lie
       above γ, and by less than 1.
    3. *Monotonicity.* ∂λ_1/∂W_j = v_j² with v ∝ (D − λ_1 I)⁻¹1, which has no zero
       entry: λ_1 strictly increases in every W_j. Hence W_max is optimal when
       feasible, and among points with all d_j ≤ γ the best is d = min(d_max, γ).
    4. *One corner above γ.* Fix d_k = c > γ. What remains (maximise λ_1 over the
       other three under Σ_{j≠k} 1/(γ − d_j) ≤ R(c) = 1/(c − γ) − 1 and their boxes)
       is convex; its KKT conditions v_j² = η/(γ − d_j)² make (γ − d_j)/(d_j − λ_1)
       equal over the free corners, i.e. d_j = clip(ℓ, d_j,min, d_j,max) with one
       level ℓ set by the constraint. Along this family, with x = c − γ, y = γ − ℓ,
       s = γ − λ_1 and m ≥ 1 free corners, dλ_1/dc has the sign of
       s(x − y) − 2xy, and the constraint gives 1/x = 1 + m/y + (bounded terms) > 1/y,
       so x < y and dλ_1/dc < 0. Raising a corner above γ therefore pays only while
       no other corner has to give way: up to
       c_s = γ + 1/(1 + Σ_{j≠k} 1/(γ − d_j,max)) when every other d_j,max < γ.

    Resulting optimum (the branches of the code):

    - every d_j,max ≤ γ: W = W_max;
    - exactly one d_k,max > γ and the others < γ: W_j = W_j,max (j ≠ k),
      d_k = min(d_k,max, c_s);
    - two or more d_j,max ≥ γ (no lower bound above γ): d = min(d_max, γ);
    - one lower bound d_k,min > γ (the corner is forced on top): as above when
      c_s ≥ d_k,min, else d_k = d_k,min and the others at clip(ℓ) where
      Σ_{j≠k} 1/(γ − clip_j(ℓ)) = R(d_k,min), solved exactly piece by piece
      (m free corners, B the bounded terms: ℓ = γ − m/(R − B));
    - infeasible when two lower bounds exceed γ, d_k,min ≥ γ + 1, or
      Σ_{j≠k} 1/(γ − d_j,min) > R(d_k,min).

    No iteration: a few dozen flops per sample, exact to rounding. Checked against
    cvxpy + Clarabel (:class:`vestim.design.consensus.ReferenceConfidenceSolver`)
    in ``tests/design/test_consensus.py`` (003 notes the problem is convex with a
    unique optimal value).
    """
    lo = np.ascontiguousarray(w_lo, dtype=float)
    hi = np.ascontiguousarray(w_hi, dtype=float)
    if lo.ndim != 2 or lo.shape[1] != N_CORNERS or hi.shape != lo.shape:
        raise ValueError(f"solve_confidences needs w_lo, w_hi of shape (n, 4); got {lo.shape}, {hi.shape}")
    if np.any(lo > hi) or not (np.all(np.isfinite(lo)) and np.all(np.isfinite(hi))):
        raise ValueError("solve_confidences needs finite bounds with w_lo <= w_hi")
    if not (math.isfinite(gamma) and gamma > SHIFT):
        raise ValueError(f"solve_confidences needs a finite gamma > 4 (the λ_max of L̄ at W = 0); got {gamma}")
    out = np.empty_like(lo)
    feasible = np.empty(lo.shape[0], dtype=np.bool_)
    _solve_kernel(lo, hi, float(gamma), out, feasible)
    return out, feasible


# --------------------------------------------------------------------------- eq. (8)–(10)


def laplacian_bar(w: np.ndarray) -> np.ndarray:
    """L̄ = L + diag(W) on the complete graph with unit edge weights (003 eq. (9)); (..., 4, 4)."""
    w = np.asarray(w, dtype=float)
    lap = SHIFT * np.eye(N_CORNERS) - np.ones((N_CORNERS, N_CORNERS))
    return lap + w[..., :, None] * np.eye(N_CORNERS)


def consensus_weights(w: np.ndarray) -> np.ndarray:
    """Column means of L̄⁻¹W (003 eq. (10)), (n, 4): c_j / Σc with c_j = W_j/(4 + W_j).

    They are the convex-combination coefficients of the fused CG value
    (1/4)·1ᵀφ̄ = φ*, sum to 1 and are positive for W > 0 (003 Proposition 1).
    """
    w = np.asarray(w, dtype=float)
    c = w / (SHIFT + w)
    return c / c.sum(axis=-1, keepdims=True)


def steady_state_opinions(phi: np.ndarray, w: np.ndarray) -> np.ndarray:
    """φ̄ = L̄⁻¹Wφ(0) of 003 eq. (10), (n, 4), in the units of φ (m/s).

    Closed form (module docstring): φ̄_k = (W_k φ_k + 4 φ*)/(4 + W_k). This is what
    003 Algorithm 2 remaps to each corner.
    """
    phi = np.asarray(phi, dtype=float)
    w = np.asarray(w, dtype=float)
    star = np.sum(consensus_weights(w) * phi, axis=-1, keepdims=True)
    return (w * phi + SHIFT * star) / (SHIFT + w)


# --------------------------------------------------------------------------- eq. (11), discrete time


@njit(**_JIT)
def _delayed_kernel(phi0: np.ndarray, lbar: np.ndarray, u: np.ndarray, dt: float, delay: int,
                    disturbance: np.ndarray, out: np.ndarray) -> None:
    n_steps = out.shape[0] - 1
    for j in range(N_CORNERS):
        out[0, j] = phi0[j]
    for k in range(n_steps):
        kd = k - delay
        if kd < 0:
            kd = 0  # constant initial history φ(t) = φ(0), t ≤ 0
        for a in range(N_CORNERS):
            acc = u[a] + disturbance[k, a]
            for b in range(N_CORNERS):
                acc -= lbar[a, b] * out[kd, b]
            out[k + 1, a] = out[k, a] + dt * acc


def simulate_delayed_dynamics(phi0: np.ndarray, w: np.ndarray, dt: float, delay_steps: int,
                              n_steps: int, disturbance: np.ndarray | None = None) -> np.ndarray:
    """Discrete-time opinion dynamics with delay, 003 eq. (11), step-invariant discretisation.

    003 eq. (11): φ̇(t) = −L̄ φ(t − τ) + W φ(0) + Ω(t), τ = ``delay_steps``·dt. The
    loop is the integrator 1/s driven by the delayed feedback; its step-invariant
    (zero-order-hold) discretisation is z⁻ᴺ·dt/(z − 1) (003 cites [34] for the
    method), which closed by −L̄ gives

        φ_{k+1} = φ_k + dt (−L̄ φ_{k−N} + W φ_0 + Ω_k),   φ_{k−N} = φ_0 for k < N.

    Each eigenmode λ of L̄ obeys x_{k+1} = x_k − λ dt x_{k−N}, asymptotically stable
    iff 0 < λ dt < 2 sin(π/(2(2N + 1))) (Levin & May 1976); as dt → 0 with N dt = τ
    this tends to 003 Lemma 2's λ τ < π/2
    (:func:`vestim.design.consensus.discrete_delay_limit`).

    Args:
        phi0: (4,) initial opinions φ(0), m/s.
        w: (4,) confidences W_j > 0.
        dt: sample time, s.
        delay_steps: N ≥ 0.
        n_steps: number of steps.
        disturbance: optional (n_steps, 4) Ω_k, m/s².

    Returns:
        (n_steps + 1, 4) trajectory φ_0 … φ_{n_steps}.
    """
    phi0 = np.ascontiguousarray(phi0, dtype=float)
    w = np.ascontiguousarray(w, dtype=float)
    if phi0.shape != (N_CORNERS,) or w.shape != (N_CORNERS,):
        raise ValueError("simulate_delayed_dynamics needs phi0 and w of shape (4,); "
                         f"got {phi0.shape}, {w.shape}")
    if delay_steps < 0 or n_steps < 0 or not dt > 0.0:
        raise ValueError("simulate_delayed_dynamics needs dt > 0, delay_steps >= 0, n_steps >= 0")
    if disturbance is None:
        dist = np.zeros((n_steps, N_CORNERS))
    else:
        dist = np.ascontiguousarray(disturbance, dtype=float)
        if dist.shape != (n_steps, N_CORNERS):
            raise ValueError(f"disturbance must have shape ({n_steps}, 4); got {dist.shape}")
    out = np.empty((n_steps + 1, N_CORNERS))
    _delayed_kernel(phi0, laplacian_bar(w), w * phi0, float(dt), int(delay_steps), dist, out)
    return out


# --------------------------------------------------------------------------- Algorithm 2


@njit(**_JIT)
def opinion_kernel(phi: np.ndarray, slip: np.ndarray, k1: float, k2: float, w_floor: float,
                   band: float, gamma: float, vx: np.ndarray, weights: np.ndarray,
                   conf: np.ndarray) -> None:
    """003 Algorithm 2 over the samples of (n, 4) ``phi`` (m/s) and ``slip``.

    Per sample: bounds from eq. (6) (:func:`confidence_bounds`), confidences from
    eq. (13) (:func:`solve_confidences`), consensus weights and fused CG value
    (module docstring). Writes ``vx`` (n,), ``weights`` (n, 4), ``conf`` (n, 4).
    Corners whose opinion is not finite drop out of the average (weights renormalised,
    :func:`~vestim.estimators.fusion.axle.weighted_average_row`); their confidence is
    still reported. Infeasible rows of eq. (13) cannot occur with validated
    :class:`~vestim.estimators.fusion.FusionParams` (they would use W = W_min).
    """
    lo = np.empty(N_CORNERS)
    hi = np.empty(N_CORNERS)
    w = np.empty(N_CORNERS)
    bp = np.empty(2 * N_CORNERS)
    for i in range(phi.shape[0]):
        _bounds_row(slip, i, k1, k2, w_floor, band, lo, hi)
        _solve_row(lo, hi, gamma, w, bp)
        for j in range(N_CORNERS):
            conf[i, j] = w[j]
            weights[i, j] = w[j] / (SHIFT + w[j])  # column means of L̄⁻¹W, up to Σ
        weighted_average_row(phi, i, weights, vx)
