"""Build :class:`~.corner.CornerVelocityInput` from a drive log and the force stage's output.

Measured channels only (never ``ref_``). The kinematic acceleration of each
wheel centre in its tire frame (001 text after eq. (21)):

1. rotate the IMU specific force to the road plane with the force stage's body
   angles (:func:`vestim.models.kinematics.road_specific_force`); grade and
   bank are not removed (they stay as a slowly varying bias, as in 000/001);
2. transport it to the corners, a_x,i = f_x − ṙ y_i − r² x_i, a_y,i = f_y + ṙ x_i − r² y_i
   (:func:`vestim.models.kinematics.corner_accelerations`), ṙ by a backward difference
   of the gyro (its noise integrates back to the yaw-rate noise times the lever arm);
3. project on the tire axes with the road-wheel angles
   (:func:`vestim.models.kinematics.to_tire_frame`).
"""

from __future__ import annotations

import numpy as np
import pandas as pd

from vestim.constants import CORNERS, G
from vestim.errors import LogFormatError
from vestim.estimators.velocity.corner import CornerVelocityInput
from vestim.io.log import road_wheel_angles
from vestim.io.vehicle import Vehicle
from vestim.models.kinematics import (
    corner_accelerations,
    corner_positions,
    road_specific_force,
    to_tire_frame,
    yaw_acceleration_kernel,
)

REQUIRED = ("t", *[f"omega_{c}" for c in CORNERS], "ax", "ay", "yaw_rate")
FORCE_COLUMNS = (*[f"mu_x_{c}" for c in CORNERS], "roll", "pitch")


def _col(df: pd.DataFrame, name: str, default: float | None = None) -> np.ndarray:
    if name in df.columns:
        return np.ascontiguousarray(df[name].to_numpy(dtype=float))
    if default is None:
        raise LogFormatError(f"column {name!r} is missing")
    return np.full(len(df), default)


def yaw_acceleration(t: np.ndarray, yaw_rate: np.ndarray) -> np.ndarray:
    """Backward difference ṙ_k = (r_k − r_{k−1})/(t_k − t_{k−1}), 0 at the first sample, rad/s²
    (:func:`~vestim.models.kinematics.yaw_acceleration_kernel`)."""
    out = np.empty(len(yaw_rate))
    yaw_acceleration_kernel(np.ascontiguousarray(t, dtype=float),
                            np.ascontiguousarray(yaw_rate, dtype=float), np.array([np.nan, 0.0]),
                            out)
    return out


def corner_inputs(log: pd.DataFrame, forces: pd.DataFrame, vehicle: Vehicle,
                  high_slip_hint: np.ndarray | None = None) -> CornerVelocityInput:
    """Corner-observer inputs from a log and :meth:`ForceEstimator.run`'s output on it.

    Args:
        log: drive log (measured channels ``t``, ``omega_*``, ``ax``, ``ay``, ``yaw_rate``,
            optional ``az`` (default g), steering ``delta_fl``/``delta_fr``, ``delta`` or
            ``steering_wheel_angle``).
        forces: the force stage's frame (``mu_x_*``, ``mu_y_*`` if present, ``roll``, ``pitch``),
            row-aligned with ``log``.
        vehicle: the vehicle file (geometry and steering ratio).
        high_slip_hint: optional (n, 4) bool flags passed through.
    """
    missing = [c for c in REQUIRED if c not in log.columns]
    if missing:
        raise LogFormatError(f"the corner velocity observers need column(s) {', '.join(missing)} "
                             "in the log (see docs/format.md)")
    missing = [c for c in FORCE_COLUMNS if c not in forces.columns]
    if missing:
        raise LogFormatError(f"the force-stage frame lacks {', '.join(missing)}; pass the output "
                             "of ForceEstimator.run(log)")
    if len(forces) != len(log):
        raise LogFormatError(f"forces has {len(forces)} rows, the log {len(log)}; they must align")
    t = _col(log, "t")
    r = _col(log, "yaw_rate")
    f_x, f_y, _ = road_specific_force(_col(log, "ax"), _col(log, "ay"), _col(log, "az", G),
                                      _col(forces, "roll"), _col(forces, "pitch"))
    xw, yw = corner_positions(vehicle)
    ax_i, ay_i = corner_accelerations(f_x, f_y, r, yaw_acceleration(t, r), xw, yw)
    delta = np.zeros((len(log), 4))
    delta[:, :2] = road_wheel_angles(log, vehicle.body.steering_ratio)
    a_xt, a_yt = to_tire_frame(ax_i, ay_i, delta)
    omega = log[[f"omega_{c}" for c in CORNERS]].to_numpy(dtype=float)
    mu_x = forces[[f"mu_x_{c}" for c in CORNERS]].to_numpy(dtype=float)
    mu_y_cols = [f"mu_y_{c}" for c in CORNERS]
    mu_y = (forces[mu_y_cols].to_numpy(dtype=float) if set(mu_y_cols) <= set(forces.columns)
            else np.full((len(log), 4), np.nan))
    hint = np.zeros((len(log), 4), dtype=bool) if high_slip_hint is None else high_slip_hint
    return CornerVelocityInput(t=t, omega=omega, mu_x=mu_x, a_xt=a_xt, delta=delta, yaw_rate=r,
                               mu_y=mu_y, a_yt=a_yt, high_slip_hint=hint)
