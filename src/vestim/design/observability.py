"""Observability of the corner models: rank tests, Gramians, stochastic observability.

- :func:`ltv_observability_matrix`: Silverman–Meadows matrix of a linear
  time-varying system, ``O_n = [τ1; …; τn]``, ``τ1 = C``, ``τ_{i+1} = τ_i A + τ̇_i``
  (000 eq. (24), 001 eq. (12), 004 eq. (15)), from the time derivatives of A and C.
- :func:`lugre_observability` (004 eq. (15), the two-state model with output
  ``C + C′A(ω)``), :func:`kalman_observability` (000 eq. (19), three states) and
  :func:`lateral_force_observability` (001 eq. (10)–(12)) evaluate it over an
  operating region.
- :func:`observability_gramian`, :func:`controllability_gramian`: 000 (A1)–(A2)
  along a discrete-time trajectory.
- :func:`stochastic_observability`: the tests 1 and 2 of 000 Lemma 1 for a
  Kalman filter whose initial covariance ψI is completely uncertain (ψ → ∞),
  000 eq. (26)–(27) and (A6)–(A7), computed as the exact diffuse Kalman filter
  (Koopman 1997): ``P_{k|k−1} = ψM_k + N_k + O(1/ψ)`` with ``M_k = U_k U_kᵀ``.
  Each measurement removes from the column space of U the direction
  ``Σ_k = U_kᵀC_kᵀΞ_k⁻¹`` it observes (000 (A7): Φ_k = I − Σ(ΣᵀΣ)⁺Σᵀ = X_kX_kᵀ,
  U ← U X_k), and N is updated with the diffuse gain; once U is empty
  (λ_max(M) = 0, test 1) N obeys the Riccati recursion 000 eq. (27).
- :func:`analyze_observability`: all of it over a drive log, with figures like
  000 Fig. 1–3 and 004 Fig. 5.
"""

from __future__ import annotations

import json
import math
from collections.abc import Sequence
from dataclasses import asdict, dataclass, field, replace
from math import comb
from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd
from scipy.linalg import null_space

from vestim.constants import CORNERS
from vestim.design.lmi import FArray
from vestim.errors import LogFormatError
from vestim.io.files import write_text_atomic
from vestim.io.vehicle import Vehicle, VehicleBody, load_vehicle
from vestim.models.lpv import (
    LuGreAxis,
    affine_output_matrices,
    affine_state_matrices,
    input_matrix,
    kalman_model,
    lateral_axis,
    longitudinal_axis,
    output_matrix,
    state_matrix,
)

__all__ = [
    "ObservabilityReport",
    "StochasticObservability",
    "analyze_observability",
    "controllability_gramian",
    "discretize",
    "expm_batched",
    "gramian_rank",
    "kalman_observability",
    "lateral_force_observability",
    "lateral_force_output_matrix",
    "ltv_observability_matrix",
    "lugre_observability",
    "observability_gramian",
    "stochastic_observability",
]

RANK_RTOL = 1e-9
"""Relative singular-value threshold of the rank tests (σ_i > RANK_RTOL·σ_max)."""


# ---------------------------------------------------------------- rank tests (LTV)
def ltv_observability_matrix(a_derivs: FArray, c_derivs: FArray, n_blocks: int | None = None
                             ) -> FArray:
    """Observability matrix of an LTV system from the time derivatives of A(t), C(t).

    000 eq. (24): O_n = [τ1; τ2; …; τn], τ1 = C, τ_{i+1} = τ_i A + τ̇_i. The
    derivatives of τ_i follow from Leibniz's rule,
    τ_{i+1}^{(j)} = Σ_l binom(j, l) τ_i^{(l)} A^{(j−l)} + τ_i^{(j+1)}.

    Args:
        a_derivs: (..., ka, n, n) with a_derivs[..., j] = d^jA/dt^j (missing orders are 0).
        c_derivs: (..., kc, q, n), likewise for C.
        n_blocks: number of blocks τ_i (default n).
    Returns:
        (..., n_blocks·q, n).
    """
    a_d = np.asarray(a_derivs, float)
    c_d = np.asarray(c_derivs, float)
    n = a_d.shape[-1]
    nb = n if n_blocks is None else n_blocks
    need = nb  # τ_1 needs derivatives up to order nb − 1

    def order(arr: FArray, j: int) -> FArray:
        return arr[..., j, :, :] if j < arr.shape[-3] else np.zeros_like(arr[..., 0, :, :])

    tau = [order(c_d, j) for j in range(need)]
    blocks = [tau[0]]
    for i in range(1, nb):
        new = []
        for j in range(need - i):
            acc = tau[j + 1].copy()
            for m in range(j + 1):
                acc = acc + comb(j, m) * tau[m] @ order(a_d, j - m)
            new.append(acc)
        tau = new
        blocks.append(tau[0])
    return np.concatenate(blocks, axis=-2)


