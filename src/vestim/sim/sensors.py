"""Sensor models: sampling, noise, bias and quantisation of the measured channels.

Defaults follow the papers and automotive-grade parts: wheel-speed variance
0.18 (rad/s)² and wheel-torque variance 32 (N m)² (000 Sec. IV-A); a MEMS IMU of
the airbag/ESC class (accelerometer noise 0.05 m/s², bias 0.05 m/s² one-sigma
per run; gyro noise 0.003 rad/s, bias 0.002 rad/s per run); steering-wheel angle
quantised to 0.1°. Biases are drawn once per run from the seeded generator.

:meth:`SensorModel.realistic` is what recorded logs have and the defaults lack (issue 29:
the defaults hid a lateral filter that drifted on real logs): body vibration on the
accelerometers (2 m/s² rms in 10–25 Hz), 4× the noise, quantised gyros and wheel speeds.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
import pandas as pd

from vestim.constants import CORNERS


@dataclass(frozen=True)
class SensorModel:
    """Noise (one-sigma), per-run bias (one-sigma) and quantisation step per sensor group.

    Units: wheel speed rad/s, torque N m, accelerometer m/s², gyro rad/s,
    steering rad (steering-wheel angle). ``rate`` is the sampling rate in Hz.
    ``accel_vibration``: rms of band-limited body vibration on each accelerometer axis, m/s²,
    in ``vibration_low_hz``–``vibration_high_hz``; ``accel_scale_sd``, ``gyro_scale_sd``:
    one-sigma of each axis's scale-factor error, drawn once per run (relative).
    """

    rate: float = 200.0
    wheel_speed_noise: float = math.sqrt(0.18)
    wheel_speed_quant: float = 0.0
    torque_noise: float = math.sqrt(32.0)
    torque_quant: float = 0.0
    accel_noise: float = 0.05
    accel_bias: float = 0.05
    accel_quant: float = 0.0
    gyro_noise: float = 0.003
    gyro_bias: float = 0.002
    gyro_quant: float = 0.0
    steering_quant: float = math.radians(0.1)
    accel_vibration: float = 0.0
    vibration_low_hz: float = 10.0
    vibration_high_hz: float = 25.0
    accel_scale_sd: float = 0.0
    gyro_scale_sd: float = 0.0

    def __post_init__(self) -> None:
        for name, value in self.__dict__.items():
            if not math.isfinite(value) or value < 0:
                raise ValueError(f"SensorModel.{name} = {value} must be finite and >= 0")
        if self.rate <= 0:
            raise ValueError("SensorModel.rate must be > 0")
        if self.accel_vibration > 0 and not (
                0 < self.vibration_low_hz < self.vibration_high_hz < self.rate / 2):
            raise ValueError(f"SensorModel vibration band {self.vibration_low_hz}–"
                             f"{self.vibration_high_hz} Hz must lie in (0, {self.rate / 2}) Hz")

    @classmethod
    def realistic(cls, rate: float = 200.0) -> SensorModel:
        """What a recorded log has (the crossplant campaign's sensor distribution, towards
        its worse end, and an automotive MEMS part's scale tolerance): accelerometer noise
        0.2 m/s², bias 0.1 m/s², scale error 2 % and band-limited body vibration of 2 m/s² rms
        in 10–25 Hz on each axis; gyro noise 0.005 rad/s, bias 0.005 rad/s, scale error 1 %,
        quantised to 0.005 rad/s; wheel speeds quantised to 0.05 rad/s."""
        return cls(rate=rate, accel_noise=0.2, accel_bias=0.1, accel_vibration=2.0,
                   gyro_noise=0.005, gyro_bias=0.005, gyro_quant=0.005,
                   wheel_speed_quant=0.05, accel_scale_sd=0.02, gyro_scale_sd=0.01)

    @classmethod
    def ideal(cls, rate: float = 200.0) -> SensorModel:
        """Noise-free, bias-free, unquantised sensors (for physics tests)."""
        return cls(rate=rate, wheel_speed_noise=0.0, torque_noise=0.0, accel_noise=0.0,
                   accel_bias=0.0, gyro_noise=0.0, gyro_bias=0.0, steering_quant=0.0)

    def apply(self, log: pd.DataFrame, steering_ratio: float,
              rng: np.random.Generator) -> pd.DataFrame:
        """Return a copy of ``log`` with measured channels corrupted; ``ref_`` columns untouched.

        Draw order is fixed (biases, then noise per group in column order, then the
        vibration), so a seeded generator gives bit-for-bit identical logs (and a model
        without vibration the logs it gave before it had one).
        """
        out = log.copy()
        n = len(out)
        groups = (
            ([f"omega_{c}" for c in CORNERS], 0.0, self.wheel_speed_noise, self.wheel_speed_quant),
            ([f"torque_{c}" for c in CORNERS], 0.0, self.torque_noise, self.torque_quant),
            (["ax", "ay", "az"], self.accel_bias, self.accel_noise, self.accel_quant),
            (["yaw_rate", "roll_rate", "pitch_rate"], self.gyro_bias, self.gyro_noise,
             self.gyro_quant),
        )
        biases = [rng.normal(0.0, b, size=len(cols)) if b > 0 else np.zeros(len(cols))
                  for cols, b, _, _ in groups]
        noises = [rng.normal(0.0, noise, size=(n, len(cols))) if noise > 0
                  else np.zeros((n, len(cols))) for cols, _, noise, _ in groups]
        vibration = (self._vibration(n, rng) if self.accel_vibration > 0
                     else np.zeros((n, 3)))
        scales = {"ax": self.accel_scale_sd, "yaw_rate": self.gyro_scale_sd}
        for (cols, _, _, quant), bias, noise in zip(groups, biases, noises, strict=True):
            values = out[cols].to_numpy()
            sd = scales.get(cols[0], 0.0)
            if sd > 0:  # drawn last, so a model without scale errors keeps its logs
                values = values * (1.0 + rng.normal(0.0, sd, size=len(cols)))
            values = values + bias + noise
            if cols[0] == "ax":
                values = values + vibration
            if quant > 0:
                values = np.round(values / quant) * quant
            out[cols] = values
        swa = out["steering_wheel_angle"].to_numpy()
        if self.steering_quant > 0:
            q = self.steering_quant
            out["steering_wheel_angle"] = np.round(swa / q) * q
            for c in ("delta_fl", "delta_fr"):
                out[c] = np.round(out[c].to_numpy() * steering_ratio / q) * q / steering_ratio
        return out

    def _vibration(self, n: int, rng: np.random.Generator) -> np.ndarray:
        """(n, 3) band-limited noise of ``accel_vibration`` rms per axis: white noise through a
        4th-order Butterworth band-pass of ``vibration_low_hz``–``vibration_high_hz``,
        scaled to the rms over the run."""
        from scipy.signal import butter, sosfilt

        sos = butter(4, [self.vibration_low_hz, self.vibration_high_hz], btype="bandpass",
                     fs=self.rate, output="sos")
        v = sosfilt(sos, rng.normal(0.0, 1.0, size=(n, 3)), axis=0)
        rms = np.sqrt(np.mean(v * v, axis=0))
        return np.asarray(v * (self.accel_vibration / np.where(rms > 0, rms, 1.0)))
