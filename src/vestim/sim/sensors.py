"""Sensor models: sampling, noise, bias and quantisation of the measured channels.

Defaults follow the papers and automotive-grade parts: wheel-speed variance
0.18 (rad/s)² and wheel-torque variance 32 (N m)² (000 Sec. IV-A); a MEMS IMU of
the airbag/ESC class (accelerometer noise 0.05 m/s², bias 0.05 m/s² one-sigma
per run; gyro noise 0.003 rad/s, bias 0.002 rad/s per run); steering-wheel angle
quantised to 0.1°. Biases are drawn once per run from the seeded generator.
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

    def __post_init__(self) -> None:
        for name, value in self.__dict__.items():
            if not math.isfinite(value) or value < 0:
                raise ValueError(f"SensorModel.{name} = {value} must be finite and >= 0")
        if self.rate <= 0:
            raise ValueError("SensorModel.rate must be > 0")

    @classmethod
    def ideal(cls, rate: float = 200.0) -> SensorModel:
        """Noise-free, bias-free, unquantised sensors (for physics tests)."""
        return cls(rate=rate, wheel_speed_noise=0.0, torque_noise=0.0, accel_noise=0.0,
                   accel_bias=0.0, gyro_noise=0.0, gyro_bias=0.0, steering_quant=0.0)

    def apply(self, log: pd.DataFrame, steering_ratio: float,
              rng: np.random.Generator) -> pd.DataFrame:
        """Return a copy of ``log`` with measured channels corrupted; ``ref_`` columns untouched.

        Draw order is fixed (biases, then noise per group in column order), so a
        seeded generator gives bit-for-bit identical logs.
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
        for (cols, _, noise, quant), bias in zip(groups, biases, strict=True):
            values = out[cols].to_numpy() + bias
            if noise > 0:
                values = values + rng.normal(0.0, noise, size=(n, len(cols)))
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
