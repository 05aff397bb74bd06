"""A causal low-pass whose bandwidth follows the signal's own measured noise.

The signal is modelled as a smooth process observed in white noise: state [a, ȧ], white
noise of spectral density q on ä, measurement noise of variance σ² per sample of length
dt (spectral density R = σ² dt). The steady-state Kalman filter of that model has the
second-order Butterworth poles (damping ζ = 1/√2) at the natural frequency

    ω_n = (q / R)^(1/4)

(the continuous-time algebraic Riccati equation of the double integrator), so the
bandwidth falls with the fourth root of the noise: sixteen times the noise power halves it.
The output here is the plain second-order low-pass with those poles, without the Kalman
filter's zero (which passes noise above ω_n at 1/f instead of 1/f²: a vibrating IMU's
10–30 Hz is what it is for). σ² is measured from the signal itself, as the exponentially
weighted mean square of the one-step prediction residual of a type-2 tracking loop of
bandwidth ``f_noise`` (it follows ramps without lag, so what it misses lies above
``f_noise``), divided by 1 + the prediction's own share of white noise,
dt ω (1 + 4ζ²)/(4ζ): a vehicle's handling accelerations hold almost nothing above a few
hertz, whereas sensor noise and the vibration of a body-mounted IMU lie there. q is given
as the bandwidth ``f_ref`` reached at a reference noise ``sigma_ref`` at 200 Hz; ω_n is
clipped to [``f_min``, ``f_max``].

Both sections are discretised exactly (the matrix exponential of their 2×2 dynamics, the
input held over the sample interval), so they are stable at any ω dt: a 20 Hz section at
100 Hz sampling (ω dt = 1.26) diverges under explicit or semi-implicit Euler. A NaN sample
leaves the states as they are and gives NaN.
"""

from __future__ import annotations

from typing import Any, NamedTuple

import numpy as np
from numba import njit

_JIT: dict[str, Any] = {"cache": True, "error_model": "numpy"}

N_LOWPASS = 8
"""Length of one signal's state in :func:`noise_adaptive_lowpass`: [y, ẏ, h, v, σ², t_prev,
started, x_prev] (the output section, the noise tracker, the noise's mean square, the
previous sample held over the tracker's next interval)."""

ZETA = 1.0 / np.sqrt(2.0)
"""Damping of both second-order sections (Butterworth)."""
DT_REF = 1.0 / 200.0
"""s; the sample period at which ``f_ref`` is reached for ``sigma_ref``."""


class LowpassParams(NamedTuple):
    """Parameters of :func:`noise_adaptive_lowpass` (see the module docstring)."""

    f_ref: float  # Hz, bandwidth at sigma_ref
    f_max: float  # Hz, the most bandwidth
    f_min: float  # Hz, the least bandwidth
    sigma_ref: float  # the noise per sample (signal's unit) at which f_ref holds at 200 Hz
    f_noise: float  # Hz, edge above which the signal is taken to be noise
    tau_noise: float  # s, averaging time of the noise's mean square


@njit(**_JIT)
def _propagate(e: float, d: float, w: float, dt: float, tracker: bool) -> tuple[float, float]:
    """(e, d) after ``dt`` under ė = A (e, d) with the characteristic polynomial
    s² + 2ζω s + ω²: the low-pass section (e = y − x, d = ẏ; A = [[0, 1], [−ω², −2ζω]]) or
    the type-2 tracker (e = y − x, d = v; A = [[−2ζω, 1], [−ω², 0]]). exp(A dt) =
    e^(−ζω dt) [cos(ω_d dt) I + sin(ω_d dt)/ω_d (A + ζω I)], ω_d = ω √(1 − ζ²)."""
    s = ZETA * w
    wd = w * np.sqrt(1.0 - ZETA * ZETA)
    decay = np.exp(-s * dt)
    c = np.cos(wd * dt)
    k = np.sin(wd * dt) / wd
    if tracker:  # A + ζω I = [[−ζω, 1], [−ω², ζω]]
        return (decay * (c * e + k * (-s * e + d)),
                decay * (c * d + k * (-w * w * e + s * d)))
    # A + ζω I = [[ζω, 1], [−ω², −ζω]]
    return (decay * (c * e + k * (s * e + d)),
            decay * (c * d + k * (-w * w * e - s * d)))


