"""The noise-adaptive low-pass of vestim.filters.lowpass against its own model.

Seeded white noise and sinusoids at 200 Hz; the figures follow from the Kalman bandwidth law
ω_n = ω_max (σ_ref² dt_ref / (σ² dt))^(1/4) and from the second-order section's noise
bandwidth ∫|H|² df = ω_n / (4ζ).
"""

import math

import numpy as np
import pytest

from vestim.filters.lowpass import (
    LowpassParams,
    bandwidth,
    new_lowpass_state,
    noise_adaptive_lowpass,
    noise_variance,
)

PRM = LowpassParams(f_ref=8.0, f_max=8.0, f_min=1.0, sigma_ref=0.1, f_noise=8.0, tau_noise=1.0)
DT = 0.005


def _run(x: np.ndarray, prm: LowpassParams = PRM) -> tuple[np.ndarray, np.ndarray]:
    t = np.arange(x.size) * DT
    out, var = np.empty_like(x), np.empty_like(x)
    noise_adaptive_lowpass(prm, new_lowpass_state(), t, x, out, var)
    return out, var


def test_bandwidth_law() -> None:
    """σ_ref at 200 Hz gives f_max; sixteen times the noise power halves the bandwidth
    (fourth root); the clip holds at both ends."""
    hz = 1.0 / (2.0 * math.pi)
    assert bandwidth(PRM, 0.1**2, DT) * hz == pytest.approx(8.0)
    assert bandwidth(PRM, 0.4**2, DT) * hz == pytest.approx(4.0)
    assert bandwidth(PRM, 0.01**2, DT) * hz == pytest.approx(8.0)  # clipped at f_max
    assert bandwidth(PRM, 100.0, DT) * hz == pytest.approx(1.0)  # clipped at f_min
    # the same noise per sample at 100 Hz has twice the density: 2^(-1/4) of the bandwidth
    assert bandwidth(PRM, 0.4**2, 2 * DT) * hz == pytest.approx(4.0 / 2**0.25)


def test_white_noise_is_measured_and_the_remaining_variance_is_honest() -> None:
    """White noise σ = 0.4 m/s² on a constant: the tracker's one-step prediction residual,
    corrected for the prediction's own noise, gives σ̂ = 0.4 within 8 %; the filter then
    runs at about 4 Hz, and the noise left in its output, σ̂² dt ω_n/(4ζ) =
    0.16·0.005·25.1/2.83 = 0.0071 (σ 0.084), is the measured one within 20 % (the
    semi-implicit Euler section at ω dt = 0.13 differs from the continuous one by that
    much; the formula errs high)."""
    rng = np.random.default_rng(1)
    x = 2.0 + 0.4 * rng.standard_normal(40_000)
    t = np.arange(x.size) * DT
    var = np.empty_like(x)
    noise_variance(PRM, new_lowpass_state(), t, x, var)
    assert math.sqrt(float(np.median(var[2000:]))) == pytest.approx(0.4, rel=0.08)
    out, var_in = _run(x)
    assert float(np.median(var_in[2000:])) == pytest.approx(float(np.median(var[2000:])))
    s2 = float(np.median(var_in[2000:]))
    left = s2 * DT * bandwidth(PRM, s2, DT) / (4.0 / math.sqrt(2.0))
    measured = float(np.var(out[2000:]))
    assert measured <= left <= 1.2 * measured
    assert measured == pytest.approx(0.0071, rel=0.2)


