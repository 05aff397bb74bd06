"""Sensor models: the default's draws are unchanged by the realistic mode's additions, and the
realistic mode has the vibration, scale errors and plant roll it states (issue 29)."""

from __future__ import annotations

import numpy as np
import pytest

from vestim.sim import SensorModel, simulate

FS = 200.0


def test_a_model_without_the_new_errors_draws_what_it_drew() -> None:
    """Vibration and scale errors are drawn after every other draw, so a model without them
    (the default, which every regression figure was made with) gives the same log bit for bit
    as with them switched off explicitly; the realistic model gives another."""
    base = simulate("lc_wet", seed=3)
    off = simulate("lc_wet", seed=3, sensors=SensorModel(accel_vibration=0.0,
                                                         accel_scale_sd=0.0))
    assert base.equals(off)
    real = simulate("lc_wet", seed=3, sensors=SensorModel.realistic())
    assert not np.allclose(base["ay"], real["ay"])


def test_vibration_has_its_rms_and_band() -> None:
    """2 m/s² rms per axis (SensorModel.realistic's), ≥ 90 % of its power in 10–25 Hz (the
    4th-order Butterworth band-pass's skirts hold the rest: 92 % measured)."""
    n = 20_000
    v = SensorModel.realistic()._vibration(n, np.random.default_rng(1))
    assert np.sqrt(np.mean(v**2, axis=0)) == pytest.approx([2.0, 2.0, 2.0], rel=1e-9)
    power = np.abs(np.fft.rfft(v[:, 1])) ** 2
    f = np.fft.rfftfreq(n, 1.0 / FS)
    assert power[(f >= 10.0) & (f <= 25.0)].sum() / power.sum() >= 0.90


def test_a_vibration_band_outside_the_sample_rate_is_refused() -> None:
    with pytest.raises(ValueError, match="vibration band"):
        SensorModel(accel_vibration=1.0, vibration_low_hz=20.0, vibration_high_hz=120.0)


def test_the_plant_rolls_roll_scale_times_as_much() -> None:
    """roll_scale = 1.6 divides the plant's roll stiffness and damping by 1.6: in the wet lane
    change's quasi-steady turns the roll is 1.6 times as large (±5 %: the roll inertia and
    the load transfer's second-order terms), while the vehicle file stays as it is."""
    one = simulate("lc_wet", seed=1)
    soft = simulate("lc_wet", seed=1, roll_scale=1.6)
    turning = np.abs(one["ref_roll"].to_numpy()) > 0.5 * np.abs(one["ref_roll"]).max()
    ratio = soft["ref_roll"].to_numpy()[turning] / one["ref_roll"].to_numpy()[turning]
    assert np.median(ratio) == pytest.approx(1.6, rel=0.05)
    assert soft.attrs["roll_scale"] == "1.6"
    with pytest.raises(ValueError, match="roll_scale"):
        simulate("lc_wet", roll_scale=0.0)
