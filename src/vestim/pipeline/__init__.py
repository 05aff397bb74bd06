"""The corner-based pipeline of 001 Fig. 1: forces → normalisation → velocity → CG and corners.

Stages are chosen by name in a :class:`PipelineConfig` (CLI flags or a
``[pipeline]`` TOML section): the force stage (``force``: ukf | ukf_rw | pid |
uio | naive; ``normal``: dynamic | static) and the velocity stage
(``velocity``: fused | reference | kinematic | kf | ukf | lpv). ``run(log)``
processes a whole log and
``step(sample)`` one sample; both advance the same compiled kernels on the same
state, so feeding a log sample by sample reproduces the batch result.

Outputs (spec names): ``vx``, ``vy``, ``sigma_vx``, ``sigma_vy``, per corner
``vx_*``, ``vy_*`` (wheel centre, body frame), ``vxt_*``, ``vyt_*`` (tire frame),
``slip_ratio_*``, ``slip_angle_*``, and the force stage's ``fx_*``, ``fy_*``,
``fz_*``, ``mu_x_*``, ``mu_y_*``, ``sigma_f*``, ``roll``, ``pitch``; plus
``bias_ax`` (the reference filter's acceleration bias, m/s²),
``cornering_stiffness`` (the online normalised cornering stiffness C_y/ΣF_z of the v_y
bounds, 1/rad), ``radius_scale`` (the effective-radius factor from ``gnss_speed``, 1
without it) and ``gnss_latency`` (the receiver's latency found from it, s; 0 without
it). Only measured channels are read.

Fewer sensors (docs/fewer-sensors.md): a log without ``ax`` gets it from the speed (the
force stage's :func:`~vestim.estimators.force.estimator.wheel_reference_speed` or
:func:`~vestim.estimators.force.estimator.speed_derivative`; the reference filter then takes
it as v̇_x, ``fx_from_speed``); a log without wheel speeds but with ``gnss_speed`` or a dense
``vehicle_speed`` runs the reference filter with no wheel measurement (v_x from a_x
integrated with the speed updates, v_y from its unchanged lateral part: a_y − r v_x with the
linear-tire slip-angle bounds), and the per-wheel outputs that need ω (``slip_ratio_*``,
``fx_*``, ``mu_x_*``, ``sigma_fx_*``, ``radius_scale``, ``gnss_latency``) are left out (a log
holds no NaN outside its sparse channels); only the "fused" and "reference" velocity
methods run without wheel speeds. The force estimator's ``input_sources`` (the output
metadata) then holds ``ax_source`` ("measured" | "wheel_speeds" | "vehicle_speed" |
"gnss_speed"), ``speed_source`` ("wheel_speeds" | "vehicle_speed" | "gnss_speed") and
``outputs_unavailable`` (comma-separated column names, "none" with every sensor) besides
the torque, attitude and a_z sources.
"""

from __future__ import annotations

import itertools
import math
from collections.abc import Callable, Iterable, Iterator, Mapping
from dataclasses import fields, replace
from pathlib import Path
from typing import Any

import numba
import numpy as np
import pandas as pd

from vestim.constants import CORNERS, G
from vestim.errors import LogFormatError
from vestim.estimators import registry
from vestim.estimators.force import ForceEstimator
from vestim.estimators.force.estimator import (
    WHEEL_OUTPUTS,
    ColumnGroup,
    Inputs,
    columns_from_groups,
    force_groups,
    frame_from_chunks,
    inputs_from_log,
    normalised,
)
from vestim.estimators.friction import (
    corner_kx,
    friction_params,
    friction_potential,
    new_friction_state,
)
from vestim.estimators.fusion import confidences, fuse
from vestim.estimators.health import (
    health_params,
    imu_health_kernel,
    imu_health_params,
    imu_health_step,
    new_imu_state,
    wheel_health_kernel,
    wheel_health_step,
)
from vestim.estimators.health import new_state as new_health_state
from vestim.estimators.uncertainty import OUTPUT_NAMES as SIGMA_NAMES
from vestim.estimators.uncertainty import new_state as new_uncertainty_state
from vestim.estimators.uncertainty import (
    uncertainty,
    uncertainty_params,
)
from vestim.estimators.validity import GROUPS as VALIDITY_GROUPS
from vestim.estimators.validity import VY_UNVERIFIED, validity, validity_params
from vestim.estimators.validity import output_names as validity_names
from vestim.estimators.velocity.corner import CornerVelocityEstimator, CornerVelocityInput
from vestim.estimators.velocity.kinematic import KinematicIntegrator
from vestim.estimators.velocity.lpv_observer import LPVParams
from vestim.estimators.velocity.lugre_kf import KFParams
from vestim.estimators.velocity.reference import (
    ReferenceFilter,
    axle_slip_angles,
    clear_state,
    gnss_calibration,
    new_radius_state,
    new_stiffness_state,
    radius_params,
    stiffness_params,
)
from vestim.io.calibration import correct_columns, corrected_log
from vestim.io.channels import REF_PREFIX, SPARSE
from vestim.io.log import check_structure
from vestim.io.vehicle import Vehicle
from vestim.models import kinematics as kin
from vestim.pipeline import online
from vestim.pipeline.config import (
    VELOCITY_METHODS,
    PipelineConfig,
    PipelineConfigError,
    _lpv_params_from_gains,
)

__all__ = ["CHUNK", "GAP_S", "HOLD_S", "VELOCITY_METHODS", "Pipeline", "PipelineConfig",
           "PipelineConfigError", "estimate"]



WHEEL_ONLY_OUTPUTS: tuple[str, ...] = (
    *(f"{q}_{c}" for q in ("slip_ratio", *WHEEL_OUTPUTS) for c in CORNERS),
    "radius_scale", "gnss_latency")
"""Outputs that need the wheel speeds: left out for a log without them."""

GAP_S = 0.5
"""A time step longer than this (s) is a recording gap: the filters restart after it."""

HOLD_S = 0.5
"""Longest time (s) :meth:`Pipeline.step` holds a channel's last finite value over NaN/inf."""

CHUNK = 65_536
"""Samples per chunk of :meth:`Pipeline.run` (bounds the intermediate arrays to ~100 MB)."""