@njit(**_JIT)
def bandwidth(prm: LowpassParams, var: float, dt: float) -> float:
    """ω_n (rad/s) for the noise variance ``var`` per sample of period ``dt`` (s):
    ω_ref (σ_ref² dt_ref / (var dt))^(1/4), clipped to [ω_min, ω_max]."""
    ratio = prm.sigma_ref * prm.sigma_ref * DT_REF / max(var * dt, 1e-300)
    return min(max(2.0 * np.pi * prm.f_ref * ratio ** 0.25, 2.0 * np.pi * prm.f_min),
               2.0 * np.pi * prm.f_max)


@njit(**_JIT)
def _noise(prm: LowpassParams, state: np.ndarray, xk: float, dt: float) -> None:
    """One sample of the noise's mean square state[4] from the residual of the type-2 tracker
    state[2:4] at ``f_noise``; starts both on the first sample (state[6] = 0)."""
    if state[6] == 0.0:
        state[0] = xk
        state[1] = 0.0
        state[2] = xk
        state[3] = 0.0
        state[4] = 0.0  # f_max until noise is seen (the mean square grows over tau_noise)
        state[6] = 1.0
    elif dt > 0.0:
        w = 2.0 * np.pi * prm.f_noise
        # The tracker over the interval with the previous sample held: its prediction, which
        # x_k has not moved. White noise: E e² = σ² (1 + dt ω (1 + 4ζ²)/(4ζ)).
        e, state[3] = _propagate(state[2] - state[7], state[3], w, dt, True)
        state[2] = state[7] + e
        r = xk - state[2]
        lam = np.exp(-dt / prm.tau_noise)
        gain = 1.0 + dt * w * (1.0 + 4.0 * ZETA * ZETA) / (4.0 * ZETA)
        state[4] = lam * state[4] + (1.0 - lam) * r * r / gain
    state[7] = xk


@njit(**_JIT)
def noise_adaptive_lowpass(prm: LowpassParams, state: np.ndarray, t: np.ndarray,
                           x: np.ndarray, out: np.ndarray, var_out: np.ndarray) -> None:
    """Filter ``x`` (n,) sampled at times ``t`` (s) into ``out`` (n,), in place on ``state``
    (:data:`N_LOWPASS`); the first finite sample starts the filter at rest on it.
    ``var_out`` (n,): the measured noise variance σ̂² per sample of ``x`` (see
    :func:`noise_variance`). The noise left in ``out`` is about σ̂² dt ω_n/(4ζ) (white noise
    of two-sided density σ̂² dt through the section, whose ∫|H|² df is ω_n/(4ζ))."""
    for k in range(x.shape[0]):
        xk = x[k]
        if np.isnan(xk):
            out[k] = np.nan
            var_out[k] = np.nan
            continue
        dt = t[k] - state[5] if state[6] != 0.0 else 0.0
        _noise(prm, state, xk, dt)
        if dt > 0.0:
            e, state[1] = _propagate(state[0] - xk, state[1], bandwidth(prm, state[4], dt), dt,
                                     False)
            state[0] = xk + e
        state[5] = t[k]
        out[k] = state[0]
        var_out[k] = state[4]


@njit(**_JIT)
def noise_variance(prm: LowpassParams, state: np.ndarray, t: np.ndarray, x: np.ndarray,
                   var_out: np.ndarray) -> None:
    """The noise variance per sample σ̂² of ``x`` (n,) into ``var_out`` (n,) (the mean square
    above ``f_noise``; NaN at NaN samples), in place on ``state`` (:data:`N_LOWPASS`)."""
    for k in range(x.shape[0]):
        if np.isnan(x[k]):
            var_out[k] = np.nan
            continue
        _noise(prm, state, x[k], t[k] - state[5] if state[6] != 0.0 else 0.0)
        state[5] = t[k]
        var_out[k] = state[4]
