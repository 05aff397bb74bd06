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

Missing channels (``shared/spec/log-format.md``; the gap of 001 Sec. VI):

* no ``torque_*`` (all four absent; a partial set is an error): the net wheel
  torques are reconstructed from the chassis equation and the drivetrain / brake
  balance (:mod:`vestim.models.chassis`) and then go through the same
  longitudinal estimator, so F_x,i = (T_i − I_w ω̇_i)/R − f F_z,i as with
  measured torques. :attr:`ForceEstimator.torque_source` says "chassis".
* no ``roll_rate`` / ``pitch_rate``: the attitude is the quasi-static roll and
  pitch from a_y and a_x (:func:`.normal.attitude_kernel`), and the dynamic load
  transfer uses the quasi-static elastic moments (:func:`.normal.normal_loads`):
  the suspension's lag and overshoot and the damper moments are lost.
* no ``az``: the road-normal specific force is taken as g (level road, no heave;
  :func:`vestim.models.kinematics.level_road_az`): road undulations and heave are lost, and a
  grade or bank γ reduces the true value by the factor cos γ (0.1 % at 5 %).
"""

from __future__ import annotations

from collections.abc import Iterable, Mapping
from dataclasses import dataclass, field

import numpy as np
import pandas as pd
from numba import njit

from vestim.constants import CORNERS
from vestim.errors import LogFormatError
from vestim.estimators.force import lateral as lat
from vestim.estimators.force import longitudinal as lon
from vestim.estimators.force import normal as nrm
from vestim.filters.ukf import ukf_weights
from vestim.io.log import road_wheel_angles
from vestim.io.vehicle import Vehicle
from vestim.models import chassis
from vestim.models.kinematics import level_road_az, road_specific_force

TORQUES: tuple[str, ...] = tuple(f"torque_{c}" for c in CORNERS)
REQUIRED = ("t", *[f"omega_{c}" for c in CORNERS], "ax", "ay", "yaw_rate")
"""Channels the force stage cannot do without; the torques are all-or-none (see module doc)."""


@dataclass(frozen=True)
class ForceConfig:
    """Choice of methods and their parameters; defaults are the project's (no per-maneuver tuning).

    Attributes:
        longitudinal: "ukf" | "ukf_rw" | "pid" | "uio" | "naive".
        normal: "static" | "dynamic" elastic load transfer (see :mod:`.normal`).
        roll_tau: crossover time constant τ_φ of the gyro/gravity roll filter, s
            (:func:`.normal.attitude_kernel`).
        roll_slide: gravity-roll disagreement e_φ (rad) at which the roll filter's gravity
            correction is halved (a sliding car's v̇_y would otherwise read as roll).
        roll_gain: correction gain L_φ towards the quasi-static roll of a stated
            ``[suspension]``, 1/s (without one, the gyro/gravity filter of ``roll_tau``).
        roll_bias_tau: time constant τ_b of the roll filter's gyro-bias integral, s.
        pitch_gain: correction gain L_θ of the pitch filter, 1/s.
        rate_filter_hz: corner frequency of the roll and pitch acceleration differentiators
            whose I ω̇ terms enter the load transfer, Hz (:func:`.normal.attitude_kernel`).
    """

    longitudinal: str = "ukf"
    normal: str = "static"
    ukf: lon.UKFParams = field(default_factory=lon.UKFParams)
    pid: lon.PIDParams = field(default_factory=lon.PIDParams)
    uio: lon.UIOParams = field(default_factory=lon.UIOParams)
    lateral: lat.LateralParams = field(default_factory=lat.LateralParams)
    roll_tau: float = 2.0
    rate_filter_hz: float = 8.0
    roll_slide: float = 0.03
    roll_gain: float = 2.0
    roll_bias_tau: float = 20.0
    pitch_gain: float = 2.0

    def __post_init__(self) -> None:
        if self.longitudinal not in lon.METHODS:
            raise ValueError(f"longitudinal force method {self.longitudinal!r}: use one of "
                             f"{', '.join(lon.METHODS)}")
        if self.normal not in nrm.MODES:
            raise ValueError(f"normal-load mode {self.normal!r}: use one of {', '.join(nrm.MODES)}")


@dataclass
class Inputs:
    """Measured channels of a chunk as contiguous float arrays (SI units, spec names).

    A channel the log does not have is NaN (``az``, ``roll_rate``, ``pitch_rate``,
    all four ``torque`` columns) and its ``*_measured`` flag is False.
    :meth:`ForceEstimator.advance` replaces a NaN ``torque`` by the chassis-equation
    torques it used, so later stages (the reference-speed filter's slip evidence)
    see the same torques as the force stage.

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

    @property
    def sources(self) -> dict[str, str]:
        """Where each optional input comes from (see :attr:`ForceEstimator.input_sources`)."""
        return {
            "torque_source": "measured" if self.torque_measured else "chassis",
            "roll_source": "rate" if self.roll_rate_measured else "quasi_static",
            "pitch_source": "rate" if self.pitch_rate_measured else "quasi_static",
            "az_source": "measured" if self.az_measured else "level_road",
        }


def _check_torques(present: set[str] | Mapping[str, float], what: str) -> bool:
    """True if all four torques are present, False if none; else a LogFormatError naming them."""
    have = [c for c in TORQUES if c in present]
    if len(have) in (0, len(TORQUES)):
        return len(have) == len(TORQUES)
    missing = [c for c in TORQUES if c not in present]
    raise LogFormatError(
        f"the {what} has wheel torque(s) {', '.join(have)} but not {', '.join(missing)}: give "
        "all four net wheel torques (drive minus brake, N·m) or drop every torque_* column, "
        "in which case F_x comes from the chassis equation (vestim.models.chassis)")


def _column(log: pd.DataFrame, name: str, default: float) -> np.ndarray:
    if name in log.columns:
        return np.ascontiguousarray(log[name].to_numpy(dtype=float))
    return np.full(len(log), default)


def inputs_from_log(log: pd.DataFrame, vehicle: Vehicle) -> Inputs:
    """Extract and check the measured channels the force stage needs (never ``ref_``).

    Required: ``t``, ``omega_*``, ``ax``, ``ay``, ``yaw_rate`` and a steering channel.
    Optional: the four ``torque_*`` together, ``az``, ``roll_rate``, ``pitch_rate``
    (NaN in :class:`Inputs` when absent; see the module docstring for what is lost).

    Raises:
        LogFormatError: a required column is missing, or only some of the torques are there.
    """
    missing = [c for c in REQUIRED if c not in log.columns]
    if missing:
        raise LogFormatError(f"the force estimators need column(s) {', '.join(missing)}; "
                             "add them to the log (see shared/spec/log-format.md)")
    cols = set(log.columns)
    has_torque = _check_torques(cols, "log")
    front = road_wheel_angles(log, vehicle.body.steering_ratio)
    delta = np.zeros((len(log), 4))
    delta[:, :2] = front
    torque = (np.ascontiguousarray(log[list(TORQUES)].to_numpy(dtype=float)) if has_torque
              else np.full((len(log), 4), np.nan))
    return Inputs(
        t=np.ascontiguousarray(log["t"].to_numpy(dtype=float)),
        omega=np.ascontiguousarray(log[[f"omega_{c}" for c in CORNERS]].to_numpy(dtype=float)),
        torque=torque,
        ax=_column(log, "ax", 0.0), ay=_column(log, "ay", 0.0), az=_column(log, "az", np.nan),
        yaw_rate=_column(log, "yaw_rate", 0.0), roll_rate=_column(log, "roll_rate", np.nan),
        pitch_rate=_column(log, "pitch_rate", np.nan), delta=delta,
        gnss_speed=_column(log, "gnss_speed", np.nan),
        torque_measured=has_torque, az_measured="az" in cols,
        roll_rate_measured="roll_rate" in cols, pitch_rate_measured="pitch_rate" in cols,
    )


ColumnGroup = tuple[list[str], np.ndarray]
"""Spec column names and their values: (n,) for one name, (n, k) for k names."""


@njit(cache=True, error_model="numpy")
def normalised(force: np.ndarray, fz: np.ndarray) -> np.ndarray:
    """Normalised tire force F/F_z (n, 4), the papers' μ_x, μ_y; 0 where F_z ≤ 1 N (lifted)."""
    out = np.empty(force.shape)
    for k in range(force.shape[0]):
        for i in range(force.shape[1]):
            out[k, i] = force[k, i] / fz[k, i] if fz[k, i] > 1.0 else 0.0
    return out


def force_groups(res: Mapping[str, np.ndarray]) -> list[ColumnGroup]:
    """Spec channels of the force stage from :meth:`ForceEstimator.advance`'s result, grouped
    by quantity (``fx_fl … fx_rr``, ``fy_*``, ``fz_*``, ``mu_x_*``, ``mu_y_*``, ``sigma_fx_*``
    only for methods that have one, ``sigma_fy_*``, ``roll``, ``pitch``).

    ``mu_x_*``/``mu_y_*`` are 0 where F_z ≤ 1 N (a lifted wheel).
    """
    fz = res["fz"]

    def names(prefix: str) -> list[str]:
        return [f"{prefix}_{c}" for c in CORNERS]

    mu_x = normalised(res["fx"], fz)
    mu_y = normalised(res["fy"], fz)
    groups: list[ColumnGroup] = [(names("fx"), res["fx"]), (names("fy"), res["fy"]),
                                 (names("fz"), fz), (names("mu_x"), mu_x), (names("mu_y"), mu_y)]
    if not np.all(np.isnan(res["sigma_fx"])):
        groups.append((names("sigma_fx"), res["sigma_fx"]))
    groups += [(names("sigma_fy"), res["sigma_fy"]), (["roll"], res["roll"]),
               (["pitch"], res["pitch"])]
    return groups


def columns_from_groups(groups: list[ColumnGroup]) -> dict[str, np.ndarray]:
    """Flatten column groups into a name → (n,) mapping (views, no copies)."""
    cols: dict[str, np.ndarray] = {}
    for group_names, values in groups:
        if values.ndim == 1:
            cols[group_names[0]] = values
        else:
            for i, name in enumerate(group_names):
                cols[name] = values[:, i]
    return cols


def frame_from_chunks(chunks: Iterable[list[ColumnGroup]], n: int) -> pd.DataFrame:
    """One float64 DataFrame from consecutive chunks of column groups (n samples in all).

    The first chunk fixes the columns; a later chunk fills its rows of the block, and a
    column it lacks is NaN there. The block is filled as its transpose (pandas stores a
    float block as (columns, samples)), so each group is one strided copy and the frame
    is not copied again.
    """
    names: list[str] = []
    rows: dict[str, int] = {}
    block = np.empty((0, n))
    start = 0
    for groups in chunks:
        if not names:
            names = [name for g, _ in groups for name in g]
            rows = {name: j for j, name in enumerate(names)}
            block = np.empty((len(names), n))
        stop = start + groups[0][1].shape[0]
        filled = np.zeros(len(names), dtype=bool)
        for group_names, values in groups:
            j = rows.get(group_names[0])
            if j is None:  # a channel the first chunk did not have (method-dependent)
                continue
            block[j:j + len(group_names), start:stop] = values.T if values.ndim == 2 else values
            filled[j:j + len(group_names)] = True
        block[~filled, start:stop] = np.nan
        start = stop
    return pd.DataFrame(block.T, columns=names, copy=False)


def force_columns(t: np.ndarray, res: Mapping[str, np.ndarray]) -> dict[str, np.ndarray]:
    """Spec columns of the force stage (``t`` first), see :func:`force_groups`."""
    return {"t": t, **columns_from_groups(force_groups(res))}


class ForceEstimator:
    """Longitudinal, lateral and normal tire forces per corner (online or batch).

    Args:
        vehicle: the vehicle file (uses [vehicle], [tire]; [suspension] and
            [aerodynamics] with their defaults for load transfer and drag;
            [powertrain] front_drive_share and brake_front_share for logs without
            wheel torques).
        config: methods and parameters.
    """

    def __init__(self, vehicle: Vehicle, config: ForceConfig | None = None) -> None:
        self.vehicle = vehicle
        self.config = config or ForceConfig()
        b, s = vehicle.body, vehicle.suspension
        self._c_roll = vehicle.body.mass * (b.cg_height - b.roll_center_height) / s.roll_stiffness
        self._c_pitch = -b.mass * (b.cg_height - s.pitch_center_height) / s.pitch_stiffness
        self._att_prm = np.array([self.config.roll_tau, self.config.pitch_gain, self._c_roll,
                                  self._c_pitch, b.wheel_radius, self.config.rate_filter_hz,
                                  {"fwd": 1.0, "rwd": 0.0}.get(b.drivetrain, -1.0),
                                  self.config.roll_slide,
                                  self.config.roll_gain if "suspension" in vehicle.given
                                  else 0.0, self.config.roll_bias_tau])
        self._xw = np.array([b.lf, b.lf, -b.lr, -b.lr])
        self._yw = 0.5 * np.array([b.track_f, -b.track_f, b.track_r, -b.track_r])
        self._w4, self._c4, self._tau4 = ukf_weights(4)
        lp = self.config.lateral
        self._q_lat = lat.lateral_q(lp, vehicle.tire.sigma0_y / vehicle.tire.kappa_y)
        self._r_lat = np.array([(b.mass * lp.sigma_ax) ** 2, (b.mass * lp.sigma_ay) ** 2,
                                lp.sigma_yaw**2, lp.sigma_split**2])
        a = vehicle.stated_aerodynamics
        self._drag_coef = 0.5 * a.air_density * a.drag_area
        self.rolling_resistance = vehicle.stated_aerodynamics.rolling_resistance
        self.reset()

    def reset(self) -> None:
        """Forget all filter states (the next sample initialises them)."""
        cfg = self.config
        self._lon = lon.LongitudinalEstimator(self.vehicle, cfg.longitudinal, cfg.ukf, cfg.pid,
                                              cfg.uio)
        # For logs without torques: the same method fed zero torque estimates the wheels'
        # inertial force −I_w ω̇_i/R alone (every method is linear in the torque).
        self._lon_inertia = lon.LongitudinalEstimator(self.vehicle, cfg.longitudinal, cfg.ukf,
                                                      cfg.pid, cfg.uio)
        self._att = np.zeros(9)
        self._lat_x = np.zeros(lat.N_X)
        self._lat_P = np.zeros((lat.N_X, lat.N_X))
        self._lat_state = np.zeros(lat.N_STATE)
        self._seen: dict[str, set[str]] = {}

    @property
    def input_sources(self) -> dict[str, str]:
        """Where the optional inputs came from since the last reset, for output metadata.

        Keys ``torque_source`` ("measured" | "chassis": the chassis equation of
        :mod:`vestim.models.chassis`), ``roll_source`` and ``pitch_source`` ("rate" |
        "quasi_static"), ``az_source`` ("measured" | "level_road"); a value is "mixed"
        when samples of both kinds were processed, and the dict is empty before any.
        """
        return {k: next(iter(v)) if len(v) == 1 else "mixed" for k, v in self._seen.items()}

    def note_sources(self, sources: Mapping[str, str]) -> None:
        """Record where a chunk's optional inputs came from (see :attr:`input_sources`)."""
        for key, value in sources.items():
            self._seen.setdefault(key, set()).add(value)

    @property
    def torque_source(self) -> str | None:
        """"measured", "chassis" or "mixed" since the last reset; None before any sample."""
        return self.input_sources.get("torque_source")

    def advance(self, u: Inputs) -> dict[str, np.ndarray]:
        """Process a chunk of measured inputs; state carries over to the next call.

        Returns arrays: ``fx``, ``sigma_fx``, ``fy``, ``sigma_fy``, ``fz`` (n, 4) in N;
        ``roll``, ``pitch`` (n,) in rad; road-plane specific force ``f_x``, ``f_y``,
        ``f_z`` (n,) in m/s²; ``torque`` (n, 4) in N m, the net wheel torques used
        (measured, or from the chassis equation, in which case ``u.torque`` is set to
        them too).
        """
        n = u.t.shape[0]
        b = self.vehicle.body
        cfg = self.config
        self.note_sources(u.sources)
        roll, pitch, roll_acc, pitch_acc = np.empty((4, n))
        nrm.attitude_kernel(u.t, u.ax, u.ay, u.roll_rate, u.pitch_rate, u.yaw_rate, u.omega,
                            self._att_prm, self._att, roll, pitch, roll_acc, pitch_acc)
        az = u.az if u.az_measured else level_road_az(u.ax, u.ay, roll, pitch)
        f_x, f_y, f_z = road_specific_force(u.ax, u.ay, az, roll, pitch)
        fz = nrm.normal_loads(f_x, f_y, f_z, roll, pitch, u.roll_rate, u.pitch_rate, roll_acc,
                              pitch_acc, self.vehicle, cfg.normal)
        if not u.torque_measured:
            # Equivalent net wheel torques from the chassis equation (models.chassis eq. (2)),
            # handed back in u so that later stages use the same torques. Its I_w Σω̇ term
            # comes from the same longitudinal method run on zero torque, whose output is
            # −I_w ω̇̂_i/R: the main run then subtracts the same ω̇̂_i, so a wheel spinning
            # up keeps only its share of the tire force.
            f_inertia, _ = self._lon_inertia.advance(u.t, u.omega, np.zeros_like(u.omega))
            omega_dot = -b.wheel_radius / b.wheel_inertia * f_inertia
            u.torque = np.ascontiguousarray(
                chassis.chassis_wheel_torques(f_x, f_y, u.delta[:, :2].mean(axis=1), fz,
                                              u.omega, self.vehicle, omega_dot))
        # Rolling resistance acts on the wheel as a moment f·R·F_z (the ground force
        # of a free-rolling tire is −f·F_z); 000 eq. (1) omits it, which biases F_x
        # by f·F_z ≈ 65 N per SUV corner. The estimators see the effective torque.
        # f is the vehicle file's own value; without one it is 0 (000 eq. (1)), not
        # the simulator's default (see Vehicle.stated_aerodynamics).
        # The moment fades out below |ω| = 3 rad/s (1 m/s): a sharper switch would
        # flip with the wheel-speed noise (σ 0.42 rad/s) at standstill.
        torque = chassis.torque_less_rolling_resistance(
            u.torque, u.omega, fz, self.rolling_resistance * b.wheel_radius)
        fx, sig_fx = self._lon.advance(u.t, u.omega, torque)
        drag = self._drag_coef * (b.wheel_radius * u.omega.mean(axis=1)) ** 2
        fy = np.empty((n, 4))
        sig_fy = np.empty((n, 4))
        lp = cfg.lateral
        weights = lat.split_weights(fz, u.omega, u.torque, u.yaw_rate, b.wheel_radius, self._yw,
                                    lp.load_exponent, lp.slip_scale)
        speed = b.wheel_radius * np.median(u.omega, axis=1)
        lat.lateral_kernel(u.t, fx, u.delta, weights, f_x, f_y, u.yaw_rate, drag, fz, speed,
                           b.mass, b.yaw_inertia, self._xw, self._yw, self._q_lat, self._r_lat,
                           self._w4, self._c4, self._tau4, self._lat_x, self._lat_P,
                           self._lat_state, fy, sig_fy)
        return {"fx": fx, "sigma_fx": sig_fx, "fy": fy, "sigma_fy": sig_fy, "fz": fz,
                "roll": roll, "pitch": pitch, "f_x": f_x, "f_y": f_y, "f_z": f_z,
                "torque": u.torque}

    def run(self, log: pd.DataFrame) -> pd.DataFrame:
        """Estimate forces over a whole log (state reset first). Returns the estimated channels."""
        self.reset()
        u = inputs_from_log(log, self.vehicle)
        return frame_from_chunks([[(["t"], u.t), *force_groups(self.advance(u))]], u.t.shape[0])

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
        has_torque = _check_torques(sample, "sample")
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
            torque=(np.array([[float(sample[c]) for c in TORQUES]]) if has_torque
                    else np.full((1, 4), np.nan)),
            ax=one("ax", 0.0), ay=one("ay", 0.0), az=one("az", np.nan),
            yaw_rate=one("yaw_rate", 0.0), roll_rate=one("roll_rate", np.nan),
            pitch_rate=one("pitch_rate", np.nan),
            delta=np.array([[float(front[0]), float(front[1]), 0.0, 0.0]]),
            gnss_speed=one("gnss_speed", np.nan),
            torque_measured=has_torque, az_measured="az" in sample,
            roll_rate_measured="roll_rate" in sample, pitch_rate_measured="pitch_rate" in sample,
        )
