"""LMI machinery for parameter-dependent Lyapunov certificates of LPV systems.

Every matrix inequality is written once, as a pure NumPy function of the
decision variables (P_i, χ_i, γ, margin t) that is affine in them and batched
over (parameter, rate) points. The same function serves twice:

1. *solving*: its affine basis ``G(x) = G0 + Σ x_j G_j`` is extracted by evaluating
   it at x = 0 and at the unit vectors, and handed to cvxpy as ``G(x) ⪰ 0``
   (Clarabel, then SCS if Clarabel fails), in balanced coordinates;
2. *verifying*: it is evaluated in the original coordinates with the returned
   matrices on a grid ten times finer than the one solved on (at least 201
   points) and at the rate vertices, and its eigenvalues decide. Solver status
   alone is never trusted.

Coordinates used for solving (exact congruences, so feasibility is unchanged):
the parameter is normalised ρ̂ = ρ/ρ_s (ρ_s = max |bound|), the states are
balanced (x̂ = D x, :func:`scipy.linalg.matrix_balance`) and time is scaled by
T0 ≈ 1/‖Â‖ (τ = t/T0). Input and output signals are not scaled, so γ is the
physical L2 gain. Back in original units P(ρ) = T0·D P̂(ρ/ρ_s) D.

Conditions (ρ ∈ Sp = [ρ_l, ρ_u], ρ̇ ∈ Sr = [−ρ̇_max, ρ̇_max]):

- affine quadratic stability, 001 eq. (27)–(28), 004 eq. (18)::

      P(ρ) ≻ 0,  A(ρ)ᵀP(ρ) + P(ρ)A(ρ) + ρ̇ ∂P/∂ρ ≺ 0   ("primal")

  and the dual form ``A Q + Q Aᵀ − ρ̇ ∂Q/∂ρ ≺ 0`` (V = xᵀQ(ρ)⁻¹x, the form of
  MATLAB's ``pdlstab``);
- multi-convexity A1ᵀP1 + P1A1 ⪰ 0 (001 after eq. (27), 004 Theorem 1), which
  makes the vertex conditions sufficient for the whole box;
- affine quadratic H∞ performance γ, 004 eq. (24)–(25) (bounded real lemma with
  ``−γI`` blocks, so ‖z‖₂ < γ‖w‖₂).
"""

from __future__ import annotations

import math
import warnings
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Any, Literal

import numpy as np
from numpy.typing import NDArray
from scipy.linalg import matrix_balance

from vestim.errors import optional_import

FArray = NDArray[np.float64]
Builder = Callable[[dict[str, FArray], "Context"], FArray]
Method = Literal["vertex", "grid"]
Form = Literal["primal", "dual"]

SOLVERS: tuple[str, ...] = ("CLARABEL", "SCS")
"""Solvers tried in order; SCS only when Clarabel fails or reports no solution."""

SCS_MAX_ITERS = 5_000
"""Iteration cap of the SCS fallback (first-order, slow to high accuracy)."""

MIN_VERIFY_POINTS = 201
"""Fewest parameter points a certificate is verified on."""

EIG_RTOL = 1e3 * np.finfo(float).eps
"""A matrix that must be ≻ 0 passes where λ_min > EIG_RTOL·‖G‖₂: eigvalsh is
backward stable, so a computed eigenvalue is within a few eps·‖G‖ of the true one."""

MULTICONVEX_RTOL = 1e-7
"""Multi-convexity (a non-strict LMI, met only to solver accuracy) passes where
λ_min ≥ −MULTICONVEX_RTOL·‖A1‖₂·max‖P(ρ)‖₂/ρ_s, the natural size of its ρ² coefficient."""

MARGIN = 1e-7
"""Margin t of the strict LMIs in balanced coordinates when γ is minimised."""