def _rank(m: FArray) -> FArray:
    s = np.linalg.svd(m, compute_uv=False)
    smax = np.maximum(s[..., :1], np.finfo(float).tiny)
    return np.sum(s > RANK_RTOL * smax, axis=-1)


def _equilibrate(o: FArray) -> FArray:
    """Scale columns to unit norm (states have different units; rank is unchanged)."""
    nrm = np.linalg.norm(o, axis=-2, keepdims=True)
    return o / np.where(nrm > 0, nrm, 1.0)


def lugre_observability(omega: FArray, omega_dot: FArray, axis: LuGreAxis,
                        omega_ddot: FArray | float = 0.0) -> tuple[FArray, FArray, FArray]:
    """004 eq. (15) for the two-state corner model with output C(ω) = C + C′A(ω).

    Args:
        omega, omega_dot, omega_ddot: wheel speed (rad/s) and its derivatives,
            broadcast together (use ≥ 0 speeds: the model uses |ω|).
    Returns:
        (O_2 of shape (..., 2, 2), det O_2, rank).
    """
    w, wd, wdd = np.broadcast_arrays(np.abs(np.asarray(omega, float)),
                                     np.asarray(omega_dot, float), np.asarray(omega_ddot, float))
    a0, a1 = affine_state_matrices(axis)
    c0, c1 = affine_output_matrices(axis)
    a = np.stack([a0 + w[..., None, None] * a1, wd[..., None, None] * a1,
                  wdd[..., None, None] * a1], axis=-3)
    c = np.stack([c0 + w[..., None, None] * c1, wd[..., None, None] * c1,
                  wdd[..., None, None] * c1], axis=-3)
    o = ltv_observability_matrix(a, c)
    return o, np.linalg.det(o), _rank(_equilibrate(o))


def kalman_observability(omega: FArray, omega_dot: FArray, omega_ddot: FArray | float,
                         axis: LuGreAxis, omega_dddot: FArray | float = 0.0
                         ) -> tuple[FArray, FArray]:
    """000 eq. (24) for the three-state model of 000 eq. (19): (O_3 (..., 3, 3), rank).

    A depends on ω and ω̇, so dA/dt = ω̇ ∂A/∂ω + ω̈ ∂A/∂ω̇ and
    d²A/dt² = ω̈ ∂A/∂ω + ω⃛ ∂A/∂ω̇; C is constant.
    """
    w, wd, wdd, wddd = np.broadcast_arrays(*(np.asarray(v, float) for v in
                                             (omega, omega_dot, omega_ddot, omega_dddot)))
    a, _, c = kalman_model(w, wd, axis)
    a_w = kalman_model(1.0, 0.0, axis)[0] - kalman_model(0.0, 0.0, axis)[0]
    a_wd = kalman_model(0.0, 1.0, axis)[0] - kalman_model(0.0, 0.0, axis)[0]
    e = (..., None, None)
    ad = np.stack([a, wd[e] * a_w + wdd[e] * a_wd, wdd[e] * a_w + wddd[e] * a_wd], axis=-3)
    cd = np.broadcast_to(c, (*w.shape, 1, 1, 3))
    o = ltv_observability_matrix(ad, cd)
    return o, _rank(_equilibrate(o))


def _lateral_parts(body: VehicleBody) -> tuple[FArray, FArray, FArray]:
    """(K0, Ks, Kc) with C̄(δ) = K0 + sin δ Ks + cos δ Kc (see :func:`lateral_force_output_matrix`)."""
    m, iz = body.mass, body.yaw_inertia
    k0, ks, kc = np.zeros((3, 3)), np.zeros((3, 3)), np.zeros((3, 3))
    ks[0, 0] = -1.0 / m
    kc[1, 0] = 1.0 / m
    k0[1, 1] = 1.0 / m
    kc[2, 0] = body.lf / iz
    k0[2, 1] = -body.lr / iz
    ks[2, 2] = -0.5 * body.track_f / iz
    return k0, ks, kc


