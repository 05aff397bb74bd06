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
from typing import Any

import numpy as np
from numba import njit

_JIT: dict[str, Any] = {"cache": True, "error_model": "numpy"}

H_W, H_D, H_AX, H_AY, H_MX, H_MY, H_R, H_T, H_REL = 0, 1, 2, 3, 4, 5, 6, 7, 8
N_HOLD = 9


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