def _slice_inputs(u: Inputs, start: int, stop: int) -> Inputs:
    """Samples [start, stop) of the inputs, as contiguous arrays (flags kept)."""
    arrays: dict[str, Any] = {f.name: np.ascontiguousarray(getattr(u, f.name)[start:stop])
                              for f in fields(u) if isinstance(getattr(u, f.name), np.ndarray)}
    return replace(u, **arrays)


class Pipeline:
    """Force and velocity estimation for one vehicle (online or batch)."""

    def __init__(self, vehicle: Vehicle, config: PipelineConfig | None = None) -> None:
        self.vehicle = vehicle
        self.config = config or PipelineConfig()
        b = vehicle.body
        self._xw, self._yw = kin.corner_positions(vehicle)
        # Cornering stiffness per load, the prior only: identified from the car's logs when
        # the file is calibrated, else the [tire] table's σ0y/κy.
        prior = vehicle.tire.sigma0_y / vehicle.tire.kappa_y
        cal = vehicle.calibration
        if cal is not None:
            cy_f, cy_r = cal.excited("tire", "cy_f"), cal.excited("tire", "cy_r")
            if cy_f is not None and cy_r is not None:
                prior = (cy_f + cy_r) / (b.mass * G)
        self._stiff_prm = stiffness_params(prior, self.config.cornering, b.wheel_radius,
                                           b.wheelbase)
        self._stiff_state = new_stiffness_state()
        self._radius_prm = radius_params(self.config.radius, b.wheel_radius)
        self._radius_state = new_radius_state()
        self._t_gnss = np.nan  # time of the previous sample, for the GNSS fixes' weight
        self._friction_prm = friction_params(self.config.friction,
                                             corner_kx(vehicle, self.config.friction))
        self._friction_state = new_friction_state()
        self.force = ForceEstimator(vehicle, self.config.force_config())
        self.reference = ReferenceFilter(b.wheel_radius, b.lf, b.lr, self._xw, self._yw,
                                         self.config.reference, mass=b.mass)
        self.kinematic = KinematicIntegrator(b.wheel_radius)
        method = self.config.velocity
        corner_method = registry.lookup("velocity", method).corner
        params: KFParams | LPVParams | None = self.config.corner
        if corner_method == "lpv":
            params = _lpv_params_from_gains(self.config.gains) if self.config.gains else None
        self.corner = (CornerVelocityEstimator(vehicle, corner_method, params)
                       if corner_method is not None else None)
        # The fused filter: a second reference filter that also takes the corner estimates.
        self.fused = ReferenceFilter(b.wheel_radius, b.lf, b.lr, self._xw, self._yw,
                                     self.config.reference, mass=b.mass)
        self._prev = np.array([np.nan, 0.0])  # (t, yaw rate) of the previous sample, for ṙ
        self._fused_is_reference = True  # the fused filter has not diverged from the plain one
        self._step_args: tuple[Any, ...] | None = None  # compiled step's arguments (cache)
        self._step_fn: Callable[..., None] | None = None  # its entry point for their types
        self._t_prev_step = -math.inf  # step()'s guard: last t, last finite value per channel
        # the last sample whose every value was finite, and its time (step()'s hold)
        self._last_good: tuple[float, Mapping[str, float]] = (-math.inf, {})
        self._t_start = math.nan  # first sample time (validity flags' convergence)
        self._held_now = False  # step() held a dropped input in this sample
        self._post: tuple[Any, ...] | None = None  # _fast_post's index arrays and buffers
        self.gaps: list[tuple[float, float]] = []  # time gaps (s) the filters restarted after
        self.vy_unverified_rows = 0
        """Rows of the last run whose v_y had no accepted pseudo-measurement for
        ``validity.unverified_s`` (reason bit 64), and all its rows: the consistency
        monitor's figure for the output metadata (:meth:`unverified_warning`)."""
        self.rows_estimated = 0
        self._health_prm = health_params(self.config.health, vehicle.body.wheel_radius)
        self._health_state = new_health_state()
        self._imu_prm = imu_health_params(self.config.imu_health, b.wheel_radius, b.track_f,
                                          b.track_r, b.lf)
        self._imu_state = new_imu_state()
        # step()'s one-sample buffers: wheel speeds, road-wheel angles, outputs, health rows
        self._imu_buf = (np.empty(4), np.zeros(4), np.empty(3), np.empty((1, 3)))
        self._chunk_imu: np.ndarray | None = None  # IMU health rows of the block (run, step)
        self._unc_prm = uncertainty_params(vehicle, self.config.uncertainty)
        self._validity_prm = validity_params(self.config.validity)
        self._unc_state = new_uncertainty_state()
        self._health_buf = (np.empty(4), np.empty((1, 4)), np.empty((1, 4)))
        # step()'s compiled entry points (wheel health, IMU health, post) for these types
        self._step_calls: tuple[Callable[..., None], ...] | None = None
        # health and "input faulty" rows of the block _advance is working on (run and step)
        self._chunk_faulty: np.ndarray | None = None
        self._chunk_health: np.ndarray | None = None
        self._step_names: list[str] = []
        self._step_rates: tuple[bool, bool] | None = None  # rate channels last noted

    def reset(self) -> None:
        """Forget every stage's state."""
        self.force.reset()
        self.reference.reset()
        self.kinematic.reset()
        self.fused.reset()
        if self.corner is not None:
            self.corner.reset()
        self._prev = np.array([np.nan, 0.0])
        clear_state(self._stiff_state)
        clear_state(self._radius_state)
        self._friction_state = new_friction_state()
        self._t_prev_step = -math.inf
        self._last_good = (-math.inf, {})
        self._health_state = new_health_state()
        self._imu_state = new_imu_state()
        self._unc_state = new_uncertainty_state()
        self._t_start = math.nan  # first sample time, for the validity flags' convergence
        self._held_now = False  # step() held a dropped input in this sample
        self._t_gnss = np.nan
        self._fused_is_reference = True
        self._step_args = None
        self._step_fn = None
        self._step_rates = None

    def unverified_warning(self) -> dict[str, str | float | None] | None:
        """The consistency monitor's warning for the output metadata (the shape of
        :meth:`vestim.io.sanity.Finding.as_dict`), or None: after :meth:`run`, where at least
        :data:`UNVERIFIED_WARN` of the rows had v_y unverified (reason bit 64: no v_y
        pseudo-measurement accepted for ``validity.unverified_s``, v_y the a_y integral
        alone)."""
        if self.rows_estimated == 0:
            return None
        share = self.vy_unverified_rows / self.rows_estimated
        if share < UNVERIFIED_WARN:
            return None
        return {"channel": "vy", "severity": "warning",
                "message": (f"v_y unverified on {100 * share:.1f} % of the rows: the tire "
                            "model's v_y and the a_y integral disagreed for more than "
                            f"{self.config.validity.unverified_s:g} s (a slide, a cornering "
                            "stiffness or roll the vehicle file does not know, or an "
                            "accelerometer scale error); v_y, β and the slip angles there are "
                            "the integral alone (reason_velocity bit 64, 'v_y unverified')"),
                "evidence": share, "check": "lateral_consistency"}

    def _yaw_acceleration(self, t: np.ndarray, r: np.ndarray) -> np.ndarray:
        """Backward difference of the gyro across chunk boundaries (0 at the first sample)."""
        acc = np.empty(t.shape[0])
        self._prev = np.array(self._prev)  # may be a view of the compiled step's state
        kin.yaw_acceleration_kernel(t, r, self._prev, acc)
        return acc

    def _corner_cg(self, out: Any, u: Any) -> np.ndarray:
        """Each corner observer's estimate mapped to the CG (n, 4), m/s (001 eq. (33))."""
        vx_b, _ = kin.to_body_frame(out.vxt, np.where(np.isnan(out.vyt), 0.0, out.vyt), u.delta)
        vx_cg, _ = kin.corners_to_cg(vx_b, np.zeros_like(vx_b), u.yaw_rate, self._xw, self._yw)
        return np.asarray(vx_cg)

    def _fuse_corners(self, out: Any, u: Any, res: dict[str, np.ndarray],
                      v_ref: np.ndarray) -> np.ndarray:
        """The corner observers' CG v_x (n,) by the configured fusion (003 Alg. 2).

        The slip ratio that sets each corner's confidence (003 eq. (6)) and the adaptive
        axle weights (001 eq. (34)) is taken against the reference filter's velocity
        ``v_ref`` (n, 2) mapped to that corner, not against the corner's own v̂_xt: a
        corner observer that has drifted towards R·ω would otherwise report a small slip
        and keep its confidence (split-μ RWD launch: the high-μ rear wheel's KF is 4 m/s
        off while its own slip reads 0.03). Stores the opinion confidences in ``res``.
        """
        cfg = self.config
        vx_i, vy_i = kin.cg_to_corners(v_ref[:, 0], v_ref[:, 1], u.yaw_rate, self._xw, self._yw)
        vxt, _ = kin.to_tire_frame(vx_i, vy_i, u.delta)
        slip = kin.slip_ratio(u.omega, vxt, self.vehicle.body.wheel_radius)
        vx, _ = fuse(cfg.fusion, self._corner_cg(out, u), slip, cfg.fusion_params)
        if cfg.fusion == "opinion":
            res["confidence"] = confidences(slip, cfg.fusion_params)
        return vx

    def _corners(self, u: Any, res: dict[str, np.ndarray], mu_x: np.ndarray,
                 ref: dict[str, np.ndarray]) -> Any:
        """Run the corner observer (inputs as in corner_inputs: 001 text after eq. (21)).

        ``ref`` is the reference filter's output: its v_y sets the tire-frame transport term
        (the no-sideslip approximation fails when the car slides: 4–5 % v_x in RWD spins),
        and its accelerometer biases b_x, b_y (learnt while the wheels roll) are removed
        from the accelerations the corner observers integrate in high slip (a 0.1 m/s²
        bias otherwise costs the corner KF 10 % on a 9 s ice launch).
        """
        assert self.corner is not None
        yaw_acc = self._yaw_acceleration(u.t, u.yaw_rate)
        bias = ref["bias"]
        ax_i, ay_i = kin.corner_accelerations(res["f_x"] - bias[:, 0], res["f_y"] - bias[:, 1],
                                              u.yaw_rate, yaw_acc, self._xw, self._yw)
        a_xt, a_yt = kin.to_tire_frame(ax_i, ay_i, u.delta)
        vx_guess = self.vehicle.body.wheel_radius * u.omega.mean(axis=1)
        vx_i, vy_i = kin.cg_to_corners(vx_guess, ref["v"][:, 1], u.yaw_rate, self._xw, self._yw)
        _, vyt = kin.to_tire_frame(vx_i, vy_i, u.delta)
        fz = res["fz"]
        mu_y = normalised(res["fy"], fz)
        inp = CornerVelocityInput(t=u.t, omega=u.omega, mu_x=mu_x, a_xt=a_xt, delta=u.delta,
                                  yaw_rate=u.yaw_rate, mu_y=mu_y, a_yt=a_yt, vyt=vyt)
        return self.corner.advance(inp)

    def _advance(self, u: Any) -> dict[str, np.ndarray]:
        method = self.config.velocity
        wheels = u.omega_measured
        if not wheels and registry.lookup("velocity", method).needs_wheel_speeds:
            raise PipelineConfigError(
                f"velocity method {method!r} needs the wheel speeds omega_fl … omega_rr, which "
                "the log does not have: use velocity 'reference' or 'fused' (the default)")
        res = self.force.advance(u)  # fills a missing a_x, and ω from the speed (see module)
        self.force.note_sources({
            "ax_source": "measured" if u.ax_measured else u.speed_source,
            "speed_source": u.speed_source,
            "outputs_unavailable": "none" if wheels else ",".join(WHEEL_ONLY_OUTPUTS)})
        fz = res["fz"]
        mu_x = normalised(res["fx"], fz)
        n = u.t.shape[0]
        # Linear-tire axle slip angles with the cornering stiffness identified online.
        axle_slip = np.empty((n, 2))
        c_y = np.empty(n)
        axle_slip_angles(self._stiff_prm, self._stiff_state, u.t, u.omega, u.yaw_rate, u.delta,
                         res["fy"], fz, axle_slip, c_y)
        # The velocity stage sees the wheel speeds at the effective radius that the GNSS
        # speed shows, and the fixes brought forward by the receiver's latency (scale 1 and
        # no measurement without gnss_speed).
        scale, latency, gnss_now = np.empty((3, n))
        if wheels:
            gnss_calibration(self._radius_prm, self._radius_state, u.t, u.omega, u.gnss_speed,
                             scale, latency, gnss_now)
        else:  # no wheel speeds to scale nor to find the latency against
            scale[:], latency[:], gnss_now[:] = 1.0, 0.0, u.gnss_speed
        if np.any(scale != 1.0):
            u = replace(u, omega=np.ascontiguousarray(u.omega * scale[:, None]))
        gnss = np.isfinite(gnss_now)
        extra = gnss_now[:, None]
        # A fix's error is white at the receiver's rate: undo the τ_wheel/T_s inflation the
        # filter gives every extra CG-speed measurement (per-sample T_s), so its weight does
        # not depend on the log's sample rate.
        p_ref = self.config.reference
        dt = np.diff(u.t, prepend=self._t_gnss)
        self._t_gnss = float(u.t[-1])
        inflate = np.maximum(p_ref.tau_wheel / np.where(dt > 0, dt, np.inf), 1.0)
        var = np.where(gnss, p_ref.sigma_gnss**2 / inflate, np.nan)[:, None]
        mu_x_c = np.ascontiguousarray(mu_x)
        if not wheels:
            # The reference filter without wheel measurements (NaN ω): v_x from a_x and the
            # speed updates (a dense vehicle_speed enters like a wheel, with the τ_wheel/T_s
            # inflation), v_y from the same lateral part as with wheel speeds.
            if u.vehicle_speed is not None:
                extra = np.column_stack((extra, u.vehicle_speed))
                var = np.column_stack((var, np.full(n, p_ref.sigma_vehicle_speed**2)))
            vel = self.reference.advance(u.t, np.full_like(u.omega, np.nan), u.torque, mu_x_c,
                                         axle_slip, res["f_x"], res["f_y"], u.yaw_rate,
                                         u.delta, extra, var, fx_from_speed=not u.ax_measured,
                                         fy_sd=res["fy_sd"])
            v, sig, bias, unverified = (vel["v"], vel["sigma"], vel["bias"][:, 0],
                                          vel["bias"][:, 3])
        elif method == "kinematic":
            v = self.kinematic.advance(u.t, u.omega, res["f_x"], res["f_y"], u.yaw_rate)
            sig = np.full_like(v, np.nan)
            bias = unverified = np.full(n, np.nan)
        elif method == "fused":
            # Corner estimates are information where the wheel speeds have none: they
            # enter (σ = sigma_corner_slip, inflated by the filter for their correlation
            # time) only while at least three corners are in high slip, i.e. when no wheel
            # speed can be trusted. Elsewhere the corner KF is biased in moderate slip
            # (docs/results.md) and the wheel speeds already carry the information. The
            # corner KF's transport term takes v_y from the plain reference filter (the
            # no-sideslip approximation fails when the car slides: 4–5 % v_x in RWD spins).
            start = self.reference.snapshot() if self._fused_is_reference else ()
            ref = self.reference.advance(u.t, u.omega, u.torque, mu_x_c, axle_slip, res["f_x"],
                                         res["f_y"], u.yaw_rate, u.delta, extra, var,
                                         fx_from_speed=not u.ax_measured,
                                         fy_sd=res["fy_sd"])
            out = self._corners(u, res, mu_x_c, ref)
            vx_corner = self._fuse_corners(out, u, res, ref["v"])
            p = self.config.reference
            all_slip = out.high_slip.sum(axis=1) >= 3
            if self._fused_is_reference and not all_slip.any():
                # Until the first corner measurement the fused filter is the plain one, bit
                # for bit (same kernel, inputs and state): its run is skipped.
                vel = ref
            else:
                if self._fused_is_reference:
                    self.fused.restore(start)
                    self._fused_is_reference = False
                extra2 = np.column_stack((extra, np.where(all_slip, vx_corner, np.nan)))
                var2 = np.column_stack((var, np.where(all_slip, p.sigma_corner_slip**2,
                                                      np.nan)))
                vel = self.fused.advance(u.t, u.omega, u.torque, mu_x_c, axle_slip, res["f_x"],
                                         res["f_y"], u.yaw_rate, u.delta, extra2, var2,
                                         fx_from_speed=not u.ax_measured,
                                         fy_sd=res["fy_sd"])
            v, sig, bias, unverified = (vel["v"], vel["sigma"], vel["bias"][:, 0],
                                          vel["bias"][:, 3])
        else:
            vel = self.reference.advance(u.t, u.omega, u.torque, mu_x_c, axle_slip, res["f_x"],
                                         res["f_y"], u.yaw_rate, u.delta, extra, var,
                                         fx_from_speed=not u.ax_measured,
                                         fy_sd=res["fy_sd"])
            v, sig, bias, unverified = (vel["v"], vel["sigma"], vel["bias"][:, 0],
                                          vel["bias"][:, 3])
            if self.corner is not None:
                out = self._corners(u, res, mu_x_c, vel)
                # CG v_x by the fusion stage; v_y from the reference filter.
                v = np.column_stack((self._fuse_corners(out, u, res, v), v[:, 1]))
                sig = np.full_like(v, np.nan)
        vx_i, vy_i = kin.cg_to_corners(v[:, 0], v[:, 1], u.yaw_rate, self._xw, self._yw)
        vxt, vyt = kin.to_tire_frame(vx_i, vy_i, u.delta)
        slip_ratio = kin.slip_ratio(u.omega, vxt, self.vehicle.body.wheel_radius)
        if not wheels:
            slip_ratio = np.full_like(slip_ratio, np.nan)
            scale = np.full(n, np.nan)
            latency = np.full(n, np.nan)
        slip_angle = kin.slip_angle(vxt, vyt)
        # σ of every channel (the estimates themselves are unchanged; friction and validity
        # below use the filter's σ_vy as before).
        unc = uncertainty(u.t, v, sig, u.delta, u.omega,
                          u.ax if u.ax_measured else res["f_x"], u.ay, fz, vxt, vyt, slip_ratio,
                          c_y, self._unc_prm, self._unc_state)
        res.update({f"uncertainty.{k}": a for k, a in unc.items()})
        res.update({"v": v, "sigma_v": sig, "bias": bias, "vy_unverified": unverified,
                    "vx_i": vx_i, "vy_i": vy_i,
                    "cornering_stiffness": c_y, "radius_scale": scale,
                    "gnss_latency": latency,
                    "vxt": vxt, "vyt": vyt,
                    "slip_ratio": slip_ratio, "slip_angle": slip_angle})
        res["mu"], res["sigma_mu"], res["mu_excited"] = friction_potential(
            self._friction_prm, self._friction_state, u.t, res["fx"], res["fy"], res["fz"],
            res["sigma_fx"], res["sigma_fy"], slip_ratio, slip_angle,
            np.fmax(sig[:, 1], self._friction_prm.sigma_vy_floor)
            / np.maximum(np.abs(v[:, 0]), 1.0), c_y)
        if math.isnan(self._t_start):
            self._t_start = float(u.t[0])
        if wheels:
            res["health_omega"] = (self._chunk_health if self._chunk_health is not None
                                   else np.ones((n, 4)))
        res["health_imu"] = self._chunk_imu if self._chunk_imu is not None else np.ones((n, 3))
        res.update(validity(u.t, self._t_start, v[:, 0], slip_ratio, slip_angle,
                            u.delta[:, :2], u.ay,
                            self._chunk_faulty if self._chunk_faulty is not None
                            else np.full(n, self._held_now),
                            self.config.validity, res["vy_unverified"]))
        self.vy_unverified_rows += int(np.count_nonzero(
            res["reason_velocity"].astype(np.int64) & VY_UNVERIFIED))
        self.rows_estimated += n
        return res

    @staticmethod
    def _groups(t: np.ndarray, res: dict[str, np.ndarray]) -> list[ColumnGroup]:
        """The output channels grouped by quantity (see :func:`force_groups`)."""

        def names(prefix: str) -> list[str]:
            return [f"{prefix}_{c}" for c in CORNERS]

        wheels = bool(res["wheel_speeds"])  # else the outputs of WHEEL_ONLY_OUTPUTS are left out
        unc = {k.removeprefix("uncertainty."): a for k, a in res.items()
               if k.startswith("uncertainty.")}

        def sigma(*quantities: str) -> list[ColumnGroup]:
            return [(names(f"sigma_{q}"), np.column_stack([unc[f"sigma_{q}_{c}"] for c in CORNERS]))
                    for q in quantities]

        groups: list[ColumnGroup] = [(["t"], t), (["vx", "vy"], res["v"])]
        velocity_sigma = not np.all(np.isnan(res["sigma_v"]))  # the methods with a filter σ
        if velocity_sigma:
            groups.append((["sigma_vx", "sigma_vy"],
                           np.column_stack((unc["sigma_vx"], unc["sigma_vy"]))))
            groups += sigma("vx", "vy", "vxt", "vyt", "slip_angle")
            if wheels:
                groups += sigma("slip_ratio")
        groups += [*sigma("fz"), (["sigma_roll", "sigma_pitch"],
                                  np.column_stack((unc["sigma_roll"], unc["sigma_pitch"])))]
        groups += [(names("vx"), res["vx_i"]), (names("vy"), res["vy_i"]),
                   (names("vxt"), res["vxt"]), (names("vyt"), res["vyt"])]
        if wheels:
            groups.append((names("slip_ratio"), res["slip_ratio"]))
        groups += [(names("slip_angle"), res["slip_angle"]), *force_groups(res)]
        if not np.all(np.isnan(res["bias"])):
            groups.append((["bias_ax"], res["bias"]))
        groups.append((["cornering_stiffness"], res["cornering_stiffness"]))
        if wheels:
            groups.append((["radius_scale", "gnss_latency"],
                           np.column_stack((res["radius_scale"], res["gnss_latency"]))))
        if "confidence" in res:
            groups.append((names("confidence"), res["confidence"]))
        groups += [(names("mu"), res["mu"]), (names("sigma_mu"), res["sigma_mu"]),
                   ([f"mu_{c}_excited" for c in CORNERS], res["mu_excited"])]
        groups += [([k], res[k]) for k in validity_names()]
        if "health_omega" in res:
            groups.append(([f"health_omega_{c}" for c in CORNERS], res["health_omega"]))
        groups.append((["health_ax", "health_ay", "health_yaw_rate"], res["health_imu"]))
        return groups

    def _calls(self) -> tuple[Callable[..., None], ...]:
        """:meth:`step`'s compiled per-sample calls (:func:`wheel_health_step`,
        :func:`imu_health_step`, :func:`online.post_step_kernel`) as entry points for the
        Numba types of this pipeline's params, states and buffers, made once: a call then
        skips the dispatcher's typing of each NamedTuple argument (several µs a call). They
        are only called with those objects (a reset state is a new one of the same type)."""
        if self._step_calls is None:
            w, out, health = self._health_buf
            wi, delta, out3, health3 = self._imu_buf
            wheel = _compiled(wheel_health_step, self._health_prm, self._health_state, 0.0, w,
                              out[0], health[0])
            imu = _compiled(imu_health_step, self._imu_prm, self._imu_state, 0.0, 0.0, 0.0,
                            0.0, wi, delta, out3, health3[0])
            post = _compiled(online.post_step_kernel, self._friction_prm,
                             self._friction_state, self._validity_prm, self._unc_prm,
                             self._unc_state, np.empty(1), np.empty(1, dtype=np.int64),
                             np.empty(1, dtype=np.int64), np.empty(1), False, 0.0, 0.0,
                             health[0], health3[0], np.empty(1))
            self._step_calls = (wheel, imu, post)
        return self._step_calls

    def _wheel_health(self, sample: Mapping[str, float]) -> Mapping[str, float]:
        """:mod:`vestim.estimators.health` on one sample (the step and state of run())."""
        w, out, health = self._health_buf
        try:
            w[0], w[1] = float(sample["omega_fl"]), float(sample["omega_fr"])
            w[2], w[3] = float(sample["omega_rl"]), float(sample["omega_rr"])
        except KeyError:  # no wheel speeds: nothing to check
            self._chunk_faulty = _HELD[self._held_now]
            self._chunk_health = None
            return sample
        self._calls()[0](self._health_prm, self._health_state, float(sample["t"]), w, out[0],
                         health[0])
        self._chunk_health = health
        h = health[0].tolist()
        bad = h[0] + h[1] + h[2] + h[3] < 4.0
        self._held_now = self._held_now or bad
        self._chunk_faulty = _HELD[self._held_now]
        if not bad:
            return sample
        fixed = dict(sample)
        fixed.update(zip(_OMEGA_KEYS, out[0].tolist(), strict=True))
        return fixed

    def _imu_health(self, sample: Mapping[str, float]) -> Mapping[str, float]:
        """:mod:`vestim.estimators.health.imu` on one sample (the step and state of run(),
        after the wheel health and the calibration, as there)."""
        w, delta, out, health = self._imu_buf
        get = sample.get
        w[0], w[1] = float(get("omega_fl", np.nan)), float(get("omega_fr", np.nan))
        w[2], w[3] = float(get("omega_rl", np.nan)), float(get("omega_rr", np.nan))
        if "delta_fl" in sample and "delta_fr" in sample:
            delta[0], delta[1] = float(sample["delta_fl"]), float(sample["delta_fr"])
        else:
            d = (float(sample["delta"]) if "delta" in sample else
                 float(get("steering_wheel_angle", 0.0)) / self.vehicle.body.steering_ratio)
            delta[0] = delta[1] = d
        self._calls()[1](self._imu_prm, self._imu_state, float(sample["t"]),
                         float(get("ax", np.nan)), float(get("ay", np.nan)),
                         float(get("yaw_rate", np.nan)), w, delta, out, health[0])
        self._chunk_imu = health
        h = health[0].tolist()
        if min(h) == 1.0:
            return sample
        self._held_now = True
        self._chunk_faulty = _HELD[True]
        fixed = dict(sample)
        for key, value in zip(("ax", "ay", "yaw_rate"), out.tolist(), strict=True):
            if key in fixed:
                fixed[key] = value
        return fixed

    def _hold_gaps(self, sample: Mapping[str, float]) -> Mapping[str, float]:
        """:meth:`step`'s guard against dropped values (see there)."""
        t = float(sample.get("t", np.nan))
        if not math.isfinite(t) or t <= self._t_prev_step:
            raise LogFormatError(f"sample t = {sample.get('t')!r} after t = {self._t_prev_step!r}: "
                                 "t must be finite and strictly increasing, in seconds")
        self._t_prev_step = t
        try:
            clean = math.isfinite(sum(sample.values()))  # every value finite (the usual case)
        except TypeError:
            clean = False
        if clean:
            self._last_good = (t, dict(sample))  # a copy: a live loop may reuse its dict
            self._held_now = False
            return sample
        fixed: dict[str, float] | None = None
        t_good, good = self._last_good
        for key, value in sample.items():
            if key in SPARSE or key.startswith(REF_PREFIX):
                continue
            v = float(value)
            if math.isfinite(v):
                continue
            last = float(good.get(key, math.nan))
            if not math.isfinite(last) or t - t_good > HOLD_S:
                since = ("the first sample" if not good else f"t = {t_good:.3f} s")
                raise LogFormatError(
                    f"sample at t = {t:.3f} s: channel {key!r} is {v} and has had no finite value "
                    f"since {since} (values are held for at most {HOLD_S} s); check the sensor "
                    "or leave the channel out")
            fixed = dict(sample) if fixed is None else fixed
            fixed[key] = last
        self._held_now = fixed is not None
        return sample if fixed is None else fixed

    def run(self, log: pd.DataFrame, chunk: int = CHUNK,
            progress: Callable[[float], None] | None = None) -> pd.DataFrame:
        """Estimate over a whole log (state reset first); returns the estimated channels.

        The log is processed in chunks of ``chunk`` samples (the state carries over, so the
        result does not depend on the chunking: :meth:`step` is the chunk of one), which
        bounds the intermediate arrays; the output is one float64 block filled in place.
        ``progress``, if given, is called with the fraction of samples done after each chunk.

        A time gap longer than :data:`GAP_S` (a recording dropout) restarts every filter at
        the first sample after it, as :meth:`step` does, instead of predicting across it (on
        the simulator's accel_brake with 2 s cut out: max v_x error after the gap 0.17 m/s,
        0.23 without the restart; issue 15 measured 7.7 m/s on an older filter). The rows
        after a gap are flagged "not
        converged" for ``validity.converge_s``, and :attr:`gaps` lists each gap (start, end).
        """
        frames = list(self.run_pieces([log], chunk=chunk, progress=progress, total=len(log)))
        return frames[0]

    def run_pieces(self, pieces: Iterable[pd.DataFrame], chunk: int = CHUNK,
                   progress: Callable[[float], None] | None = None,
                   total: int | None = None) -> Iterator[pd.DataFrame]:
        """Estimate over a log given as consecutive pieces (state reset first); yields each
        piece's estimates as it is done, so a long log goes in bounded memory
        (:func:`vestim.io.iter_log` reads the pieces, :class:`vestim.io.LogWriter` writes
        them).

        Every stage's state carries over from one piece to the next, and a time gap between
        two pieces restarts the filters as one inside a piece does: the pieces concatenated are
        :meth:`run` of the whole log, bit for bit. The first piece fixes the output columns (a
        channel a later piece lacks is NaN there). ``progress`` gets the fraction of ``total``
        samples done (it is not called without ``total``).

        Raises:
            LogFormatError: a piece's structure is wrong, or its ``t`` does not go on
                increasing from the piece before.
        """
        self.reset()
        self.gaps = []
        self.vy_unverified_rows = 0
        self.rows_estimated = 0
        b = self.vehicle.body
        health_state, imu_state = new_health_state(), new_imu_state()
        names: list[str] = []
        t_last, done = -math.inf, 0
        try:
            for log in pieces:
                check_structure(log, source="Pipeline.run input", first_row=done)
                if done == 0:  # the log's own declaration, else the configuration's
                    kind = str(log.attrs.get("accelerometer",
                                             self.config.force_params.accelerometer))
                    try:
                        self.force.set_accelerometer(kind)
                    except ValueError as exc:
                        raise LogFormatError(f"log metadata {exc} (what ax, ay, az hold)") from None
                log = corrected_log(log, self.vehicle.calibration, wheel_radius=b.wheel_radius,
                                    steering_ratio=b.steering_ratio)
                u = inputs_from_log(log, self.vehicle)
                n = u.t.shape[0]
                if not u.t[0] > t_last:
                    raise LogFormatError(
                        f"Pipeline.run input: column 't' is not strictly increasing at row {done}"
                        f" (t = {u.t[0]!r} s after t = {t_last!r} s); give the pieces in order")
                # the first sample after each gap (and the piece's first, after one between
                # pieces): the filters and the wheel health start again there
                after = np.flatnonzero(np.diff(np.concatenate(([t_last], u.t))) > GAP_S)
                restarts = [int(i) for i in after if t_last > -math.inf or i > 0]
                self.gaps += [(float(t_last if i == 0 else u.t[i - 1]), float(u.t[i]))
                              for i in restarts]
                cuts = [0, *(i for i in restarts if i > 0), n]
                omega, health = np.empty_like(u.omega), np.empty_like(u.omega)
                imu = np.empty((3, n))  # a_x, a_y, yaw rate with the faulty readings replaced
                imu_health = np.empty((n, 3))
                for s_, e in itertools.pairwise(cuts):
                    if s_ in restarts:
                        health_state, imu_state = new_health_state(), new_imu_state()
                    wheel_health_kernel(self._health_prm, health_state, u.t[s_:e],
                                        np.ascontiguousarray(u.omega[s_:e]), omega[s_:e],
                                        health[s_:e])
                    imu_health_kernel(self._imu_prm, imu_state, u.t[s_:e], u.ax[s_:e],
                                      u.ay[s_:e], u.yaw_rate[s_:e], omega[s_:e],
                                      np.ascontiguousarray(u.delta[s_:e]), imu[0, s_:e],
                                      imu[1, s_:e], imu[2, s_:e], imu_health[s_:e])
                u = replace(u, omega=omega, ax=imu[0], ay=imu[1], yaw_rate=imu[2])
                faulty = np.any(health == 0.0, axis=1) | np.any(imu_health == 0.0, axis=1)
                spans = [(a, min(a + chunk, e)) for s_, e in itertools.pairwise(cuts)
                         for a in range(s_, max(e, s_ + 1), chunk)]

                def advance(a: int, stop: int, u: Inputs = u, faulty: np.ndarray = faulty,
                            health: np.ndarray = health, imu_health: np.ndarray = imu_health,
                            restarts: list[int] = restarts, done: int = done,
                            ) -> list[ColumnGroup]:
                    if a in restarts:  # the first sample after a gap: start again
                        self.reset()
                    self._chunk_faulty, self._chunk_health = faulty[a:stop], health[a:stop]
                    self._chunk_imu = imu_health[a:stop]
                    groups = self._groups(u.t[a:stop], self._advance(_slice_inputs(u, a, stop)))
                    if progress is not None and total:
                        progress(min((done + stop) / total, 1.0))
                    return groups

                frame = frame_from_chunks((advance(a, e) for a, e in spans), n, names)
                names = list(frame.columns)
                t_last, done = float(u.t[-1]), done + n
                yield frame
        finally:
            self._chunk_faulty = self._chunk_health = self._chunk_imu = None

    def step(self, sample: Mapping[str, float]) -> dict[str, float]:
        """Advance by one sample (mapping of the log's column names); return that row.

        Samples with wheel torques and ``az`` in the common configurations go through one
        compiled call (:mod:`vestim.pipeline.online`); others through the general path. Both give
        the batch result.

        A live feed drops values: a NaN or inf in a measured channel is replaced by its value
        in the last sample whose every value was finite, for up to :data:`HOLD_S` (one bad
        value must not make every later row NaN); longer, or a non-finite or non-increasing
        ``t``, raises
        :class:`~vestim.errors.LogFormatError` naming the channel. ``gnss_speed`` is sparse:
        NaN means "no fix".
        """
        t_new = float(sample.get("t", np.nan))
        if math.isfinite(self._t_prev_step) and t_new - self._t_prev_step > GAP_S:
            gap = (self._t_prev_step, t_new)
            self.reset()  # as run() does after a gap
            self.gaps.append(gap)
        sample = self._hold_gaps(sample)
        sample = self._wheel_health(sample)
        cal = self.vehicle.calibration
        if cal is not None and cal.groups:
            b = self.vehicle.body
            cols = {k: np.array([float(v)]) for k, v in sample.items()}
            correct_columns(cols, cal, wheel_radius=b.wheel_radius, steering_ratio=b.steering_ratio)
            sample = {k: float(v[0]) for k, v in cols.items()}
        sample = self._imu_health(sample)
        row = self._fast_step(sample)
        if row is not None:
            return row
        self._step_args = self._step_fn = None  # the general path moves state it caches
        u = self.force._inputs_from_sample(sample)
        cols = columns_from_groups(self._groups(u.t, self._advance(u)))
        return {k: float(v[0]) for k, v in cols.items()}

    def _fast_step(self, sample: Mapping[str, float]) -> dict[str, float] | None:
        """One sample through :func:`vestim.pipeline.online.step_kernel`, or None if not covered
        (a ``gnss_speed`` channel takes the general path)."""
        if "gnss_speed" in sample:
            return None
        if self._step_args is None:
            self._step_args = online.build_step(self)
            if self._step_args is None:
                return None
            per_corner = ("vx", "vy", "vxt", "vyt", "slip_ratio", "slip_angle", "fx", "fy", "fz",
                          "mu_x", "mu_y", "sigma_fx", "sigma_fy")
            self._step_names = ["t", "vx", "vy", "sigma_vx", "sigma_vy",
                                *(f"{q}_{c}" for q in per_corner for c in CORNERS),
                                "roll", "pitch", "bias_ax", "cornering_stiffness"]
        try:
            vec = [float(sample[k]) for k in online.SAMPLE_KEYS[:13]]  # t … yaw_rate
            vec += [float(sample.get("roll_rate", np.nan)),
                    float(sample.get("pitch_rate", np.nan)),
                    float(sample["delta_fl"]), float(sample["delta_fr"])]
        except KeyError:  # no torques, az or per-wheel steering: the general path
            return None
        s = np.array(vec)
        out = np.empty(len(self._step_names))
        args = self._step_args
        if self._step_fn is None:  # the entry point for these argument types, typed once
            self._step_fn = _compiled(online.step_kernel, s, out, *args)
        self._step_fn(s, out, *args)
        pstate = args[online.STEP_PSTATE]
        self._prev = pstate[:2]  # a view: the general path replaces it, never writes into it
        self._fused_is_reference = bool(pstate[2])
        if self.corner is not None and self.config.velocity == "fused":
            self.corner._t_last = vec[0]
        rates = ("roll_rate" in sample, "pitch_rate" in sample)
        if rates != self._step_rates:
            self._step_rates = rates
            self.force.note_sources({
                "torque_source": "measured", "az_source": "measured",
                "roll_source": "rate" if rates[0] else "quasi_static",
                "pitch_source": "rate" if rates[1] else "quasi_static",
                "ax_source": "measured", "speed_source": "wheel_speeds",
                "outputs_unavailable": "none"})
        row = dict(zip(self._step_names, out.tolist(), strict=True))
        row["radius_scale"] = 1.0  # no gnss_speed on this path
        row["gnss_latency"] = 0.0
        self._fast_post(out, s, row)
        return row

    def _fast_post(self, out: np.ndarray, s: np.ndarray, row: dict[str, float]) -> None:
        """The friction, validity and uncertainty stages and the health flags for one sample
        ``s`` (layout of :data:`~vestim.pipeline.online.SAMPLE_KEYS` + δ_fl, δ_fr) of the
        compiled path, in one call of :func:`~vestim.pipeline.online.post_step_kernel`
        (the same steps as :meth:`_advance`'s kernels) on buffers made once."""
        if self._post is None:
            at = {name: j for j, name in enumerate(self._step_names)}
            ix = [at["t"], at["vx"], at["sigma_vy"], at["cornering_stiffness"]]
            ix += [at[f"{q}_{c}"] for q in ("fx", "fy", "fz", "sigma_fx", "sigma_fy",
                                            "slip_ratio", "slip_angle") for c in CORNERS]
            ix_unc = [at[k] for k in ("vx", "sigma_vx", "sigma_vy", "cornering_stiffness")]
            ix_unc += [at[f"{q}_{c}"] for q in ("fz", "vxt", "vyt", "slip_ratio")
                       for c in CORNERS]
            self._post = (np.array(ix, dtype=np.int64), np.array(ix_unc, dtype=np.int64),
                          np.empty(online.N_POST))
        ix, ix_unc, post = self._post
        if math.isnan(self._t_start):
            self._t_start = float(out[ix[0]])
        ones = _ONES
        wheel = ones if self._chunk_health is None else self._health_buf[2][0]
        imu = ones if self._chunk_imu is None else self._imu_buf[3][0]
        ref = self.reference if self._fused_is_reference else self.fused  # the one output
        self._calls()[2](self._friction_prm, self._friction_state, self._validity_prm,
                         self._unc_prm, self._unc_state, out, ix, ix_unc, s,
                         bool(self._held_now), self._t_start,
                         float(ref.state.t_vy_unverified[0]), wheel, imu, post)
        row.update(zip(_POST_NAMES, post.tolist(), strict=True))