def lateral_force_output_matrix(delta: FArray | float, body: VehicleBody) -> FArray:
    """C̄(δ) of the lateral force estimator, 001 eq. (10), derived from 001 eq. (9).

    State [F_yf, F_yr, F̄_yf] (axle sums and the front right-minus-left
    difference, N); output [ā_x, ā_y, ṙ] (m/s², m/s², rad/s²; the extraction of
    eq. (10) is garbled, and with Ā = 0 only ṙ, not r, is a function of the
    forces). Rows: m ā_x ∋ −F_yf sin δ; m ā_y ∋ F_yf cos δ + F_yr;
    I_z ṙ ∋ L_f cos δ F_yf − L_r F_yr − (T_rf/2) sin δ F̄_yf. Shape (..., 3, 3).
    """
    d = np.asarray(delta, float)[..., None, None]
    k0, ks, kc = _lateral_parts(body)
    return k0 + np.sin(d) * ks + np.cos(d) * kc


def lateral_force_observability(delta: FArray, delta_dot: FArray, delta_ddot: FArray,
                                body: VehicleBody) -> tuple[FArray, FArray]:
    """001 eq. (12) for the lateral force model (10) with Ā = 0: (O_3 (..., 9, 3), rank).

    C̄ is affine in (sin δ, cos δ); its time derivatives follow from
    d(sin δ)/dt = cos δ·δ̇, d²(sin δ)/dt² = −sin δ·δ̇² + cos δ·δ̈ (and likewise for cos).
    """
    d, dd, ddd = np.broadcast_arrays(*(np.asarray(v, float) for v in
                                       (delta, delta_dot, delta_ddot)))
    k0, ks, kc = _lateral_parts(body)
    s, co = np.sin(d), np.cos(d)
    e = (..., None, None)
    c_0 = k0 + s[e] * ks + co[e] * kc
    c_1 = (co * dd)[e] * ks - (s * dd)[e] * kc
    c_2 = (-s * dd**2 + co * ddd)[e] * ks + (-co * dd**2 - s * ddd)[e] * kc
    cd = np.stack([c_0, c_1, c_2], axis=-3)
    ad = np.zeros((*d.shape, 1, 3, 3))
    o = ltv_observability_matrix(ad, cd)
    return o, _rank(_equilibrate(o))


# ------------------------------------------------------------------------ Gramians
def discretize(a: FArray, b: FArray, dt: FArray | float) -> tuple[FArray, FArray]:
    """Zero-order-hold discretisation (001 Remark 1, 000 Sec. III-B), batched.

    A_d = e^{A T_s}, B_d = ∫_0^{T_s} e^{Aτ}dτ B, via the exponential of [[A, B], [0, 0]]·T_s.
    """
    a = np.asarray(a, float)
    b = np.asarray(b, float)
    n, m = a.shape[-1], b.shape[-1]
    lead = np.broadcast_shapes(a.shape[:-2], b.shape[:-2], np.shape(dt))
    big = np.zeros((*lead, n + m, n + m))
    big[..., :n, :n] = a
    big[..., :n, n:] = b
    e = expm_batched(big * np.asarray(dt, float)[..., None, None])
    return e[..., :n, :n], e[..., :n, n:]


def expm_batched(m: FArray, order: int = 18) -> FArray:
    """Matrix exponential of a stack (..., n, n): scaling and squaring with a Taylor series.

    After scaling ‖X‖₁ ≤ 1/2, the truncation error of order 18 is below
    (1/2)^19/19! ≈ 1e-23 relative, far under double precision; vectorised over
    the stack (scipy's expm loops over it in Python, which dominates long logs).
    """
    m = np.asarray(m, float)
    if m.size == 0:
        return m.copy()
    nrm = float(np.max(np.abs(m).sum(axis=-2)))
    sq = int(max(0, math.ceil(math.log2(nrm / 0.5)))) if nrm > 0.5 else 0
    x = m / 2.0**sq
    eye = np.broadcast_to(np.eye(m.shape[-1]), m.shape)
    e = eye + x
    term = x
    for k in range(2, order + 1):
        term = term @ x / k
        e = e + term
    for _ in range(sq):
        e = e @ e
    return e


