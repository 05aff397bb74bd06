"""LPV corner velocity observers of 001 (longitudinal eq. (22)–(24), lateral eq. (36)–(38)) and 004.

Per tire direction q ∈ {x, y}, state x = [z̄_q, v_rq] (:class:`vestim.models.lpv.LPVState`),
scheduled by ρ = |ω| (the corner model of :mod:`vestim.models.lpv`)::

    ẋ = A(ρ) x + B u_q + Ω,   A = [[−κ_q R ρ, 1], [0, 0]],  B = [0, 1]ᵀ       (001 eq. (22), (37))
    μ_q = C_q(ρ) x + σ1q Ω_z,   C_q(ρ) = [σ0q − σ1q κ_q R ρ, σ1q + σ2q]       (001 eq. (23), (36))

with u_x = R ω̇ − v̇_xt and u_y = −v̇_yt; v_rx = Rω − v_xt, v_ry = −v_yt.

Observers:

* 001 eq. (24), (38) — innovation form x̂˙ = A x̂ + B u + L (μ − C_q x̂), gains
  L_x = [0.68, 183.1]ᵀ, L_y = [1.11, 16.7]ᵀ (001 Sec. IV-A, IV-B).
* 004 eq. (10)–(14) — output-derivative form x̂˙ = A x̂ + B u + L̃ (μ − μ̂),
  μ̂ = C x̂ + C′ x̂˙ with C = [σ0, σ2], C′ = [σ1, 0]; the implicit x̂˙ is solved,
  x̂˙ = (I + L̃C′)⁻¹[(A − L̃C) x̂ + B u + L̃ μ] (004 eq. (16)), which is *identical* to the
  innovation form with L = L̃/(1 + σ1 L̃1) (:func:`vestim.models.lpv.output_derivative_to_innovation`;
  C′B = 0). Gains L̃ = [0.65, 197]ᵀ (004 Sec. III-C) or the wheel-speed-scheduled
  gains of 004 eq. (35), valid on the design grid ω ∈ [0, 120] rad/s and held at the
  ends outside it (L̃1's denominator vanishes at ω ≈ 154 rad/s).

The kernel integrates the innovation form; output-derivative gains are converted
pointwise on their grid when the observer is built (the test suite checks the
kernel against a literal integration of 004 eq. (10)–(14)). Each step is exact
for inputs held over the step (step invariance, as 000/003 discretise):
x_k = x_{k−1} + Φ (M x_{k−1} + g), M = A − L C_q, g = B u + L μ, Φ = ∫_0^h e^{Mτ}dτ
(:func:`~.corner_discrete.expm2_phi`); forward Euler would be unstable at 200 Hz
(the error pole −L1σ0 ≈ −430 1/s gives |1 − 430·0.005| > 1).

The longitudinal and lateral observers are coupled only through the transport
term of the kinematics: v̇_xt = a_xt + (r + δ̇) v_yt uses v̂_yt = −v̂_ry and
v̇_yt = a_yt − (r + δ̇) v_xt uses v̂_xt = Rω − v̂_rx, both from the previous sample.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass, field
from typing import Any, Literal

import numpy as np
from numba import njit

from vestim.estimators.velocity.corner_common import (
    H_AX,
    H_AY,
    H_D,
    H_MX,
    H_MY,
    H_R,
    H_T,
    H_W,
    CornerInputs,
    CornerOutputs,
    CornerParams,
    CornerState,
    count_release,
    pick,
    store,
    transport_rate,
    vyt_no_sideslip,
)
from vestim.estimators.velocity.corner_discrete import expm2_phi, kf_transition
from vestim.estimators.velocity.corner_slip import (
    HighSlipParams,
    detector_step,
    is_high_slip,
    slip_ratio_estimate,
)
from vestim.models.lpv import LPVState, output_derivative_to_innovation

_JIT: dict[str, Any] = {"cache": True, "error_model": "numpy"}

ZS, VRS = int(LPVState.Z), int(LPVState.VR)
GainForm = Literal["innovation", "output_derivative"]


def _floats(name: str, values: Sequence[float] | np.ndarray) -> tuple[float, ...]:
    arr = np.asarray(values, dtype=float).ravel()
    if arr.size == 0 or not np.all(np.isfinite(arr)):
        raise ValueError(f"GainSchedule.{name} must be a non-empty sequence of finite numbers")
    return tuple(float(v) for v in arr)


@dataclass(frozen=True)
class GainSchedule:
    """Observer gains L1(|ω|), L2(|ω|) on a grid of wheel speeds (linear interpolation, held outside).

    Attributes:
        omega: grid of |ω|, rad/s, strictly increasing; one point means constant gains.
        l1: L1 at the grid points, m/s per unit normalised force.
        l2: L2 at the grid points, m/s² per unit normalised force; must be > 0 (the
            error dynamics have det = L2(σ0 + σ2κR|ω|), so L2 ≤ 0 cannot be stable).
        form: "innovation" (001 eq. (24): gains on μ − C_q x̂) or "output_derivative"
            (004 eq. (10)–(14): gains on μ − C x̂ − C′x̂˙).
    """

    omega: tuple[float, ...]
    l1: tuple[float, ...]
    l2: tuple[float, ...]
    form: GainForm = "innovation"

    def __post_init__(self) -> None:
        for name in ("omega", "l1", "l2"):
            object.__setattr__(self, name, _floats(name, getattr(self, name)))
        if not len(self.omega) == len(self.l1) == len(self.l2):
            raise ValueError(f"GainSchedule: omega, l1, l2 have lengths {len(self.omega)}, "
                             f"{len(self.l1)}, {len(self.l2)}; they must be equal")
        if np.any(np.diff(self.omega) <= 0):
            raise ValueError("GainSchedule.omega must be strictly increasing")
        if min(self.l2) <= 0.0:
            raise ValueError(f"GainSchedule.l2 must be > 0 everywhere (min {min(self.l2)})")
        if self.form not in ("innovation", "output_derivative"):
            raise ValueError(f"GainSchedule.form {self.form!r}: use 'innovation' or "
                             "'output_derivative'")

    @classmethod
    def constant(cls, l1: float, l2: float, form: GainForm = "innovation") -> GainSchedule:
        """Constant gains (a one-point grid)."""
        return cls((0.0,), (l1,), (l2,), form)

    def innovation_gains(self, sigma1: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """(ω grid, L1, L2) in the innovation form of 001 eq. (24), for rubber damping σ1 (s/m)."""
        w = np.array(self.omega)
        l1 = np.array(self.l1)
        l2 = np.array(self.l2)
        if self.form == "output_derivative":
            l1, l2 = output_derivative_to_innovation(l1, l2, sigma1)
        return w, np.ascontiguousarray(l1, dtype=float), np.ascontiguousarray(l2, dtype=float)


def gains_004_eq35(omega: np.ndarray | float) -> tuple[np.ndarray, np.ndarray]:
    """Wheel-speed-scheduled gains of 004 eq. (35) (output-derivative form), ω in rad/s.

    L̃1 = (1.78ω² − 50.1ω − 2.83e4)/(0.0221ω² + 154ω − 2.38e4),
    L̃2 = 4822(2.76ω² + 150ω − 7.34e4)/(0.885ω² + 6140ω − 9.51e5); designed on ω ∈ [0, 120].
    """
    w = np.asarray(omega, dtype=float)
    l1 = (1.78 * w**2 - 50.1 * w - 2.83e4) / (0.0221 * w**2 + 154.0 * w - 2.38e4)
    l2 = 4822.0 * (2.76 * w**2 + 150.0 * w - 7.34e4) / (0.885 * w**2 + 6140.0 * w - 9.51e5)
    return l1, l2


GAINS_001_X = GainSchedule.constant(0.68, 183.1)
"""001 Sec. IV-A: L1x = 0.68, L2x = 183.1 (innovation form, eq. (24))."""
GAINS_001_Y = GainSchedule.constant(1.11, 16.7)
"""001 Sec. IV-B: L1y = 1.11, L2y = 16.7 (innovation form, eq. (38))."""
GAINS_004 = GainSchedule.constant(0.65, 197.0, "output_derivative")
"""004 Sec. III-C: L1 = 0.65, L2 = 197 (output-derivative form, eq. (10)–(14))."""


def _schedule_004() -> GainSchedule:
    w = np.linspace(0.0, 120.0, 481)
    l1, l2 = gains_004_eq35(w)
    return GainSchedule(tuple(w), tuple(l1), tuple(l2), "output_derivative")


GAINS_004_SCHEDULED = _schedule_004()
"""004 eq. (35) tabulated every 0.25 rad/s on its design grid [0, 120] rad/s."""


@dataclass(frozen=True)
class LPVParams:
    """Gains of the LPV corner observers (default: 001's constant gains, both directions).

    Attributes:
        longitudinal: gains of the longitudinal observer.
        lateral: gains of the lateral observer (001 eq. (38)); None runs no lateral
            observer (v̂_yt is then NaN and the longitudinal transport term uses the
            no-side-slip approximation or the caller's ``vyt``).
        high_slip: detection parameters; the LPV observers only *report* the flags
            (the papers switch nothing in them).
    """

    longitudinal: GainSchedule = GAINS_001_X
    lateral: GainSchedule | None = GAINS_001_Y
    high_slip: HighSlipParams = field(default_factory=HighSlipParams)

    @classmethod
    def paper_001(cls) -> LPVParams:
        """001 eq. (24) and (38) with L_x = [0.68, 183.1], L_y = [1.11, 16.7]."""
        return cls()

    @classmethod
    def paper_004(cls) -> LPVParams:
        """004 eq. (10)–(14) with constant L̃ = [0.65, 197]; lateral observer of 001."""
        return cls(longitudinal=GAINS_004)

    @classmethod
    def paper_004_scheduled(cls) -> LPVParams:
        """004 eq. (10)–(14) with the scheduled gains of eq. (35); lateral observer of 001."""
        return cls(longitudinal=GAINS_004_SCHEDULED)


@njit(**_JIT)
def interp_gain(rho: float, grid: np.ndarray, l1: np.ndarray, l2: np.ndarray) -> tuple[float, float]:
    """Linear interpolation of (L1, L2) at ρ on an increasing grid, held outside it (binary search)."""
    m = grid.shape[0]
    if m == 1 or rho <= grid[0]:
        return l1[0], l2[0]
    if rho >= grid[m - 1]:
        return l1[m - 1], l2[m - 1]
    lo = 0
    hi = m - 1
    while hi - lo > 1:
        mid = (lo + hi) // 2
        if grid[mid] <= rho:
            lo = mid
        else:
            hi = mid
    f = (rho - grid[lo]) / (grid[hi] - grid[lo])
    return l1[lo] + f * (l1[hi] - l1[lo]), l2[lo] + f * (l2[hi] - l2[lo])


@njit(**_JIT)
def lpv_step(xs: np.ndarray, c: int, kr: float, s0: float, s1: float, s2: float, rho: float, g1: float,
             g2: float, u: float, y: float, h: float, Ak: np.ndarray, Bk: np.ndarray) -> None:
    """Advance one direction's observer state ``xs[c]`` = [z̄, v_r] over a step h, in place.

    Innovation form (001 eq. (24)) with gains (g1, g2), inputs u and μ = y held:
    M = A(ρ) − L C_q(ρ), g = B u + L y, x ← x + Φ(M x + g). NaN y: open loop
    (L = 0), propagated exactly with the closed form of :func:`~.corner_discrete.kf_transition`.
    """
    a = kr * rho
    if math.isnan(y):
        kf_transition(a, 0.0, h, Ak, Bk)
        z = xs[c, ZS]
        v = xs[c, VRS]
        xs[c, ZS] = Ak[0, 0] * z + Ak[0, 1] * v + Bk[0] * u
        xs[c, VRS] = v + h * u
        return
    c1 = s0 - s1 * a
    c2 = s1 + s2
    m00 = -a - g1 * c1
    m01 = 1.0 - g1 * c2
    m10 = -g2 * c1
    m11 = -g2 * c2
    _, _, _, _, p00, p01, p10, p11 = expm2_phi(m00, m01, m10, m11, h)
    z = xs[c, ZS]
    v = xs[c, VRS]
    f0 = m00 * z + m01 * v + g1 * y
    f1 = m10 * z + m11 * v + u + g2 * y
    xs[c, ZS] = z + p00 * f0 + p01 * f1
    xs[c, VRS] = v + p10 * f0 + p11 * f1


@njit(**_JIT)
def lpv_kernel(p: CornerParams, s: CornerState, inp: CornerInputs, out: CornerOutputs) -> None:
    """Advance the four corners' LPV observers over a chunk, in place on xx, xy (4, 2) and hold.

    Inputs as :func:`~.lugre_kf.lugre_kf_kernel` plus mu_y (n, 4); outputs (n, 4):
    v̂_xt, v̂_yt (NaN without lateral observer), high-slip flags (reported, not used),
    v̂_rx, ẑ_x, v̂_ry, ẑ_y. μ is held at the mean of the two samples of a step.
    ``p``, ``s``, ``inp``, ``out``: :mod:`.corner_common`'s trees (``out.sigma`` and
    ``out.zdot`` are not written).
    """
    t, omega, mu_x, mu_y, a_xt = inp.t, inp.omega, inp.mu_x, inp.mu_y, inp.a_xt
    a_yt, delta, yaw_rate, hint, vyt_in = inp.a_yt, inp.delta, inp.yaw_rate, inp.hint, inp.vyt_in
    radius, kappa_x, s0x, s1x, s2x = p.radius, p.kappa, p.sigma0, p.sigma1, p.sigma2
    kappa_y, s0y, s1y, s2y, x_corner = p.kappa_y, p.sigma0_y, p.sigma1_y, p.sigma2_y, p.xw
    gx_w, gx_1, gx_2, lateral = p.gx_w, p.gx_1, p.gx_2, p.lateral
    gy_w, gy_1, gy_2 = p.gy_w, p.gy_1, p.gy_2
    lam_u, lam_l, beta_e, wdot_th = p.lam_u, p.lam_l, p.beta_e, p.wdot_th
    min_speed, mu_release, release_window = p.min_speed, p.mu_release, p.release_window
    xx, xy, hold, acc_buf, stats = s.xx, s.xy, s.hold, s.acc, s.stats
    w_buf, t_buf, ring = s.w_buf, s.t_buf, s.ring
    out_vxt, out_vyt, out_high, out_vrx = out.vxt, out.vyt, out.high, out.vrx
    out_zx, out_vry, out_zy = out.zx, out.vry, out.zy
    n = t.shape[0]
    krx = kappa_x * radius
    kry = kappa_y * radius
    Ak = np.empty((3, 3))
    Bk = np.empty(3)
    wdh = np.empty(4, dtype=np.bool_)
    nan = math.nan
    for k in range(n):
        tk = t[k]
        if math.isnan(tk):
            for c in range(4):
                out_vxt[k, c] = nan
                out_vyt[k, c] = nan
                out_high[k, c] = False
                out_vrx[k, c] = nan
                out_zx[k, c] = nan
                out_vry[k, c] = nan
                out_zy[k, c] = nan
            continue
        thr = detector_step(k, tk, omega, a_xt, a_yt, lam_u, lam_l, beta_e, wdot_th,
                            acc_buf, stats, w_buf, t_buf, ring, wdh)
        for c in range(4):
            wk = omega[k, c]
            if math.isnan(wk):
                out_vxt[k, c] = nan
                out_vyt[k, c] = nan
                out_high[k, c] = False
                out_vrx[k, c] = nan
                out_zx[k, c] = nan
                out_vry[k, c] = nan
                out_zy[k, c] = nan
                continue
            mx = mu_x[k, c]
            my = mu_y[k, c]
            if math.isnan(hold[H_T, c]):
                xx[c, ZS] = 0.0 if math.isnan(mx) else mx / s0x
                xx[c, VRS] = 0.0
                xy[c, ZS] = 0.0 if (math.isnan(my) or not lateral) else my / s0y
                xy[c, VRS] = 0.0
            else:
                h = tk - hold[H_T, c]
                w0 = hold[H_W, c]
                rho = 0.5 * (abs(w0) + abs(wk))
                d_prev = hold[H_D, c]
                d_now = pick(delta[k, c], d_prev)
                r_mid = 0.5 * (pick(yaw_rate[k], hold[H_R, c]) + hold[H_R, c])
                rate = transport_rate(r_mid, d_now, d_prev, h)
                vxt_prev = radius * w0 - xx[c, VRS]
                vyt = vyt_in[k, c]
                if math.isnan(vyt):
                    vyt = -xy[c, VRS] if lateral else vyt_no_sideslip(r_mid, x_corner[c], vxt_prev,
                                                                       d_now)
                ax_mid = 0.5 * (pick(a_xt[k, c], hold[H_AX, c]) + hold[H_AX, c])
                ux = radius * (wk - w0) / h - (ax_mid + rate * vyt)
                ymx = mx if math.isnan(hold[H_MX, c]) or math.isnan(mx) else 0.5 * (mx + hold[H_MX, c])
                g1, g2 = interp_gain(rho, gx_w, gx_1, gx_2)
                if lateral:
                    ay_mid = 0.5 * (pick(a_yt[k, c], hold[H_AY, c]) + hold[H_AY, c])
                    uy = -(ay_mid - rate * vxt_prev)
                    ymy = my if math.isnan(hold[H_MY, c]) or math.isnan(my) else 0.5 * (my + hold[H_MY, c])
                    gy1, gy2 = interp_gain(rho, gy_w, gy_1, gy_2)
                    lpv_step(xy, c, kry, s0y, s1y, s2y, rho, gy1, gy2, uy, ymy, h, Ak, Bk)
                lpv_step(xx, c, krx, s0x, s1x, s2x, rho, g1, g2, ux, ymx, h, Ak, Bk)
            lam_k = slip_ratio_estimate(radius * wk, xx[c, VRS], min_speed)
            out_vxt[k, c] = radius * wk - xx[c, VRS]
            out_vyt[k, c] = -xy[c, VRS] if lateral else nan
            rel = count_release(hold, c, mx, mu_release, release_window)
            out_high[k, c] = is_high_slip(lam_k, thr, wdh[c], hint[k, c], rel)
            out_vrx[k, c] = xx[c, VRS]
            out_zx[k, c] = xx[c, ZS]
            out_vry[k, c] = xy[c, VRS] if lateral else nan
            out_zy[k, c] = xy[c, ZS] if lateral else nan
            store(hold, c, tk, wk, delta[k, c], a_xt[k, c], a_yt[k, c], mx, my, yaw_rate[k])
