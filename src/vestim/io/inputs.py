"""The measured inputs of a log or of one live sample, as the estimators read them.

:func:`inputs_from_log` (a whole log or a piece of it) and :func:`inputs_from_sample` (one
sample of a live feed, a mapping of channel names) check the channels and bundle them into
:class:`Inputs`: contiguous float arrays in SI units under the spec's names
(docs/format.md, :mod:`vestim.io.channels`), never ``ref_`` columns. The force stage
(:class:`vestim.estimators.force.ForceEstimator`) and the pipeline
(:class:`vestim.pipeline.Pipeline`) both read them.

Required: ``t``, ``ay``, ``yaw_rate`` (:data:`~vestim.io.channels.MEASURED_REQUIRED`), a
steering channel and a speed: the four ``omega_*``, or one of
:data:`~vestim.io.channels.SPEED_SOURCES`. The wheel torques and the wheel speeds are each
all four or none. What the estimators do without the optional channels is in
:mod:`vestim.estimators.force.estimator` and docs/fewer-sensors.md.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any

import numpy as np
import pandas as pd

from vestim.errors import LogFormatError
from vestim.io import channels as ch
from vestim.io.log import road_wheel_angles
from vestim.io.vehicle import Vehicle

__all__ = ["Inputs", "check_speeds", "check_torques", "front_angles", "inputs_from_log",
           "inputs_from_sample", "sample_channels"]


@dataclass
class Inputs:
    """Measured channels of a chunk as contiguous float arrays (SI units, spec names).

    A channel the log does not have is NaN (``az``, ``roll_rate``, ``pitch_rate``,
    all four ``torque`` columns) and its ``*_measured`` flag is False.
    :meth:`ForceEstimator.advance <vestim.estimators.force.ForceEstimator.advance>`
    replaces a NaN ``torque`` by the chassis-equation torques it used, so later stages (the
    reference-speed filter's slip evidence) see the same torques as the force stage.

    Attributes:
        t: (n,) s. omega: (n, 4) rad/s. torque: (n, 4) N m, net drive minus brake.
        ax, ay, az: (n,) m/s², specific force. yaw_rate, roll_rate, pitch_rate: (n,) rad/s.
        delta: (n, 4) rad, road-wheel angles, rear wheels 0.
        gnss_speed: (n,) m/s, speed over ground where a GNSS fix falls, NaN elsewhere.
    """

    t: np.ndarray
    omega: np.ndarray
    torque: np.ndarray
    ax: np.ndarray
    ay: np.ndarray
    az: np.ndarray
    yaw_rate: np.ndarray
    roll_rate: np.ndarray
    pitch_rate: np.ndarray
    delta: np.ndarray
    gnss_speed: np.ndarray
    torque_measured: bool = True
    az_measured: bool = True
    roll_rate_measured: bool = True
    pitch_rate_measured: bool = True
    vehicle_speed: np.ndarray | None = None
    ax_measured: bool = True
    omega_measured: bool = True

    @property
    def speed_source(self) -> str:
        """"wheel_speeds", or the speed channel that stands in for them."""
        if self.omega_measured:
            return "wheel_speeds"
        return "vehicle_speed" if self.vehicle_speed is not None else "gnss_speed"

    @property
    def sources(self) -> dict[str, str]:
        """Where each optional input comes from (see :attr:`ForceEstimator.input_sources
        <vestim.estimators.force.ForceEstimator.input_sources>`).

        ``ax_source`` and ``speed_source`` are listed only where a_x or the wheel speeds are
        missing (the pipeline lists them always)."""
        out = {
            "torque_source": "measured" if self.torque_measured else "chassis",
            "roll_source": "rate" if self.roll_rate_measured else "quasi_static",
            "pitch_source": "rate" if self.pitch_rate_measured else "quasi_static",
            "az_source": "measured" if self.az_measured else "level_road",
        }
        if not self.ax_measured:
            out["ax_source"] = self.speed_source
        if not self.omega_measured:
            out["speed_source"] = self.speed_source
        return out


def check_torques(present: set[str] | Mapping[str, float], what: str) -> bool:
    """True if all four torques are present, False if none; else a LogFormatError naming them."""
    have = [c for c in ch.TORQUES if c in present]
    if len(have) in (0, len(ch.TORQUES)):
        return len(have) == len(ch.TORQUES)
    missing = [c for c in ch.TORQUES if c not in present]
    raise LogFormatError(
        f"the {what} has wheel torque(s) {', '.join(have)} but not {', '.join(missing)}: give "
        "all four net wheel torques (drive minus brake, N·m) or drop every torque_* column, "
        "in which case F_x comes from the chassis equation (vestim.models.chassis)")


def check_speeds(present: set[str] | Mapping[str, float], what: str) -> bool:
    """True if all four wheel speeds are present, False if none and a speed channel stands in;
    else a LogFormatError naming what is missing."""
    have = [c for c in ch.WHEEL_SPEEDS if c in present]
    if len(have) == len(ch.WHEEL_SPEEDS):
        return True
    if have:
        missing = [c for c in ch.WHEEL_SPEEDS if c not in present]
        raise LogFormatError(
            f"the {what} has wheel speed(s) {', '.join(have)} but not {', '.join(missing)}: "
            "give all four (rad/s) or drop every omega_* column and give gnss_speed or "
            "vehicle_speed (m/s)")
    if not any(c in present for c in ch.SPEED_SOURCES):
        raise LogFormatError(
            f"the {what} has no speed channel: give the four wheel speeds omega_fl … omega_rr "
            "(rad/s), or gnss_speed (sparse) or vehicle_speed (dense CAN vehicle speed), m/s")
    return False


def sample_channels(sample: Mapping[str, Any]) -> tuple[bool, bool, str]:
    """What one sample (a live feed's mapping of channel names) holds: whether it has the
    four wheel torques, the four wheel speeds, and its steering channel (``delta_fl`` for
    both front road-wheel angles, ``delta`` or ``steering_wheel_angle``).

    Raises:
        LogFormatError: a required channel or the steering is missing; some wheel speeds or
            torques but not all four; no speed channel at all.
    """
    missing = [c for c in ch.MEASURED_REQUIRED if c not in sample]
    if missing:
        raise LogFormatError(f"the force estimators need channel(s) {', '.join(missing)} "
                             "in every sample")
    torques = check_torques(sample, "sample")
    wheels = check_speeds(sample, "sample")
    steering = next((k for k in ("delta_fl", "delta", "steering_wheel_angle") if k in sample
                     and (k != "delta_fl" or "delta_fr" in sample)), None)
    if steering is None:
        raise LogFormatError("no steering channel: give delta_fl and delta_fr, delta, or "
                             "steering_wheel_angle")
    return torques, wheels, steering


def front_angles(sample: Mapping[str, Any], steering: str,
                 steering_ratio: float) -> tuple[float, float]:
    """The front road-wheel angles (left, right), rad, of a sample whose steering channel is
    ``steering`` (:func:`sample_channels`); a steering-wheel angle over the ratio."""
    if steering == "delta_fl":
        return float(sample["delta_fl"]), float(sample["delta_fr"])
    d = float(sample[steering])
    if steering == "steering_wheel_angle":
        d = d / steering_ratio
    return d, d


def _column(log: pd.DataFrame, name: str, default: float) -> np.ndarray:
    if name in log.columns:
        return np.ascontiguousarray(log[name].to_numpy(dtype=float))
    return np.full(len(log), default)


def inputs_from_log(log: pd.DataFrame, vehicle: Vehicle) -> Inputs:
    """Extract and check the measured channels the force stage needs (never ``ref_``).

    Required: ``t``, ``ay``, ``yaw_rate``, a steering channel and a speed (the four
    ``omega_*``, or ``vehicle_speed`` or ``gnss_speed``). Optional: ``ax``, the four
    ``torque_*`` together, ``az``, ``roll_rate``, ``pitch_rate`` (NaN in :class:`Inputs` when
    absent, ``omega`` too; what is lost without them: the module docstring of
    :mod:`vestim.estimators.force.estimator`).

    Raises:
        LogFormatError: a required column is missing, or only some of the torques or wheel
            speeds are there.
    """
    missing = [c for c in ch.MEASURED_REQUIRED if c not in log.columns]
    if missing:
        raise LogFormatError(f"the force estimators need column(s) {', '.join(missing)}; "
                             "add them to the log (see docs/format.md)")
    cols = set(log.columns)
    has_torque = check_torques(cols, "log")
    has_omega = check_speeds(cols, "log")
    front = road_wheel_angles(log, vehicle.body.steering_ratio)
    delta = np.zeros((len(log), 4))
    delta[:, :2] = front
    torque = (np.ascontiguousarray(log[list(ch.TORQUES)].to_numpy(dtype=float)) if has_torque
              else np.full((len(log), 4), np.nan))
    return Inputs(
        t=np.ascontiguousarray(log["t"].to_numpy(dtype=float)),
        omega=(np.ascontiguousarray(log[list(ch.WHEEL_SPEEDS)].to_numpy(dtype=float)) if has_omega
               else np.full((len(log), 4), np.nan)),
        torque=torque,
        ax=_column(log, "ax", np.nan), ay=_column(log, "ay", 0.0), az=_column(log, "az", np.nan),
        yaw_rate=_column(log, "yaw_rate", 0.0), roll_rate=_column(log, "roll_rate", np.nan),
        pitch_rate=_column(log, "pitch_rate", np.nan), delta=delta,
        gnss_speed=_column(log, "gnss_speed", np.nan),
        torque_measured=has_torque, az_measured="az" in cols,
        roll_rate_measured="roll_rate" in cols, pitch_rate_measured="pitch_rate" in cols,
        vehicle_speed=(_column(log, "vehicle_speed", np.nan) if "vehicle_speed" in cols
                       else None),
        ax_measured="ax" in cols, omega_measured=has_omega,
    )



def inputs_from_sample(sample: Mapping[str, float], vehicle: Vehicle) -> Inputs:
    """The measured channels of one sample (a mapping of the log's column names) as
    one-row :class:`Inputs`, built directly (no DataFrame); checked as
    :func:`sample_channels` does, absent channels as in :func:`inputs_from_log`.

    Raises:
        LogFormatError: as :func:`sample_channels`.
    """
    has_torque, has_omega, steering = sample_channels(sample)
    front = front_angles(sample, steering, vehicle.body.steering_ratio)

    def one(name: str, default: float) -> np.ndarray:
        return np.array([float(sample.get(name, default))])

    return Inputs(
        t=one("t", np.nan),
        omega=(np.array([[float(sample[c]) for c in ch.WHEEL_SPEEDS]]) if has_omega
               else np.full((1, 4), np.nan)),
        torque=(np.array([[float(sample[c]) for c in ch.TORQUES]]) if has_torque
                else np.full((1, 4), np.nan)),
        ax=one("ax", np.nan), ay=one("ay", 0.0), az=one("az", np.nan),
        yaw_rate=one("yaw_rate", 0.0), roll_rate=one("roll_rate", np.nan),
        pitch_rate=one("pitch_rate", np.nan),
        delta=np.array([[float(front[0]), float(front[1]), 0.0, 0.0]]),
        gnss_speed=one("gnss_speed", np.nan),
        torque_measured=has_torque, az_measured="az" in sample,
        roll_rate_measured="roll_rate" in sample, pitch_rate_measured="pitch_rate" in sample,
        vehicle_speed=(one("vehicle_speed", np.nan) if "vehicle_speed" in sample
                       else None),
        ax_measured="ax" in sample, omega_measured=has_omega,
    )
