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

Missing channels (docs/format.md; the gap of 001 Sec. VI):

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
* no ``ax`` (OBD logs): a_x is the derivative of a reference wheel speed, low-passed
  (:func:`wheel_reference_speed`: the free-rolling wheels while accelerating, the fastest
  wheel while decelerating), or without wheel speeds of ``vehicle_speed`` / ``gnss_speed``
  (:func:`speed_derivative`); it is the road-plane f_x itself (not rotated by the pitch).
  :attr:`ForceEstimator.input_sources` says ``ax_source`` = "wheel_speeds" (or the speed
  channel's name). It is v̇_x, not a specific force (the velocity filter then leaves r v_y
  out of its prediction, see :meth:`~vestim.estimators.velocity.reference.ReferenceFilter.
  advance`). What degrades: it holds no grade (g sin γ) and lags by about 0.1 s (0.5 s
  from GNSS fixes), so F_x from the chassis equation (logs without torques) carries a
  grade as a force, and the reference filter's accelerometer slip evidence |R ω̇ − a_x|
  compares the wheels with themselves (a spin of the free-rolling axle, or of all four
  wheels, is no longer seen by it; the μ_x evidence remains). docs/fewer-sensors.md has
  the figures.
* no ``omega_*`` (all four absent; a partial set is an error) but ``vehicle_speed`` (dense)
  or ``gnss_speed`` (sparse): the force stage's speed references (attitude, drag, lateral
  split, the pipeline's stiffness regression) use that speed (``gnss_speed`` held between
  fixes and advanced by a_x, :func:`speed_hold`) on all four wheels, and F_x is the chassis
  equation's (or the measured torques') share without the wheels' inertia. Per-corner F_x
  (and μ_x, σ_Fx) cannot be given: they are left out of the output (``speed_source`` names
  the channel used, :data:`WHEEL_OUTPUTS` lists what is lost).
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass, field
from typing import NamedTuple

import numpy as np
import pandas as pd
from numba import njit

from vestim.constants import CORNERS, G
from vestim.estimators.force import lateral as lat
from vestim.estimators.force import longitudinal as lon
from vestim.estimators.force import normal as nrm
from vestim.filters.lowpass import (
    LowpassParams,
    LowpassState,
    new_lowpass_state,
    noise_adaptive_lowpass,
    noise_variance,
)
from vestim.filters.ukf import ukf_weights
from vestim.io.frames import ColumnGroup, columns_from_groups, frame_from_chunks
from vestim.io.inputs import Inputs, inputs_from_log, inputs_from_sample
from vestim.io.vehicle import Vehicle
from vestim.models import chassis
from vestim.models.kinematics import level_road_az, road_specific_force
from vestim.params import check_ranges, pack

ACCELEROMETERS: tuple[str, ...] = ("specific_force", "gravity_free")
"""What a log's ``ax``, ``ay``, ``az`` may hold (:attr:`ForceConfig.accelerometer`)."""
WHEEL_OUTPUTS: tuple[str, ...] = ("fx", "mu_x", "sigma_fx")
"""Per-corner force outputs (``<name>_fl`` …) that need wheel speeds (left out without them)."""
AX_TAU = (0.05, 0.05)
"""Low-pass time constants (speed, derivative), s, of a_x from a dense speed: with the
wheel-speed noise σ_ω R ≈ 0.02 m/s at 200 Hz the derivative's noise is ≈ 0.05 m/s²; delay
≈ 0.1 s."""
AX_BRAKING = 0.0
"""Deceleration (m/s²) beyond which a_x from the wheel speeds follows the fastest wheel
(every wheel may be braked) rather than the free-rolling ones. 0: on the crossplant logs
without ax, 0.5 m/s² raised the v_x RMSE of the brake logs x03/x07 from 0.085/0.078 to
0.125/0.101 m/s and changed no other log by more than 0.005 m/s."""
AX_TAU_SPARSE = (0.0, 0.5)
"""The same for ``gnss_speed`` fixes (each fix differenced with the previous one, then
low-passed over 0.5 s: 0.05 m/s fix noise at 10 Hz gives ≈ 0.2 m/s²)."""