def observability_gramian(a_seq: FArray, c_seq: FArray) -> FArray:
    """Cumulative observability Gramians V(0, k), k = 0 … N−1, 000 (A1).

    V(k1, k2) = Σ_{k=k1}^{k2} φ_{k,k1}ᵀ C_kᵀ C_k φ_{k,k1}, φ_{k+1,k} = A_k.

    Args:
        a_seq: (N, n, n) discrete state matrices; c_seq: (N, q, n) output matrices.
    Returns:
        (N, n, n).
    """
    a_seq = np.asarray(a_seq, float)
    c_seq = np.asarray(c_seq, float)
    n = a_seq.shape[-1]
    out = np.empty((a_seq.shape[0], n, n))
    phi = np.eye(n)
    v = np.zeros((n, n))
    for k in range(a_seq.shape[0]):
        cp = c_seq[k] @ phi
        v = v + cp.T @ cp
        out[k] = v
        phi = a_seq[k] @ phi
    return out


def controllability_gramian(a_seq: FArray, b_seq: FArray) -> FArray:
    """Cumulative controllability Gramians W(0, k−1), k = 1 … N, 000 (A2).

    W(k1, k2−1) = Σ_{k=k1}^{k2−1} φ_{k2,k+1} B_k B_kᵀ φ_{k2,k+1}ᵀ, i.e. W ← A_k W A_kᵀ + B_k B_kᵀ.
    """
    a_seq = np.asarray(a_seq, float)
    b_seq = np.asarray(b_seq, float)
    n = a_seq.shape[-1]
    out = np.empty((a_seq.shape[0], n, n))
    w = np.zeros((n, n))
    for k in range(a_seq.shape[0]):
        w = a_seq[k] @ w @ a_seq[k].T + b_seq[k] @ b_seq[k].T
        out[k] = w
    return out


def gramian_rank(g: FArray) -> tuple[FArray, FArray]:
    """(rank, log10 of λ_min/λ_max) of each Gramian in (N, n, n), after symmetric equilibration."""
    d = np.sqrt(np.maximum(np.diagonal(g, axis1=-2, axis2=-1), np.finfo(float).tiny))
    ge = g / (d[..., :, None] * d[..., None, :])
    lam = np.linalg.eigvalsh(0.5 * (ge + np.swapaxes(ge, -1, -2)))
    lmax = np.maximum(lam[..., -1], np.finfo(float).tiny)
    rank = np.sum(lam > RANK_RTOL * lmax[..., None], axis=-1)
    with np.errstate(divide="ignore", invalid="ignore"):
        lrc = np.log10(np.clip(lam[..., 0] / lmax, 1e-300, None))
    return rank, lrc


# --------------------------------------------------------- stochastic observability
@dataclass(frozen=True)
class StochasticObservability:
    """Tests 1 and 2 of 000 Lemma 1 along a trajectory (ψ → ∞).

    Attributes:
        lam_m: λ_max(M_{k+1}) after each step (unit ψ), (N,).
        lam_n: λ_max(N_{k+1}), (N,).
        diffuse_rank: dim of the not-yet-observed initial subspace after each step.
        k_f: first step after which M = 0 (test 1), or None.
        test1: M reached 0 in finite time.
        test2: λ_max(N) < bound for all steps from k_f on.
        bound: λ_b used by test 2.
    """

    lam_m: FArray
    lam_n: FArray
    diffuse_rank: FArray
    k_f: int | None
    test1: bool
    test2: bool
    bound: float

    @property
    def observable(self) -> bool:
        """Stochastically observable in the sense of 000 Lemma 1 (both tests)."""
        return self.test1 and self.test2