_HELD = {False: np.array([False]), True: np.array([True])}
"""step()'s "input held" row of the block, by value (read only)."""

_ONES = np.ones(4)
"""The health of a stage that did not run in step() (1.0: healthy)."""

_OMEGA_KEYS = tuple(f"omega_{c}" for c in CORNERS)

_POST_NAMES: tuple[str, ...] = (
    *(n for c in CORNERS for n in (f"mu_{c}", f"sigma_mu_{c}", f"mu_{c}_excited")),
    *(n for g in VALIDITY_GROUPS for n in (f"valid_{g}", f"reason_{g}")),
    *(f"health_omega_{c}" for c in CORNERS), "health_ax", "health_ay", "health_yaw_rate",
    *SIGMA_NAMES)
"""The names of :func:`online.post_step_kernel`'s ``post`` row, in order (step()'s row
order)."""


UNVERIFIED_WARN = 0.01
"""Share of a run's rows with v_y unverified from which the output metadata warns."""


def _compiled(kernel: Any, *args: Any) -> Callable[..., None]:
    """The compiled entry point of the Numba ``kernel`` for the types of ``args`` (loaded
    from the cache or compiled): a call skips the dispatcher's per-call typing. Call it
    only with arguments of those types."""
    return kernel.compile(tuple(numba.typeof(a) for a in args))


