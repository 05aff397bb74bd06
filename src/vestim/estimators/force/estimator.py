"""The force stage of the corner-based structure (001 Fig. 1): F_x, F_y, F_z per corner.

:class:`ForceEstimator` chains, per sample: body attitude → normal loads →
longitudinal forces (UKF, PID, UIO or naive) → lateral forces (UKF), and
writes the spec's estimated channels ``fx_*``, ``fy_*``, ``fz_*``,
``mu_x_*`` = F_x/F_z, ``mu_y_*`` = F_y/F_z, ``sigma_fx_*`` (UKFs only),
``sigma_fy_*``, and the body angles ``roll``, ``pitch``.

``run(log)`` processes a whole log; ``step(sample)`` one sample. Both advance
the same compiled kernels on the same state, so a log fed sample by sample
gives exactly the batch result. Only measured channels are read — never
``ref_`` columns.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass, field

import numpy as np
import pandas as pd

from vestim.constants import CORNERS, G
from vestim.errors import LogFormatError
from vestim.estimators.force import lateral as lat
from vestim.estimators.force import longitudinal as lon
from vestim.estimators.force import normal as nrm
from vestim.filters.ukf import ukf_weights
from vestim.io.log import road_wheel_angles
from vestim.io.vehicle import Vehicle

REQUIRED = ("t", *[f"omega_{c}" for c in CORNERS], *[f"torque_{c}" for c in CORNERS], "ax", "ay",
            "yaw_rate")


@dataclass(frozen=True)
class ForceConfig:
    """Choice of methods and their parameters; defaults are the project's (no per-maneuver tuning).

    Attributes:
        longitudinal: "ukf" | "ukf_rw" | "pid" | "uio" | "naive".
        normal: "static" | "dynamic" elastic load transfer (see :mod:`.normal`).
        roll_gain, pitch_gain: correction gains L_φ, L_θ of the attitude filter, 1/s.
    """

    longitudinal: str = "ukf"
    normal: str = "dynamic"
    ukf: lon.UKFParams = field(default_factory=lon.UKFParams)
    pid: lon.PIDParams = field(default_factory=lon.PIDParams)
    uio: lon.UIOParams = field(default_factory=lon.UIOParams)
    lateral: lat.LateralParams = field(default_factory=lat.LateralParams)
    roll_gain: float = 2.0
    pitch_gain: float = 2.0

    def __post_init__(self) -> None:
        if self.longitudinal not in lon.METHODS:
            raise ValueError(f"longitudinal force method {self.longitudinal!r}: use one of "
                             f"{', '.join(lon.METHODS)}")
        if self.normal not in nrm.MODES:
            raise ValueError(f"normal-load mode {self.normal!r}: use one of {', '.join(nrm.MODES)}")


@dataclass
class Inputs:
    """Measured channels of a chunk as contiguous float arrays."""

    t: np.ndarray
    omega: np.ndarray
    torque: np.ndarray
    ax: np.ndarray
    ay: np.ndarray
    az: np.ndarray
    yaw_rate: np.ndarray
    roll_rate: np.ndarray
    pitch_rate: np.ndarray
    delta: np.ndarray  # (n, 4), rear wheels 0


def _column(log: pd.DataFrame, name: str, default: float) -> np.ndarray:
    if name in log.columns:
        return np.ascontiguousarray(log[name].to_numpy(dtype=float))
    return np.full(len(log), default)


def inputs_from_log(log: pd.DataFrame, vehicle: Vehicle) -> Inputs:
    """Extract and check the measured channels the force stage needs (never ``ref_``)."""
    missing = [c for c in REQUIRED if c not in log.columns]
    if missing:
        raise LogFormatError(f"the force estimators need column(s) {', '.join(missing)}; "
                             "add them to the log (see shared/spec/log-format.md)")
    front = road_wheel_angles(log, vehicle.body.steering_ratio)
    delta = np.zeros((len(log), 4))
    delta[:, :2] = front
    return Inputs(
        t=np.ascontiguousarray(log["t"].to_numpy(dtype=float)),
        omega=np.ascontiguousarray(log[[f"omega_{c}" for c in CORNERS]].to_numpy(dtype=float)),
        torque=np.ascontiguousarray(log[[f"torque_{c}" for c in CORNERS]].to_numpy(dtype=float)),
        ax=_column(log, "ax", 0.0), ay=_column(log, "ay", 0.0), az=_column(log, "az", G),
        yaw_rate=_column(log, "yaw_rate", 0.0), roll_rate=_column(log, "roll_rate", np.nan),
        pitch_rate=_column(log, "pitch_rate", np.nan), delta=delta,
    )


def force_columns(t: np.ndarray, res: Mapping[str, np.ndarray]) -> dict[str, np.ndarray]:
    """Spec columns of the force stage from :meth:`ForceEstimator.advance`'s result.

    ``mu_x_*``/``mu_y_*`` are 0 where F_z ≤ 1 N (a lifted wheel); ``sigma_fx_*`` only
    for methods that have one.
    """
    cols: dict[str, np.ndarray] = {"t": t}
    fz_all = res["fz"]
    for i, c in enumerate(CORNERS):
        fz, fx, fy = fz_all[:, i], res["fx"][:, i], res["fy"][:, i]
        cols[f"fx_{c}"] = fx
        cols[f"fy_{c}"] = fy
        cols[f"fz_{c}"] = fz
        with np.errstate(divide="ignore", invalid="ignore"):
            cols[f"mu_x_{c}"] = np.where(fz > 1.0, fx / fz, 0.0)
            cols[f"mu_y_{c}"] = np.where(fz > 1.0, fy / fz, 0.0)
        if not np.all(np.isnan(res["sigma_fx"][:, i])):
            cols[f"sigma_fx_{c}"] = res["sigma_fx"][:, i]
        cols[f"sigma_fy_{c}"] = res["sigma_fy"][:, i]
    cols["roll"] = res["roll"]
    cols["pitch"] = res["pitch"]
    return cols


class ForceEstimator:
    """Longitudinal, lateral and normal tire forces per corner (online or batch).

    Args:
        vehicle: the vehicle file (uses [vehicle], [tire]; [suspension] and
            [aerodynamics] with their defaults for load transfer and drag).
        config: methods and parameters.
    """

    def __init__(self, vehicle: Vehicle, config: ForceConfig | None = None) -> None:
        self.vehicle = vehicle
        self.config = config or ForceConfig()
        b, s = vehicle.body, vehicle.suspension
        self._c_roll = vehicle.body.mass * (b.cg_height - b.roll_center_height) / s.roll_stiffness
        self._c_pitch = -b.mass * (b.cg_height - s.pitch_center_height) / s.pitch_stiffness
        self._xw = np.array([b.lf, b.lf, -b.lr, -b.lr])
        self._yw = 0.5 * np.array([b.track_f, -b.track_f, b.track_r, -b.track_r])
        self._w4, self._c4, self._tau4 = ukf_weights(4)
        lp = self.config.lateral
        self._q_lat = np.array([lp.q_force, lp.q_force, lp.q_split, lp.q_yaw])
        self._r_lat = np.array([(b.mass * lp.sigma_ax) ** 2, (b.mass * lp.sigma_ay) ** 2,
                                lp.sigma_yaw**2, lp.sigma_split**2])
        a = vehicle.aerodynamics
        self._drag_coef = 0.5 * a.air_density * a.drag_area
        self.reset()

    def reset(self) -> None:
        """Forget all filter states (the next sample initialises them)."""
        cfg = self.config
        self._lon = lon.LongitudinalEstimator(self.vehicle, cfg.longitudinal, cfg.ukf, cfg.pid,
                                              cfg.uio)
        self._att = np.zeros(4)
        self._lat_x = np.zeros(lat.N_X)
        self._lat_P = np.zeros((lat.N_X, lat.N_X))
        self._lat_state = np.zeros(10)

    def advance(self, u: Inputs) -> dict[str, np.ndarray]:
        """Process a chunk of measured inputs; arrays of forces (n, 4), angles and road-frame
        specific force (n,). State carries over to the next call."""
        n = u.t.shape[0]
        b = self.vehicle.body
        cfg = self.config
        roll = np.empty(n)
        pitch = np.empty(n)
        nrm.attitude_kernel(u.t, u.ax, u.ay, u.roll_rate, u.pitch_rate, cfg.roll_gain,
                            cfg.pitch_gain, self._c_roll, self._c_pitch, self._att, roll, pitch)
        f_x, f_y, f_z = nrm.road_specific_force(u.ax, u.ay, u.az, roll, pitch)
        fz = nrm.normal_loads(f_x, f_y, f_z, roll, pitch, u.roll_rate, u.pitch_rate,
                              self.vehicle, cfg.normal)
        # Rolling resistance acts on the wheel as a moment f·R·F_z (the ground force
        # of a free-rolling tire is −f·F_z); 000 eq. (1) omits it, which biases F_x
        # by f·F_z ≈ 65 N per SUV corner. The estimators see the effective torque.
        rr = self.vehicle.aerodynamics.rolling_resistance * b.wheel_radius * fz
        # The moment fades out below |ω| = 3 rad/s (1 m/s): a sharper switch would
        # flip with the wheel-speed noise (σ 0.42 rad/s) at standstill.
        torque = np.ascontiguousarray(u.torque - rr * np.clip(u.omega / 3.0, -1.0, 1.0))
        fx, sig_fx = self._lon.advance(u.t, u.omega, torque)
        drag = self._drag_coef * (b.wheel_radius * u.omega.mean(axis=1)) ** 2
        fy = np.empty((n, 4))
        sig_fy = np.empty((n, 4))
        lp = cfg.lateral
        weights = lat.split_weights(fz, u.omega, u.torque, u.yaw_rate, b.wheel_radius, self._yw,
                                    lp.load_exponent, lp.slip_scale)
        lat.lateral_kernel(u.t, fx, u.delta, weights, f_x, f_y, u.yaw_rate, drag, b.mass,
                           b.yaw_inertia, self._xw, self._yw, self._q_lat, self._r_lat,
                           self._w4, self._c4, self._tau4, self._lat_x, self._lat_P,
                           self._lat_state, fy, sig_fy)
        return {"fx": fx, "sigma_fx": sig_fx, "fy": fy, "sigma_fy": sig_fy, "fz": fz,
                "roll": roll, "pitch": pitch, "f_x": f_x, "f_y": f_y, "f_z": f_z}

    def run(self, log: pd.DataFrame) -> pd.DataFrame:
        """Estimate forces over a whole log (state reset first). Returns the estimated channels."""
        self.reset()
        u = inputs_from_log(log, self.vehicle)
        return pd.DataFrame(force_columns(u.t, self.advance(u)))

    def step(self, sample: Mapping[str, float]) -> dict[str, float]:
        """Advance by one sample (a mapping with the log's column names); return that row.

        Builds the one-sample input arrays directly (no DataFrame), so a call costs
        tens of microseconds, dominated by the kernels' dispatch.
        """
        u = self._inputs_from_sample(sample)
        return {k: float(v[0]) for k, v in force_columns(u.t, self.advance(u)).items()}

    def _inputs_from_sample(self, sample: Mapping[str, float]) -> Inputs:
        missing = [c for c in REQUIRED if c not in sample]
        if missing:
            raise LogFormatError(f"the force estimators need channel(s) {', '.join(missing)} "
                                 "in every sample")
        if "delta_fl" in sample and "delta_fr" in sample:
            front = (sample["delta_fl"], sample["delta_fr"])
        elif "delta" in sample:
            front = (sample["delta"], sample["delta"])
        elif "steering_wheel_angle" in sample:
            d = sample["steering_wheel_angle"] / self.vehicle.body.steering_ratio
            front = (d, d)
        else:
            raise LogFormatError("no steering channel: give delta_fl and delta_fr, delta, or "
                                 "steering_wheel_angle")

        def one(name: str, default: float) -> np.ndarray:
            return np.array([float(sample.get(name, default))])

        return Inputs(
            t=one("t", np.nan),
            omega=np.array([[float(sample[f"omega_{c}"]) for c in CORNERS]]),
            torque=np.array([[float(sample[f"torque_{c}"]) for c in CORNERS]]),
            ax=one("ax", 0.0), ay=one("ay", 0.0), az=one("az", G), yaw_rate=one("yaw_rate", 0.0),
            roll_rate=one("roll_rate", np.nan), pitch_rate=one("pitch_rate", np.nan),
            delta=np.array([[float(front[0]), float(front[1]), 0.0, 0.0]]),
        )