# ----------------------------------------------------------------------------- data
@dataclass(frozen=True)
class ParameterBox:
    """Scheduling-parameter region: ρ ∈ [lower, upper], |ρ̇| ≤ rate (units of ρ, per s)."""

    lower: float
    upper: float
    rate: float

    def __post_init__(self) -> None:
        if not (math.isfinite(self.lower) and math.isfinite(self.upper) and self.lower < self.upper):
            raise ValueError(f"ParameterBox: need finite lower < upper, got [{self.lower}, {self.upper}]")
        if not (math.isfinite(self.rate) and self.rate >= 0):
            raise ValueError(f"ParameterBox: rate = {self.rate} must be finite and >= 0")

    @property
    def scale(self) -> float:
        """ρ_s = max(|lower|, |upper|), the normalisation of the parameter."""
        return max(abs(self.lower), abs(self.upper))

    def vertices(self) -> FArray:
        """Sp, the two parameter vertices."""
        return np.array([self.lower, self.upper])

    def rate_vertices(self) -> FArray:
        """Sr, the two rate vertices (one when the rate bound is zero)."""
        return np.array([0.0]) if self.rate == 0 else np.array([-self.rate, self.rate])

    def grid(self, n: int) -> FArray:
        """n uniformly spaced parameter points including both bounds."""
        if n < 2:
            raise ValueError(f"a parameter grid needs at least 2 points, got {n}")
        return np.linspace(self.lower, self.upper, n)


def verification_grid(box: ParameterBox, n_solve: int) -> FArray:
    """The fine grid a certificate is checked on: 10× the solve grid, at least 201 points."""
    return box.grid(max(10 * (n_solve - 1) + 1, MIN_VERIFY_POINTS))


@dataclass(frozen=True)
class LPVSystem:
    """ẋ = A(ρ)x + B(ρ)w, z = C(ρ)x + D(ρ)w.

    ``evaluate`` maps an array of ρ (shape (K,)) to (A, B, C, D) with shapes
    (K, n, n), (K, n, m), (K, p, n), (K, p, m). ``affine`` holds
    (A0, A1, B0, B1, C0, C1, D0, D1) when every matrix is affine in ρ (needed by
    the vertex method and its multi-convexity constraint).
    """

    evaluate: Callable[[FArray], tuple[FArray, FArray, FArray, FArray]]
    affine: tuple[FArray, ...] | None = None
    name: str = ""

    @staticmethod
    def from_affine(a0: FArray, a1: FArray, b0: FArray | None = None, b1: FArray | None = None,
                    c0: FArray | None = None, c1: FArray | None = None,
                    d0: FArray | None = None, d1: FArray | None = None,
                    name: str = "") -> LPVSystem:
        """An affine LPV system; omitted B, C default to I (D to 0), omitted slopes to 0."""
        a0 = np.asarray(a0, float)
        n = a0.shape[0]
        b0 = np.eye(n) if b0 is None else np.asarray(b0, float)
        c0 = np.eye(n) if c0 is None else np.asarray(c0, float)
        d0 = np.zeros((c0.shape[0], b0.shape[1])) if d0 is None else np.asarray(d0, float)
        mats = [a0, np.asarray(a1, float)]
        for m0, m1 in ((b0, b1), (c0, c1), (d0, d1)):
            mats += [m0, np.zeros_like(m0) if m1 is None else np.asarray(m1, float)]
        coeffs = tuple(mats)

        def evaluate(rho: FArray) -> tuple[FArray, FArray, FArray, FArray]:
            r = np.asarray(rho, float).reshape(-1)[:, None, None]
            return (coeffs[0] + r * coeffs[1], coeffs[2] + r * coeffs[3],
                    coeffs[4] + r * coeffs[5], coeffs[6] + r * coeffs[7])

        return LPVSystem(evaluate=evaluate, affine=coeffs, name=name)

    def matrices(self, rho: FArray) -> tuple[FArray, FArray, FArray, FArray]:
        """(A, B, C, D) at the points ``rho`` (1-D), each with a leading axis of len(rho)."""
        r = np.atleast_1d(np.asarray(rho, float))
        a, b, c, d = self.evaluate(r)
        k = r.size
        return (np.broadcast_to(a, (k, *a.shape[-2:])), np.broadcast_to(b, (k, *b.shape[-2:])),
                np.broadcast_to(c, (k, *c.shape[-2:])), np.broadcast_to(d, (k, *d.shape[-2:])))