def stochastic_observability(a_seq: FArray, c_seq: FArray, q: FArray | float,
                             r: FArray | float, bound: float = 1.0,
                             tol: float = 1e-10) -> StochasticObservability:
    """Tests 1 and 2 of 000 Lemma 1 with initial covariance ψI, ψ → ∞.

    Exact diffuse Kalman filter, measurements processed one whitened row at a
    time (R_k = Ξ_kᵀΞ_k, rows of Ξ_k⁻ᵀC_k). For a row c with s = Uᵀcᵀ ≠ 0
    (000 (A7)'s Σ_k): N ← N + f* k kᵀ − k cN − Ncᵀkᵀ with k = UUᵀcᵀ/‖s‖² and
    f* = cNcᵀ + 1, and U ← U X (X an orthonormal basis of s⊥); with s = 0 the
    ordinary update of N (000 eq. (27)). Then U ← A U, N ← A N Aᵀ + Q.
    With U = I and N = 0 the first step reproduces 000 (A6).

    Args:
        a_seq: (N, n, n); c_seq: (N, q, n).
        q: process noise covariance (n, n) or a scalar times I (000 used 2.5e-3).
        r: measurement noise covariance (q, q) or a scalar times I (000 used 1e-3).
        bound: λ_b of test 2.
        tol: relative size of ‖s‖² below which a row observes nothing new.
    """
    a_seq = np.asarray(a_seq, float)
    c_seq = np.asarray(c_seq, float)
    nsteps, n = a_seq.shape[0], a_seq.shape[-1]
    ny = c_seq.shape[-2]
    qm = np.asarray(q, float) * np.eye(n) if np.ndim(q) == 0 else np.asarray(q, float)
    rm = np.asarray(r, float) * np.eye(ny) if np.ndim(r) == 0 else np.asarray(r, float)
    xi = np.linalg.cholesky(rm).T  # R = ΞᵀΞ
    u = np.eye(n)
    nm = np.zeros((n, n))
    lam_m = np.empty(nsteps)
    lam_n = np.empty(nsteps)
    drank = np.empty(nsteps, dtype=int)
    for k in range(nsteps):
        cw = np.linalg.solve(xi.T, c_seq[k])
        for c in cw:
            s = u.T @ c
            f_inf = float(s @ s)
            if u.shape[1] > 0 and f_inf > tol * float(c @ c) * max(float(np.sum(u * u)), 1e-300):
                kinf = u @ s / f_inf
                cn = c @ nm
                f_star = float(cn @ c) + 1.0
                nm = nm + f_star * np.outer(kinf, kinf) - np.outer(kinf, cn) - np.outer(cn, kinf)
                u = u @ null_space(s[None, :])
            else:
                nc = nm @ c
                f_star = float(c @ nc) + 1.0
                nm = nm - np.outer(nc, nc) / f_star
        u = a_seq[k] @ u
        nm = a_seq[k] @ nm @ a_seq[k].T + qm
        nm = 0.5 * (nm + nm.T)
        drank[k] = u.shape[1]
        lam_m[k] = float(np.linalg.norm(u, 2) ** 2) if u.shape[1] else 0.0
        lam_n[k] = float(np.linalg.eigvalsh(nm)[-1])
    done = np.flatnonzero(drank == 0)
    k_f = int(done[0]) if done.size else None
    test1 = k_f is not None
    test2 = bool(test1 and np.all(lam_n[k_f:] < bound))
    return StochasticObservability(lam_m, lam_n, drank, k_f, test1, test2, float(bound))


# ------------------------------------------------------------------ log analysis
MODELS: dict[str, str] = {
    "lugre_x": "longitudinal LuGre corner model, 001 eq. (22)-(23) (2 states)",
    "kalman_x": "longitudinal Kalman model, 000 eq. (19) (3 states)",
    "lugre_y": "lateral LuGre corner model, 001 eq. (36)-(37) (2 states)",
}


@dataclass(frozen=True)
class CornerModelResult:
    """Observability findings of one model at one corner over a log."""

    corner: str
    model: str
    n_states: int
    gramian_full_rank_from: float | None
    controllability_full_rank_from: float | None
    noise_controllability_full_rank_from: float | None
    pointwise_full_rank_fraction: float
    stochastic_t_f: float | None
    stochastic_test1: bool
    stochastic_test2: bool
    max_lambda_n_after_t_f: float | None


