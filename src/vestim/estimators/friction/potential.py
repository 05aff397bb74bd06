"""Road friction potential μ under each tire from the estimated forces and slips.

A tire tells the road's friction only once it uses a good part of it: in the linear range
the force is the slip stiffness times the slip, whatever μ is. This stage compares, per
corner and sample, the friction the tire *uses*,

    u = ‖(F_x, F_y)‖ / F_z                      (the estimates' μ_x, μ_y),

with the force a linear tire would give at the estimated slips,

    k = ‖(K_x κ', K_y tan α')‖,  κ' = κ/(1+|κ|),  tan α' = tan α/(1+|κ|),

(K_x, K_y: slip stiffnesses per unit load; the combined-slip magnitudes of the brush and
Magic Formula theory, Pacejka, *Tire and Vehicle Dynamics*, 3rd ed., §3.2–3.3). A tire of
friction μ and the Magic Formula shape of unit initial slope

    u = μ · F(k/μ),   F(z) = sin(C · atan(z / C))                             (1)

(the pure-slip Magic Formula with D = μ, B C D = K, E = 0; ibid. §4.3) uses less than k
once k approaches μ. With y = u/μ and q = k/u ≥ 1, (1) is F(q y) = y, which has exactly one
root in (0, 1] (:func:`invert_shape`), so μ = u / y.

Choices, none from the papers (they take μ from rig tests), each documented in
docs/methods.md:

- **Shape.** C = 1.3 laterally and 1.65 longitudinally, the textbook passenger-car shape
  factors (ibid. Table 4.2 region); E = 0. The shape is blended by the share of the lateral
  term in k. A sharper real tire (E < 0) saturates sooner than (1), so μ reads high near
  the peak; the σ below does not cover that model error.
- **Stiffness.** K_y is the pipeline's online normalised cornering stiffness; K_x comes from
  the vehicle file's ``[stiffness]`` table when it states one (axle total / static axle
  load), else ``kx_nominal`` = 20 per unit slip ratio (passenger-car tires: 15–30).
- **Uncertainty.** σ_μ propagates a relative stiffness error ``sigma_k`` (15 %), slip errors
  ``sigma_slip_ratio``, ``sigma_slip_angle`` (the crossplant estimates' corner slip errors
  in braking and cornering: about 0.015 and 0.2°), the velocity filter's σ_vy / v_x with
  σ_vy at least ``sigma_vy_floor`` (0.1 m/s: the filter's own σ_vy is not yet honest in
  slides, where its v_y misses by 0.3–0.9 m/s on x06 and x10, and at 5 m/s 0.3 m/s is 3.4° of
  slip angle), and the force σ through (1).
- **Excited** (``mu_*_excited`` = 1) when the slip excess k − u is at least
  ``excess_sigmas`` times its σ (the tire is measurably off its linear line), σ_μ ≤
  ``sigma_max`` (so 2σ is within 0.1), u ≥ ``u_min``, and both have held for
  ``persist_s`` (two samples at 200 Hz: a single-sample slip spike is not evidence).
  Elsewhere μ and σ_μ are NaN: not excited is not "high friction".
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any, NamedTuple

import numpy as np
from numba import njit

from vestim.constants import G
from vestim.io.vehicle import Vehicle
from vestim.params import check_ranges, pack

_JIT: dict[str, Any] = {"cache": True, "error_model": "numpy"}


@dataclass(frozen=True)
class FrictionParams:
    """Parameters of the friction-potential stage (units in the module docstring)."""

    shape_lateral: float = 1.3
    shape_longitudinal: float = 1.65
    kx_nominal: float = 20.0
    sigma_k: float = 0.15
    sigma_slip_ratio: float = 0.015
    sigma_slip_angle: float = 0.0035
    excess_sigmas: float = 2.0
    sigma_max: float = 0.05
    u_min: float = 0.05
    persist_s: float = 0.01
    sigma_vy_floor: float = 0.1

    def __post_init__(self) -> None:
        for name in ("shape_lateral", "shape_longitudinal"):
            c = getattr(self, name)
            if not 1.0 <= c < 2.0:
                raise ValueError(f"friction {name} = {c}: a Magic Formula shape factor in [1, 2)")
        check_ranges(self, "friction", positive=("kx_nominal", "sigma_k", "sigma_slip_ratio",
                                                 "sigma_slip_angle", "excess_sigmas",
                                                 "sigma_max", "u_min", "sigma_vy_floor"))
        if self.persist_s < 0:
            raise ValueError(f"friction persist_s = {self.persist_s} must be >= 0")


class FrictionKernelParams(NamedTuple):
    """:func:`friction_step`'s parameters: the :class:`FrictionParams` fields the kernel
    reads (units in the module docstring) and the longitudinal slip stiffness per unit load
    of each corner, ``kx_fl`` … ``kx_rr`` (per unit slip ratio, :func:`corner_kx`)."""

    shape_lateral: float
    shape_longitudinal: float
    sigma_k: float
    sigma_slip_ratio: float
    sigma_slip_angle: float
    excess_sigmas: float
    sigma_max: float
    u_min: float
    persist_s: float
    sigma_vy_floor: float
    kx_fl: float
    kx_fr: float
    kx_rl: float
    kx_rr: float


class FrictionState(NamedTuple):
    """:func:`friction_step`'s state: ``since`` (4,) per corner, the time since which the
    excitation test has held (s; NaN: it does not hold)."""

    since: np.ndarray


def friction_params(p: FrictionParams, kx: np.ndarray) -> FrictionKernelParams:
    """:func:`friction_step`'s parameters from the validated ``p`` and the corners'
    longitudinal slip stiffness per unit load ``kx`` (4,) (:func:`corner_kx`)."""
    return pack(FrictionKernelParams, p, kx_fl=kx[0], kx_fr=kx[1], kx_rl=kx[2], kx_rr=kx[3])


def new_friction_state() -> FrictionState:
    """A fresh :class:`FrictionState` (no corner excited)."""
    return FrictionState(np.full(4, np.nan))


def corner_kx(vehicle: Vehicle, params: FrictionParams) -> np.ndarray:
    """Longitudinal slip stiffness per unit load per corner (4,), per unit slip ratio.

    From a calibrated file's ``[calibration.tire] cx_f, cx_r`` (an axle the logs did not
    excite takes the other's), else the file's ``[stiffness]`` axle totals when it states
    that table, each divided by the static axle load, else ``params.kx_nominal``.
    """
    b = vehicle.body
    wheelbase = b.lf + b.lr
    front = b.mass * G * b.lr / wheelbase
    rear = b.mass * G * b.lf / wheelbase
    cal = vehicle.calibration
    if cal is not None:
        cx_f, cx_r = cal.excited("tire", "cx_f"), cal.excited("tire", "cx_r")
        if cx_f is not None or cx_r is not None:  # an unexcited axle borrows the other's
            kf = cx_f / front if cx_f is not None else None
            kr = cx_r / rear if cx_r is not None else None
            kf = kf if kf is not None else kr
            kr = kr if kr is not None else kf
            return np.array([kf, kf, kr, kr], dtype=np.float64)
    if vehicle.stiffness is None or "stiffness" not in vehicle.given:
        return np.full(4, params.kx_nominal)
    kf, kr = vehicle.stiffness.cx_f / front, vehicle.stiffness.cx_r / rear
    return np.array([kf, kf, kr, kr])


@njit(**_JIT)
def _shape(z: float, c: float) -> float:
    return math.sin(c * math.atan(z / c))


@njit(**_JIT)
def invert_shape(q: float, c: float) -> float:
    """Root y ∈ (0, 1] of F(q·y) = y for q ≥ 1, F of eq. (1) with shape factor ``c``.

    g(y) = F(q y) − y has g(0) = 0, g'(0) = q − 1 > 0 and g(1) ≤ 0 (F ≤ 1), and F is
    concave on the rising branch, so bisection on (0, 1] finds the one positive root
    (to 2⁻⁴⁰). q ≤ 1 is the linear range: y = 1 is returned as "no information".
    """
    if q <= 1.0:
        return 1.0
    lo, hi = 0.0, 1.0
    for _ in range(40):
        mid = 0.5 * (lo + hi)
        if _shape(q * mid, c) > mid:
            lo = mid
        else:
            hi = mid
    return 0.5 * (lo + hi)


@njit(**_JIT, inline="always")
def friction_step(p: FrictionKernelParams, s: FrictionState, t: float, fx: np.ndarray,
                  fy: np.ndarray, fz: np.ndarray, sigma_fx: np.ndarray, sigma_fy: np.ndarray,
                  slip_ratio: np.ndarray, slip_angle: np.ndarray, sigma_alpha: float,
                  ky: float, mu: np.ndarray, sigma_mu: np.ndarray, excited: np.ndarray) -> None:
    """Friction potential per corner of one sample at time ``t`` (s); ``s`` is advanced.

    Args:
        fx, fy, fz: tire forces (4,), N, tire frame; u = ‖(F_x, F_y)‖ / max(F_z, 1 N).
        sigma_fx, sigma_fy: their one-σ (4,), N (NaN: none, and the sample is not excited).
        slip_ratio, slip_angle: estimated slips (4,), – and rad (spec signs).
        sigma_alpha: one-σ of the slip angles, rad, beyond ``sigma_slip_angle`` (the
            velocity filter's σ_vy / v_x; 0 when it has none).
        ky: normalised cornering stiffness, 1/rad.
        mu, sigma_mu, excited: outputs (4,), written; μ and σ are NaN where not excited.
    """
    eps = 1.01
    s_a = p.sigma_slip_angle
    var_a = s_a * s_a + sigma_alpha * sigma_alpha
    for c in range(4):
        kx = p.kx_fl if c == 0 else p.kx_fr if c == 1 else p.kx_rl if c == 2 else p.kx_rr
        load = max(fz[c], 1.0)
        u = math.hypot(fx[c], fy[c]) / load
        su = math.hypot(sigma_fx[c], sigma_fy[c]) / load
        sr = slip_ratio[c]
        scale = 1.0 / (1.0 + abs(sr))
        lx = kx * sr * scale
        ly = ky * math.tan(slip_angle[c]) * scale
        lin = math.hypot(lx, ly)
        w = ly * ly / (lin * lin) if lin > 1e-12 else 0.0
        shape = p.shape_lateral * w + p.shape_longitudinal * (1.0 - w)
        var_lin = ((p.sigma_k * lin) ** 2 + (kx * p.sigma_slip_ratio) ** 2 * (1.0 - w)
                   + ky ** 2 * var_a * w)
        ok = u >= p.u_min and lin - u >= p.excess_sigmas * math.sqrt(var_lin)
        m, sm = np.nan, np.nan
        if ok:
            q = lin / u
            y = invert_shape(q, shape)
            dlny = math.log(invert_shape(q * eps, shape) / y) / math.log(eps)
            rel_u = su / u
            rel_q2 = var_lin / (lin * lin) + rel_u * rel_u
            m = u / y
            sm = m * math.sqrt(dlny * dlny * rel_q2 + rel_u * rel_u)
            ok = sm <= p.sigma_max
        if ok:
            if math.isnan(s.since[c]):
                s.since[c] = t
            ok = t - s.since[c] >= p.persist_s - 1e-9
        else:
            s.since[c] = np.nan
        if ok:
            mu[c], sigma_mu[c], excited[c] = m, sm, 1.0
        else:
            mu[c], sigma_mu[c], excited[c] = np.nan, np.nan, 0.0


@njit(**_JIT)
def friction_kernel(p: FrictionKernelParams, s: FrictionState, t: np.ndarray, fx: np.ndarray,
                    fy: np.ndarray, fz: np.ndarray, sigma_fx: np.ndarray, sigma_fy: np.ndarray,
                    slip_ratio: np.ndarray, slip_angle: np.ndarray, sigma_alpha: np.ndarray,
                    ky: np.ndarray, mu: np.ndarray, sigma_mu: np.ndarray,
                    excited: np.ndarray) -> None:
    """:func:`friction_step` over a block of samples (causal; ``s`` carries on): ``t`` (s),
    ``sigma_alpha`` (rad) and ``ky`` (1/rad) (n,), the per-corner inputs and the outputs
    (n, 4), C-contiguous; units as there."""
    for k in range(t.shape[0]):
        friction_step(p, s, t[k], fx[k], fy[k], fz[k], sigma_fx[k], sigma_fy[k],
                      slip_ratio[k], slip_angle[k], sigma_alpha[k], ky[k], mu[k],
                      sigma_mu[k], excited[k])


def friction_potential(p: FrictionKernelParams, s: FrictionState, t: np.ndarray,
                       fx: np.ndarray, fy: np.ndarray, fz: np.ndarray, sigma_fx: np.ndarray,
                       sigma_fy: np.ndarray, slip_ratio: np.ndarray, slip_angle: np.ndarray,
                       sigma_alpha: np.ndarray,
                       ky: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """:func:`friction_kernel` on the force and velocity stages' arrays, outputs allocated;
    ``s`` is advanced.

    ``sigma_alpha``: (n,) rad, the velocity filter's slip-angle σ (NaN is taken as 0).

    Returns:
        μ, σ_μ (NaN where not excited) and the excitation flag (1/0), each (n, 4).
    """
    n = t.shape[0]
    mu, smu, ex = np.empty((n, 4)), np.empty((n, 4)), np.empty((n, 4))
    c = np.ascontiguousarray
    friction_kernel(p, s, c(t, dtype=np.float64), c(fx, dtype=np.float64),
                    c(fy, dtype=np.float64), c(fz, dtype=np.float64),
                    c(sigma_fx, dtype=np.float64), c(sigma_fy, dtype=np.float64),
                    c(slip_ratio, dtype=np.float64), c(slip_angle, dtype=np.float64),
                    c(np.nan_to_num(sigma_alpha, nan=0.0), dtype=np.float64),
                    c(ky, dtype=np.float64), mu, smu, ex)
    return mu, smu, ex
