"""Wheel-speed sensor health (issue 15): a faulty wheel speed is left out, not believed.

Per wheel and sample, causally (the same kernel in :meth:`Pipeline.run` and ``step``), a
wheel-speed reading is **faulty** when:

- **spike**: it jumps from its last healthy value faster than any wheel can spin up or
  brake (``max_wheel_acc``, m/s² at the periphery: 4× a free wheel's spin-up under full
  drive torque, 3000 N m on 1.7 kg m² at 0.33 m); flagged at once, and a reading stays
  faulty until it is back within reach of its last healthy value;
- **dropout**: it reads below ``dropout_speed`` while the other wheels' median exceeds
  ``min_speed``, for longer than ``hold_s`` (a sensor or cable dropping to 0; an ABS cycle
  locks a wheel for well under 0.3 s);
- **stuck**: it has not changed for ``stuck_s`` while the other wheels' median changed by
  more than ``stuck_motion`` (a frozen CAN value).

Where the other wheels' median is the reference, a real spinning or locked wheel (slip on
ice) is not a fault: only physically impossible readings are. A faulty reading is replaced
by the speed of the other wheel on the same axle (or the mean of the healthy ones), so the
filters go on from the other three (that corner's F_x is then the mate's);
``health_omega_<c>`` is 0 while it is left out, and the row's ``reason_*`` gets the "input
faulty" bit.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numba import njit

from vestim.estimators.health.imu import ImuHealthParams as ImuHealthParams
from vestim.estimators.health.imu import imu_health_kernel as imu_health_kernel
from vestim.estimators.health.imu import imu_health_params as imu_health_params
from vestim.estimators.health.imu import new_imu_state as new_imu_state
from vestim.params import check_ranges


@dataclass(frozen=True)
class HealthParams:
    """Thresholds of the wheel-speed health test (SI; see the module docstring)."""

    max_wheel_acc: float = 1500.0
    dropout_speed: float = 0.2
    min_speed: float = 5.0
    hold_s: float = 0.3
    stuck_s: float = 0.1
    stuck_motion: float = 0.5
    noise: float = 1.0

    def __post_init__(self) -> None:
        check_ranges(self, "health", positive=("max_wheel_acc", "dropout_speed", "min_speed",
                                               "stuck_s", "stuck_motion", "noise"),
                     nonnegative=("hold_s",))


def health_params(p: HealthParams, radius: float) -> np.ndarray:
    """Pack for :func:`wheel_health_kernel`; ``radius`` (m) turns accelerations into rad/s²."""
    return np.array([p.max_wheel_acc / radius, p.dropout_speed, p.min_speed, p.hold_s,
                     p.stuck_s, p.stuck_motion, p.noise])


def new_state() -> np.ndarray:
    """Kernel state, per wheel: last raw value, time it last changed, the others' median
    then, time the dropout began (NaN: none), last healthy value and its time."""
    return np.full((4, 6), np.nan)


@njit(cache=True)
def _median3(a: float, b: float, c: float) -> float:
    return max(min(a, b), min(max(a, b), c))


@njit(cache=True)
def wheel_health_kernel(t: np.ndarray, omega: np.ndarray, prm: np.ndarray, state: np.ndarray,
                        out: np.ndarray, health: np.ndarray) -> None:
    """Health of each wheel speed over a block of samples; ``out`` gets the wheel speeds with
    the faulty ones replaced, ``health`` 1.0 (healthy) or 0.0 (left out). NaN readings (a log
    without wheel speeds) pass through untouched."""
    acc, drop, vmin, hold, stuck_s, motion, noise = (prm[0], prm[1], prm[2], prm[3], prm[4],
                                                     prm[5], prm[6])
    for k in range(t.shape[0]):
        w = omega[k]
        bad = np.zeros(4, dtype=np.bool_)
        for i in range(4):
            out[k, i] = w[i]
            health[k, i] = 1.0
            if np.isnan(w[i]):
                continue
            a, b, c = (w[1], w[2], w[3]) if i == 0 else (w[0], w[2], w[3]) if i == 1 else (
                (w[0], w[1], w[3]) if i == 2 else (w[0], w[1], w[2]))
            m = _median3(a, b, c)
            fault = False
            if not np.isnan(state[i, 4]):  # spike: out of reach of the last healthy value
                fault = abs(w[i] - state[i, 4]) > acc * (t[k] - state[i, 5]) + noise
            if not np.isnan(m) and m > vmin and abs(w[i]) < drop:  # dropout, held
                if np.isnan(state[i, 3]):
                    state[i, 3] = t[k]
                fault = fault or t[k] - state[i, 3] >= hold
            else:
                state[i, 3] = np.nan
            if np.isnan(state[i, 0]) or w[i] != state[i, 0]:  # stuck: frozen while others move
                state[i, 0], state[i, 1], state[i, 2] = w[i], t[k], m
            elif t[k] - state[i, 1] >= stuck_s and abs(m - state[i, 2]) > motion:
                fault = True
            bad[i] = fault
            if not fault:
                state[i, 4], state[i, 5] = w[i], t[k]
        for i in range(4):
            if not bad[i]:
                continue
            mate = i + 1 if i % 2 == 0 else i - 1
            if not bad[mate] and not np.isnan(w[mate]):
                out[k, i] = w[mate]
            else:
                s, n = 0.0, 0
                for j in range(4):
                    if not bad[j] and not np.isnan(w[j]):
                        s += w[j]
                        n += 1
                if n > 0:
                    out[k, i] = s / n
            health[k, i] = 0.0