@dataclass(frozen=True)
class ObservabilityReport:
    """Result of :func:`analyze_observability`: findings, figure and summary paths."""

    log_name: str
    vehicle: str
    duration: float
    sample_time: float
    q: float
    r: float
    bound: float
    results: tuple[CornerModelResult, ...]
    figures: tuple[Path, ...] = ()
    summary_json: Path | None = None
    summary_md: Path | None = None
    region: dict[str, Any] = field(default_factory=dict)

    @property
    def observable(self) -> bool:
        """Every model observable by Gramian rank and stochastically (tests 1 and 2)."""
        return all(r.gramian_full_rank_from is not None and r.stochastic_test1
                   and r.stochastic_test2 for r in self.results)

    def summary(self) -> str:
        """Markdown table of the findings."""
        lines = [
            f"# Observability of {self.log_name} ({self.vehicle})",
            "",
            f"{self.duration:.2f} s at T_s = {self.sample_time * 1e3:.2f} ms; stochastic tests with "
            f"Q = {self.q:g} I, R = {self.r:g}, lambda_b = {self.bound:g} (000 Sec. III-C).",
            "",
            "| corner | model | V(0,k) full rank from [s] | W (input B) full rank from [s] | "
            "W (noise sqrt(Q)) full rank from [s] | pointwise rank O_n full [%] | "
            "test 1: t_f [s] | test 2 | max lambda(N), t >= t_f |",
            "|---|---|---|---|---|---|---|---|---|",
        ]

        def f(v: float | None) -> str:
            return "never" if v is None else f"{v:.3f}"

        for r in self.results:
            lines.append(
                f"| {r.corner} | {r.model} | {f(r.gramian_full_rank_from)} | "
                f"{f(r.controllability_full_rank_from)} | "
                f"{f(r.noise_controllability_full_rank_from)} | "
                f"{100 * r.pointwise_full_rank_fraction:.1f} | "
                f"{f(r.stochastic_t_f)} | {'pass' if r.stochastic_test2 else 'fail'} | "
                f"{'-' if r.max_lambda_n_after_t_f is None else f'{r.max_lambda_n_after_t_f:.3g}'} |")
        if self.region:
            lines += ["", "Operating region (004 eq. (15), Fig. 5): "
                      f"min det O_2 = {self.region['min_det']:.4g} over |omega| <= "
                      f"{self.region['omega_max']:g} rad/s, |omega_dot| <= "
                      f"{self.region['omega_dot_max']:g} rad/s^2 (full rank everywhere: "
                      f"{self.region['full_rank']})."]
        lines += ["", f"Overall: {'observable' if self.observable else 'NOT observable'} "
                  "by every test."]
        return "\n".join(lines) + "\n"

    def to_dict(self) -> dict[str, Any]:
        """JSON-ready dictionary."""
        return {
            "log": self.log_name, "vehicle": self.vehicle, "duration_s": self.duration,
            "sample_time_s": self.sample_time, "q": self.q, "r": self.r, "lambda_b": self.bound,
            "observable": self.observable, "region": self.region,
            "results": [asdict(r) for r in self.results],
            "figures": [p.name for p in self.figures],
        }


def _first_full(t: FArray, rank: FArray, n: int) -> float | None:
    """First time from which the rank stays full until the end."""
    bad = np.flatnonzero(rank < n)
    if bad.size == 0:
        return float(t[0])
    if bad[-1] == rank.size - 1:
        return None
    return float(t[bad[-1] + 1])


def _log_frame(log: pd.DataFrame | str | Path) -> tuple[pd.DataFrame, str]:
    if isinstance(log, pd.DataFrame):
        return log, str(log.attrs.get("maneuver", "log"))
    from vestim.io import read_log

    p = Path(log)
    return read_log(p), p.stem


def _model_sequences(model: str, omega: FArray, omega_dot: FArray, dt: FArray,
                     veh: Vehicle) -> tuple[FArray, FArray, FArray]:
    """(A_d, B_d, C) sequences of one model along a log."""
    if model == "kalman_x":
        ax = longitudinal_axis(veh)
        a, b, c = kalman_model(omega, omega_dot, ax)
    else:
        ax = longitudinal_axis(veh) if model == "lugre_x" else lateral_axis(veh)
        a, b = state_matrix(omega, ax), input_matrix()
        c = output_matrix(omega, ax)
    ad, bd = discretize(a, np.broadcast_to(b, (*omega.shape, *b.shape)), dt)
    c = np.broadcast_to(c, (omega.size, *c.shape[-2:]))
    return ad, bd, np.array(c)