@dataclass(frozen=True)
class Context:
    """Data an LMI builder sees: the (ρ, ρ̇) points and the system there (one coordinate frame)."""

    rho: FArray
    rate: FArray
    mats: dict[str, FArray]
    extra: dict[str, float] = field(default_factory=dict)


@dataclass(frozen=True)
class LMICheck:
    """One verified condition: min eigenvalue of the matrix that must be ≻ 0 (or ⪰ 0).

    ``min_eig`` is the smallest eigenvalue over all points, found at
    (``worst_rho``, ``worst_rate``); ``margin`` is the smallest λ_min/‖G‖₂ over all points.
    """

    name: str
    min_eig: float
    margin: float
    worst_rho: float
    worst_rate: float
    ok: bool
    strict: bool = True
    required: bool = True


@dataclass(frozen=True)
class LMIResult:
    """Outcome of a solve (or of checking given matrices) and its independent verification.

    Attributes:
        problem: what was solved, with the equations.
        feasible: the solver returned a solution with a positive margin that satisfies
            the LMIs (by eigenvalues) at the points they were imposed on (``None`` when
            matrices were given, not solved for).
        verified: every required check passed on the fine grid and rate vertices.
        min_eig: the smallest ``min_eig`` over the required strict checks (original units).
        gamma: certified L2 gain (H∞ problems), verified with ``lyapunov``; ``None`` if
            not verified.
        gamma_opt: solver optimum before the robustness slack (H∞ problems), unverified.
        lyapunov: coefficients (f+1, n, n) of P(ρ) = Σ P_i ρ^i in original units
            (Q(ρ) for the dual form, where V = xᵀQ⁻¹x).
        checks: every evaluated condition.
        solver, status: solver used and its final status.
        solve_grid, verify_grid: parameter points (ρ) solved on and verified on.
        frozen_max_real: max real part of the eigenvalues of A(ρ) on the fine grid.
        extra: problem-specific arrays (e.g. χ coefficients of a synthesis).
    """

    problem: str
    feasible: bool | None
    verified: bool
    min_eig: float
    gamma: float | None
    gamma_opt: float | None
    lyapunov: FArray | None
    checks: tuple[LMICheck, ...]
    solver: str
    status: str
    solve_grid: FArray
    verify_grid: FArray
    form: Form = "primal"
    method: Method = "grid"
    frozen_max_real: float = float("nan")
    message: str = ""
    extra: dict[str, FArray] = field(default_factory=dict)

    def summary(self) -> str:
        """A few lines: verdict, γ, margins of each check."""
        verdict = "VERIFIED" if self.verified else "NOT VERIFIED"
        feas = {None: "given matrices", True: "solver: feasible", False: "solver: infeasible"}[
            self.feasible]
        lines = [f"{self.problem}: {verdict} ({feas}; {self.solver} {self.status})"]
        if self.gamma is not None:
            opt = "" if self.gamma_opt is None else f" (solver optimum {self.gamma_opt:.6g})"
            lines.append(f"  gamma = {self.gamma:.6g}{opt}")
        lines.append(f"  grid: solved on {self.solve_grid.size} points, verified on "
                     f"{self.verify_grid.size} points of [{self.verify_grid[0]:g}, "
                     f"{self.verify_grid[-1]:g}]; max Re eig A(rho) = {self.frozen_max_real:.4g}")
        for c in self.checks:
            tag = "ok " if c.ok else "FAIL"
            req = "" if c.required else " (informative)"
            where = ("" if math.isnan(c.worst_rho)
                     else f" at rho = {c.worst_rho:.4g}, rate = {c.worst_rate:.4g}")
            lines.append(f"  [{tag}] {c.name}: min eig {c.min_eig:.4g} (rel {c.margin:.2e})"
                         f"{where}{req}")
        if self.message:
            lines.append(f"  note: {self.message}")
        return "\n".join(lines)


