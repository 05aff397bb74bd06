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
from typing import NamedTuple

import numpy as np
from numba import njit

from vestim.estimators.health.imu import ImuHealthKernelParams as ImuHealthKernelParams
from vestim.estimators.health.imu import ImuHealthParams as ImuHealthParams
from vestim.estimators.health.imu import ImuHealthState as ImuHealthState
from vestim.estimators.health.imu import imu_health_kernel as imu_health_kernel
from vestim.estimators.health.imu import imu_health_params as imu_health_params
from vestim.estimators.health.imu import imu_health_step as imu_health_step
from vestim.estimators.health.imu import new_imu_state as new_imu_state
from vestim.params import check_ranges, pack


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


class HealthKernelParams(NamedTuple):
    """:func:`wheel_health_step`'s parameters: the :class:`HealthParams` fields (SI) and
    ``max_wheel_rate``, the spike bound ``max_wheel_acc`` / wheel radius (rad/s²)."""

    max_wheel_rate: float
    dropout_speed: float
    min_speed: float
    hold_s: float
    stuck_s: float
    stuck_motion: float
    noise: float


class HealthState(NamedTuple):
    """:func:`wheel_health_step`'s state, one entry per wheel (fl, fr, rl, rr), NaN: none
    yet. ``last_raw`` the last reading (rad/s), ``t_changed`` when it last changed (s),
    ``median_then`` the other wheels' median then (rad/s), ``t_dropout`` when the present
    dropout began (s; NaN: none), ``last_healthy`` the last healthy reading (rad/s) and
    ``t_healthy`` its time (s)."""

    last_raw: np.ndarray
    t_changed: np.ndarray
    median_then: np.ndarray
    t_dropout: np.ndarray
    last_healthy: np.ndarray
    t_healthy: np.ndarray


def health_params(p: HealthParams, radius: float) -> HealthKernelParams:
    """:func:`wheel_health_step`'s parameters from the validated ``p``; ``radius`` (m, the
    vehicle's wheel radius) turns the spike bound into rad/s²."""
    return pack(HealthKernelParams, p, max_wheel_rate=p.max_wheel_acc / radius)


def new_state() -> HealthState:
    """A fresh :class:`HealthState` (every entry NaN: nothing seen yet)."""
    return HealthState(*(np.full(4, np.nan) for _ in HealthState._fields))


@njit(cache=True, error_model="numpy")
def _median3(a: float, b: float, c: float) -> float:
    return max(min(a, b), min(max(a, b), c))


@njit(cache=True, error_model="numpy", inline="always")
def wheel_health_step(p: HealthKernelParams, s: HealthState, t: float, w: np.ndarray,
                      out: np.ndarray, health: np.ndarray) -> None:
    """Health of the four wheel speeds ``w`` (4,) rad/s (fl, fr, rl, rr) of one sample at
    time ``t`` (s); ``out`` (4,) gets them with the faulty ones replaced, ``health`` (4,)
    1.0 (healthy) or 0.0 (left out); ``s`` is advanced. A NaN reading (a log without wheel
    speeds) passes through untouched."""
    last_raw, t_changed, median_then = s.last_raw, s.t_changed, s.median_then
    t_dropout, last_healthy, t_healthy = s.t_dropout, s.last_healthy, s.t_healthy
    bad = np.zeros(4, dtype=np.bool_)
    for i in range(4):
        out[i] = w[i]
        health[i] = 1.0
        if np.isnan(w[i]):
            continue
        a, b, c = (w[1], w[2], w[3]) if i == 0 else (w[0], w[2], w[3]) if i == 1 else (
            (w[0], w[1], w[3]) if i == 2 else (w[0], w[1], w[2]))
        m = _median3(a, b, c)
        fault = False
        if not np.isnan(last_healthy[i]):  # spike: out of reach of the last healthy value
            fault = (abs(w[i] - last_healthy[i])
                     > p.max_wheel_rate * (t - t_healthy[i]) + p.noise)
        if not np.isnan(m) and m > p.min_speed and abs(w[i]) < p.dropout_speed:  # dropout
            if np.isnan(t_dropout[i]):
                t_dropout[i] = t
            fault = fault or t - t_dropout[i] >= p.hold_s
        else:
            t_dropout[i] = np.nan
        if np.isnan(last_raw[i]) or w[i] != last_raw[i]:  # stuck: frozen, others move
            last_raw[i], t_changed[i], median_then[i] = w[i], t, m
        elif t - t_changed[i] >= p.stuck_s and abs(m - median_then[i]) > p.stuck_motion:
            fault = True
        bad[i] = fault
        if not fault:
            last_healthy[i], t_healthy[i] = w[i], t
    for i in range(4):
        if not bad[i]:
            continue
        mate = i + 1 if i % 2 == 0 else i - 1
        if not bad[mate] and not np.isnan(w[mate]):
            out[i] = w[mate]
        else:
            total, n = 0.0, 0
            for j in range(4):
                if not bad[j] and not np.isnan(w[j]):
                    total += w[j]
                    n += 1
            if n > 0:
                out[i] = total / n
        health[i] = 0.0


@njit(cache=True, error_model="numpy")
def wheel_health_kernel(p: HealthKernelParams, s: HealthState, t: np.ndarray,
                        omega: np.ndarray, out: np.ndarray, health: np.ndarray) -> None:
    """:func:`wheel_health_step` over a block of samples: ``t`` (n,) s, ``omega``, ``out``
    and ``health`` (n, 4), C-contiguous; ``s`` carries on from block to block."""
    for k in range(t.shape[0]):
        wheel_health_step(p, s, t[k], omega[k], out[k], health[k])
