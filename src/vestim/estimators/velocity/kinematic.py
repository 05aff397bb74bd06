"""Kinematic baseline (000 eq. (15)): integrate the accelerations, no correction.

v̇_x = f_x + r v_y,  v̇_y = f_y − r v_x, started from the mean wheel speed at the
first sample (v_y = 0). It shows the drift that the corrected estimators
remove: accelerometer bias and road grade integrate into a speed error that
grows linearly with time.
"""

from __future__ import annotations

from typing import Any, NamedTuple

import numpy as np
from numba import njit

_JIT: dict[str, Any] = {"cache": True, "error_model": "numpy"}


class KinematicState(NamedTuple):
    """State of :func:`kinematic_kernel` (in place); each field a 1-element array.

    Attributes:
        vx, vy: the integrated CG velocity, m/s.
        t_prev: time of the previous sample, s.
        fx_prev, fy_prev: the previous sample's specific force, m/s², and ``r_prev`` its yaw
            rate, rad/s, held over the integration interval.
        started: 1.0 once the first sample set v_x.
    """

    vx: np.ndarray
    vy: np.ndarray
    t_prev: np.ndarray
    fx_prev: np.ndarray
    fy_prev: np.ndarray
    r_prev: np.ndarray
    started: np.ndarray


def new_kinematic_state() -> KinematicState:
    """A fresh :class:`KinematicState` (the next sample starts the integration)."""
    return KinematicState(*(np.zeros(1) for _ in KinematicState._fields))


@njit(**_JIT)
def kinematic_kernel(t: np.ndarray, omega: np.ndarray, f_x: np.ndarray, f_y: np.ndarray,
                     yaw_rate: np.ndarray, radius: float, state: KinematicState,
                     out_v: np.ndarray) -> None:
    """Advance the integration over a chunk, in place on ``state``
    (:class:`KinematicState`): ``t`` (n,) s, ``omega`` (n, 4) rad/s, ``f_x``, ``f_y`` (n,)
    m/s², ``yaw_rate`` (n,) rad/s, ``radius`` m; ``out_v`` (n, 2) [v_x, v_y], m/s."""
    for k in range(t.shape[0]):
        if state.started[0] == 0.0:
            v0 = 0.0
            for i in range(4):
                v0 += 0.25 * radius * omega[k, i]
            state.vx[0] = v0
            state.vy[0] = 0.0
            state.started[0] = 1.0
        else:
            dt = t[k] - state.t_prev[0]
            vx, vy = state.vx[0], state.vy[0]
            state.vx[0] = vx + dt * (state.fx_prev[0] + state.r_prev[0] * vy)
            state.vy[0] = vy + dt * (state.fy_prev[0] - state.r_prev[0] * vx)
        state.t_prev[0] = t[k]
        state.fx_prev[0] = f_x[k]
        state.fy_prev[0] = f_y[k]
        state.r_prev[0] = yaw_rate[k]
        out_v[k, 0] = state.vx[0]
        out_v[k, 1] = state.vy[0]


class KinematicIntegrator:
    """Stateful wrapper of :func:`kinematic_kernel`."""

    def __init__(self, radius: float) -> None:
        self.radius = radius
        self.reset()

    def reset(self) -> None:
        self._state = new_kinematic_state()

    def advance(self, t: np.ndarray, omega: np.ndarray, f_x: np.ndarray, f_y: np.ndarray,
                yaw_rate: np.ndarray) -> np.ndarray:
        """CG velocity (n, 2) [v_x, v_y] in m/s over a chunk."""
        out = np.empty((t.shape[0], 2))
        kinematic_kernel(t, omega, f_x, f_y, yaw_rate, self.radius, self._state, out)
        return out