def analyze_observability(log: pd.DataFrame | str | Path, vehicle: Vehicle | str | Path,
                          out_dir: str | Path, *, q: float = 2.5e-3, r: float = 1e-3,
                          bound: float = 1e3, corners: Sequence[str] = CORNERS,
                          omega_max: float = 180.0, omega_dot_max: float = 800.0,
                          derivative_window: float = 0.05) -> ObservabilityReport:
    """Observability analysis of the corner models over a drive log; writes figures + summary.

    For each corner and model (longitudinal two-state LuGre, 000's three-state
    Kalman model, lateral two-state LuGre) along the log's wheel speeds:
    the rank of the cumulative observability and controllability Gramians
    (000 (A1)–(A2), cf. 000 Fig. 1; W both with the input matrix and with the
    process-noise factor √Q·I), the pointwise rank of the observability matrix
    (000 eq. (24)), and the
    stochastic observability tests 1 and 2 (000 eq. (26)–(27), Fig. 2–3).
    Also det O_2 of 004 eq. (15) over the operating region (004 Fig. 5).

    Args:
        log: DataFrame or path (CSV/Parquet) with ``t`` and ``omega_<corner>``.
        vehicle: vehicle object, TOML path or built-in name.
        out_dir: where ``observability_*.png``, ``observability.json`` and
            ``observability.md`` are written (atomically).
        q, r: noise covariances of the stochastic tests (000: 2.5e-3 and 1e-3).
        bound: λ_b of test 2 (000 gives none; the states mix m and m/s, so this is a
            divergence flag: with 000's Q and R the LuGre models settle at λ(N) ≈ 1–10).
        derivative_window: length (s) of the Savitzky–Golay filter (quadratic) that gives
            ω̇ and ω̈ for 000's three-state model and the rank test; raw differences of a
            200 Hz wheel-speed signal would make ω̇ mostly noise.
    Raises:
        LogFormatError: a required column is missing or time is not increasing.
    """
    df, name = _log_frame(log)
    veh = vehicle if isinstance(vehicle, Vehicle) else load_vehicle(vehicle)
    need = ["t", *(f"omega_{c}" for c in corners)]
    missing = [c for c in need if c not in df.columns]
    if missing:
        raise LogFormatError(f"observability analysis needs column(s) {', '.join(missing)} "
                             "(spec: docs/format.md)")
    t = df["t"].to_numpy(float)
    if t.size < 3 or np.any(np.diff(t) <= 0):
        raise LogFormatError("column t must be strictly increasing with at least 3 samples")
    dt = np.diff(t, append=t[-1] + (t[-1] - t[-2]))
    out = Path(out_dir)
    results: list[CornerModelResult] = []
    series: dict[tuple[str, str], dict[str, FArray]] = {}
    ts = float(np.median(np.diff(t)))
    win = max(5, 2 * round(derivative_window / ts / 2) + 1)
    for corner in corners:
        w = np.abs(df[f"omega_{corner}"].to_numpy(float))
        wd, wdd = _derivatives(w, ts, win)
        for model in MODELS:
            ad, bd, c = _model_sequences(model, w, wd, dt, veh)
            n = ad.shape[-1]
            v_rank, v_lrc = gramian_rank(observability_gramian(ad, c))
            w_rank, _ = gramian_rank(controllability_gramian(ad, bd))
            g_noise = np.broadcast_to(math.sqrt(q) * np.eye(n), ad.shape)
            wq_rank, _ = gramian_rank(controllability_gramian(ad, g_noise))
            if model == "kalman_x":
                _, pr = kalman_observability(w, wd, wdd, longitudinal_axis(veh))
            else:
                ax = longitudinal_axis(veh) if model == "lugre_x" else lateral_axis(veh)
                _, _, pr = lugre_observability(w, wd, ax, wdd)
            so = stochastic_observability(ad, c, q, r, bound)
            tf = None if so.k_f is None else float(t[so.k_f])
            results.append(CornerModelResult(
                corner=corner, model=model, n_states=n,
                gramian_full_rank_from=_first_full(t, v_rank, n),
                controllability_full_rank_from=_first_full(t, w_rank, n),
                noise_controllability_full_rank_from=_first_full(t, wq_rank, n),
                pointwise_full_rank_fraction=float(np.mean(pr == n)),
                stochastic_t_f=tf, stochastic_test1=so.test1, stochastic_test2=so.test2,
                max_lambda_n_after_t_f=None if so.k_f is None else float(np.max(so.lam_n[so.k_f:]))))
            series[(corner, model)] = {"v_rank": v_rank, "v_lrc": v_lrc, "lam_m": so.lam_m,
                                       "lam_n": so.lam_n}
    wg = np.linspace(0.0, omega_max, 91)
    wdg = np.linspace(-omega_dot_max, omega_dot_max, 81)
    _, det, rk = lugre_observability(wg[:, None], wdg[None, :], longitudinal_axis(veh))
    region = {"omega_max": omega_max, "omega_dot_max": omega_dot_max,
              "min_det": float(det.min()), "full_rank": bool(np.all(rk == 2))}
    figs = _figures(out, t, series, corners, wg, wdg, det)
    report = ObservabilityReport(log_name=name, vehicle=veh.name, duration=float(t[-1] - t[0]),
                                 sample_time=float(np.median(np.diff(t))), q=q, r=r, bound=bound,
                                 results=tuple(results), figures=figs, region=region)
    js = write_text_atomic(out / "observability.json", json.dumps(report.to_dict(), indent=2,
                                                            default=_json_default))
    md = write_text_atomic(out / "observability.md", report.summary())
    return replace(report, summary_json=js, summary_md=md)


