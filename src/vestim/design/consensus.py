"""Robustness of the opinion-dynamics fusion (003 Lemma 1, Lemma 2) and a cvxpy reference
for its confidence optimisation (003 eq. (13)).

- :func:`robustness`: λ_min(L̄), λ_max(L̄), the H∞ norm 1/λ_min(L̄) of 003 eq. (8)
  from the disturbance Ω to the opinions (003 Lemma 1) and the delay bound
  π/(2 λ_max(L̄)) of 003 eq. (11)–(12) (Lemma 2).
- :func:`discrete_delay_limit`, :func:`max_stable_delay_steps`: the exact stability
  limit of the step-invariant discretisation used by
  :func:`vestim.estimators.fusion.opinion.simulate_delayed_dynamics`.
- :class:`ReferenceConfidenceSolver`: 003 eq. (13) as a cvxpy problem (Clarabel),
  built once with Parameters; the reference the exact solver
  :func:`vestim.estimators.fusion.opinion.solve_confidences` is tested against.

cvxpy is imported here only (never in :mod:`vestim.estimators`).
"""

from __future__ import annotations

import math
import warnings
from dataclasses import dataclass

import numpy as np

from vestim.errors import optional_import
from vestim.estimators.fusion.opinion import N_CORNERS, SHIFT, laplacian_bar

cp = optional_import("cvxpy", "design", "the opinion-fusion reference solver")


@dataclass(frozen=True)
class Robustness:
    """Robustness figures of the opinion dynamics for confidences W, arrays of shape (n,).

    Attributes:
        lambda_min: λ_1(L̄), 1/s.
        lambda_max: λ_4(L̄), 1/s.
        hinf_norm: ‖(sI + L̄)⁻¹‖_∞ = 1/λ_1(L̄), s (003 Lemma 1): the worst-case
            steady gain from a disturbance Ω (m/s²) to the opinions (m/s).
        delay_margin: π/(2 λ_4(L̄)), s (003 Lemma 2, eq. (12)): (11) is asymptotically
            stable for every constant delay τ below it, unstable above.
    """

    lambda_min: np.ndarray
    lambda_max: np.ndarray
    hinf_norm: np.ndarray
    delay_margin: np.ndarray


def robustness(w: np.ndarray) -> Robustness:
    """003 Lemma 1 and Lemma 2 figures for confidences ``w`` of shape (4,) or (n, 4)."""
    w2 = np.atleast_2d(np.asarray(w, dtype=float))
    if w2.shape[-1] != N_CORNERS:
        raise ValueError(f"robustness needs confidences of shape (4,) or (n, 4); got {np.shape(w)}")
    ev = np.linalg.eigvalsh(laplacian_bar(w2))
    lmin, lmax = ev[:, 0], ev[:, -1]
    return Robustness(lambda_min=lmin, lambda_max=lmax, hinf_norm=1.0 / lmin,
                      delay_margin=math.pi / (2.0 * lmax))


def discrete_delay_limit(delay_steps: int) -> float:
    """Largest λ·dt for which x_{k+1} = x_k − λ dt x_{k−N} is asymptotically stable.

    2 sin(π/(2(2N + 1))) (Levin & May 1976, "A note on difference-delay equations",
    Theor. Pop. Biol. 9); each eigenmode of the step-invariant discretisation of
    003 eq. (11) is of this form. N = 0 gives 2 (forward Euler); for N → ∞ with
    N dt = τ it tends to π/(2N), i.e. λτ < π/2 of 003 Lemma 2.
    """
    if delay_steps < 0:
        raise ValueError(f"delay_steps = {delay_steps} must be >= 0")
    return 2.0 * math.sin(math.pi / (2.0 * (2 * delay_steps + 1)))


def max_stable_delay_steps(lambda_max: float, dt: float) -> int:
    """Largest delay N (samples) for which the discretised (11) stays stable; −1 if none.

    Inverts :func:`discrete_delay_limit`: λ dt < 2 sin(π/(2(2N+1))) ⇔
    2N + 1 < π/(2 asin(λ dt/2)).
    """
    x = lambda_max * dt
    if not x > 0.0:
        raise ValueError(f"lambda_max·dt = {x} must be > 0")
    if x >= 2.0:
        return -1
    bound = math.pi / (2.0 * math.asin(0.5 * x))  # 2N + 1 must stay strictly below
    n = math.ceil((bound - 1.0) / 2.0) - 1
    while n >= 0 and discrete_delay_limit(n) <= x:  # guard the rounding of asin
        n -= 1
    while discrete_delay_limit(n + 1) > x:
        n += 1
    return n


@dataclass(frozen=True)
class ReferenceSolution:
    """cvxpy solution of 003 eq. (13): confidences (4,), optimal λ_min(L̄) and solver status."""

    w: np.ndarray
    objective: float
    status: str

    @property
    def feasible(self) -> bool:
        return self.status in (cp.OPTIMAL, cp.OPTIMAL_INACCURATE)


class ReferenceConfidenceSolver:
    """003 eq. (13) in cvxpy: maximise λ_min(L̄) s.t. λ_max(L̄) ≤ γ, W_min ≤ W ≤ W_max.

    L̄ = L + diag(W) with the complete-graph Laplacian of unit edge weights (003
    eq. (9)). The problem is built once with Parameters (DPP) and re-solved per
    instance with Clarabel at tight tolerances (``tol``: absolute and relative gap
    and feasibility), so a solve costs about a millisecond.
    """

    def __init__(self, tol: float = 1e-10) -> None:
        self._w = cp.Variable(N_CORNERS)
        self._lo = cp.Parameter(N_CORNERS)
        self._hi = cp.Parameter(N_CORNERS)
        self._gamma = cp.Parameter()
        lap = SHIFT * np.eye(N_CORNERS) - np.ones((N_CORNERS, N_CORNERS))
        lbar = lap + cp.diag(self._w)
        self._problem = cp.Problem(
            cp.Maximize(cp.lambda_min(lbar)),
            [cp.lambda_max(lbar) <= self._gamma, self._w >= self._lo, self._w <= self._hi])
        self._opts = {"tol_gap_abs": tol, "tol_gap_rel": tol, "tol_feas": tol}

    def solve(self, w_lo: np.ndarray, w_hi: np.ndarray, gamma: float) -> ReferenceSolution:
        """Solve one instance; bounds (4,), γ > 0."""
        self._lo.value = np.asarray(w_lo, dtype=float)
        self._hi.value = np.asarray(w_hi, dtype=float)
        self._gamma.value = float(gamma)
        try:
            with warnings.catch_warnings():  # "may be inaccurate": the status records it
                warnings.simplefilter("ignore", UserWarning)
                self._problem.solve(solver=cp.CLARABEL, **self._opts)
        except cp.SolverError:
            return ReferenceSolution(w=np.full(N_CORNERS, np.nan), objective=math.nan, status="solver_error")
        status = str(self._problem.status)
        if status not in (cp.OPTIMAL, cp.OPTIMAL_INACCURATE) or self._w.value is None:
            return ReferenceSolution(w=np.full(N_CORNERS, np.nan), objective=math.nan, status=status)
        return ReferenceSolution(w=np.array(self._w.value, dtype=float),
                                 objective=float(self._problem.value), status=status)
