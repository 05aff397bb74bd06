"""Shared per-sample bookkeeping of the corner velocity kernels (held inputs, transport term).

Every corner kernel advances its state from the previous sample k−1 to the
current sample k, with the inputs held over the interval as follows (so that a
constant-acceleration, constant-slip motion is reproduced exactly):

* ω̇: the difference (ω_k − ω_{k−1})/h, so R ∫ω̇ dt over the step is exactly R Δω and
  the relative velocity v_rx = Rω − v_xt carries the same wheel-speed noise as R ω_k
  (it cancels in v̂_xt = Rω_k − v̂_rx);
* a_xt, a_yt, yaw rate: trapezoidal means of the two samples;
* the LuGre decay rate κR|ω| at the mean |ω| of the two samples, and d|ω|/dt as above.

Rows of the ``hold`` array (9, 4) store the last valid sample per corner
(``H_T`` is NaN until the first sample has been seen) and, in ``H_REL``, the
number of consecutive samples with |μ_x| below the high-slip release level.
"""

from __future__ import annotations

import math
from typing import Any, NamedTuple

import numpy as np
from numba import njit

_JIT: dict[str, Any] = {"cache": True, "error_model": "numpy"}

H_W, H_D, H_AX, H_AY, H_MX, H_MY, H_R, H_T, H_REL = 0, 1, 2, 3, 4, 5, 6, 7, 8
N_HOLD = 9


class CornerParams(NamedTuple):
    """A corner observer's parameters, whole (SI): ``lpv`` (the LPV observer) or the LuGre
    KF/UKF (``use_ukf``); the wheel radius and corner positions; the tire's κ, σ0, σ1, σ2
    (x and y); the KF's noise (``r``, ``r_high``, ``step_ref``, ``q``, ``q_high``, ``p0``)
    and sigma-point weights; the LPV's gain schedules (ω grid, L1, L2, longitudinal and
    lateral); the high-slip detector's (``lam_u`` … ``release_window``). Fields a method does
    not use hold placeholders."""

    lpv: bool
    radius: float
    xw: np.ndarray
    kappa: float
    sigma0: float
    sigma1: float
    sigma2: float
    r: float
    r_high: float
    step_ref: float
    lam_u: float
    lam_l: float
    beta_e: float
    wdot_th: float
    min_speed: float
    mu_release: float
    q: np.ndarray
    q_high: np.ndarray
    p0: np.ndarray
    release_window: int
    use_ukf: bool
    wm: np.ndarray
    wc: np.ndarray
    tau: float
    kappa_y: float
    sigma0_y: float
    sigma1_y: float
    sigma2_y: float
    gx_w: np.ndarray
    gx_1: np.ndarray
    gx_2: np.ndarray
    lateral: bool
    gy_w: np.ndarray
    gy_1: np.ndarray
    gy_2: np.ndarray


class CornerState(NamedTuple):
    """A corner observer's states: the KF's ``x`` (4, 3), ``P`` (4, 3, 3), the LPV's ``xx``,
    ``xy`` (4, 2), the held inputs ``hold`` (:data:`N_HOLD`, 4) and the high-slip detector's
    rings (``acc``, ``stats``, ``w_buf``, ``t_buf``, ``ring``)."""

    x: np.ndarray
    P: np.ndarray
    xx: np.ndarray
    xy: np.ndarray
    hold: np.ndarray
    acc: np.ndarray
    stats: np.ndarray
    w_buf: np.ndarray
    t_buf: np.ndarray
    ring: np.ndarray


class CornerInputs(NamedTuple):
    """A chunk of n samples for a corner observer: t (n,) s; omega, mu_x, mu_y, a_xt, a_yt,
    delta (n, 4); yaw_rate (n,) rad/s; hint (n, 4) bool; vyt_in (n, 4) m/s (NaN: the
    no-sideslip value)."""

    t: np.ndarray
    omega: np.ndarray
    mu_x: np.ndarray
    mu_y: np.ndarray
    a_xt: np.ndarray
    a_yt: np.ndarray
    delta: np.ndarray
    yaw_rate: np.ndarray
    hint: np.ndarray
    vyt_in: np.ndarray


