"""Axle-weighted CG velocity: fixed weights (000 Sec. III, 004 Sec. III) and the adaptive
slip-based weights of 001 eq. (34)–(35) (longitudinal) and (43)–(45) (lateral).

Both schemes average the two corners of an axle, then blend the axles:

    v_x,f = (v_x,fL + v_x,fR)/2,   v_x,r = (v_x,rL + v_x,rR)/2,   V_x = W_f v_x,f + W_r v_x,r.

The yaw-rate terms of the two corners of an axle cancel in the axle mean, so the
axle mean of the corner velocities mapped to the CG (003 eq. (5), what
:func:`vestim.estimators.fusion.fuse` receives) is the axle mean of the raw
corner velocities; per corner the weights are (W_f/2, W_f/2, W_r/2, W_r/2).

*Fixed* (``"axle"``): W_f = η1, W_r = η2 = 1 − η1, with η1 = η2 = 0.5 (004
Sec. III: "W_f = W_r = 0.5"; 000 after eq. (28) writes û_x = η1 û_x,f + η2 û_x,r).

*Adaptive* (``"adaptive"``), 001 eq. (34)–(35)::

    Σ_i = |λ_iL| + |λ_iR|  (per axle),     λ_am = max{Σ_f, Σ_r},
    W_i = W_s + W̄ atan[ρ (λ_am − λ_th)],  W_−i = 1 − W_i,   W̄ = (W̄_ub − W̄_lb)/π.

Reading of (34) (a choice): the text says the rule "allocate[s] a smaller weight
to an axle with higher slip ratio"; W_i rises with λ_am (W̄ > 0), so i is the axle
with the *smaller* Σ and −i, the one that slips more, gets 1 − W_i. With
W_s = (W̄_lb + W̄_ub)/2 the weight W_i stays in (W̄_lb, W̄_ub). 001 gives no values;
our defaults (:class:`AxleWeightParams`) put W̄_lb = 0.5 so that in normal driving
(λ_am well below λ_th) both axles weigh ≈ 0.5, and the less-slipping axle takes up
to W̄_ub = 0.9 once the worse axle's summed slip passes λ_th = 0.1. On an exact tie
Σ_f = Σ_r (standstill, or both axles spinning alike) neither axle is "the one with
higher slip" and both get 0.5. The rule is discontinuous across Σ_f = Σ_r when
λ_am is large (the roles of i and −i swap), as in 001.

Lateral (001 eq. (42)–(45)): v_y,f = −r L_f + (v_y,fL + v_y,fR)/2,
v_y,r = r L_r + (v_y,rL + v_y,rR)/2, V_y = W_yf v_y,f + W_yr v_y,r with the same
weight function of the summed slip-angle magnitudes Σ_yi = |α_iL| + |α_iR|
(:func:`fuse_lateral_adaptive`).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

import numpy as np
from numba import njit

_JIT: dict[str, Any] = {"cache": True, "error_model": "numpy"}

N_CORNERS = 4
FL, FR, RL, RR = 0, 1, 2, 3
"""Corner columns (order of :data:`vestim.constants.CORNERS`)."""


@dataclass(frozen=True)
class AxleWeightParams:
    """Shape of the adaptive axle weight of 001 eq. (34) / (44) (values ours; 001 gives none).

    Attributes:
        w_lb: W̄_lb, lower bound of the less-slipping axle's weight.
        w_ub: W̄_ub, upper bound of that weight; W̄ = (W̄_ub − W̄_lb)/π.
        w_s: W_s, "static weight", the weight at λ_am = λ_th; (W̄_lb + W̄_ub)/2 keeps the
            weight inside [W̄_lb, W̄_ub].
        rho: ρ_w, steepness of the transition, 1/(unit of the slip measure).
        threshold: λ_th (or α_th), the summed slip of an axle (|λ_L| + |λ_R|, or
            |α_L| + |α_R| in rad) at the middle of the transition.
    """

    w_lb: float = 0.5
    w_ub: float = 0.9
    w_s: float = 0.7
    rho: float = 50.0
    threshold: float = 0.1

    def __post_init__(self) -> None:
        for name in ("w_lb", "w_ub", "w_s", "rho", "threshold"):
            v = getattr(self, name)
            if not (isinstance(v, int | float) and math.isfinite(v)):
                raise ValueError(f"AxleWeightParams.{name} = {v!r} must be a finite number")
        if not 0.0 <= self.w_lb <= self.w_ub <= 1.0:
            raise ValueError(f"AxleWeightParams needs 0 <= w_lb ({self.w_lb}) <= w_ub ({self.w_ub}) <= 1")
        half = 0.5 * (self.w_ub - self.w_lb)
        if self.w_s - half < 0.0 or self.w_s + half > 1.0:
            raise ValueError(f"AxleWeightParams.w_s = {self.w_s} ± (w_ub − w_lb)/2 must stay in [0, 1] "
                             "so that both axle weights are in [0, 1]")
        if self.rho <= 0.0:
            raise ValueError(f"AxleWeightParams.rho = {self.rho} must be > 0")
        if self.threshold < 0.0:
            raise ValueError(f"AxleWeightParams.threshold = {self.threshold} must be >= 0")

    @property
    def w_range(self) -> float:
        """W̄ = (W̄_ub − W̄_lb)/π of 001 eq. (34)."""
        return (self.w_ub - self.w_lb) / math.pi


LATERAL_AXLE_WEIGHTS = AxleWeightParams(threshold=0.1, rho=50.0)
"""Defaults for 001 eq. (44): α_th = 0.1 rad summed over an axle (≈ 2.9° per tire), ρ = 50 1/rad."""


@njit(**_JIT)
def _abs0(x: float) -> float:
    """|x|, NaN counted as 0 (no slip information, e.g. at standstill)."""
    return 0.0 if x != x else abs(x)


@njit(**_JIT)
def axle_weight_pair(sigma_f: float, sigma_r: float, w_s: float, w_range: float, rho: float,
                     threshold: float) -> tuple[float, float]:
    """(W_f, W_r) of 001 eq. (34) (or (44)) from the axles' summed slips Σ_f, Σ_r (≥ 0).

    The less-slipping axle gets W_s + W̄ atan[ρ(λ_am − λ_th)], the other its
    complement; equal slips give 0.5 each (module docstring).
    """
    if sigma_f == sigma_r:
        return 0.5, 0.5
    lam_am = max(sigma_f, sigma_r)
    w_low = w_s + w_range * math.atan(rho * (lam_am - threshold))
    if sigma_f < sigma_r:
        return w_low, 1.0 - w_low
    return 1.0 - w_low, w_low


@njit(**_JIT)
def weighted_average_row(phi: np.ndarray, i: int, weights: np.ndarray, vx: np.ndarray) -> None:
    """Normalise the raw weights in ``weights[i]`` to sum 1 and write the fused ``vx[i]``.

    Corners whose value ``phi[i, j]`` is not finite are left out (weight 0, the others
    renormalised keeping their ratios); with none left, vx and the weights are NaN.
    """
    total = 0.0
    for j in range(N_CORNERS):
        if math.isfinite(phi[i, j]):
            total += weights[i, j]
        else:
            weights[i, j] = 0.0
    if total > 0.0:
        acc = 0.0
        for j in range(N_CORNERS):
            weights[i, j] /= total
            if weights[i, j] > 0.0:
                acc += weights[i, j] * phi[i, j]
        vx[i] = acc
    else:
        vx[i] = np.nan
        for j in range(N_CORNERS):
            weights[i, j] = np.nan


@njit(**_JIT)
def fixed_axle_kernel(phi: np.ndarray, eta_front: float, vx: np.ndarray, weights: np.ndarray) -> None:
    """Fixed axle weights (000 Sec. III, 004 Sec. III): per corner (η1/2, η1/2, η2/2, η2/2)."""
    half_f = 0.5 * eta_front
    half_r = 0.5 * (1.0 - eta_front)
    for i in range(phi.shape[0]):
        weights[i, FL] = half_f
        weights[i, FR] = half_f
        weights[i, RL] = half_r
        weights[i, RR] = half_r
        weighted_average_row(phi, i, weights, vx)


@njit(**_JIT)
def adaptive_axle_kernel(phi: np.ndarray, slip: np.ndarray, w_s: float, w_range: float, rho: float,
                         threshold: float, vx: np.ndarray, weights: np.ndarray) -> None:
    """Adaptive axle weights of 001 eq. (34)–(35) over the samples of (n, 4) ``phi`` and ``slip``."""
    for i in range(phi.shape[0]):
        sigma_f = _abs0(slip[i, FL]) + _abs0(slip[i, FR])
        sigma_r = _abs0(slip[i, RL]) + _abs0(slip[i, RR])
        w_f, w_r = axle_weight_pair(sigma_f, sigma_r, w_s, w_range, rho, threshold)
        weights[i, FL] = 0.5 * w_f
        weights[i, FR] = 0.5 * w_f
        weights[i, RL] = 0.5 * w_r
        weights[i, RR] = 0.5 * w_r
        weighted_average_row(phi, i, weights, vx)


@njit(**_JIT)
def _axle_weights_kernel(slip: np.ndarray, w_s: float, w_range: float, rho: float, threshold: float,
                         out: np.ndarray) -> None:
    for i in range(slip.shape[0]):
        sigma_f = _abs0(slip[i, FL]) + _abs0(slip[i, FR])
        sigma_r = _abs0(slip[i, RL]) + _abs0(slip[i, RR])
        w_f, w_r = axle_weight_pair(sigma_f, sigma_r, w_s, w_range, rho, threshold)
        out[i, 0] = w_f
        out[i, 1] = w_r


def adaptive_axle_weights(slip: np.ndarray, params: AxleWeightParams = AxleWeightParams()) -> np.ndarray:
    """Axle weights (W_f, W_r), (n, 2), of 001 eq. (34)–(35) (slip ratios) or (44)–(45) (slip angles, rad).

    ``slip`` is (n, 4) per corner (fl, fr, rl, rr); NaN counts as zero slip.
    """
    s = _as_n4(slip, "slip")
    out = np.empty((s.shape[0], 2))
    _axle_weights_kernel(s, params.w_s, params.w_range, params.rho, params.threshold, out)
    return out


def fuse_lateral_adaptive(vy_corner: np.ndarray, yaw_rate: np.ndarray, lf: float, lr: float,
                          slip_angle: np.ndarray,
                          params: AxleWeightParams = LATERAL_AXLE_WEIGHTS) -> tuple[np.ndarray, np.ndarray]:
    """CG lateral velocity by the adaptive axle weights of 001 eq. (42)–(45).

    Args:
        vy_corner: (n, 4) corner lateral velocities in the body frame (001 eq. (42)), m/s.
        yaw_rate: (n,) r, rad/s.
        lf, lr: CG to front / rear axle, m.
        slip_angle: (n, 4) tire slip angles α, rad (NaN counts as 0).
        params: weight shape (001 eq. (44)); threshold in rad.

    Returns:
        ``(vy_cg (n,), axle_weights (n, 2))``: V_y = W_yf v_y,f + W_yr v_y,r with
        v_y,f = −r L_f + (v_y,fL + v_y,fR)/2 and v_y,r = r L_r + (v_y,rL + v_y,rR)/2, m/s.
    """
    vy = _as_n4(vy_corner, "vy_corner")
    r = np.asarray(yaw_rate, dtype=float)
    if r.shape != (vy.shape[0],):
        raise ValueError(f"yaw_rate must have shape ({vy.shape[0]},); got {r.shape}")
    w = adaptive_axle_weights(slip_angle, params)
    if w.shape[0] != vy.shape[0]:
        raise ValueError(f"slip_angle must have {vy.shape[0]} rows; got {w.shape[0]}")
    vy_f = -r * lf + 0.5 * (vy[:, FL] + vy[:, FR])
    vy_r = r * lr + 0.5 * (vy[:, RL] + vy[:, RR])
    return w[:, 0] * vy_f + w[:, 1] * vy_r, w


def _as_n4(a: np.ndarray, name: str) -> np.ndarray:
    arr = np.ascontiguousarray(a, dtype=float)
    if arr.ndim != 2 or arr.shape[1] != N_CORNERS:
        raise ValueError(f"{name} must have shape (n, 4) with columns fl, fr, rl, rr; got {arr.shape}")
    return arr
