"""Fusion of the four corner velocity estimates into the CG longitudinal velocity (issue 6).

Three methods, all stateless per sample (any chunking gives the same result):

- ``"axle"``: fixed axle weights η1 = η2 = 0.5 (000 Sec. III, 004 Sec. III);
- ``"adaptive"``: slip-adaptive axle weights of 001 eq. (34)–(35);
- ``"opinion"``: opinion-dynamics consensus with per-sample confidence optimisation
  (003 eq. (5)–(13), Algorithm 2).

:func:`fuse` returns the fused CG velocity and the per-corner convex weights;
:func:`confidences` the opinion method's confidences W_j (003 eq. (6) bounds, eq. (13)
optimum). Equations and choices: ``docs/methods_fusion.md``.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from vestim.estimators.fusion.axle import (
    LATERAL_AXLE_WEIGHTS,
    AxleWeightParams,
    adaptive_axle_kernel,
    adaptive_axle_weights,
    fixed_axle_kernel,
    fuse_lateral_adaptive,
)
from vestim.estimators.fusion.opinion import (
    SHIFT,
    confidence_bounds,
    consensus_weights,
    eq6_confidence,
    laplacian_bar,
    opinion_kernel,
    simulate_delayed_dynamics,
    solve_confidences,
    steady_state_opinions,
)
from vestim.estimators.registry import register, registered


@dataclass(frozen=True)
class FusionParams:
    """Parameters of the three fusion methods (dimensionless unless stated).

    Attributes:
        k1, k2: constants of the confidence W_j = k1 (k2 − |λ_j|), 003 eq. (6); 003
            Sec. IV uses k1 = 25, k2 = 1.
        w_floor: lower floor of every confidence bound (003 needs W_j > 0; eq. (6) is
            ≤ 0 for |λ| ≥ k2). A fully slipping corner keeps weight ≈ 0.1/4.1 of a
            confident one's 25/29.
        band: relative half-width of the bounds [W_min, W_max] of 003 eq. (13) around
            the eq. (6) value: W_min = max(w_floor, (1 − band) W6),
            W_max = max(w_floor, (1 + band) W6) (our rule; 003 only says the bounds come
            "from the slip condition and (6)").
        gamma: γ of 003 eq. (13), bound on λ_max(L̄), 1/s. Lemma 2 then guarantees
            stability for delays up to π/(2γ) (29 → 54 ms, about ten samples at
            200 Hz). The default 4 + k1·k2 = 29 is the λ_max bound of eq. (6)'s
            zero-slip confidence: with band = 0.2 it caps confidences at 25, so every
            corner with |λ| ≤ band·k2/(1 + band) ≈ 0.17 gets the same confidence
            (small slips do not reorder the corners), while a lone confident corner
            may rise up to 1 above the cap (:func:`solve_confidences`). Must exceed
            4 + max(w_floor, (1 − band) k1 k2), which makes eq. (13) feasible for every slip.
        eta_front: η1 of the fixed axle weights (η2 = 1 − η1); 0.5 in 000 / 004.
        adaptive: shape of the adaptive axle weight, 001 eq. (34).
    """

    k1: float = 25.0
    k2: float = 1.0
    w_floor: float = 0.1
    band: float = 0.2
    gamma: float = 29.0
    eta_front: float = 0.5
    adaptive: AxleWeightParams = field(default_factory=AxleWeightParams)

    def __post_init__(self) -> None:
        for name in ("k1", "k2", "w_floor", "band", "gamma", "eta_front"):
            v = getattr(self, name)
            if not (isinstance(v, int | float) and math.isfinite(v)):
                raise ValueError(f"FusionParams.{name} = {v!r} must be a finite number")
        for name in ("k1", "k2", "w_floor"):
            if getattr(self, name) <= 0.0:
                raise ValueError(f"FusionParams.{name} = {getattr(self, name)} must be > 0")
        if not 0.0 <= self.band < 1.0:
            raise ValueError(f"FusionParams.band = {self.band} must be in [0, 1)")
        if not 0.0 <= self.eta_front <= 1.0:
            raise ValueError(f"FusionParams.eta_front = {self.eta_front} must be in [0, 1]")
        gamma_min = SHIFT + max(self.w_floor, (1.0 - self.band) * self.k1 * self.k2)
        if self.gamma <= gamma_min:
            raise ValueError(f"FusionParams.gamma = {self.gamma} must exceed "
                             f"4 + max(w_floor, (1 − band)·k1·k2) = {gamma_min} so that 003 eq. (13) "
                             "is feasible for every slip; raise gamma or lower band, k1 or k2")
        if not isinstance(self.adaptive, AxleWeightParams):
            raise ValueError("FusionParams.adaptive must be an AxleWeightParams; "
                             f"got {type(self.adaptive).__name__}")


@register("fusion", "axle", "fixed axle weights η1 = η2 = 0.5", default=True,
          cite="000 Sec. III, 004 Sec. III", tables=("fusion_params",), needs_wheel_speeds=False,
          params=FusionParams)
def _fixed(phi: np.ndarray, slip: np.ndarray, params: FusionParams, vx: np.ndarray,
           weights: np.ndarray) -> None:
    """Fixed axle weights η1 = ``params.eta_front``, η2 = 1 − η1 (``slip`` unused)."""
    fixed_axle_kernel(phi, float(params.eta_front), vx, weights)


@register("fusion", "adaptive", "slip-adaptive axle weights", cite="001 eq. (34)–(35)",
          tables=("fusion_params",), needs_wheel_speeds=False, params=FusionParams)
def _adaptive(phi: np.ndarray, slip: np.ndarray, params: FusionParams, vx: np.ndarray,
              weights: np.ndarray) -> None:
    """Slip-adaptive axle weights of ``params.adaptive``."""
    a = params.adaptive
    adaptive_axle_kernel(phi, slip, float(a.w_s), float(a.w_range), float(a.rho),
                         float(a.threshold), vx, weights)


@register("fusion", "opinion", "opinion-dynamics consensus with per-sample confidence "
          "optimisation (writes confidence_*)", cite="003 eq. (5)–(13), Alg. 2",
          tables=("fusion_params",), needs_wheel_speeds=False, outputs=("confidence",),
          params=FusionParams)
def _opinion(phi: np.ndarray, slip: np.ndarray, params: FusionParams, vx: np.ndarray,
             weights: np.ndarray) -> None:
    """Opinion-dynamics consensus with the confidences of ``params``."""
    conf = np.empty((phi.shape[0], 4))
    opinion_kernel(phi, slip, float(params.k1), float(params.k2), float(params.w_floor),
                   float(params.band), float(params.gamma), vx, weights, conf)


FUSION_METHODS: tuple[str, ...] = tuple(registered("fusion"))
"""Names accepted by :func:`fuse`, in the registry's order (each a function of the signature
``(phi, slip, params, vx, weights)`` filling ``vx`` (n,) and ``weights`` (n, 4) in place,
registered above)."""


def _check_inputs(vx_corner_cg: np.ndarray, slip_ratio: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    phi = np.ascontiguousarray(vx_corner_cg, dtype=float)
    slip = np.ascontiguousarray(slip_ratio, dtype=float)
    if phi.ndim != 2 or phi.shape[1] != 4:
        raise ValueError(f"vx_corner_cg must have shape (n, 4) with columns fl, fr, rl, rr; got {phi.shape}")
    if slip.shape != phi.shape:
        raise ValueError(f"slip_ratio must have the shape of vx_corner_cg {phi.shape}; got {slip.shape}")
    return phi, slip


def fuse(method: str, vx_corner_cg: np.ndarray, slip_ratio: np.ndarray,
         params: FusionParams = FusionParams()) -> tuple[np.ndarray, np.ndarray]:
    """Fused CG longitudinal velocity and per-corner weights, sample by sample.

    Args:
        method: one of :data:`FUSION_METHODS`.
        vx_corner_cg: (n, 4) corner longitudinal velocities already mapped to the CG,
            m/s (fl, fr, rl, rr): the opinions φ of 003 eq. (5). Non-finite entries
            drop out of that sample's average (the other weights renormalised); a row
            with none finite gives NaN.
        slip_ratio: (n, 4) slip ratios λ (dimensionless); NaN (standstill) counts as 0.
        params: :class:`FusionParams`.

    Returns:
        ``(vx_cg, weights)``: (n,) fused CG velocity, m/s, and (n, 4) weights that sum to
        1 in each row, vx_cg = Σ_j weights_j φ_j. For ``"opinion"`` the weights are the
        column means of L̄⁻¹W (003 eq. (10)), i.e. vx_cg is the mean of the steady-state
        opinions φ̄ (:func:`~vestim.estimators.fusion.opinion.steady_state_opinions` gives
        φ̄ per corner for the remap of 003 Algorithm 2).

    Raises:
        ValueError: unknown method (the message names it) or wrong shapes.
    """
    if method not in FUSION_METHODS:
        raise ValueError(f"unknown fusion method {method!r}; choose one of {', '.join(FUSION_METHODS)}")
    phi, slip = _check_inputs(vx_corner_cg, slip_ratio)
    n = phi.shape[0]
    vx = np.empty(n)
    weights = np.empty((n, 4))
    fill = registered("fusion")[method].impl
    assert fill is not None  # every fusion method registers its function above
    fill(phi, slip, params, vx, weights)
    return vx, weights


def confidences(slip_ratio: np.ndarray, params: FusionParams = FusionParams()) -> np.ndarray:
    """Confidences W_j, (n, 4), that the ``"opinion"`` fusion uses: the exact optimum of
    003 eq. (13) within the eq. (6) bounds of :class:`FusionParams` (NaN slip counts as 0)."""
    slip = np.ascontiguousarray(slip_ratio, dtype=float)
    if slip.ndim != 2 or slip.shape[1] != 4:
        raise ValueError(f"slip_ratio must have shape (n, 4) with columns fl, fr, rl, rr; got {slip.shape}")
    lo, hi = confidence_bounds(slip, params.k1, params.k2, params.w_floor, params.band)
    w, _ = solve_confidences(lo, hi, params.gamma)
    return w


__all__ = [
    "FUSION_METHODS",
    "LATERAL_AXLE_WEIGHTS",
    "AxleWeightParams",
    "FusionParams",
    "adaptive_axle_weights",
    "confidence_bounds",
    "confidences",
    "consensus_weights",
    "eq6_confidence",
    "fuse",
    "fuse_lateral_adaptive",
    "laplacian_bar",
    "simulate_delayed_dynamics",
    "solve_confidences",
    "steady_state_opinions",
]