class CornerOutputs(NamedTuple):
    """A corner observer's outputs (n, 4): v̂_xt, v̂_yt, the one-sigma of v̂_xt, the high-slip
    flags, v̂_rx, ẑ_x, ż̂_x, v̂_ry, ẑ_y (what a method does not estimate is left as given)."""

    vxt: np.ndarray
    vyt: np.ndarray
    sigma: np.ndarray
    high: np.ndarray
    vrx: np.ndarray
    zx: np.ndarray
    zdot: np.ndarray
    vry: np.ndarray
    zy: np.ndarray


def new_hold() -> np.ndarray:
    """A fresh ``hold`` array: nothing seen yet (t NaN), zero held inputs, no μ."""
    hold = np.zeros((N_HOLD, 4))
    hold[H_T] = np.nan
    hold[H_MX] = np.nan
    hold[H_MY] = np.nan
    return hold


@njit(**_JIT)
def pick(value: float, held: float) -> float:
    """``value`` if it is a number, else the held one (missing samples hold the last input)."""
    return held if math.isnan(value) else value


@njit(**_JIT)
def transport_rate(yaw_rate_mid: float, delta_now: float, delta_prev: float, h: float) -> float:
    """Rotation rate of the tire frame, r + δ̇, rad/s.

    The wheel-centre velocity in the tire frame obeys v̇_xt = a_xt + (r + δ̇) v_yt and
    v̇_yt = a_yt − (r + δ̇) v_xt, a_xt, a_yt the inertial (kinematic) acceleration of
    the wheel centre projected on the tire axes: the frame rotates with the body
    (yaw rate r) and with the steering (δ̇). 001 writes this as the corrected
    acceleration "ā_x + r V_y" transported to the corner (text after eq. (21)).
    """
    return yaw_rate_mid + (delta_now - delta_prev) / h


@njit(**_JIT)
def vyt_no_sideslip(yaw_rate: float, x_corner: float, vxt: float, delta: float) -> float:
    """Tire-frame lateral speed of a corner assuming no side slip at the CG (v_y = 0), m/s.

    v_y,i = v_y + r x_i ≈ r x_i and v_y,i = v_xt sin δ + v_yt cos δ give
    v_yt = (r x_i − v_xt sin δ)/cos δ. Used by the longitudinal-only methods
    for the transport term (r + δ̇)·v_yt when no v_yt input is supplied.
    """
    if delta == 0.0:
        return yaw_rate * x_corner  # rear wheels: no trigonometry
    return (yaw_rate * x_corner - vxt * math.sin(delta)) / math.cos(delta)


@njit(**_JIT)
def count_release(hold: np.ndarray, c: int, mu: float, mu_release: float, window: int) -> bool:
    """Count consecutive samples with |μ_x| < mu_release; True once ``window`` of them in a row."""
    if abs(mu) < mu_release:
        hold[H_REL, c] += 1.0
    else:
        hold[H_REL, c] = 0.0
    return hold[H_REL, c] >= window


@njit(**_JIT)
def store(hold: np.ndarray, c: int, t: float, omega: float, delta: float, axt: float, ayt: float,
          mux: float, muy: float, yaw_rate: float) -> None:
    """Remember the valid parts of sample k for corner c (NaN inputs keep the held value)."""
    hold[H_T, c] = t
    hold[H_W, c] = omega
    if not math.isnan(delta):
        hold[H_D, c] = delta
    if not math.isnan(axt):
        hold[H_AX, c] = axt
    if not math.isnan(ayt):
        hold[H_AY, c] = ayt
    if not math.isnan(yaw_rate):
        hold[H_R, c] = yaw_rate
    hold[H_MX, c] = mux
    hold[H_MY, c] = muy


def as_array(x: Any) -> np.ndarray:
    """Contiguous float64 copy-free view where possible (kernels need C-contiguous arrays)."""
    return np.ascontiguousarray(x, dtype=np.float64)