@dataclass(frozen=True)
class LoadFilterConfig:
    """The low-pass of the specific force that the force stage uses (normal loads, chassis
    torques, lateral-force UKF; :mod:`vestim.filters.lowpass`): its bandwidth follows the
    log's own accelerometer noise, measured above ``f_noise``.

    Attributes:
        f_ref: bandwidth for ``sigma_ref`` of noise at 200 Hz, Hz.
        f_max: the most bandwidth, Hz.
        f_min: the least bandwidth, Hz.
        sigma_ref: noise per sample at which ``f_max`` holds, m/s².
        f_noise: edge above which the accelerometer signal is taken to be noise, Hz.
        tau_noise: averaging time of the noise's mean square, s.
        enabled: False passes the specific force through unfiltered and leaves the lateral
            UKF's measurement noise at its configured values.
    """

    f_ref: float = 12.0
    f_max: float = 20.0
    f_min: float = 1.0
    sigma_ref: float = 0.1
    f_noise: float = 8.0
    tau_noise: float = 1.0
    enabled: bool = True

    def __post_init__(self) -> None:
        check_ranges(self, "force_params.load_filter",
                     positive=("f_ref", "f_max", "f_min", "sigma_ref", "f_noise", "tau_noise"))
        if self.f_min > self.f_max:
            raise ValueError(f"force_params.load_filter f_min = {self.f_min} Hz is above f_max "
                             f"= {self.f_max} Hz: give f_min ≤ f_max")


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
        roll_gradient_prior, roll_gradient_sd: prior mean and one-sigma of the roll gradient
            dφ/da_y that a log without a roll rate and a vehicle file without a
            ``[suspension]`` table (or a calibrated ``roll_gradient``) identifies online,
            rad per m/s² (:func:`.normal.attitude_kernel`). 5 ± 5°/g: 0°/g is an INS's
            gravity-free acceleration or a race car, 10°/g a soft passenger car. The
            gravity of roll is 0–17 % of a_y over that range, so no fixed value is right for
            every car (the file's default suspension said 6–9°/g, and an INS log then read
            11–14 % low).
        roll_id_tau: forgetting time of that identification, s.
        roll_id_noise: one-sigma of the sideslip acceleration v̇_y/g that the identification
            treats as noise, rad, with a correlation time of 0.5 s.
        accelerometer: what ``ax``, ``ay``, ``az`` hold: "specific_force" (the format's
            body-fixed specific force, gravity through roll and pitch included) or
            "gravity_free" (an INS's levelled kinematic accelerations: the attitude's
            gravity is not removed). A log declares it in its metadata (``accelerometer``,
            or a channel map's ``[imu] acceleration``), which :meth:`Pipeline.run
            <vestim.pipeline.Pipeline.run>` follows.
    """

    longitudinal: str = "ukf"
    normal: str = "static"
    ukf: lon.UKFParams = field(default_factory=lon.UKFParams)
    pid: lon.PIDParams = field(default_factory=lon.PIDParams)
    uio: lon.UIOParams = field(default_factory=lon.UIOParams)
    lateral: lat.LateralParams = field(default_factory=lat.LateralParams)
    load_filter: LoadFilterConfig = field(default_factory=LoadFilterConfig)
    roll_tau: float = 2.0
    rate_filter_hz: float = 8.0
    roll_slide: float = 0.03
    roll_gain: float = 2.0
    roll_bias_tau: float = 20.0
    pitch_gain: float = 2.0
    roll_gradient_prior: float = 0.0089
    roll_gradient_sd: float = 0.0089
    roll_id_tau: float = 120.0
    roll_id_noise: float = 0.1
    accelerometer: str = "specific_force"

    def __post_init__(self) -> None:
        if self.accelerometer not in ACCELEROMETERS:
            raise ValueError(f"force_params accelerometer = {self.accelerometer!r}: use one of "
                             f"{', '.join(ACCELEROMETERS)}")
        if self.longitudinal not in lon.METHODS:
            raise ValueError(f"longitudinal force method {self.longitudinal!r}: use one of "
                             f"{', '.join(lon.METHODS)}")
        if self.normal not in nrm.MODES:
            raise ValueError(f"normal-load mode {self.normal!r}: use one of {', '.join(nrm.MODES)}")
        check_ranges(self, "force_params", positive=("roll_tau", "rate_filter_hz", "roll_slide",
                                                     "roll_gain", "roll_bias_tau", "pitch_gain",
                                                     "roll_gradient_sd", "roll_id_tau",
                                                     "roll_id_noise"))
        if not math.isfinite(self.roll_gradient_prior):
            raise ValueError(f"force_params roll_gradient_prior = {self.roll_gradient_prior} "
                             "must be finite")


class SpeedDerivativeState(NamedTuple):
    """State of :func:`speed_derivative` (in place); each field a 1-element array.

    Attributes:
        t_prev: time of the last finite speed sample, s.
        v_lp: its low-passed speed, m/s.
        rate: the derivative, m/s² (0 until the second finite sample).
        started: 1.0 once the first finite sample was seen.
    """

    t_prev: np.ndarray
    v_lp: np.ndarray
    rate: np.ndarray
    started: np.ndarray


def new_speed_derivative_state() -> SpeedDerivativeState:
    """A fresh :class:`SpeedDerivativeState` (not started)."""
    return SpeedDerivativeState(np.zeros(1), np.zeros(1), np.zeros(1), np.zeros(1))


class SpeedHoldState(NamedTuple):
    """State of :func:`speed_hold` (in place); each field a 1-element array.

    Attributes:
        speed: the held speed, m/s.
        t_prev: time of the previous sample, s.
        started: 1.0 once a sample was seen.
    """

    speed: np.ndarray
    t_prev: np.ndarray
    started: np.ndarray


def new_speed_hold_state() -> SpeedHoldState:
    """A fresh :class:`SpeedHoldState` (not started)."""
    return SpeedHoldState(np.zeros(1), np.zeros(1), np.zeros(1))


class LoadFilterState(NamedTuple):
    """State of :func:`load_specific_force`: the low-pass of each road-plane specific-force
    component and the noise measurement of the yaw gyro."""

    f_x: LowpassState
    f_y: LowpassState
    f_z: LowpassState
    yaw_rate: LowpassState


def new_load_filter_state() -> LoadFilterState:
    """A fresh :class:`LoadFilterState` (the next sample starts every filter)."""
    return LoadFilterState(new_lowpass_state(), new_lowpass_state(), new_lowpass_state(),
                           new_lowpass_state())


@njit(cache=True, error_model="numpy")
def wheel_reference_speed(t: np.ndarray, omega: np.ndarray, yaw_rate: np.ndarray,
                          yw: np.ndarray, radius: float, free: int, tau_v: float,
                          tau_a: float, state: SpeedDerivativeState,
                          out: np.ndarray) -> None:
    """a_x (n,) m/s² from the wheel speeds (n, 4) rad/s, by :func:`speed_derivative` of a
    reference speed. Each wheel's speed is brought to the CG's, R ω_i + r y_i (yaw rate r
    rad/s, lateral positions ``yw`` m); the reference is, while accelerating (or steady),
    the free-rolling wheels' (the mean of axle ``free``, 0 front, 1 rear; with ``free`` < 0,
    AWD, the slowest wheel), while decelerating (the derivative so far < 0: every wheel may
    be braked: beyond :data:`AX_BRAKING`) the fastest wheel's, as an ABS reference speed. ``state`` as
    :func:`speed_derivative`'s."""
    v = np.empty(1)
    a = np.empty(1)
    w = np.empty(4)
    for k in range(t.shape[0]):
        for i in range(4):
            w[i] = radius * omega[k, i] + yaw_rate[k] * yw[i]
        if state.started[0] == 1.0 and state.rate[0] < -AX_BRAKING:
            ref = w.max()
        elif free >= 0:
            ref = 0.5 * (w[2 * free] + w[2 * free + 1])
        else:
            ref = w.min()
        v[0] = ref
        speed_derivative(t[k:k + 1], v, tau_v, tau_a, state, a)
        out[k] = a[0]


@njit(cache=True, error_model="numpy")
def load_specific_force(prm: LowpassParams, enabled: bool, state: LoadFilterState,
                        t: np.ndarray,
                        f_x: np.ndarray,
                        f_y: np.ndarray, f_z: np.ndarray, r: np.ndarray
                        ) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """The road-plane specific force (m/s²) for the load balances, and the noise of the
    measurements.

    Each component goes through :func:`~vestim.filters.lowpass.noise_adaptive_lowpass`
    (``state.f_x``, ``f_y``, ``f_z``), or passes through where not ``enabled``: the
    normal loads take these (a body-mounted IMU's 10–30 Hz
    vibration of up to 4 m/s² is no tire load; the campaign's F_z was 13 of 48 times worse
    than the static loads with it). The fourth array (4, n) holds the measured noise
    variance per sample of f_x, f_y, f_z ((m/s²)²) and of the yaw gyro ((rad/s)²,
    ``state.yaw_rate``), for the lateral UKF, which takes the unfiltered force (a delay there costs
    F_y in proportion to the steering frequency: 1.3–2.3 points on the crossplant sine
    steers at 8 Hz) and weighs its noise with these (0 where the filter is off: the
    configured values alone). The chassis torques (a torque step's m a_x: our simulator's
    AWD braking without torques lost 1.5 points of F_x to the delay) and the velocity
    filters take the unfiltered force too."""
    n = t.shape[0]
    var = np.zeros((4, n))
    if not enabled:
        return f_x, f_y, f_z, var
    out = np.empty((3, n))
    noise_adaptive_lowpass(prm, state.f_x, t, f_x, out[0], var[0])
    noise_adaptive_lowpass(prm, state.f_y, t, f_y, out[1], var[1])
    noise_adaptive_lowpass(prm, state.f_z, t, f_z, out[2], var[2])
    noise_variance(prm, state.yaw_rate, t, r, var[3])
    return out[0], out[1], out[2], var


@njit(cache=True, error_model="numpy")
def speed_derivative(t: np.ndarray, v: np.ndarray, tau_v: float, tau_a: float,
                     state: SpeedDerivativeState, out: np.ndarray) -> None:
    """Causal derivative of a speed v (n,) m/s into ``out`` (n,) m/s²: v low-passed (τ_v),
    backward-differenced between its finite samples, low-passed again (τ_a, both s).

    NaN samples of v (a sparse channel between fixes) hold the output. ``state``
    (:class:`SpeedDerivativeState`) carries over chunks; the derivative is 0 until the
    second finite sample.
    """
    for k in range(t.shape[0]):
        if not np.isnan(v[k]):
            if state.started[0] == 0.0:
                state.t_prev[0], state.v_lp[0], state.rate[0] = t[k], v[k], 0.0
                state.started[0] = 1.0
            else:
                dt = t[k] - state.t_prev[0]
                if dt > 0.0:
                    g = min(dt / tau_v, 1.0) if tau_v > 0.0 else 1.0
                    v_lp = state.v_lp[0] + g * (v[k] - state.v_lp[0])
                    g = min(dt / tau_a, 1.0) if tau_a > 0.0 else 1.0
                    state.rate[0] += g * ((v_lp - state.v_lp[0]) / dt - state.rate[0])
                    state.t_prev[0], state.v_lp[0] = t[k], v_lp
        out[k] = state.rate[0]


@njit(cache=True, error_model="numpy")
def speed_hold(t: np.ndarray, fix: np.ndarray, ax: np.ndarray, state: SpeedHoldState,
               out: np.ndarray) -> None:
    """A dense speed (n,) m/s from sparse fixes (NaN between): the last fix advanced by the
    integral of the specific force ``ax`` (m/s²), ≥ 0; 0 before the first fix. ``state``
    (:class:`SpeedHoldState`) carries over chunks."""
    for k in range(t.shape[0]):
        if state.started[0] == 1.0:
            state.speed[0] = max(state.speed[0] + (t[k] - state.t_prev[0]) * ax[k], 0.0)
        state.t_prev[0], state.started[0] = t[k], 1.0
        if not np.isnan(fix[k]):
            state.speed[0] = fix[k]
        out[k] = state.speed[0]


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
    only for methods that have one, ``sigma_fy_*``, ``roll``, ``pitch``). Without wheel
    speeds (``res["wheel_speeds"]`` False) ``fx_*``, ``mu_x_*`` and ``sigma_fx_*`` are left
    out.

    ``mu_x_*``/``mu_y_*`` are 0 where F_z ≤ 1 N (a lifted wheel).
    """
    fz = res["fz"]

    def names(prefix: str) -> list[str]:
        return [f"{prefix}_{c}" for c in CORNERS]

    wheels = "wheel_speeds" not in res or bool(res["wheel_speeds"])  # else no F_x per corner
    mu_y = normalised(res["fy"], fz)
    groups: list[ColumnGroup] = [(names("fx"), res["fx"])] if wheels else []
    groups += [(names("fy"), res["fy"]), (names("fz"), fz)]
    if wheels:
        groups.append((names("mu_x"), normalised(res["fx"], fz)))
    groups.append((names("mu_y"), mu_y))
    if not np.all(np.isnan(res["sigma_fx"])):
        groups.append((names("sigma_fx"), res["sigma_fx"]))
    groups += [(names("sigma_fy"), res["sigma_fy"]), (["roll"], res["roll"]),
               (["pitch"], res["pitch"])]
    return groups


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
        cal = vehicle.calibration
        if cal is not None:  # gradients identified from the car's logs beat any default
            roll = cal.excited("body", "roll_gradient")
            pitch = cal.excited("body", "pitch_gradient")
            if roll is not None:
                # The quasi-static roll of a log without a roll rate. With a roll rate the
                # gyro/gravity filter stays: on the crossplant hold-out the model roll in its
                # place cost v_y (x10: 0.059 -> 0.096 m/s) in slides.
                self._c_roll = roll
            if pitch is not None:  # pitch_gradient = −dθ/da_x (the nose rises accelerating)
                self._c_pitch = -pitch
        roll_known = "suspension" in vehicle.given or (
            cal is not None and cal.excited("body", "roll_gradient") is not None)
        self._att_prm = nrm.attitude_params(self.config, self._c_roll, self._c_pitch,
                                            b.wheel_radius, b.drivetrain,
                                            "suspension" in vehicle.given, roll_known)
        self.set_accelerometer(self.config.accelerometer)
        self.load_filter_params = pack(LowpassParams, self.config.load_filter)
        """The force stage's specific-force low-pass (:func:`load_specific_force`)."""
        self._xw = np.array([b.lf, b.lf, -b.lr, -b.lr])
        self._yw = 0.5 * np.array([b.track_f, -b.track_f, b.track_r, -b.track_r])
        wm, wc, tau = ukf_weights(4)
        lp = self.config.lateral
        self.lateral_params = lat.lateral_params(
            lp, b.mass, b.yaw_inertia, self._xw, self._yw,
            vehicle.tire.sigma0_y / vehicle.tire.kappa_y,
            np.array([(b.mass * lp.sigma_ax) ** 2, (b.mass * lp.sigma_ay) ** 2,
                      lp.sigma_yaw**2, lp.sigma_split**2]), wm, wc, tau)
        """The lateral-force UKF's parameters (:func:`~.lateral.lateral_kernel`)."""
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
        self._att = nrm.new_attitude_state()
        self.lateral_state = lat.new_lateral_state()
        self._ax_state = new_speed_derivative_state()  # speed_derivative's (logs without ax)
        self.load_filter_state = new_load_filter_state()  # load_specific_force's
        self._hold_state = new_speed_hold_state()  # speed_hold's (gnss_speed, no wheel speeds)
        self._seen: dict[str, set[str]] = {}

    @property
    def input_sources(self) -> dict[str, str]:
        """Where the optional inputs came from since the last reset, for output metadata.

        Keys ``torque_source`` ("measured" | "chassis": the chassis equation of
        :mod:`vestim.models.chassis`), ``roll_source`` and ``pitch_source`` ("rate" |
        "quasi_static"), ``az_source`` ("measured" | "level_road"), and where a_x or the
        wheel speeds are missing ``ax_source`` ("wheel_speeds" | "vehicle_speed" |
        "gnss_speed") and ``speed_source`` ("vehicle_speed" | "gnss_speed"); a value is
        "mixed" when samples of both kinds were processed, and the dict is empty before any.
        (:class:`vestim.pipeline.Pipeline` adds ``ax_source``, ``speed_source`` and
        ``outputs_unavailable`` for every log.)
        """
        return {k: next(iter(v)) if len(v) == 1 else "mixed" for k, v in self._seen.items()}

    def note_sources(self, sources: Mapping[str, str]) -> None:
        """Record where a chunk's optional inputs came from (see :attr:`input_sources`)."""
        for key, value in sources.items():
            self._seen.setdefault(key, set()).add(value)

    def set_accelerometer(self, kind: str) -> None:
        """Take ``ax``, ``ay``, ``az`` as ``kind`` ("specific_force" | "gravity_free", see
        :class:`ForceConfig`) from the next sample on."""
        if kind not in ACCELEROMETERS:
            raise ValueError(f"accelerometer = {kind!r}: use one of {', '.join(ACCELEROMETERS)}")
        self._att_prm = self._att_prm._replace(gravity=0.0 if kind == "gravity_free" else 1.0)
        self.accelerometer = kind

    @property
    def roll_assumption(self) -> dict[str, str]:
        """The roll gradient used without a roll rate, for output metadata:
        ``roll_gradient_source`` ("identified" from the log, "suspension" of the vehicle
        file, "calibrated") and ``roll_gradient_deg_per_g`` (the value now, °/g). Empty when
        every sample so far had a roll rate (the gradient is not used then)."""
        if self.input_sources.get("roll_source", "rate") == "rate":
            return {}
        p = self._att_prm
        if p.roll_identify:
            source, k = "identified", nrm.roll_gradient_estimate(p, self._att)[0]
        else:
            source = "suspension" if "suspension" in self.vehicle.given else "calibrated"
            k = p.c_roll
        return {"roll_gradient_source": source,
                "roll_gradient_deg_per_g": f"{math.degrees(k) * G:.2f}"}

    @property
    def torque_source(self) -> str | None:
        """"measured", "chassis" or "mixed" since the last reset; None before any sample."""
        return self.input_sources.get("torque_source")

    def advance(self, u: Inputs) -> dict[str, np.ndarray]:
        """Process a chunk of measured inputs; state carries over to the next call.

        Returns arrays: ``fx``, ``sigma_fx`` (NaN without wheel speeds), ``fy``, ``sigma_fy``,
        ``fz`` (n, 4) in N;
        ``roll``, ``pitch`` (n,) in rad; road-plane specific force ``f_x``, ``f_y``,
        ``f_z`` (n,) in m/s²; ``torque`` (n, 4) in N m, the net wheel torques used
        (measured, or from the chassis equation, in which case ``u.torque`` is set to
        them too).
        """
        n = u.t.shape[0]
        b = self.vehicle.body
        cfg = self.config
        self.note_sources(u.sources)
        if not (u.ax_measured and u.omega_measured):
            self._speed_inputs(u)
        roll, pitch, roll_acc, pitch_acc, fy_sd = np.empty((5, n))
        nrm.attitude_kernel(u.t, u.ax, u.ay, u.roll_rate, u.pitch_rate, u.yaw_rate, u.omega,
                            self._att_prm, self._att, roll, pitch, roll_acc, pitch_acc, fy_sd)
        # The attitude's gravity as the accelerometers read it (none in an INS's output).
        g_roll, g_pitch = self._att_prm.gravity * roll, self._att_prm.gravity * pitch
        az = u.az if u.az_measured else level_road_az(u.ax, u.ay, g_roll, g_pitch)
        f_x, f_y, f_z = road_specific_force(u.ax, u.ay, az, g_roll, g_pitch)
        if not u.ax_measured:
            # A speed's derivative is already the road-plane acceleration: rotating it by the
            # pitch would add a g sin θ that a body-fixed accelerometer reads and it does not
            # (braking at 4 m/s², ~1° of pitch: 0.2 m/s², v_x 0.9 m/s high on crossplant x10).
            f_x = u.ax.copy()
        l_x, l_y, l_z, noise = load_specific_force(
            self.load_filter_params, cfg.load_filter.enabled, self.load_filter_state, u.t, f_x,
            f_y, f_z, u.yaw_rate)
        fz = nrm.normal_loads(l_x, l_y, l_z, roll, pitch, u.roll_rate, u.pitch_rate, roll_acc,
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
        lat.lateral_kernel(self.lateral_params, self.lateral_state, u.t, fx, u.delta, weights,
                           f_x, f_y, u.yaw_rate, noise, drag, fz, speed, fy, sig_fy)
        if not u.omega_measured:  # per-corner F_x needs the wheels' own speeds
            fx = np.full_like(fx, np.nan)
            sig_fx = np.full_like(sig_fx, np.nan)
        return {"fx": fx, "sigma_fx": sig_fx, "fy": fy, "sigma_fy": sig_fy, "fz": fz,
                "roll": roll, "pitch": pitch, "f_x": f_x, "f_y": f_y, "f_z": f_z,
                "fy_sd": fy_sd,
                "torque": u.torque, "wheel_speeds": np.array(u.omega_measured)}

    def _speed_inputs(self, u: Inputs) -> None:
        """Fill a missing a_x (m/s²) and missing wheel speeds (rad/s) of ``u`` in place from
        the speed channels (see the module docstring), with state carried over chunks."""
        n = u.t.shape[0]
        radius = self.vehicle.body.wheel_radius
        if not u.ax_measured:
            ax = np.empty(n)
            if u.omega_measured:
                wheel_reference_speed(u.t, u.omega, u.yaw_rate, self._yw, radius,
                                      self._att_prm.undriven_axle, AX_TAU[0], AX_TAU[1],
                                      self._ax_state, ax)
            else:
                v, tau = ((u.vehicle_speed, AX_TAU) if u.vehicle_speed is not None
                          else (u.gnss_speed, AX_TAU_SPARSE))
                speed_derivative(u.t, np.ascontiguousarray(v, dtype=float), tau[0], tau[1],
                                 self._ax_state, ax)
            u.ax = ax
        if not u.omega_measured:
            if u.vehicle_speed is not None:
                v = u.vehicle_speed
            else:
                v = np.empty(n)
                speed_hold(u.t, u.gnss_speed, u.ax, self._hold_state, v)
            u.omega = np.ascontiguousarray(np.repeat((v / radius)[:, None], 4, axis=1))

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
        u = inputs_from_sample(sample, self.vehicle)
        return {k: float(v[0]) for k, v in force_columns(u.t, self.advance(u)).items()}
