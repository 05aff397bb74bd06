"""Online sensor-noise estimate and torque-innovation switch of the default longitudinal UKF.

``ukf_kernel`` estimates the wheel-speed and torque noise from the log (median of second
differences) and enables its torque-innovation switch only where the wheel speed resolves a
torque step quickly (τ = √(2 σ_ω I_w/σ_T) ≤ ``resolve_time``). Synthetic logs here, with the
two sensor sets the project meets: our simulator's (σ_ω 0.42 rad/s, σ_T 5.7 N m) and the
crossplant logs' (σ_ω 0.06 rad/s, σ_T 20 N m).
"""

import numpy as np
import pytest

from vestim.estimators.force import longitudinal as lon
from vestim.io import load_vehicle

SUV = load_vehicle("hashemi_suv")
DT = 0.005


def synthetic(sigma_w: float, sigma_t: float, n: int = 2000, chops: bool = False, seed: int = 0):
    """A wheel under a slowly varying force with a sinusoidal drive torque, noisy ω and T.
    ``chops``: the torque is cut by 300 N m for 10 samples (50 ms) at random starts, 1 % of
    the samples (a limiter at a saturated tire: ω̇ takes the step, F_x stays), so that the
    steps reach about 4 % of the second differences."""
    rng = np.random.default_rng(seed)
    b = SUV.body
    t = np.arange(n) * DT
    torque = np.repeat((300 + 200 * np.sin(0.8 * t))[:, None], 4, axis=1)
    if chops:
        starts = (rng.random((n, 4)) < 0.01).astype(float)
        cut = np.stack([np.convolve(starts[:, c], np.ones(10))[:n] for c in range(4)], 1)
        torque = torque - 300.0 * (cut > 0)
    force = np.repeat((800 + 500 * np.sin(0.8 * t + 0.3))[:, None], 4, axis=1)
    omega_dot = (torque - b.wheel_radius * force) / b.wheel_inertia
    omega = 30 + np.cumsum(omega_dot, axis=0) * DT
    return (t, omega + rng.normal(0, sigma_w, omega.shape),
            torque + rng.normal(0, sigma_t, torque.shape), force)


def run(t, omega, torque, **kw):
    est = lon.LongitudinalEstimator(SUV, "ukf", lon.UKFParams(**kw))
    fx, _ = est.advance(t, omega, torque)
    sigma_w = np.exp(est.state.x[:, lon.X_LW]) / lon._D2_MEDIAN
    sigma_t = np.exp(est.state.x[:, lon.X_LT]) / lon._D2_MEDIAN
    return fx, sigma_w, sigma_t


@pytest.mark.parametrize("sigma_w, sigma_t", [(0.06, 20.0), (0.42, 32.0**0.5), (0.2, 2.0)])
@pytest.mark.parametrize("chops", [False, True])
def test_noise_levels_are_estimated_from_the_log(sigma_w, sigma_t, chops):
    """After 10 s every corner's σ̂_ω and σ̂_T is within 12 % of the truth (the tracker's
    ≈ 1000-sample memory gives ≈ 4 % one-sigma), with or without limiter chops on 5 % of
    the samples (a median ignores that minority), from the simulator's prior r_ω = 0.18,
    r_T = 32 whatever the truth."""
    t, omega, torque, _ = synthetic(sigma_w, sigma_t, chops=chops)
    _, sw, st = run(t, omega, torque)
    assert np.all(np.abs(sw / sigma_w - 1) < 0.12), sw
    assert np.all(np.abs(st / sigma_t - 1) < 0.12), st


def test_torque_switch_is_off_on_our_simulators_sensors():
    """σ_ω 0.42 rad/s, σ_T 5.7 N m on the SUV wheel: τ = √(2·0.42·1.68/5.7) ≈ 0.5 s > 0.2 s, so
    the torque switch stays off and F̂_x equals the filter without it, bit for bit (with it,
    T̂ would follow chops long before ω̇̂ can: 1–7 points worse on our TC/ABS maneuvers)."""
    t, omega, torque, _ = synthetic(0.18**0.5, 32.0**0.5, chops=True)
    fx, _, _ = run(t, omega, torque)
    fx_off, _, _ = run(t, omega, torque, innov_torque_one=1e9, innov_torque_mean=1e9)
    assert np.array_equal(fx, fx_off)


def test_torque_switch_helps_on_crossplant_sensors():
    """σ_ω 0.06 rad/s, σ_T 20 N m: τ ≈ 0.1 s, the switch is on; with torque chops it lowers
    the F_x RMS error against the filter without it (and the fixed, mis-stated simulator
    noise does worse than both)."""
    t, omega, torque, force = synthetic(0.06, 20.0, chops=True, n=4000)
    keep = t >= 1.0

    def rms(fx):
        return float(np.sqrt(np.mean((fx[keep] - force[keep]) ** 2)))

    on = rms(run(t, omega, torque)[0])
    off = rms(run(t, omega, torque, innov_torque_one=1e9, innov_torque_mean=1e9)[0])
    fixed = rms(run(t, omega, torque, noise_online=False)[0])
    assert on < 0.9 * off
    assert on < fixed
