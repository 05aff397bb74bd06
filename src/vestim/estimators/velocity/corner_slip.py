"""High-slip detection module of the Kalman corner velocity estimator (000 Sec. III, eq. (29)).

A corner is flagged "high slip" when either criterion of 000 Sec. III holds:

* slip: |λ| ≥ λ̄_th, with λ = v̂_rx / max(R|ω|, |v̂_xt|, v_min) from the filter's own
  prior estimate and the adaptive threshold of 000 eq. (29)::

      λ̄_th = λ_u − (λ_u − λ_l) exp(−β_e σ_e / (2 φ_e²)),   φ_e = (λ_u − λ_l)/√(2π),

  σ_e the variance of ‖a_k‖₂ over the last N_a samples;
* wheel acceleration: |ω̇| ≥ |ω̇_th|, ω̇ a difference over a short window (the
  raw one-sample difference of a 200 Hz wheel speed with the papers' 0.18 (rad/s)²
  noise has a one-sigma of 120 rad/s², above any useful threshold);

or when the caller's ``high_slip_hint`` is set. While flagged, the filter uses
the papers' high-slip covariances (000 Sec. III: Q̄ = 3.3e-4, R̄ = 2.1e-1).

Reading of eq. (29): the extraction prints the prefactor as 1/(φ_e√(2π)) =
1/(λ_u − λ_l), which makes λ̄_th = λ_u − 1/(λ_u − λ_l) ≈ −10 for any sensible
bounds (a negative threshold flags every sample). The threshold must move between
λ_l and λ_u ("the threshold changes between the predefined upper and lower
bounds"), which the prefactor φ_e√(2π) = λ_u − λ_l does: λ̄_th = λ_l at rest
(σ_e = 0, prompt detection in calm driving) rising to λ_u under strong
excitation (no spurious detection in harsh maneuvers, where moderate slip is
normal). We use that. 000 gives none of λ_u, λ_l, β_e, N_a, ω̇_th; our defaults
are in :class:`HighSlipParams`. ‖a_k‖ is the mean over the corners of the norm of
their tire-frame kinematic accelerations (the norm is rotation-invariant; it
differs from the CG's by the yaw-acceleration and centripetal transport terms only).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

import numpy as np
from numba import njit

_JIT: dict[str, Any] = {"cache": True, "error_model": "numpy"}

# entries of the statistics array ``stats`` (3,)
S_SUM, S_SUMSQ, S_COUNT = 0, 1, 2


@dataclass(frozen=True)
class HighSlipParams:
    """Parameters of the high-slip detection (000 Sec. III; values ours, 000 gives none).

    Attributes:
        lambda_upper: λ_u, upper bound of the slip-ratio threshold (strong excitation).
        lambda_lower: λ_l, lower bound (calm driving).
        beta_e: β_e, rate of transition between the bounds, 1/(m/s²)²; 0.005 puts the
            threshold half-way at σ_e ≈ 0.44 (m/s²)² for the default bounds.
        accel_window: N_a, samples in the moving variance of ‖a‖ (0.5 s at 200 Hz).
        omega_dot_threshold: |ω̇_th|, rad/s²; 40 rad/s² is 1.3 g at the SUV's tire
            periphery, the force stage's switching threshold.
        omega_dot_window: samples spanned by the ω̇ difference (10: noise one-sigma
            0.42·√2/0.05 s ≈ 12 rad/s² at 200 Hz).
        min_speed: floor of the slip-ratio denominator, m/s (a standing wheel has no
            meaningful slip ratio).
        mu_release: our addition — no high slip once |μ_x| < mu_release for
            ``release_window`` samples in a row (0 disables). A tire transmitting almost
            no force is near free rolling on any road whose sliding friction exceeds
            it, and without this release a filter that entered the high-slip mode
            with a wrong speed keeps itself there (its own slip estimate stays above
            the threshold while it ignores the forces). 0.03 sits above the force
            stage's free-rolling noise and below the Magic Formula's sliding μ_x on
            ice (0.054 at μ = 0.1); roads slipperier than that defeat it.
        release_window: consecutive samples for the release (0.1 s at 200 Hz; a single
            noisy μ_x sample must not release a sliding tire).
    """

    lambda_upper: float = 0.15
    lambda_lower: float = 0.05
    beta_e: float = 0.005
    accel_window: int = 100
    omega_dot_threshold: float = 40.0
    omega_dot_window: int = 10
    min_speed: float = 1.0
    mu_release: float = 0.03
    release_window: int = 20

    def __post_init__(self) -> None:
        if not 0.0 < self.lambda_lower < self.lambda_upper:
            raise ValueError(f"HighSlipParams needs 0 < lambda_lower ({self.lambda_lower}) < "
                             f"lambda_upper ({self.lambda_upper})")
        if not (math.isfinite(self.mu_release) and self.mu_release >= 0.0):
            raise ValueError(f"HighSlipParams.mu_release = {self.mu_release} must be finite and >= 0")
        for name in ("beta_e", "omega_dot_threshold", "min_speed"):
            v = getattr(self, name)
            if not (math.isfinite(v) and v > 0.0):
                raise ValueError(f"HighSlipParams.{name} = {v} must be finite and > 0")
        for name in ("accel_window", "omega_dot_window", "release_window"):
            v = getattr(self, name)
            if not (isinstance(v, int) and v >= 2):
                raise ValueError(f"HighSlipParams.{name} = {v!r} must be an integer >= 2")


def slip_threshold(lambda_upper: float, lambda_lower: float, beta_e: float,
                   sigma_e: np.ndarray | float) -> np.ndarray:
    """Adaptive slip-ratio threshold λ̄_th of 000 eq. (29) (prefactor read as φ_e√(2π)); vectorised."""
    phi_e = (lambda_upper - lambda_lower) / math.sqrt(2.0 * math.pi)
    s = np.asarray(sigma_e, dtype=float)
    return lambda_upper - (lambda_upper - lambda_lower) * np.exp(-beta_e * s / (2.0 * phi_e**2))


@njit(**_JIT)
def detector_step(k: int, t: float, omega: np.ndarray, a_x: np.ndarray, a_y: np.ndarray,
                  lambda_upper: float, lambda_lower: float, beta_e: float,
                  omega_dot_threshold: float, acc_buf: np.ndarray, stats: np.ndarray,
                  w_buf: np.ndarray, t_buf: np.ndarray, ring: np.ndarray,
                  wdot_high: np.ndarray) -> float:
    """Push sample k of the (n, 4) arrays into the detector's windows; return λ̄_th and
    write the |ω̇| flags (4,). (Whole arrays and an index, not row views: a view per
    sample costs reference counting in the time loop.)

    ‖a_k‖ is the mean over the corners of ‖(a_xt, a_yt)‖ (NaN a_yt counts as 0; corners
    with NaN a_xt are left out): the vehicle's acceleration level of 000 eq. (29),
    one threshold for all corners.

    State (all updated in place): ``acc_buf`` (N_a,) ring of ‖a‖; ``stats`` (3,)
    running sum, sum of squares and count of that ring; ``w_buf`` (m, 4) and
    ``t_buf`` (m,) rings of ω and t; ``ring`` int64 (3,): next slot of each ring
    and the number of (ω, t) samples stored.
    """
    na = acc_buf.shape[0]
    m = t_buf.shape[0]
    phi_e = (lambda_upper - lambda_lower) / math.sqrt(2.0 * math.pi)
    tot = 0.0
    cnt = 0
    for c in range(4):
        ay = 0.0 if math.isnan(a_y[k, c]) else a_y[k, c]  # longitudinal-only callers may omit a_yt
        v = math.sqrt(a_x[k, c] * a_x[k, c] + ay * ay)
        if not math.isnan(v):
            tot += v
            cnt += 1
    if cnt > 0:
        v = tot / cnt
        slot = ring[0]
        if stats[S_COUNT] >= na:
            old = acc_buf[slot]
            stats[S_SUM] -= old
            stats[S_SUMSQ] -= old * old
        else:
            stats[S_COUNT] += 1.0
        acc_buf[slot] = v
        stats[S_SUM] += v
        stats[S_SUMSQ] += v * v
        ring[0] = (slot + 1) % na
    n_acc = stats[S_COUNT]
    var = 0.0
    if n_acc > 1.0:
        mean = stats[S_SUM] / n_acc
        var = max(stats[S_SUMSQ] / n_acc - mean * mean, 0.0)
    threshold = lambda_upper - (lambda_upper - lambda_lower) * math.exp(
        -beta_e * var / (2.0 * phi_e * phi_e))
    # ω̇ over the window: the oldest stored sample against this one.
    stored = ring[2]
    if stored == 0:
        for c in range(4):
            wdot_high[c] = False
    else:
        old_slot = ring[1] if stored >= m else 0
        span = t - t_buf[old_slot]
        for c in range(4):
            wd = (omega[k, c] - w_buf[old_slot, c]) / span if span > 0.0 else 0.0
            wdot_high[c] = abs(wd) >= omega_dot_threshold
    w_slot = ring[1]
    t_buf[w_slot] = t
    for c in range(4):
        w_buf[w_slot, c] = omega[k, c]
    ring[1] = (w_slot + 1) % m
    if stored < m:
        ring[2] = stored + 1
    return threshold


@njit(**_JIT)
def is_high_slip(lam: float, threshold: float, wdot_high: bool, hint: bool,
                 released: bool) -> bool:
    """000 Sec. III's rule {|λ| ≥ λ̄_th ∨ |ω̇| ≥ |ω̇_th|} unless released (small |μ_x|); or the hint."""
    if hint:
        return True
    if released:
        return False
    return abs(lam) >= threshold or wdot_high


@njit(**_JIT)
def slip_ratio_estimate(omega_r: float, v_r: float, min_speed: float) -> float:
    """λ = v_r / max(|Rω|, |Rω − v_r|, v_min): the spec's slip ratio with a speed floor."""
    den = max(abs(omega_r), abs(omega_r - v_r), min_speed)
    return v_r / den
