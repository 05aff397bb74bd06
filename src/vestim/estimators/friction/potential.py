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
from typing import Any

import numpy as np
from numba import njit

from vestim.constants import G
from vestim.io.vehicle import Vehicle
from vestim.params import check_ranges

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


def friction_params(p: FrictionParams) -> np.ndarray:
    """Pack :class:`FrictionParams` for :func:`friction_kernel` (order of the fields)."""
    return np.array([p.shape_lateral, p.shape_longitudinal, p.sigma_k, p.sigma_slip_ratio,
                     p.sigma_slip_angle, p.excess_sigmas, p.sigma_max, p.u_min, p.persist_s])


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


@njit(**_JIT)
def friction_kernel(t: np.ndarray, fx: np.ndarray, fy: np.ndarray, fz: np.ndarray,
                    sigma_fx: np.ndarray, sigma_fy: np.ndarray, slip_ratio: np.ndarray,
                    slip_angle: np.ndarray, sigma_alpha: np.ndarray, ky: np.ndarray,
                    kx: np.ndarray, prm: np.ndarray, state: np.ndarray, mu: np.ndarray,
                    sigma_mu: np.ndarray, excited: np.ndarray) -> None:
    """Friction potential per corner over a block of samples (causal; ``state`` carries on).

    Args:
        t: sample times (n,), s.
        fx, fy, fz: tire forces (n, 4), N, tire frame; u = ‖(F_x, F_y)‖ / max(F_z, 1 N).
        sigma_fx, sigma_fy: their one-σ (n, 4), N (NaN: none, and no sample is excited).
        slip_ratio, slip_angle: estimated slips (n, 4), – and rad (spec signs).
        sigma_alpha: one-σ of the slip angles (n,), rad, beyond ``sigma_slip_angle`` (the
            velocity filter's σ_vy / v_x; 0 when it has none).
        ky: normalised cornering stiffness (n,), 1/rad; kx: normalised longitudinal slip
            stiffness per corner (4,), per unit slip ratio.
        prm: :func:`friction_params`.
        state: (4,) per corner, the time since which the excitation test has held (NaN: it
            does not hold); reset to NaN.
        mu, sigma_mu, excited: outputs (n, 4), written; μ and σ are NaN where not excited.
    """
    c_lat, c_lon, s_k, s_s, s_a, n_sig, s_max, u_min, persist = (
        prm[0], prm[1], prm[2], prm[3], prm[4], prm[5], prm[6], prm[7], prm[8])
    eps = 1.01
    for k in range(t.shape[0]):
        for c in range(4):
            load = max(fz[k, c], 1.0)
            u = math.hypot(fx[k, c], fy[k, c]) / load
            su = math.hypot(sigma_fx[k, c], sigma_fy[k, c]) / load
            s = slip_ratio[k, c]
            scale = 1.0 / (1.0 + abs(s))
            lx = kx[c] * s * scale
            ly = ky[k] * math.tan(slip_angle[k, c]) * scale
            lin = math.hypot(lx, ly)
            w = ly * ly / (lin * lin) if lin > 1e-12 else 0.0
            shape = c_lat * w + c_lon * (1.0 - w)
            var_a = s_a * s_a + sigma_alpha[k] * sigma_alpha[k]
            var_lin = (s_k * lin) ** 2 + (kx[c] * s_s) ** 2 * (1.0 - w) + ky[k] ** 2 * var_a * w
            ok = u >= u_min and lin - u >= n_sig * math.sqrt(var_lin)
            m, sm = np.nan, np.nan
            if ok:
                q = lin / u
                y = invert_shape(q, shape)
                dlny = math.log(invert_shape(q * eps, shape) / y) / math.log(eps)
                rel_u = su / u
                rel_q2 = var_lin / (lin * lin) + rel_u * rel_u
                m = u / y
                sm = m * math.sqrt(dlny * dlny * rel_q2 + rel_u * rel_u)
                ok = sm <= s_max
            if ok:
                if math.isnan(state[c]):
                    state[c] = t[k]
                ok = t[k] - state[c] >= persist - 1e-9
            else:
                state[c] = np.nan
            if ok:
                mu[k, c], sigma_mu[k, c], excited[k, c] = m, sm, 1.0
            else:
                mu[k, c], sigma_mu[k, c], excited[k, c] = np.nan, np.nan, 0.0




def friction_potential(t: np.ndarray, fx: np.ndarray, fy: np.ndarray, fz: np.ndarray,
                       sigma_fx: np.ndarray, sigma_fy: np.ndarray, slip_ratio: np.ndarray,
                       slip_angle: np.ndarray, sigma_alpha: np.ndarray, ky: np.ndarray,
                       kx: np.ndarray, prm: np.ndarray,
                       state: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """:func:`friction_kernel` on the force and velocity stages' arrays, outputs allocated.

    ``sigma_alpha``: (n,) rad, the velocity filter's slip-angle σ (NaN is taken as 0).

    Returns:
        μ, σ_μ (NaN where not excited) and the excitation flag (1/0), each (n, 4).
    """
    n = t.shape[0]
    mu, smu, ex = np.empty((n, 4)), np.empty((n, 4)), np.empty((n, 4))
    c = np.ascontiguousarray
    friction_kernel(c(t, dtype=np.float64), c(fx, dtype=np.float64), c(fy, dtype=np.float64),
                    c(fz, dtype=np.float64), c(sigma_fx, dtype=np.float64),
                    c(sigma_fy, dtype=np.float64), c(slip_ratio, dtype=np.float64),
                    c(slip_angle, dtype=np.float64),
                    c(np.nan_to_num(sigma_alpha, nan=0.0), dtype=np.float64),
                    c(ky, dtype=np.float64), kx, prm, state, mu, smu, ex)
    return mu, smu, ex