# ------------------------------------------------------------------- decision layout
class Layout:
    """Decision vector layout: named blocks, symmetric ones stored by their upper triangle."""

    def __init__(self) -> None:
        self._items: list[tuple[str, tuple[int, ...], bool, int]] = []
        self.size = 0

    def add(self, name: str, shape: tuple[int, ...], symmetric: bool = False) -> None:
        """Add a block; ``symmetric`` needs shape (..., n, n)."""
        if symmetric:
            n = shape[-1]
            count = int(np.prod(shape[:-2], dtype=int)) * n * (n + 1) // 2
        else:
            count = int(np.prod(shape, dtype=int))
        self._items.append((name, shape, symmetric, count))
        self.size += count

    def unpack(self, x: FArray) -> dict[str, FArray]:
        """Decision vector → named arrays."""
        out: dict[str, FArray] = {}
        pos = 0
        for name, shape, sym, count in self._items:
            seg = x[pos:pos + count]
            pos += count
            if sym:
                n = shape[-1]
                lead = shape[:-2]
                iu = np.triu_indices(n)
                m = np.zeros((*lead, n, n))
                m[..., iu[0], iu[1]] = seg.reshape(*lead, -1)
                m = m + np.swapaxes(m, -1, -2) - m * np.eye(n)
                out[name] = m
            else:
                out[name] = seg.reshape(shape)
        return out

    def pack(self, vals: dict[str, FArray]) -> FArray:
        """Named arrays → decision vector (inverse of :meth:`unpack`)."""
        parts = []
        for name, shape, sym, _ in self._items:
            v = np.asarray(vals[name], float)
            if sym:
                n = shape[-1]
                iu = np.triu_indices(n)
                parts.append(v[..., iu[0], iu[1]].reshape(-1))
            else:
                parts.append(v.reshape(-1))
        return np.concatenate(parts)


def affine_basis(layout: Layout, builder: Builder, ctx: Context) -> tuple[FArray, FArray]:
    """(G0, Gx) with G(x) = G0 + (Gx @ x).reshape: shapes (K, m, m) and (K, m·m, nx)."""
    x0 = np.zeros(layout.size)
    g0 = np.asarray(builder(layout.unpack(x0), ctx), float)
    k, m, _ = g0.shape
    gx = np.empty((k, m * m, layout.size))
    for j in range(layout.size):
        e = x0.copy()
        e[j] = 1.0
        gx[:, :, j] = (np.asarray(builder(layout.unpack(e), ctx), float) - g0).reshape(k, m * m)
    return g0, gx


@dataclass(frozen=True)
class SolveOutcome:
    """Solution vector (``None`` if none), solver name and status."""

    x: FArray | None
    solver: str
    status: str

    @property
    def accurate(self) -> bool:
        """A solution the solver reports as optimal to its full accuracy."""
        return self.x is not None and self.status == "optimal"


@dataclass(frozen=True)
class Family:
    """A batch of LMIs G(x) ⪰ 0 with G = builder(x) [+ p·scaled(x)] on ``ctx``.

    ``param`` names a scalar cvxpy Parameter p multiplying the affine function
    ``scaled`` (so that bisections re-solve without recompiling).
    """

    builder: Builder
    ctx: Context
    param: str | None = None
    scaled: Builder | None = None


