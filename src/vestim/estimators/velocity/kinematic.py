"""Kinematic baseline (000 eq. (15)): integrate the accelerations, no correction.

v̇_x = f_x + r v_y,  v̇_y = f_y − r v_x, started from the mean wheel speed at the
first sample (v_y = 0). It shows the drift that the corrected estimators
remove: accelerometer bias and road grade integrate into a speed error that
grows linearly with time.
"""

from __future__ import annotations

from typing import Any

import numpy as np
from numba import njit

_JIT: dict[str, Any] = {"cache": True, "error_model": "numpy"}


@njit(**_JIT)
def kinematic_kernel(t: np.ndarray, omega: np.ndarray, f_x: np.ndarray, f_y: np.ndarray,
                     yaw_rate: np.ndarray, radius: float, state: np.ndarray,
                     out_v: np.ndarray) -> None:
    """Advance the integration over a chunk; ``state`` = [v_x, v_y, t, f_x, f_y, r, started]."""
    for k in range(t.shape[0]):
        if state[6] == 0.0:
            v0 = 0.0
            for i in range(4):
                v0 += 0.25 * radius * omega[k, i]
            state[0] = v0
            state[1] = 0.0
            state[6] = 1.0
        else:
            dt = t[k] - state[2]
            vx, vy = state[0], state[1]
            state[0] = vx + dt * (state[3] + state[5] * vy)
            state[1] = vy + dt * (state[4] - state[5] * vx)
        state[2] = t[k]
        state[3] = f_x[k]
        state[4] = f_y[k]
        state[5] = yaw_rate[k]
        out_v[k, 0] = state[0]
        out_v[k, 1] = state[1]


class KinematicIntegrator:
    """Stateful wrapper of :func:`kinematic_kernel`."""

    def __init__(self, radius: float) -> None:
        self.radius = radius
        self.reset()

    def reset(self) -> None:
        self._state = np.zeros(7)

    def advance(self, t: np.ndarray, omega: np.ndarray, f_x: np.ndarray, f_y: np.ndarray,
                yaw_rate: np.ndarray) -> np.ndarray:
        """CG velocity (n, 2) [v_x, v_y] in m/s over a chunk."""
        out = np.empty((t.shape[0], 2))
        kinematic_kernel(t, omega, f_x, f_y, yaw_rate, self.radius, self._state, out)
        return out