def estimate(
    log: pd.DataFrame | str | Path,
    vehicle: Vehicle | str | Path,
    config: PipelineConfig | None = None,
) -> pd.DataFrame:
    """Estimate forces and velocities for a whole log: the library form of ``vestim estimate``.

    Args:
        log: a drive log (spec columns and SI units, docs/format.md) or the path of a
            ``.csv`` / ``.parquet`` file; it is only read.
        vehicle: a :class:`~vestim.io.vehicle.Vehicle`, a vehicle TOML file or a built-in name.
        config: the stages and their parameters (default: :class:`PipelineConfig`).

    Returns:
        One row per input sample: ``t`` and the estimate channels listed in this module's
        docstring (SI units); its ``attrs`` hold the metadata ``vestim estimate`` writes
        (:func:`vestim.pipeline.provenance.estimate_metadata`, the input checks' warnings
        included).
    """
    from vestim.io import load_vehicle, read_log
    from vestim.io.sanity import find_problems
    from vestim.pipeline.provenance import estimate_metadata

    veh = vehicle if isinstance(vehicle, Vehicle) else load_vehicle(vehicle)
    df = log if isinstance(log, pd.DataFrame) else read_log(
        log, require=["measured"], wheel_radius=veh.body.wheel_radius)
    pipe = Pipeline(veh, config)
    out = pipe.run(df)
    meta: dict[Any, Any] = estimate_metadata(
        pipe, vehicle, source="DataFrame" if log is df else str(log), log_attrs=df.attrs,
        findings=[f.as_dict() for f in find_problems(df, veh)])
    out.attrs = meta
    return out