class LMIProblem:
    """cvxpy problem min objective·x s.t. every family ⪰ 0, compiled once, re-solvable.

    Uses Clarabel, then SCS if Clarabel raises or returns no solution (unless
    the status certifies infeasibility, which is final).
    """

    def __init__(self, layout: Layout, families: list[Family], objective: FArray) -> None:
        cp = optional_import("cvxpy", "design", "the LMI tools (vestim design, vestim analyze)")
        self._cp = cp
        self.layout = layout
        self.x = cp.Variable(layout.size)
        self.params: dict[str, Any] = {}
        cons = []
        for fam in families:
            expr = self._expr(fam.builder, fam.ctx)
            if fam.param is not None and fam.scaled is not None:
                p = self.params.setdefault(fam.param, cp.Parameter(name=fam.param, value=0.0))
                extra = self._expr(fam.scaled, fam.ctx)
                expr = [e + p * f for e, f in zip(expr, extra, strict=True)]
            for e in expr:
                if e.shape == ():
                    cons.append(e >= 0)
                else:
                    cons.append(0.5 * (e + e.T) >> 0)
        self.problem = cp.Problem(cp.Minimize(objective @ self.x), cons)

    def _expr(self, builder: Builder, ctx: Context) -> list[Any]:
        cp = self._cp
        g0, gx = affine_basis(self.layout, builder, ctx)
        k, m, _ = g0.shape
        g0 = 0.5 * (g0 + np.swapaxes(g0, -1, -2))
        if m == 1:
            return [g0[i, 0, 0] + gx[i, 0, :] @ self.x for i in range(k)]
        return [g0[i] + cp.reshape(gx[i] @ self.x, (m, m), order="C") for i in range(k)]

    def solve(self, params: dict[str, float] | None = None,
              solvers: tuple[str, ...] = SOLVERS) -> SolveOutcome:
        """Solve with the given parameter values."""
        cp = self._cp
        for name, value in (params or {}).items():
            if name in self.params:  # a family may be absent (e.g. no decay constraint)
                self.params[name].value = float(value)
        final = {*cp.settings.INF_OR_UNB, cp.UNBOUNDED, cp.UNBOUNDED_INACCURATE}
        last = "not solved"
        for name in solvers:
            try:
                with warnings.catch_warnings():
                    warnings.simplefilter("ignore")
                    if name == "SCS":
                        self.problem.solve(solver=name, eps_abs=1e-7, eps_rel=1e-7,
                                           max_iters=SCS_MAX_ITERS)
                    else:
                        self.problem.solve(solver=name)
            except cp.error.SolverError as exc:
                last = f"solver error: {exc}"
                continue
            last = str(self.problem.status)
            if last in (cp.OPTIMAL, cp.OPTIMAL_INACCURATE) and self.x.value is not None:
                return SolveOutcome(np.asarray(self.x.value, float), name, last)
            if last in final:
                # A certificate of infeasibility is an answer, not a failure to retry.
                return SolveOutcome(None, name, last)
        return SolveOutcome(None, solvers[-1], last)


def solve_lmis(layout: Layout, families: list[tuple[Builder, Context]], objective: FArray,
               solvers: tuple[str, ...] = SOLVERS) -> SolveOutcome:
    """Minimise objective·x subject to G_f(x) ⪰ 0 for every (builder, context) family."""
    fams = [Family(b, c) for b, c in families]
    return LMIProblem(layout, fams, objective).solve(None, solvers)


# --------------------------------------------------------------------- evaluation
def eig_margins(g: FArray, atol: float = 0.0) -> tuple[FArray, FArray, FArray]:
    """Per matrix of ``g`` (K, m, m): (λ_min, max |λ|, tolerance EIG_RTOL·max|λ| + atol)."""
    g = 0.5 * (g + np.swapaxes(g, -1, -2))
    lam = np.asarray(np.linalg.eigvalsh(g), float)
    norm = np.maximum(np.abs(lam).max(axis=1), np.finfo(float).tiny)
    return lam[:, 0], norm, np.asarray(EIG_RTOL * norm + atol, float)


