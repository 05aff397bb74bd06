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


class LowpassState(NamedTuple):
    """State of one signal in :func:`noise_adaptive_lowpass` and :func:`noise_variance` (in
    place); each field a 1-element array, :func:`new_lowpass_state` makes a fresh one.

    Attributes:
        y, y_rate: the output section: the output (the signal's unit) and its rate (per s).
        h, v: the type-2 noise tracker: its value and rate.
        var: the noise's mean square σ̂² per sample (the signal's unit squared).
        t_prev: time of the previous sample, s.
        started: 1.0 once the first finite sample started the filter.
        x_prev: the previous sample, held over the tracker's next interval.
    """

    y: np.ndarray
    y_rate: np.ndarray
    h: np.ndarray
    v: np.ndarray
    var: np.ndarray
    t_prev: np.ndarray
    started: np.ndarray
    x_prev: np.ndarray


def new_lowpass_state() -> LowpassState:
    """A fresh :class:`LowpassState` (the next finite sample starts the filter)."""
    return LowpassState(*(np.zeros(1) for _ in LowpassState._fields))


@njit(**_JIT)
def _propagate(e: float, d: float, w: float, dt: float, tracker: bool) -> tuple[float, float]:
    """(e, d) after ``dt`` under ė = A (e, d) with the characteristic polynomial
    s² + 2ζω s + ω²: the low-pass section (e = y − x, d = ẏ; A = [[0, 1], [−ω², −2ζω]]) or
    the type-2 tracker (e = y − x, d = v; A = [[−2ζω, 1], [−ω², 0]]). exp(A dt) =
    e^(−ζω dt) [cos(ω_d dt) I + sin(ω_d dt)/ω_d (A + ζω I)], ω_d = ω √(1 − ζ²)."""
    s = ZETA * w
    wd = w * np.sqrt(1.0 - ZETA * ZETA)
    return _apply(e, d, w, np.exp(-s * dt), np.cos(wd * dt), np.sin(wd * dt) / wd, tracker)


@njit(**_JIT)
def _apply(e: float, d: float, w: float, decay: float, c: float, k: float,
           tracker: bool) -> tuple[float, float]:
    """:func:`_propagate` from its coefficients e^(−ζω dt), cos(ω_d dt), sin(ω_d dt)/ω_d."""
    s = ZETA * w
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
def _tracker_row(prm: LowpassParams, dt: float, cache: np.ndarray, slot: np.ndarray) -> int:
    """The row of ``cache`` (2, 6) with the tracker's coefficients for the interval ``dt`` (s):
    [Δt, e^(−ζω dt), cos(ω_d dt), sin(ω_d dt)/ω_d, λ = e^(−Δt/τ), the white-noise gain
    1 + Δt ω (1 + 4ζ²)/(4ζ)], computed into row ``slot[0]`` (then the other) where neither
    holds this Δt. A log's Δt alternates between a few values that differ in the time stamps'
    last bits: two rows spare the four transcendentals for ≈ 99 % of the samples, and the
    numbers are those computed afresh."""
    if cache[0, 0] == dt:
        return 0
    if cache[1, 0] == dt:
        return 1
    i = slot[0]
    slot[0] = 1 - i
    w = 2.0 * np.pi * prm.f_noise
    s = ZETA * w
    wd = w * np.sqrt(1.0 - ZETA * ZETA)
    cache[i, 0] = dt
    cache[i, 1] = np.exp(-s * dt)
    cache[i, 2] = np.cos(wd * dt)
    cache[i, 3] = np.sin(wd * dt) / wd
    cache[i, 4] = np.exp(-dt / prm.tau_noise)
    cache[i, 5] = 1.0 + dt * w * (1.0 + 4.0 * ZETA * ZETA) / (4.0 * ZETA)
    return i


@njit(**_JIT)
def _track(prm: LowpassParams, h: float, v: float, var: float, x_prev: float, xk: float,
           dt: float, cache: np.ndarray, slot: np.ndarray) -> tuple[float, float, float]:
    """One interval ``dt`` (s) of the type-2 tracker (h, v) at ``f_noise`` and the noise's mean
    square ``var`` from its residual against the sample ``xk``; returns the new (h, v, var).
    ``cache``, ``slot``: the call's :func:`_tracker_row`."""
    w = 2.0 * np.pi * prm.f_noise
    i = _tracker_row(prm, dt, cache, slot)
    # The tracker over the interval with the previous sample held: its prediction, which
    # x_k has not moved. White noise: E e² = σ² (1 + dt ω (1 + 4ζ²)/(4ζ)) (the gain).
    e, v = _apply(h - x_prev, v, w, cache[i, 1], cache[i, 2], cache[i, 3], True)
    h = x_prev + e
    r = xk - h
    lam = cache[i, 4]
    return h, v, lam * var + (1.0 - lam) * r * r / cache[i, 5]


