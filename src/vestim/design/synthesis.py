"""LPV observer gain synthesis with a parameter-dependent Lyapunov matrix.

Plant, polynomial in the scheduling parameter ρ (for the LuGre corner
observers ρ = |ω|, :mod:`vestim.models.lpv`)::

    ẋ = A(ρ) x + B w,    y = C_y(ρ) x + F w,    z = H e

Observer ``x̂˙ = A x̂ + L(ρ)(y − C_y x̂)`` (001 eq. (24)); error dynamics
``ė = (A − L C_y) e + (B − L F) w``. With χ(ρ) = P(ρ) L(ρ) the bounded real
lemma becomes an LMI in (P, χ, γ) (001 eq. (30)–(32); 004 eq. (30) with
η = P T)::

    ⎡ He(PA − χC_y) + ρ̇ ∂P/∂ρ   PB − χF   Hᵀ  ⎤
    ⎢          *                  −γI      0   ⎥ ≺ 0,    P(ρ) ≻ 0,
    ⎣          *                   *      −γI  ⎦

imposed on a ρ grid × the rate vertices with P(ρ) = Σ P_i ρ^i, χ(ρ) = Σ χ_i ρ^i
(001 after eq. (32): "P(ω) := Σ P_i ω^i ... gridded"; 004 after eq. (34)).
The gains are L(ρ) = P(ρ)⁻¹ χ(ρ), a rational function of ρ as in 004 eq. (35).

Optionally (our addition, see ``pole_radius``) the frozen error dynamics are
kept in the disk |λ| ≤ r with the same P (Chilali–Gahinet D-region LMI)::

    ⎡ −rP            (PA − χC_y)ᵀ ⎤
    ⎣ PA − χC_y      −rP          ⎦ ≺ 0.

Two stages: (1) minimise γ; (2) within γ ≤ (1 + slack)·γ*, maximise the
guaranteed decay rate α of V = eᵀP(ρ)e (``He(PA − χC_y) + ρ̇P′ + 2αP ≺ 0``, by
bisection), then take a central feasible point at 0.9·α. Stage 2 is our addition: for the
LuGre observers γ has a gain-independent floor (see :mod:`vestim.design.observer`),
so stage 1 alone leaves the gains undetermined. The result is verified in
original units on a grid ten times finer than the solve grid.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from typing import Literal

import numpy as np
from scipy.linalg import solve_continuous_are

from vestim.design.lmi import (
    MARGIN,
    SOLVERS,
    Builder,
    Context,
    Family,
    FArray,
    Layout,
    LMIProblem,
    LMIResult,
    LPVSystem,
    ParameterBox,
    Scaling,
    block,
    dpoly,
    eig_check,
    eig_margins,
    eye_like,
    grid_points,
    poly,
    sym,
    tr,
    verification_grid,
)

__all__ = ["ObserverPlant", "SynthesisResult", "synthesize_observer", "verify_synthesis"]

Objective = Literal["decay", "margin"]


@dataclass(frozen=True)
class ObserverPlant:
    """Plant of an observer synthesis; see the module docstring.

    Attributes:
        a: coefficients (f+1, n, n) of A(ρ) = Σ a[i] ρ^i.
        cy: coefficients (f+1, q, n) of the measurement matrix C_y(ρ).
        b: (n, m) disturbance input matrix.
        f: (q, m) disturbance-to-measurement matrix.
        h: (p, n) performance output (z = H e).
    """

    a: FArray
    cy: FArray
    b: FArray
    f: FArray
    h: FArray

    def __post_init__(self) -> None:
        n = self.a.shape[-1]
        if self.a.ndim != 3 or self.a.shape[1] != n:
            raise ValueError(f"ObserverPlant.a must have shape (f+1, n, n), got {self.a.shape}")
        if self.cy.ndim != 3 or self.cy.shape[2] != n:
            raise ValueError(f"ObserverPlant.cy must have shape (f+1, q, {n}), got {self.cy.shape}")
        if self.b.shape[0] != n or self.f.shape != (self.cy.shape[1], self.b.shape[1]):
            raise ValueError("ObserverPlant: b must be (n, m) and f (q, m)")
        if self.h.shape[1] != n:
            raise ValueError(f"ObserverPlant.h must have {n} columns")

    def matrices(self, rho: FArray) -> tuple[FArray, FArray]:
        """(A(ρ), C_y(ρ)) with a leading axis of len(rho)."""
        r = np.atleast_1d(np.asarray(rho, float))
        return poly(self.a, r), poly(self.cy, r)

    def closed_loop(self, gain: Callable[[FArray], FArray]) -> LPVSystem:
        """Error dynamics for a gain function ρ (K,) → L (K, n, q) as an :class:`LPVSystem`."""
        def evaluate(rho: FArray) -> tuple[FArray, FArray, FArray, FArray]:
            a, cy = self.matrices(rho)
            lg = gain(np.atleast_1d(rho))
            k = a.shape[0]
            return (a - lg @ cy, self.b - lg @ self.f,
                    np.broadcast_to(self.h, (k, *self.h.shape)),
                    np.zeros((k, self.h.shape[0], self.b.shape[1])))
        return LPVSystem(evaluate=evaluate, name="observer error dynamics")


@dataclass(frozen=True)
class SynthesisResult:
    """Certificate of a synthesis and the gain it defines, L(ρ) = P(ρ)⁻¹ χ(ρ)."""

    certificate: LMIResult
    chi: FArray | None
    pole_radius: float | None

    def gain(self, rho: FArray) -> FArray:
        """L(ρ), shape (K, n, q), in original units."""
        if self.chi is None or self.certificate.lyapunov is None:
            raise ValueError("the synthesis returned no solution, so there is no gain")
        r = np.atleast_1d(np.asarray(rho, float))
        return np.asarray(np.linalg.solve(poly(self.certificate.lyapunov, r), poly(self.chi, r)),
                          float)


# --------------------------------------------------------------------------- builders
def _pa(vals: dict[str, FArray], ctx: Context) -> tuple[FArray, FArray]:
    p = poly(vals["P"], ctx.rho)
    x = poly(vals["X"], ctx.rho)
    return p, p @ ctx.mats["A"] - x @ ctx.mats["Cy"]


def _neg_brl(vals: dict[str, FArray], ctx: Context) -> FArray:
    p, pa = _pa(vals, ctx)
    x = poly(vals["X"], ctx.rho)
    dp = dpoly(vals["P"], ctx.rho)
    b, f, h = ctx.mats["B"], ctx.mats["F"], ctx.mats["H"]
    k, n, m = b.shape
    pdim = h.shape[1]
    g = vals["gamma"]
    m11 = sym(pa) + ctx.rate[:, None, None] * dp
    m12 = p @ b - x @ f
    mat = block([[m11, m12, tr(h)],
                 [tr(m12), -g * eye_like(k, m), np.zeros((k, m, pdim))],
                 [h, np.zeros((k, pdim, m)), -g * eye_like(k, pdim)]])
    return -mat - vals["t"] * eye_like(k, n + m + pdim)


def _neg_disk(vals: dict[str, FArray], ctx: Context) -> FArray:
    p, pa = _pa(vals, ctx)
    r = ctx.extra["radius"]
    mat = block([[-r * p, tr(pa)], [pa, -r * p]])
    return -mat - vals["t"] * eye_like(mat.shape[0], mat.shape[1])


def _neg_decay(vals: dict[str, FArray], ctx: Context) -> FArray:
    """−(He(PA − χC_y) + ρ̇P′ + 2αP) − tI: V decays at least as e^(−2αt)."""
    p, pa = _pa(vals, ctx)
    dp = dpoly(vals["P"], ctx.rho)
    m = sym(pa) + ctx.rate[:, None, None] * dp + 2.0 * ctx.extra["alpha"] * p
    return -m - vals["t"] * eye_like(m.shape[0], m.shape[1])


def _pos_p(vals: dict[str, FArray], ctx: Context) -> FArray:
    p = poly(vals["P"], ctx.rho)
    return p - vals["t"] * eye_like(p.shape[0], p.shape[1])


def _scalar(fn: Callable[[dict[str, FArray]], object]) -> Callable[[dict[str, FArray], Context], FArray]:
    def build(vals: dict[str, FArray], ctx: Context) -> FArray:
        return np.reshape(np.asarray(fn(vals), float), (1, 1, 1))
    return build


# ---------------------------------------------------------------------------- helpers
def _nominal_scaling(plant: ObserverPlant, box: ParameterBox) -> Scaling:
    """Balance A − L0 C_y at mid-range, L0 a Kalman gain (unit weights), so the LMIs are well scaled."""
    a, cy = plant.matrices(np.array([0.5 * (box.lower + box.upper)]))
    a, cy = a[0], cy[0]
    try:
        q = plant.b @ plant.b.T + 1e-9 * np.eye(a.shape[0])
        x = solve_continuous_are(a.T, cy.T, q, np.eye(cy.shape[0]))
        acl = a - x @ cy.T @ cy
    except (np.linalg.LinAlgError, ValueError):
        acl = a
    return Scaling.from_matrix(acl, box.scale)


def _context(plant: ObserverPlant, box: ParameterBox, rho: FArray, scaling: Scaling | None,
             radius: float | None, with_rates: bool = True) -> Context:
    if with_rates:
        r, q = grid_points(rho, box.rate_vertices())
    else:
        r, q = np.asarray(rho, float), np.zeros(np.size(rho))
    a, cy = plant.matrices(r)
    k = r.size
    mats = {"A": a, "Cy": cy, "B": np.broadcast_to(plant.b, (k, *plant.b.shape)),
            "F": np.broadcast_to(plant.f, (k, *plant.f.shape)),
            "H": np.broadcast_to(plant.h, (k, *plant.h.shape))}
    extra = {"radius": float(radius)} if radius is not None else {}
    if scaling is None:
        return Context(r, q, mats, extra)
    s = scaling
    sm = {"A": s.state(a), "Cy": cy / s.d[None, :], "B": s.t0 * s.d[:, None] * mats["B"],
          "F": mats["F"], "H": mats["H"] / s.d[None, :]}
    if radius is not None:
        extra = {"radius": float(radius) * s.t0}
    return Context(r / s.rho_s, q * s.t0 / s.rho_s, sm, extra)


# ------------------------------------------------------------------------------ API
MAX_REFINE = 3
"""Rounds of adding failing fine-grid points to the solve grid of the last stage."""

DECAY_BACKOFF = 0.9
"""The certified decay rate is this fraction of the largest one the bisection found."""


def _neg_decay_base(vals: dict[str, FArray], ctx: Context) -> FArray:
    _, pa = _pa(vals, ctx)
    m = sym(pa) + ctx.rate[:, None, None] * dpoly(vals["P"], ctx.rho)
    return -m - vals["t"] * eye_like(m.shape[0], m.shape[1])


def _neg_2p(vals: dict[str, FArray], ctx: Context) -> FArray:
    return -2.0 * poly(vals["P"], ctx.rho)


def synthesize_observer(plant: ObserverPlant, box: ParameterBox, *, degree: int = 1,
                        n_grid: int = 37, pole_radius: float | None = None,
                        slack: float = 0.02, objective: Objective = "decay",
                        n_bisect: int = 9,
                        solvers: tuple[str, ...] = SOLVERS) -> SynthesisResult:
    """LPV observer gains minimising the H∞ performance γ (001 eq. (30)–(32), 004 eq. (26)–(35)).

    Args:
        plant: see :class:`ObserverPlant`.
        box: ρ range and rate bound.
        degree: polynomial degree f of P(ρ) and χ(ρ).
        n_grid: number of ρ grid points the LMIs are imposed on (001 used 140, 004 120).
        pole_radius: if given (1/s), frozen closed-loop poles are kept in |λ| ≤ r.
        slack: relative γ slack of the second stage (0 skips it).
        objective: second stage, within γ ≤ (1 + slack)·γ*: "decay" maximises the
            guaranteed decay rate α (He(PA − χC_y) + ρ̇P′ + 2αP ≺ 0, by bisection
            with ``n_bisect`` steps) and returns a central feasible point at
            :data:`DECAY_BACKOFF`·α; "margin" maximises the LMI margin only.
    Returns:
        :class:`SynthesisResult`; its certificate was verified on a grid ten times
        finer than the base solve grid, in original units, with the rational gains.
        Where the last stage's certificate fails between grid points, the failing
        fine-grid points are added to its solve grid (at most :data:`MAX_REFINE`
        rounds); ``certificate.solve_grid`` lists the points finally used.
    """
    if degree < 0 or n_grid < 2:
        raise ValueError(f"degree = {degree} must be >= 0 and n_grid = {n_grid} >= 2")
    if pole_radius is not None and not pole_radius > 0:
        raise ValueError(f"pole_radius = {pole_radius} must be > 0")
    if objective not in ("decay", "margin"):
        raise ValueError(f"objective {objective!r}: use 'decay' or 'margin'")
    rho = box.grid(n_grid)
    scaling = _nominal_scaling(plant, box)
    n, q = plant.a.shape[-1], plant.cy.shape[1]
    layout = Layout()
    layout.add("P", (degree + 1, n, n), symmetric=True)
    layout.add("X", (degree + 1, n, q))
    layout.add("gamma", ())
    layout.add("t", ())
    unit = Context(np.zeros(1), np.zeros(1), {})

    def base(pts: FArray) -> list[Family]:
        ctx = _context(plant, box, pts, scaling, None)
        pctx = _context(plant, box, pts, scaling, pole_radius, with_rates=False)
        fams = [Family(_pos_p, pctx), Family(_neg_brl, ctx)]
        if pole_radius is not None:
            fams.append(Family(_neg_disk, pctx))
        return fams

    def decay(pts: FArray) -> Family:
        return Family(_neg_decay_base, _context(plant, box, pts, scaling, None), "alpha", _neg_2p)

    fix_t = [Family(_scalar(lambda v: v["t"] - MARGIN), unit),
             Family(_scalar(lambda v: MARGIN - v["t"]), unit)]
    cap_fam = Family(_scalar(lambda v: -v["gamma"]), unit, "cap", _scalar(lambda v: 1.0))
    obj_gamma = np.zeros(layout.size)
    obj_gamma[layout.size - 2] = 1.0
    obj_margin = np.zeros(layout.size)
    obj_margin[-1] = -1.0

    out = LMIProblem(layout, [*base(rho), *fix_t], obj_gamma).solve(None, solvers)
    problem = "LPV observer synthesis (001 eq. (30)-(32), 004 eq. (30))"
    vgrid = verification_grid(box, n_grid)
    if out.x is None:
        cert = LMIResult(problem=problem, feasible=False, verified=False, min_eig=float("nan"),
                         gamma=None, gamma_opt=None, lyapunov=None, checks=(), solver=out.solver,
                         status=out.status, solve_grid=rho, verify_grid=vgrid,
                         message="no gains: the synthesis LMIs are infeasible")
        return SynthesisResult(cert, None, pole_radius)
    g_opt = float(layout.unpack(out.x)["gamma"])
    cap = (1.0 + slack) * g_opt
    alpha_max: float | None = None
    if slack > 0 and objective == "decay":
        bis = LMIProblem(layout, [*base(rho), *fix_t, cap_fam, decay(rho)],
                         np.zeros(layout.size))
        lo = 0.0
        hi = float(pole_radius) if pole_radius is not None else 10.0 / scaling.t0
        for _ in range(n_bisect):
            mid = 0.5 * (lo + hi)
            # Only a fully accurate solution counts as feasible: bisection must not creep
            # past the boundary on an inaccurate point.
            if bis.solve({"cap": cap, "alpha": mid * scaling.t0}, ("CLARABEL",)).accurate:
                lo = mid
            else:
                hi = mid
        alpha_max = lo
    alpha = None if alpha_max is None else DECAY_BACKOFF * alpha_max

    pts = rho
    x_best, solver, status = out.x, out.solver, out.status
    for _ in range(MAX_REFINE + 1):
        if slack > 0:
            fams = [*base(pts), cap_fam]
            if alpha is not None:
                fams.append(decay(pts))
            prm = {"cap": cap, "alpha": 0.0 if alpha is None else alpha * scaling.t0}
            if alpha is None:
                out3 = LMIProblem(layout, fams, obj_margin).solve(prm, solvers)
            else:
                # A pure feasibility problem: the interior-point method returns a central
                # point of {γ ≤ cap, decay ≥ α}, which keeps slack in every LMI. (Maximising
                # the margin t here is numerically fragile near the decay limit.)
                out3 = LMIProblem(layout, [*fams, *fix_t], np.zeros(layout.size)).solve(
                    prm, solvers)
            if out3.x is not None and float(layout.unpack(out3.x)["t"]) > 0:
                x_best, solver, status = out3.x, out3.solver, out3.status
        vals = layout.unpack(x_best)
        p_coef, x_coef = _to_original(vals, scaling, degree)
        gamma = float(vals["gamma"])
        decay_ok = alpha if x_best is not out.x else None
        cert = verify_synthesis(plant, box, p_coef, x_coef, gamma, pole_radius, vgrid,
                                problem=problem, decay_rate=decay_ok)
        if cert.verified or slack <= 0:
            break
        bad = _failing_points(plant, box, p_coef, x_coef, gamma, pole_radius, vgrid, decay_ok)
        new = np.setdiff1d(bad, pts)
        if new.size == 0:
            break
        pts = np.union1d(pts, new)
    msg = f"solver margin t = {float(vals['t']):.3g} (balanced coordinates)"
    extra = {"chi": x_coef}
    if decay_ok is not None and alpha_max is not None:
        msg += (f"; guaranteed decay rate alpha = {decay_ok:.4g} 1/s "
                f"({DECAY_BACKOFF:g} x the largest found, {alpha_max:.4g})")
        extra["decay_rate"] = np.array(decay_ok)
    if pts.size > rho.size:
        msg += f"; {pts.size - rho.size} fine-grid points added to the last stage's grid"
    at_solve = verify_synthesis(plant, box, p_coef, x_coef, gamma, pole_radius, pts,
                                decay_rate=decay_ok)
    if not at_solve.verified:
        msg += "; the solver's answer violates the LMIs where they were imposed: infeasible"
    cert = LMIResult(problem=problem, feasible=at_solve.verified,
                     verified=cert.verified and at_solve.verified, min_eig=cert.min_eig,
                     gamma=gamma, gamma_opt=g_opt, lyapunov=p_coef, checks=cert.checks,
                     solver=solver, status=status, solve_grid=pts, verify_grid=vgrid,
                     frozen_max_real=cert.frozen_max_real, message=msg, extra=extra)
    return SynthesisResult(cert, x_coef, pole_radius)


def _to_original(vals: dict[str, FArray], scaling: Scaling, degree: int) -> tuple[FArray, FArray]:
    """P_i = T0 D P̂_i D/ρ_s^i and χ_i = D χ̂_i/ρ_s^i (so that L = P⁻¹χ = D⁻¹L̂/T0)."""
    p_coef = scaling.lyapunov_to_original(vals["P"], "primal")
    x_coef = (scaling.d[None, :, None] * vals["X"]
              / (scaling.rho_s ** np.arange(degree + 1))[:, None, None])
    return p_coef, x_coef


def _with_alpha(ctx: Context, alpha: float) -> Context:
    return Context(ctx.rho, ctx.rate, ctx.mats, {**ctx.extra, "alpha": float(alpha)})


def _families_original(plant: ObserverPlant, box: ParameterBox, rho: FArray,
                       pole_radius: float | None, decay_rate: float | None
                       ) -> list[tuple[str, Builder, Context]]:
    ctx = _context(plant, box, rho, None, pole_radius)
    pctx = _context(plant, box, rho, None, pole_radius, with_rates=False)
    fams: list[tuple[str, Builder, Context]] = [("P(rho) > 0", _pos_p, pctx),
                                                ("bounded real lemma", _neg_brl, ctx)]
    if pole_radius is not None:
        fams.append((f"pole disk |lambda| <= {pole_radius:g} 1/s", _neg_disk, pctx))
    if decay_rate is not None:
        fams.append((f"decay rate >= {decay_rate:.4g} 1/s", _neg_decay,
                     _with_alpha(ctx, decay_rate)))
    return fams


def _failing_points(plant: ObserverPlant, box: ParameterBox, lyapunov: FArray, chi: FArray,
                    gamma: float, pole_radius: float | None, rho: FArray,
                    decay_rate: float | None, worst: int = 8) -> FArray:
    """Up to ``worst`` ρ of ``rho`` where some synthesis LMI fails, most violated first."""
    vals = {"P": lyapunov, "X": chi, "gamma": np.array(gamma), "t": np.array(0.0)}
    scores: dict[float, float] = {}
    for _, build, ctx in _families_original(plant, box, rho, pole_radius, decay_rate):
        lmin, norm, tol = eig_margins(build(vals, ctx))
        rel = (lmin - tol) / norm
        for r, v in zip(ctx.rho[rel <= 0], rel[rel <= 0], strict=True):
            scores[float(r)] = min(scores.get(float(r), 0.0), float(v))
    order = sorted(scores, key=lambda r: scores[r])
    return np.array(sorted(order[:worst]))


def verify_synthesis(plant: ObserverPlant, box: ParameterBox, lyapunov: FArray, chi: FArray,
                     gamma: float, pole_radius: float | None, rho: FArray,
                     problem: str = "LPV observer certificate",
                     decay_rate: float | None = None) -> LMIResult:
    """Evaluate the synthesis LMIs with (P, χ, γ) in original units at ``rho`` × rate vertices."""
    vals = {"P": np.asarray(lyapunov, float), "X": np.asarray(chi, float),
            "gamma": np.array(float(gamma)), "t": np.array(0.0)}
    checks = []
    for name, build, ctx in _families_original(plant, box, rho, pole_radius, decay_rate):
        if name == "bounded real lemma":
            name = f"bounded real lemma at gamma = {gamma:.6g} (001 eq. (30))"
        checks.append(eig_check(name, build(vals, ctx), ctx))
    r = np.asarray(rho, float)
    gain = np.linalg.solve(poly(vals["P"], r), poly(vals["X"], r))
    a, cy = plant.matrices(r)
    frozen = float(np.max(np.linalg.eigvals(a - gain @ cy).real))
    return LMIResult(problem=problem, feasible=None, verified=all(c.ok for c in checks),
                     min_eig=float(min(c.min_eig for c in checks)), gamma=gamma, gamma_opt=None,
                     lyapunov=np.asarray(lyapunov, float), checks=tuple(checks), solver="-",
                     status="-", solve_grid=np.array([]), verify_grid=r,
                     frozen_max_real=frozen, extra={"chi": np.asarray(chi, float)})