def test_vibration_is_removed_and_a_slow_signal_kept() -> None:
    """A 0.5 Hz sine of 3 m/s² under a 15 Hz vibration of 3 m/s² rms (a body-mounted IMU's):
    the bandwidth falls to 8 (0.1/3)^(1/2) = 1.46 Hz, the vibration is attenuated by
    (1.46/15)² to 0.03 m/s², and the sine is delayed by 2ζ/ω_n = 0.154 s, an error of
    3·2π·0.5·0.154/√2 = 1.03 m/s² rms: below 1.1, where the raw signal is 3 m/s² off. That
    lag is the price of the model's smoothness (its q); the force stage pays it only on
    such logs. On the clean sine (no noise) the filter stays at f_max and is within
    0.19 m/s² (the 28 ms group delay of 8 Hz: 3·2π·0.5·0.028/√2)."""
    t = np.arange(40_000) * DT
    sine = 3.0 * np.sin(2 * np.pi * 0.5 * t)
    vib = 3.0 * math.sqrt(2.0) * np.sin(2 * np.pi * 15.0 * t)
    out, _ = _run(sine + vib)
    err = out[2000:] - sine[2000:]
    assert float(np.sqrt(np.mean(err**2))) < 1.1
    assert float(np.sqrt(np.mean(vib[2000:] ** 2))) == pytest.approx(3.0, rel=0.01)
    clean, _ = _run(sine)
    assert float(np.sqrt(np.mean((clean[2000:] - sine[2000:]) ** 2))) < 0.19


def test_nan_samples_pass_through_and_do_not_poison_the_state() -> None:
    """A NaN sample gives NaN and leaves the filter where it was: after it the output of a
    constant is that constant again."""
    x = np.full(400, 1.5)
    x[100] = np.nan
    out, var = _run(x)
    assert np.isnan(out[100]) and np.isnan(var[100])
    assert np.allclose(out[101:], 1.5)


@pytest.mark.parametrize("rate", [80.0, 100.0])
def test_exact_discretisation_is_stable_where_euler_is_not(rate: float) -> None:
    """A 20 Hz section sampled at 80 or 100 Hz (ω dt = 1.57, 1.26; semi-implicit Euler
    diverges there: the Revs log at 100 Hz gave F_z of 1e306 N) stays bounded on white
    noise and settles on a constant step within 1e-9 after 1 s."""
    prm = PRM._replace(f_ref=20.0, f_max=20.0, f_min=20.0)
    t = np.arange(2000) / rate
    rng = np.random.default_rng(2)
    x = np.where(t > 5.0, 3.0, 0.3 * rng.standard_normal(t.size))
    out, var = np.empty_like(x), np.empty_like(x)
    noise_adaptive_lowpass(prm, new_lowpass_state(), t, x, out, var)
    assert np.all(np.isfinite(out)) and float(np.max(np.abs(out))) < 3.5
    assert abs(float(out[-1]) - 3.0) < 1e-9


@pytest.mark.parametrize("spread", [0.0, 1e-18, 2e-4])  # Δt exact, in its last bits, jittered
def test_one_call_equals_sample_by_sample_calls_bit_for_bit(spread):
    """A call keeps the tracker's coefficients of the last two intervals Δt (issue 27's
    speed); sample-by-sample calls compute them afresh every time. Both must give the same
    floats, whether Δt repeats exactly, alternates in its last bits (the time stamps of a
    real log) or never repeats."""
    rng = np.random.default_rng(7)
    n = 600
    t = np.cumsum(DT + spread * rng.standard_normal(n)) if spread else np.arange(n) * DT
    x = np.sin(2.0 * np.pi * 0.7 * t) + 0.05 * rng.standard_normal(n)
    x[100:103] = np.nan
    out, var, var2 = np.empty(n), np.empty(n), np.empty(n)
    noise_adaptive_lowpass(PRM, new_lowpass_state(), t, x, out, var)
    noise_variance(PRM, new_lowpass_state(), t, x, var2)
    one, onev, onev2 = np.empty(n), np.empty(n), np.empty(n)
    st, st2 = new_lowpass_state(), new_lowpass_state()
    for k in range(n):
        noise_adaptive_lowpass(PRM, st, t[k:k + 1], x[k:k + 1], one[k:k + 1], onev[k:k + 1])
        noise_variance(PRM, st2, t[k:k + 1], x[k:k + 1], onev2[k:k + 1])
    assert np.array_equal(out, one, equal_nan=True)
    assert np.array_equal(var, onev, equal_nan=True)
    assert np.array_equal(var2, onev2, equal_nan=True)
    assert np.array_equal(var, var2, equal_nan=True)  # the same tracker in both