@njit(**_JIT)
def noise_adaptive_lowpass(prm: LowpassParams, st: LowpassState, t: np.ndarray,
                           x: np.ndarray, out: np.ndarray, var_out: np.ndarray) -> None:
    """Filter ``x`` (n,) sampled at times ``t`` (s) into ``out`` (n,), in place on ``st``
    (:class:`LowpassState`); the first finite sample starts the filter at rest on it.
    ``var_out`` (n,): the measured noise variance σ̂² per sample of ``x`` (see
    :func:`noise_variance`). The noise left in ``out`` is about σ̂² dt ω_n/(4ζ) (white noise
    of two-sided density σ̂² dt through the section, whose ∫|H|² df is ω_n/(4ζ)).

    The state is read into scalars once per call and written back at its end (a field of
    ``st`` read per sample costs a reference count each, more than the filter's own work)."""
    y, y_rate, h, v, var = st.y[0], st.y_rate[0], st.h[0], st.v[0], st.var[0]
    t_prev, started, x_prev = st.t_prev[0], st.started[0], st.x_prev[0]
    cache = np.full((2, 6), np.nan)
    slot = np.zeros(1, dtype=np.int64)
    for k in range(x.shape[0]):
        xk = x[k]
        if np.isnan(xk):
            out[k] = np.nan
            var_out[k] = np.nan
            continue
        dt = t[k] - t_prev if started != 0.0 else 0.0
        if started == 0.0:  # start both sections on the first sample
            y, y_rate, h, v = xk, 0.0, xk, 0.0
            var = 0.0  # f_max until noise is seen (the mean square grows over tau_noise)
            started = 1.0
        elif dt > 0.0:
            h, v, var = _track(prm, h, v, var, x_prev, xk, dt, cache, slot)
        x_prev = xk
        if dt > 0.0:
            e, y_rate = _propagate(y - xk, y_rate, bandwidth(prm, var, dt), dt, False)
            y = xk + e
        t_prev = t[k]
        out[k] = y
        var_out[k] = var
    st.y[0], st.y_rate[0], st.h[0], st.v[0], st.var[0] = y, y_rate, h, v, var
    st.t_prev[0], st.started[0], st.x_prev[0] = t_prev, started, x_prev


@njit(**_JIT)
def noise_variance(prm: LowpassParams, st: LowpassState, t: np.ndarray, x: np.ndarray,
                   var_out: np.ndarray) -> None:
    """The noise variance per sample σ̂² of ``x`` (n,) into ``var_out`` (n,) (the mean square
    above ``f_noise``; NaN at NaN samples), in place on ``st`` (:class:`LowpassState`; the
    output section's y, y_rate are started, not run). The state is held in scalars over the
    call, as in :func:`noise_adaptive_lowpass`."""
    y, y_rate, h, v, var = st.y[0], st.y_rate[0], st.h[0], st.v[0], st.var[0]
    t_prev, started, x_prev = st.t_prev[0], st.started[0], st.x_prev[0]
    cache = np.full((2, 6), np.nan)
    slot = np.zeros(1, dtype=np.int64)
    for k in range(x.shape[0]):
        xk = x[k]
        if np.isnan(xk):
            var_out[k] = np.nan
            continue
        dt = t[k] - t_prev if started != 0.0 else 0.0
        if started == 0.0:
            y, y_rate, h, v = xk, 0.0, xk, 0.0
            var = 0.0
            started = 1.0
        elif dt > 0.0:
            h, v, var = _track(prm, h, v, var, x_prev, xk, dt, cache, slot)
        x_prev = xk
        t_prev = t[k]
        var_out[k] = var
    st.y[0], st.y_rate[0], st.h[0], st.v[0], st.var[0] = y, y_rate, h, v, var
    st.t_prev[0], st.started[0], st.x_prev[0] = t_prev, started, x_prev