def _derivatives(w: FArray, ts: float, window: int) -> tuple[FArray, FArray]:
    """(ω̇, ω̈) by a quadratic Savitzky–Golay filter of ``window`` samples (uniform T_s)."""
    from scipy.signal import savgol_filter

    if w.size < window:
        wd = np.gradient(w, ts)
        return wd, np.gradient(wd, ts)
    return (savgol_filter(w, window, 2, deriv=1, delta=ts, mode="interp"),
            savgol_filter(w, window, 2, deriv=2, delta=ts, mode="interp"))


def _json_default(o: Any) -> Any:
    if isinstance(o, np.generic):
        return o.item()
    if isinstance(o, float) and math.isnan(o):
        return None
    raise TypeError(f"not JSON serialisable: {type(o).__name__}")


def _figures(out: Path, t: FArray, series: dict[tuple[str, str], dict[str, FArray]],
             corners: Sequence[str], wg: FArray, wdg: FArray, det: FArray) -> tuple[Path, ...]:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    from vestim.report.plots import save_figure

    paths = []
    models = list(MODELS)
    fig, axes = plt.subplots(len(models), 2, figsize=(11, 2.6 * len(models)), sharex=True,
                             constrained_layout=True)
    for i, m in enumerate(models):
        for c in corners:
            s = series[(c, m)]
            axes[i, 0].step(t, s["v_rank"], where="post", lw=1, label=c)
            axes[i, 1].plot(t, s["v_lrc"], lw=1, label=c)
        axes[i, 0].set_ylabel(f"rank V(0,k)\n{m}")
        axes[i, 1].set_ylabel("log10 lmin/lmax")
        axes[i, 1].set_ylim(-16, 0.5)  # below ~1e-16 a Gramian is numerically singular
        axes[i, 0].legend(fontsize=7, ncol=4)
    axes[-1, 0].set_xlabel("t [s]")
    axes[-1, 1].set_xlabel("t [s]")
    fig.suptitle("Observability Gramian 000 (A1) along the log (cf. 000 Fig. 1)")
    paths.append(save_figure(fig, out / "observability_gramian.png", dpi=90))

    for key, title, fname in (
            ("lam_m", "Test 1: lambda_max(M_k), 000 eq. (26) (cf. 000 Fig. 2)", "test1"),
            ("lam_n", "Test 2: lambda_max(N_k), 000 eq. (27) (cf. 000 Fig. 3)", "test2")):
        fig, axes = plt.subplots(1, len(models), figsize=(12, 3.2), constrained_layout=True)
        for i, m in enumerate(models):
            for c in corners:
                y = series[(c, m)][key]
                if key == "lam_n":
                    axes[i].semilogy(t, np.maximum(y, np.finfo(float).tiny), lw=1, label=c)
                else:  # λ_max(M) is exactly 0 after t_f: a linear, normalised scale shows it
                    axes[i].plot(t, y / max(float(np.max(y)), np.finfo(float).tiny), lw=1,
                                 label=c, drawstyle="steps-post")
            axes[i].set_title(m, fontsize=9)
            axes[i].set_xlabel("t [s]")
            if key == "lam_m":
                last = max((float(t[np.flatnonzero(series[(c, m)]["lam_m"] > 0)[-1]])
                            for c in corners if np.any(series[(c, m)]["lam_m"] > 0)),
                           default=float(t[0]))
                axes[i].set_xlim(t[0], min(t[-1], t[0] + max(0.1, 1.5 * (last - t[0]))))
                axes[i].set_ylabel("lambda_max(M_k) / max")
        axes[0].legend(fontsize=7)
        fig.suptitle(title)
        paths.append(save_figure(fig, out / f"observability_{fname}.png", dpi=90))

    fig, ax = plt.subplots(figsize=(6, 4.2), constrained_layout=True)
    cs = ax.contourf(wg, wdg, det.T, levels=20)
    fig.colorbar(cs, ax=ax, label="det O_2")
    ax.set_xlabel("|omega| [rad/s]")
    ax.set_ylabel("omega_dot [rad/s^2]")
    ax.set_title("004 eq. (15): det of the observability matrix (cf. 004 Fig. 5)")
    paths.append(save_figure(fig, out / "observability_region.png", dpi=90))
    return tuple(paths)
