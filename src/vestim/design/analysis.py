"""Analysis of LPV error dynamics for given gains: affine quadratic stability and H∞ γ.

- :func:`affine_quadratic_stability`: find P(ρ) (001 eq. (27)–(28), 004 eq. (18)).
- :func:`hinf_performance`: minimal affine quadratic H∞ performance γ (004 eq. (22)–(25)).
- :func:`check_lyapunov`: verify a *given* P(ρ) (e.g. one printed in a paper).

``method="vertex"`` is the papers' test: affine P(ρ) = P0 + ρP1, the LMIs at the
parameter and rate vertices plus the multi-convexity constraint (needs an affine
system). ``method="grid"`` drops multi-convexity and imposes the LMIs on a grid of
ρ (polynomial P of any degree), which is less conservative for one parameter.
Either way the result is verified on a fine grid (see :mod:`vestim.design.lmi`).
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np

from vestim.design.lmi import (
    MARGIN,
    MULTICONVEX_RTOL,
    SOLVERS,
    Builder,
    Context,
    FArray,
    Form,
    Layout,
    LMICheck,
    LMIResult,
    LPVSystem,
    Method,
    ParameterBox,
    Scaling,
    block,
    dpoly,
    eig_check,
    eye_like,
    grid_points,
    poly,
    solve_lmis,
    tr,
    verification_grid,
)

__all__ = ["affine_quadratic_stability", "check_lyapunov", "hinf_performance"]


# ------------------------------------------------------------------------- builders
def _lyap_matrix(vals: dict[str, FArray], ctx: Context, form: Form) -> FArray:
    p = poly(vals["P"], ctx.rho)
    dp = dpoly(vals["P"], ctx.rho)
    a = ctx.mats["A"]
    q = ctx.rate[:, None, None]
    if form == "primal":
        return tr(a) @ p + p @ a + q * dp
    return a @ p + p @ tr(a) - q * dp


def _neg_lyap(form: Form) -> Builder:
    def build(vals: dict[str, FArray], ctx: Context) -> FArray:
        m = _lyap_matrix(vals, ctx, form)
        return -m - vals["t"] * eye_like(m.shape[0], m.shape[1])
    return build


def _pos_p(vals: dict[str, FArray], ctx: Context) -> FArray:
    p = poly(vals["P"], ctx.rho)
    return p - vals["t"] * eye_like(p.shape[0], p.shape[1])


def _cap_p(vals: dict[str, FArray], ctx: Context) -> FArray:
    p = poly(vals["P"], ctx.rho)
    return eye_like(p.shape[0], p.shape[1]) - p


def _multiconvex(form: Form, with_b: bool) -> Builder:
    """ρ² coefficient of the Lyapunov/BRL matrix must be ⪰ 0 (001 after (27); 004 (25))."""
    def build(vals: dict[str, FArray], ctx: Context) -> FArray:
        p1 = vals["P"][1][None]
        a1 = ctx.mats["A1"][:1]
        m = tr(a1) @ p1 + p1 @ a1 if form == "primal" else a1 @ p1 + p1 @ tr(a1)
        if not with_b:
            return m
        pb = p1 @ ctx.mats["B1"][:1]
        return block([[m, pb], [tr(pb), np.zeros((1, pb.shape[2], pb.shape[2]))]])
    return build


def _neg_brl(vals: dict[str, FArray], ctx: Context) -> FArray:
    """−(004 eq. (24)) − tI: [[AᵀP + PA + ρ̇P′, PB, Cᵀ], [BᵀP, −γI, Dᵀ], [C, D, −γI]]."""
    p = poly(vals["P"], ctx.rho)
    dp = dpoly(vals["P"], ctx.rho)
    a, b, c, d = (ctx.mats[k] for k in ("A", "B", "C", "D"))
    k, n, m = b.shape
    pdim = c.shape[1]
    g = vals["gamma"]
    m11 = tr(a) @ p + p @ a + ctx.rate[:, None, None] * dp
    m12 = p @ b
    mat = block([[m11, m12, tr(c)],
                 [tr(m12), -g * eye_like(k, m), tr(d)],
                 [c, d, -g * eye_like(k, pdim)]])
    return -mat - vals["t"] * eye_like(k, n + m + pdim)


def _scalar(fn: Callable[[dict[str, FArray]], object]) -> Builder:
    def build(vals: dict[str, FArray], ctx: Context) -> FArray:
        return np.reshape(np.asarray(fn(vals), float), (1, 1, 1))
    return build


# ------------------------------------------------------------------------- contexts
def _contexts(system: LPVSystem, box: ParameterBox, rho: FArray,
              scaling: Scaling | None) -> Context:
    r, q = grid_points(rho, box.rate_vertices())
    a, b, c, d = system.matrices(r)
    mats: dict[str, FArray] = {"A": np.array(a), "B": np.array(b), "C": np.array(c),
                               "D": np.array(d)}
    if system.affine is not None:
        mats["A1"] = np.broadcast_to(system.affine[1], (r.size, *system.affine[1].shape)).copy()
        mats["B1"] = np.broadcast_to(system.affine[3], (r.size, *system.affine[3].shape)).copy()
    if scaling is None:
        return Context(r, q, mats)
    s = scaling
    dd = s.d
    sm = {
        "A": s.state(mats["A"]),
        "B": s.t0 * dd[:, None] * mats["B"],
        "C": mats["C"] / dd[None, :],
        "D": mats["D"],
    }
    if "A1" in mats:
        sm["A1"] = s.rho_s * s.state(mats["A1"])
        sm["B1"] = s.rho_s * s.t0 * dd[:, None] * mats["B1"]
    return Context(r / s.rho_s, q * s.t0 / s.rho_s, sm)


def _scaling_for(system: LPVSystem, box: ParameterBox) -> Scaling:
    a, _, _, _ = system.matrices(np.array([0.5 * (box.lower + box.upper)]))
    return Scaling.from_matrix(a[0], box.scale)


def _frozen_max_real(system: LPVSystem, rho: FArray) -> float:
    a, _, _, _ = system.matrices(rho)
    return float(np.max(np.linalg.eigvals(a).real))


def _solve_points(system: LPVSystem, box: ParameterBox, method: Method, degree: int,
                  n_grid: int) -> FArray:
    if method == "vertex":
        if system.affine is None:
            raise ValueError("method='vertex' needs an affine system (LPVSystem.from_affine)")
        if degree != 1:
            raise ValueError("method='vertex' is the affine test: use degree=1")
        return box.vertices()
    if method == "grid":
        return box.grid(n_grid)
    raise ValueError(f"method {method!r}: use 'vertex' or 'grid'")


# ------------------------------------------------------------------------ public API
def check_lyapunov(system: LPVSystem, box: ParameterBox, lyapunov: FArray, *,
                   form: Form = "primal", gamma: float | None = None,
                   n_verify: int | None = None, problem: str = "given P(rho)",
                   multiconvexity_required: bool = False,
                   rho: FArray | None = None) -> LMIResult:
    """Verify a given P(ρ) = Σ P_i ρ^i (original units) on a fine grid × rate vertices.

    Checks P(ρ) ≻ 0; the Lyapunov condition (001 eq. (28); ``form="dual"``:
    A Q + Q Aᵀ − ρ̇ Q′ ≺ 0); with ``gamma`` also the bounded real lemma
    (004 eq. (24)); and, for affine P and A, the multi-convexity constraint
    (informative unless ``multiconvexity_required``).

    Args:
        lyapunov: coefficients (f+1, n, n); P(ρ) = Σ lyapunov[i] ρ^i.
        n_verify: number of fine-grid points (default: that of :func:`verification_grid`
            for a 21-point solve grid, i.e. 201).
        rho: explicit parameter points instead of a uniform grid.
    """
    coeffs = np.asarray(lyapunov, float)
    if rho is None:
        rho = box.grid(n_verify) if n_verify else verification_grid(box, 21)
    ctx = _contexts(system, box, rho, None)
    vals: dict[str, FArray] = {"P": coeffs, "t": np.array(0.0)}
    checks = [eig_check("P(rho) > 0", _pos_p(vals, ctx), ctx)]
    lyap_name = ("A'P + PA + rate dP/drho < 0 (001 eq. (28))" if form == "primal"
                 else "AQ + QA' - rate dQ/drho < 0 (dual, V = e'Q^-1 e)")
    checks.append(eig_check(lyap_name, _neg_lyap(form)(vals, ctx), ctx))
    if gamma is not None:
        vals["gamma"] = np.array(float(gamma))
        checks.append(eig_check(f"bounded real lemma at gamma = {gamma:.6g} (004 eq. (24))",
                                _neg_brl(vals, ctx), ctx))
    if system.affine is not None and coeffs.shape[0] == 2:
        mc = _multiconvex(form, False)(vals, ctx)
        ref = (float(np.linalg.norm(system.affine[1], 2))
               * float(np.max(np.linalg.norm(poly(coeffs, rho), 2, axis=(1, 2)))) / box.scale)
        checks.append(eig_check("multi-convexity A1'P1 + P1A1 >= 0", mc,
                                Context(np.array([np.nan]), np.array([np.nan]), {}), strict=False,
                                required=multiconvexity_required, atol=MULTICONVEX_RTOL * ref))
    verified = all(c.ok for c in checks if c.required)
    return LMIResult(problem=problem, feasible=None, verified=verified, min_eig=_min_eig(checks),
                     gamma=gamma, gamma_opt=None, lyapunov=coeffs, checks=tuple(checks),
                     solver="-", status="-", solve_grid=np.array([]), verify_grid=rho, form=form,
                     method="grid", frozen_max_real=_frozen_max_real(system, rho))


def affine_quadratic_stability(system: LPVSystem, box: ParameterBox, *,
                               method: Method = "vertex", form: Form = "primal",
                               degree: int = 1, n_grid: int = 21,
                               solvers: tuple[str, ...] = SOLVERS) -> LMIResult:
    """Search P(ρ) proving affine quadratic stability; 001 eq. (27)–(28), 004 eq. (18).

    Solves: maximise t s.t. t I ⪯ P(ρ) ⪯ I, Lyapunov condition ⪯ −t I at the
    solve points × rate vertices, and (vertex method) multi-convexity ⪰ 0, in
    balanced coordinates. Feasible iff t > 0. The P found is then verified in
    original units on the fine grid (:func:`check_lyapunov`).

    Args:
        system: error dynamics; affine for ``method="vertex"``.
        box: ρ range and rate bound (for the LuGre observers ρ = |ω| ∈ [0, ω_max]).
        method: "vertex" (papers' test) or "grid".
        form: "primal" (001 eq. (28)) or "dual" (V = xᵀQ(ρ)⁻¹x).
        degree: polynomial degree of P in ρ (1 for the vertex method).
        n_grid: solve-grid size for ``method="grid"``.
    """
    pts = _solve_points(system, box, method, degree, n_grid)
    scaling = _scaling_for(system, box)
    ctx = _contexts(system, box, pts, scaling)
    n = ctx.mats["A"].shape[-1]
    pos_ctx = Context(pts / scaling.rho_s, np.zeros_like(pts), ctx.mats)
    layout = Layout()
    layout.add("P", (degree + 1, n, n), symmetric=True)
    layout.add("t", ())
    families: list[tuple[Builder, Context]] = [(_pos_p, pos_ctx), (_cap_p, pos_ctx),
                                               (_neg_lyap(form), ctx)]
    if method == "vertex":
        families.append((_multiconvex(form, False), Context(pts[:1], pts[:1], ctx.mats)))
    objective = np.zeros(layout.size)
    objective[-1] = -1.0
    out = solve_lmis(layout, families, objective, solvers)
    eq = "001 eq. (28)" if form == "primal" else "dual form"
    problem = f"affine quadratic stability ({method}, {form}, {eq})"
    if out.x is None:
        return LMIResult(problem=problem, feasible=False, verified=False, min_eig=float("nan"),
                         gamma=None, gamma_opt=None, lyapunov=None, checks=(), solver=out.solver,
                         status=out.status, solve_grid=pts,
                         verify_grid=verification_grid(box, pts.size), form=form, method=method,
                         message="the solver found no P(rho)")
    vals = layout.unpack(out.x)
    t_opt = float(vals["t"])
    coeffs = scaling.lyapunov_to_original(vals["P"], form)
    chk = check_lyapunov(system, box, coeffs, form=form,
                         n_verify=verification_grid(box, pts.size).size, problem=problem,
                         multiconvexity_required=(method == "vertex"))
    feasible = t_opt > 1e-9 and _holds_at_solve_points(system, box, coeffs, form, None, pts,
                                                          method)
    msg = f"solver margin t = {t_opt:.3g} (balanced coordinates)"
    if not feasible:
        msg += "; no strictly feasible P(rho): the LMIs are infeasible"
    return LMIResult(problem=problem, feasible=feasible, verified=feasible and chk.verified,
                     min_eig=chk.min_eig, gamma=None, gamma_opt=None, lyapunov=coeffs,
                     checks=chk.checks, solver=out.solver, status=out.status, solve_grid=pts,
                     verify_grid=chk.verify_grid, form=form, method=method,
                     frozen_max_real=chk.frozen_max_real, message=msg)


def hinf_performance(system: LPVSystem, box: ParameterBox, *, method: Method = "vertex",
                     degree: int = 1, n_grid: int = 21, slack: float = 0.01,
                     solvers: tuple[str, ...] = SOLVERS) -> LMIResult:
    """Affine quadratic H∞ performance γ (004 eq. (22)–(25)) of given error dynamics.

    Stage 1 minimises γ with the LMIs ⪯ −t I for a tiny t; stage 2 keeps
    γ ≤ (1 + slack)·γ* and maximises the margin t, so that the certificate
    survives the fine-grid verification. The returned ``gamma`` is the one
    verified (``None`` if verification fails); ``gamma_opt`` is γ* of stage 1, as
    the solver reported it. ``feasible`` is the solver's claim *checked by
    eigenvalues at the solve points*.
    """
    pts = _solve_points(system, box, method, degree, n_grid)
    scaling = _scaling_for(system, box)
    ctx = _contexts(system, box, pts, scaling)
    n = ctx.mats["A"].shape[-1]
    pos_ctx = Context(pts / scaling.rho_s, np.zeros_like(pts), ctx.mats)
    layout = Layout()
    layout.add("P", (degree + 1, n, n), symmetric=True)
    layout.add("gamma", ())
    layout.add("t", ())
    base: list[tuple[Builder, Context]] = [(_pos_p, pos_ctx), (_neg_brl, ctx)]
    if method == "vertex":
        with_b = bool(np.any(system.affine[3])) if system.affine is not None else False
        base.append((_multiconvex("primal", with_b), Context(pts[:1], pts[:1], ctx.mats)))
    unit = Context(np.zeros(1), np.zeros(1), {})
    stage1 = [*base, (_scalar(lambda v: v["t"] - MARGIN), unit),
              (_scalar(lambda v: MARGIN - v["t"]), unit)]
    obj = np.zeros(layout.size)
    obj[layout.size - 2] = 1.0
    out = solve_lmis(layout, stage1, obj, solvers)
    problem = f"affine quadratic H-infinity performance ({method}, 004 eq. (24)-(25))"
    if out.x is None:
        return LMIResult(problem=problem, feasible=False, verified=False, min_eig=float("nan"),
                         gamma=None, gamma_opt=None, lyapunov=None, checks=(), solver=out.solver,
                         status=out.status, solve_grid=pts,
                         verify_grid=verification_grid(box, pts.size), method=method,
                         message="no finite gamma: the LMIs are infeasible")
    g_opt = float(layout.unpack(out.x)["gamma"])
    x_best, solver, status = out.x, out.solver, out.status
    if slack > 0:
        cap = (1.0 + slack) * g_opt
        stage2 = [*base, (_scalar(lambda v: cap - v["gamma"]), unit)]
        obj2 = np.zeros(layout.size)
        obj2[-1] = -1.0
        out2 = solve_lmis(layout, stage2, obj2, solvers)
        if out2.x is not None:
            x_best, solver, status = out2.x, out2.solver, out2.status
    vals = layout.unpack(x_best)
    gamma = float(vals["gamma"])
    coeffs = scaling.lyapunov_to_original(vals["P"], "primal")
    chk = check_lyapunov(system, box, coeffs, gamma=gamma,
                         n_verify=verification_grid(box, pts.size).size, problem=problem,
                         multiconvexity_required=(method == "vertex"))
    checks = tuple(c for c in chk.checks if not c.name.startswith("A'P"))
    checks = _relabel_stability(chk.checks, checks)
    verified = all(c.ok for c in checks if c.required)
    feasible = _holds_at_solve_points(system, box, coeffs, "primal", gamma, pts, method)
    msg = "" if feasible else ("the solver's answer violates the LMIs where they were imposed: "
                               "infeasible (no finite gamma)")
    return LMIResult(problem=problem, feasible=feasible, verified=verified and feasible,
                     min_eig=_min_eig(checks), gamma=gamma if verified and feasible else None,
                     gamma_opt=g_opt, lyapunov=coeffs, checks=checks, solver=solver,
                     status=status, solve_grid=pts, verify_grid=chk.verify_grid, method=method,
                     frozen_max_real=chk.frozen_max_real, message=msg)


def _min_eig(checks: list[LMICheck] | tuple[LMICheck, ...]) -> float:
    """Smallest eigenvalue over the required strict checks (non-strict ones have a tolerance)."""
    vals = [c.min_eig for c in checks if c.required and c.strict]
    return float(min(vals)) if vals else float("nan")


def _holds_at_solve_points(system: LPVSystem, box: ParameterBox, coeffs: FArray, form: Form,
                           gamma: float | None, pts: FArray, method: Method) -> bool:
    """Does the solver's answer satisfy the LMIs where they were imposed? (Else: infeasible.)"""
    res = check_lyapunov(system, box, coeffs, form=form, gamma=gamma, rho=pts,
                         multiconvexity_required=(method == "vertex"))
    return res.verified


def _relabel_stability(all_checks: tuple[LMICheck, ...],
                       kept: tuple[LMICheck, ...]) -> tuple[LMICheck, ...]:
    """Keep the plain Lyapunov check as informative (the BRL implies it)."""
    lyap = [c for c in all_checks if c.name.startswith("A'P")]
    extra = tuple(LMICheck(c.name, c.min_eig, c.margin, c.worst_rho, c.worst_rate, c.ok,
                           c.strict, required=False) for c in lyap)
    return kept + extra