def eig_check(name: str, g: FArray, ctx: Context, strict: bool = True,
              required: bool = True, atol: float = 0.0) -> LMICheck:
    """Check that every matrix of ``g`` (K, m, m) is ≻ 0 (``strict``) or ⪰ 0, by eigenvalues.

    The tolerance is ``EIG_RTOL·‖G‖₂`` (rounding of the eigenvalue computation)
    plus ``atol`` (for non-strict conditions met only to solver accuracy).
    """
    lmin, norm, tol = eig_margins(g, atol)
    ok_pts = lmin > tol if strict else lmin >= -tol
    rel = lmin / norm
    i = int(np.argmin(lmin))
    return LMICheck(name=name, min_eig=float(lmin[i]), margin=float(rel.min()),
                    worst_rho=float(ctx.rho[i]), worst_rate=float(ctx.rate[i]),
                    ok=bool(np.all(ok_pts)), strict=strict, required=required)


def poly(coeffs: FArray, rho: FArray) -> FArray:
    """Σ coeffs[i] ρ^i for coeffs (f+1, r, c) → (K, r, c)."""
    powers = np.asarray(rho, float)[:, None] ** np.arange(coeffs.shape[0])[None, :]
    return np.einsum("ki,irc->krc", powers, coeffs)


def dpoly(coeffs: FArray, rho: FArray) -> FArray:
    """d/dρ Σ coeffs[i] ρ^i → (K, r, c)."""
    f = coeffs.shape[0] - 1
    if f == 0:
        return np.zeros((np.size(rho), *coeffs.shape[1:]))
    d = coeffs[1:] * np.arange(1, f + 1)[:, None, None]
    return poly(d, rho)


def sym(m: FArray) -> FArray:
    """M + Mᵀ over the last two axes."""
    return m + np.swapaxes(m, -1, -2)


def tr(m: FArray) -> FArray:
    """Transpose of the last two axes."""
    return np.swapaxes(m, -1, -2)


def eye_like(k: int, n: int) -> FArray:
    """(K, n, n) identity stack."""
    return np.broadcast_to(np.eye(n), (k, n, n)).copy()


def block(rows: list[list[FArray]]) -> FArray:
    """Batched block matrix from (K, r_i, c_j) blocks."""
    return np.concatenate([np.concatenate(r, axis=-1) for r in rows], axis=-2)


# ------------------------------------------------------------------------ scaling
@dataclass(frozen=True)
class Scaling:
    """x̂ = D x, τ = t/T0, ρ̂ = ρ/ρ_s (see the module docstring)."""

    d: FArray
    t0: float
    rho_s: float

    @staticmethod
    def from_matrix(a_mid: FArray, rho_s: float) -> Scaling:
        """Balance a representative (stable) state matrix; T0 = 1/‖Â‖₂."""
        a_mid = np.asarray(a_mid, float)
        if not np.all(np.isfinite(a_mid)) or not np.any(a_mid):
            return Scaling(np.ones(a_mid.shape[0]), 1.0, rho_s)
        _, (s, _) = matrix_balance(a_mid, permute=False, separate=True)
        d = 1.0 / np.asarray(s, float)
        ab = (d[:, None] * a_mid) / d[None, :]
        nrm = float(np.linalg.norm(ab, 2))
        return Scaling(d, 1.0 / nrm if nrm > 0 else 1.0, rho_s)

    def state(self, a: FArray) -> FArray:
        """Â = T0 D A D⁻¹."""
        return self.t0 * (self.d[:, None] * a) / self.d[None, :]

    def lyapunov_to_original(self, p_hat: FArray, form: Form = "primal") -> FArray:
        """P_i = T0 D P̂_i D / ρ_s^i (primal) or Q_i = T0 D⁻¹ Q̂_i D⁻¹ / ρ_s^i (dual)."""
        f = p_hat.shape[0]
        dd = self.d if form == "primal" else 1.0 / self.d
        out = self.t0 * dd[None, :, None] * p_hat * dd[None, None, :]
        return out / (self.rho_s ** np.arange(f))[:, None, None]


def grid_points(rho: FArray, rates: FArray) -> tuple[FArray, FArray]:
    """Cartesian product of parameter points and rate vertices, flattened."""
    r, q = np.meshgrid(rho, rates, indexing="ij")
    return r.reshape(-1), q.reshape(-1)
