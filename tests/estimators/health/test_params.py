"""The health stages' kernel parameters (issue 12): each :class:`HealthKernelParams` /
:class:`ImuHealthKernelParams` field is filled by :func:`vestim.params.pack` from the
validated config dataclass (plus the vehicle's geometry), and a changed config value reaches
the compiled step and changes its output where it should."""

from __future__ import annotations

from dataclasses import fields
from typing import Any

import numpy as np

from vestim.estimators.health import (
    HealthKernelParams,
    HealthParams,
    ImuHealthKernelParams,
    ImuHealthParams,
    health_params,
    imu_health_kernel,
    imu_health_params,
    new_imu_state,
    new_state,
    wheel_health_kernel,
)

RADIUS = 0.33  # m


def test_wheel_params_are_the_config_fields_and_the_radius() -> None:
    """Every field but the spike bound is the config's value (non-default values, so a
    field left at its default or taken from another would show); the spike bound is
    max_wheel_acc / R = 100 / 0.33 = 303.03 rad/s²."""
    cfg = HealthParams(max_wheel_acc=100.0, dropout_speed=0.3, min_speed=4.0, hold_s=0.2,
                       stuck_s=0.15, stuck_motion=0.6, noise=0.8)
    prm = health_params(cfg, RADIUS)
    assert isinstance(prm, HealthKernelParams)
    assert prm.max_wheel_rate == 100.0 / RADIUS
    for name in HealthKernelParams._fields[1:]:
        assert getattr(prm, name) == getattr(cfg, name), name


def _wheel_spike(cfg: HealthParams) -> tuple[np.ndarray, np.ndarray]:
    """Four wheels at 30 rad/s at 200 Hz, the front-left one 5 rad/s high at sample 10."""
    n = 20
    t = np.arange(n) * 0.005
    omega = np.full((n, 4), 30.0)
    omega[10, 0] += 5.0
    out, health = np.empty((n, 4)), np.empty((n, 4))
    wheel_health_kernel(health_params(cfg, RADIUS), new_state(), t, omega, out, health)
    return out, health


def test_max_wheel_acc_reaches_the_kernel() -> None:
    """A 5 rad/s jump in one 5 ms sample: within reach with the default 1500 m/s² (bound
    1500 / 0.33 × 0.005 + noise 1 = 23.7 rad/s), a spike with max_wheel_acc = 100 m/s²
    (bound 2.5 rad/s): left out there only, and replaced by the mate's 30 rad/s."""
    out, health = _wheel_spike(HealthParams())
    assert np.all(health == 1.0)
    assert out[10, 0] == 35.0
    out, health = _wheel_spike(HealthParams(max_wheel_acc=100.0))
    assert health[10, 0] == 0.0 and out[10, 0] == 30.0
    assert (health == 0.0).sum() == 1


def test_imu_params_are_the_config_fields_and_the_geometry() -> None:
    """Every config field (non-default values) and the four geometry values reach the
    kernel's parameters by name; sat_n is stored as a float (one Numba type)."""
    values: dict[str, Any] = {f.name: (7 if f.name == "sat_n" else 0.9 if f.name == "off_frac"
                                       else 1.5 * getattr(ImuHealthParams(), f.name))
                              for f in fields(ImuHealthParams)}
    cfg = ImuHealthParams(**values)
    prm = imu_health_params(cfg, 0.31, 1.55, 1.6, 1.2)
    assert isinstance(prm, ImuHealthKernelParams)
    assert (prm.wheel_radius, prm.track_f, prm.track_r, prm.lf) == (0.31, 1.55, 1.6, 1.2)
    for f in fields(ImuHealthParams):
        assert getattr(prm, f.name) == getattr(cfg, f.name), f.name
    assert isinstance(prm.sat_n, float)


def _imu(cfg: ImuHealthParams) -> np.ndarray:
    """2 s at 200 Hz, straight at 9.9 m/s: a_x 3 m/s² (a constant offset against the wheel
    reference, taken into the baseline at the start) with 0.01 noise; the health rows."""
    n = 400
    rng = np.random.default_rng(0)
    t = np.arange(n) * 0.005
    ax = 3.0 + 0.01 * rng.standard_normal(n)
    ay = 0.01 * rng.standard_normal(n)
    r = 0.001 * rng.standard_normal(n)
    omega = np.full((n, 4), 30.0)
    out, health = np.empty((3, n)), np.empty((n, 3))
    imu_health_kernel(imu_health_params(cfg, RADIUS, 1.6, 1.6, 1.3), new_imu_state(), t, ax,
                      ay, r, omega, np.zeros((n, 4)), out[0], out[1], out[2], health)
    return health


def test_imu_range_reaches_the_kernel() -> None:
    """The a_x reading of about 3 m/s² is healthy with an unknown range (inf), and
    saturated at every sample with range_acc = 2.5 m/s² (|a_x| ≥ range); a_y and the yaw
    rate are untouched by the a_x range."""
    assert np.all(_imu(ImuHealthParams()) == 1.0)
    health = _imu(ImuHealthParams(range_acc=2.5))
    assert np.all(health[:, 0] == 0.0)
    assert np.all(health[:, 1:] == 1.0)
