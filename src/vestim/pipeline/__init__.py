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
import logging
import math
import operator
from collections.abc import Callable, Iterable, Iterator, Mapping
from dataclasses import replace
from pathlib import Path
from typing import Any, NamedTuple

import numba
import numpy as np
import pandas as pd

from vestim import _cache
from vestim.constants import CORNERS, G
from vestim.errors import LogFormatError
from vestim.estimators import registry
from vestim.estimators.force import ForceEstimator
from vestim.estimators.force.estimator import WHEEL_OUTPUTS
from vestim.estimators.friction import (
    corner_kx,
    friction_params,
    new_friction_state,
)
from vestim.estimators.health import (
    health_params,
    imu_health_kernel,
    imu_health_params,
    new_imu_state,
    wheel_health_kernel,
)
from vestim.estimators.health import new_state as new_health_state
from vestim.estimators.uncertainty import new_state as new_uncertainty_state
from vestim.estimators.uncertainty import (
    uncertainty_params,
)
from vestim.estimators.validity import VY_UNVERIFIED, new_consistency_state, validity_params
from vestim.estimators.velocity.corner import LPV, CornerVelocityEstimator
from vestim.estimators.velocity.kinematic import KinematicIntegrator
from vestim.estimators.velocity.lpv_observer import LPVParams
from vestim.estimators.velocity.lugre_kf import KFParams
from vestim.estimators.velocity.reference import (
    ReferenceFilter,
    clear_state,
    new_radius_state,
    new_stiffness_state,
    radius_params,
    stiffness_params,
)
from vestim.io.calibration import correct_columns, corrected_log
from vestim.io.channels import REF_PREFIX, SPARSE
from vestim.io.inputs import Inputs, front_angles, inputs_from_log, sample_channels
from vestim.io.log import check_structure
from vestim.io.sanity import SAMPLE_RANGES, validate_sample
from vestim.io.vehicle import Vehicle
from vestim.models import kinematics as kin
from vestim.pipeline import rows as rows_kernel
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
        self._t_gnss = np.array([np.nan])  # the previous sample's time (a fix's weight)
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
        if corner_method is not None and registry.lookup("corner", corner_method).code == LPV:
            params = _lpv_params_from_gains(self.config.gains) if self.config.gains else None
        self.corner = (CornerVelocityEstimator(vehicle, corner_method, params)
                       if corner_method is not None else None)
        # The fused filter: a second reference filter that also takes the corner estimates.
        self.fused = ReferenceFilter(b.wheel_radius, b.lf, b.lr, self._xw, self._yw,
                                     self.config.reference, mass=b.mass)
        self._prev = np.array([np.nan, 0.0])  # (t, yaw rate) of the previous sample, for ṙ
        self._fused_same = True  # the fused filter has not diverged from the plain one
        # pipeline_rows' parameter and state trees (sharing the stages' arrays) and its entry
        # point for their types: made on first use, dropped when a stage's state is replaced
        self._rows: tuple[rows_kernel.Params, rows_kernel.State] | None = None
        self._rows_fn: Callable[..., None] | None = None
        self._stepper: rows_kernel.Stepper | None = None  # the trees, held by compiled code
        self._step_fn: Callable[..., None] | None = None  # step_sample's entry point
        self._rows_names: tuple[str, ...] = ()  # the output order the trees write
        self._x1 = np.empty((1, rows_kernel.N_X))  # step()'s input row and output column
        self._y1 = np.empty((rows_kernel.N_ROW, 1))
        self._t_prev_step = -math.inf  # step()'s guard: last t, last finite value per channel
        # the last sample whose every value was finite, and its time (step()'s hold)
        self._last_good: tuple[float, tuple[str, ...], tuple[Any, ...]] = (-math.inf, (), ())
        self._t_start = np.array([np.nan])  # first sample time (validity flags' convergence)
        self._consistency_state = new_consistency_state()  # validity bit 128's test
        self._corner_seeded = np.zeros(1)  # the corner observers took the reference's v (1.0)
        self._held_now = False  # step() held a dropped input in this sample
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
        self._unc_prm = uncertainty_params(vehicle, self.config.uncertainty)
        self._validity_prm = validity_params(self.config.validity)
        self._unc_state = new_uncertainty_state()
        self._layout: _Layout | None = None  # step()'s channels, checked once per set
        self._fast: _Fast | None = None  # step()'s index maps for its channels

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
        self._last_good = (-math.inf, (), ())
        self._health_state = new_health_state()
        self._imu_state = new_imu_state()
        self._unc_state = new_uncertainty_state()
        self._t_start = np.array([np.nan])  # first sample time (validity flags' convergence)
        self._consistency_state = new_consistency_state()  # validity bit 128's test
        self._corner_seeded = np.zeros(1)  # the corner observers took the reference's v (1.0)
        self._held_now = False  # step() held a dropped input in this sample
        self._t_gnss = np.array([np.nan])
        self._fused_is_reference = True
        self._rows = None
        self._stepper = None
        self._layout = None

    @property
    def _fused_is_reference(self) -> bool:
        """Whether the fused filter is still the plain reference filter (the compiled
        state's flag where the trees exist)."""
        if self._rows is not None:
            return bool(self._rows[1].velocity.prev[rows_kernel.PREV_FUSED_SAME])
        return self._fused_same

    @_fused_is_reference.setter
    def _fused_is_reference(self, value: bool) -> None:
        self._fused_same = value

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

    def _note_sources(self, u: Inputs) -> None:
        """The input sources of ``u`` in the force estimator's metadata (after its own)."""
        self.force.note_sources({
            "ax_source": "measured" if u.ax_measured else u.speed_source,
            "speed_source": u.speed_source,
            "outputs_unavailable": ("none" if u.omega_measured
                                    else ",".join(WHEEL_ONLY_OUTPUTS))})

    def _columns(self, wheels: bool) -> tuple[str, ...]:
        """The output columns of this configuration for a log with or without wheel speeds
        (:func:`~vestim.pipeline.rows.output_columns`).

        Raises:
            PipelineConfigError: the velocity method needs wheel speeds and there are none.
        """
        cfg = self.config
        velocity = registry.lookup("velocity", cfg.velocity)
        if not wheels and velocity.needs_wheel_speeds:
            raise PipelineConfigError(
                f"velocity method {cfg.velocity!r} needs the wheel speeds omega_fl … omega_rr, "
                "which the log does not have: use velocity 'reference' (the default) or 'fused'")
        corners = velocity.corner is not None and wheels
        force = registry.lookup("force", cfg.force)
        fusion = registry.lookup("fusion", cfg.fusion)
        return rows_kernel.output_columns(
            wheels, "sigma_fx" in force.outputs, "sigma_v" in velocity.outputs,
            "bias_ax" in velocity.outputs, corners and "confidence" in fusion.outputs)

    def _run_rows(self, u: Inputs, faulty: np.ndarray, health: np.ndarray,
                  imu_health: np.ndarray, spans: list[tuple[int, int]], restarts: list[int],
                  names: tuple[str, ...], on_span: Callable[[int], None]) -> pd.DataFrame:
        """One piece's estimates through :func:`~vestim.pipeline.rows.pipeline_rows`, span by
        span (a restart after each gap), into one block (the frame's transpose)."""
        self.force.note_sources(u.sources)
        self._note_sources(u)
        n = u.t.shape[0]
        block = np.empty((len(names), n))
        written = rows_kernel.columns(names)
        block[np.setdiff1d(np.arange(len(names)), written[written >= 0])] = np.nan
        X = np.empty((max(b - a for a, b in spans), rows_kernel.N_X))
        speed = u.vehicle_speed if u.vehicle_speed is not None else np.full(n, np.nan)
        inputs = (u.t, u.omega, u.torque, u.ax, u.ay, u.az, u.yaw_rate, u.roll_rate,
                  u.pitch_rate, u.delta[:, :2], faulty, health, imu_health, u.gnss_speed, speed)
        sensors = rows_kernel.Sensors(ax=u.ax_measured, az=u.az_measured,
                                      torque=u.torque_measured, omega=u.omega_measured,
                                      vehicle_speed=u.vehicle_speed is not None)
        for a, stop in spans:
            if a in restarts:  # the first sample after a gap: start again
                self.reset()
            self._trees(names, sensors)
            j = 0
            for values in inputs:
                width = 1 if values.ndim == 1 else values.shape[1]
                X[:stop - a, j:j + width] = values[a:stop].reshape(stop - a, width)
                j += width
            self._call_rows(X, block, a, stop)
            on_span(stop)
        reason = block[names.index("reason_velocity")].astype(np.int64)
        self.vy_unverified_rows += int(np.count_nonzero(reason & VY_UNVERIFIED))
        self.rows_estimated += n
        return pd.DataFrame(block.T, columns=list(names), copy=False)

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
            # validate_sample's own copy, never changed after
            self._last_good = (t, tuple(sample.keys()), tuple(sample.values()))
            self._held_now = False
            return sample
        fixed: dict[str, float] | None = None
        t_good, good_keys, good_values = self._last_good
        good = dict(zip(good_keys, good_values, strict=True))
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
                    f"sample at t = {t:.3f} s: channel {key!r} is "
                    f"{getattr(sample, 'rejected', {}).get(key, v)} and has had no finite value "
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

            def on_span(stop: int, done: int = done) -> None:
                if progress is not None and total:
                    progress(min((done + stop) / total, 1.0))

            frame = self._run_rows(u, faulty, health, imu_health, spans, restarts,
                                   tuple(names) or self._columns(u.omega_measured), on_span)
            names = list(frame.columns)
            t_last, done = float(u.t[-1]), done + n
            yield frame

    def step(self, sample: Mapping[str, float]) -> dict[str, float]:
        """Advance by one sample (mapping of the log's column names); return that row.

        The sample goes through :func:`~vestim.pipeline.rows.pipeline_rows`, the call
        :meth:`run` makes over its blocks, so the two give the same numbers.

        A live feed drops values: a NaN or inf in a measured channel is replaced by its value
        in the last sample whose every value was finite, for up to :data:`HOLD_S` (one bad
        value must not make every later row NaN); longer, or a non-finite or non-increasing
        ``t``, raises
        :class:`~vestim.errors.LogFormatError` naming the channel. ``gnss_speed`` is sparse:
        NaN means "no fix". A value of the wrong type (``None``, a string, a list) or outside
        its channel's physical range (:func:`vestim.io.sanity.validate_sample`) is such a
        dropped value too. This is the gate of a live feed; :func:`estimate` is the gated
        form of :meth:`run` (the whole-log checks, :func:`vestim.io.sanity.gate`).
        """
        f = self._fast
        if (f is not None and type(sample) is dict and sample.keys() == f.keys
                and f.layout is self._layout):
            vals = f.check(sample)
            t = vals[0]
            t_prev = self._t_prev_step
            # every value a float, finite and in its channel's range, t a step on
            # without a gap: validate_sample and the hold would change nothing
            if (_FAST_TYPES.issuperset(map(type, vals)) and t > t_prev
                    and t - t_prev <= GAP_S and all(map(operator.le, f.lo, vals))
                    and all(map(operator.le, vals, f.hi))):
                clean = True
                for key, lo, hi in f.sparse:  # NaN: no fix (the sample is not "clean")
                    v = sample[key]
                    if type(v) not in _FAST_TYPES or not (lo <= v <= hi or v != v):
                        break
                    clean = clean and v == v
                else:
                    return self._fast_step(f, sample, vals, clean)
        raw = sample
        sample = validate_sample(sample)
        t_new = float(sample.get("t", np.nan))
        if math.isfinite(self._t_prev_step) and t_new - self._t_prev_step > GAP_S:
            gap = (self._t_prev_step, t_new)
            self.reset()  # as run() does after a gap
            self.gaps.append(gap)
        sample = self._hold_gaps(sample)
        cal = self.vehicle.calibration
        if cal is not None and cal.groups:  # before the health stages, as in run()
            b = self.vehicle.body
            cols = {k: np.array([float(v)]) for k, v in sample.items()}
            correct_columns(cols, cal, wheel_radius=b.wheel_radius, steering_ratio=b.steering_ratio)
            sample = {k: float(v[0]) for k, v in cols.items()}
        out = self._row_step(sample)
        if cal is None or not cal.groups:
            self._fast = _fast_layout(self._fast, raw, self._layout,
                                      self.vehicle.body.steering_ratio, self._y1)
        return out

    def _fast_step(self, f: _Fast, sample: Mapping[str, Any], vals: tuple[Any, ...],
                   clean: bool) -> dict[str, float]:
        """:meth:`step` of a sample that :func:`~vestim.io.sanity.validate_sample` and the
        hold would leave as it is (every value a real number in its range, finite but for a
        sparse channel's NaN, ``t`` on by at most :data:`GAP_S`) with the channels of the
        sample before: its values straight into the input row by the layout's index map,
        the compiled step, and the output row as a dict."""
        t = vals[0]
        self._t_prev_step = float(t)
        if clean:
            self._last_good = (t, f.check_keys, vals)
        self._held_now = False
        x = self._x1[0]
        x[:] = f.base
        x[f.dst] = f.read(sample)
        if f.ratio:  # a steering-wheel angle: the road-wheel angles are it over the ratio
            x[rows_kernel.X_DELTA:rows_kernel.X_DELTA + 2] /= f.ratio
        step_fn = self._step_fn
        assert step_fn is not None
        step_fn(self._stepper, self._x1, self._y1)
        if self.corner is not None:
            self.corner._t_last = float(t)
        # out has len(columns) entries by make: strict=True would cost 2 µs a sample
        return dict(zip(f.layout.columns, f.out.tolist(), strict=False))

    def _trees(self, names: tuple[str, ...], sensors: rows_kernel.Sensors) -> None:
        """Make :func:`~vestim.pipeline.rows.pipeline_rows`' parameter and state trees once
        (until a reset), for a log with ``sensors``, writing Y's rows in
        the order of ``names``."""
        if self._rows is None or sensors != self._rows[0].sensors:
            self._rows = rows_kernel.build(self, names, sensors)
            self._rows_names = names
            self._stepper = None
        elif names is not self._rows_names:
            P, S = self._rows
            self._rows = (P._replace(col=rows_kernel.columns(names)), S)
            self._rows_names = names
            self._stepper = None

    def _call_rows(self, X: np.ndarray, Y: np.ndarray, start: int, stop: int) -> None:
        """:func:`~vestim.pipeline.rows.pipeline_rows` on the trees, through the entry point
        for their types (typed once), then the Python-side state that mirrors its state."""
        assert self._rows is not None
        P, S = self._rows
        if self._rows_fn is None:
            self._rows_fn = _compiled(rows_kernel.pipeline_rows, P, S, X, Y, start, stop)
        self._rows_fn(P, S, X, Y, start, stop)
        self._mirror(S, X, stop - start)

    def _mirror(self, S: rows_kernel.State, X: np.ndarray, m: int) -> None:
        """The Python-side state that mirrors the compiled one after ``m`` rows of ``X``."""
        self._prev = S.velocity.prev[:rows_kernel.PREV_R + 1]  # (t, r), a view (reset() replaces it)
        if self.corner is not None:
            self.corner._t_last = float(X[m - 1, rows_kernel.X_T])

    def _step_layout(self, sample: Mapping[str, float]) -> _Layout:
        """What a sample with these channels holds (checked once per set of channels).

        Raises:
            LogFormatError: a required channel, or a steering channel, is missing; some wheel
                speeds or torques but not all four; no speed channel at all.
        """
        keys = sample.keys()
        if self._layout is not None and keys == self._layout.keys:
            return self._layout
        torques, wheels, steering = sample_channels(sample)
        present = ("ax" in sample, "az" in sample, torques, wheels, "vehicle_speed" in sample,
                   "roll_rate" in sample, "pitch_rate" in sample)
        speed = "wheel_speeds" if wheels else "vehicle_speed" if present[4] else "gnss_speed"
        self.force.note_sources({
            "torque_source": "measured" if torques else "chassis",
            "az_source": "measured" if present[1] else "level_road",
            "roll_source": "rate" if present[5] else "quasi_static",
            "pitch_source": "rate" if present[6] else "quasi_static",
            "ax_source": "measured" if present[0] else speed, "speed_source": speed,
            "outputs_unavailable": "none" if wheels else ",".join(WHEEL_ONLY_OUTPUTS)})
        self._layout = _Layout(set(keys), _SENSORS[present[:5]], steering,
                               self._columns(wheels))
        return self._layout

    def _row_step(self, sample: Mapping[str, float]) -> dict[str, float]:
        """One sample through :func:`~vestim.pipeline.rows.pipeline_rows` (the call run()
        makes over its blocks)."""
        layout = self._step_layout(sample)
        sensors = layout.sensors
        x = self._x1[0]
        get = sample.get
        nan = math.nan
        x[rows_kernel.X_T] = float(sample["t"])
        for j, key in enumerate(_OMEGA_KEYS, rows_kernel.X_OMEGA):
            x[j] = float(sample[key]) if sensors.omega else nan
        for j, key in enumerate(_TORQUES, rows_kernel.X_TORQUE):
            x[j] = float(sample[key]) if sensors.torque else nan
        x[rows_kernel.X_DELTA], x[rows_kernel.X_DELTA + 1] = front_angles(
            sample, layout.steering, self.vehicle.body.steering_ratio)
        x[rows_kernel.X_AX] = float(get("ax", nan))
        x[rows_kernel.X_AY] = float(get("ay", 0.0))
        x[rows_kernel.X_AZ] = float(get("az", nan))
        x[rows_kernel.X_R] = float(get("yaw_rate", 0.0))
        x[rows_kernel.X_P] = float(get("roll_rate", nan))
        x[rows_kernel.X_Q] = float(get("pitch_rate", nan))
        x[rows_kernel.X_GNSS] = float(get("gnss_speed", nan))
        x[rows_kernel.X_VSPEED] = float(get("vehicle_speed", nan))
        x[rows_kernel.X_HELD] = 1.0 if self._held_now else 0.0
        columns = layout.columns
        self._trees(columns, sensors)
        assert self._rows is not None
        if self._stepper is None:
            self._stepper = rows_kernel.new_stepper(*self._rows, rows_kernel.new_health_buffers(
                self._health_prm, self._health_state, self._imu_prm, self._imu_state))
            if self._step_fn is None:  # the entry point for these types, typed once
                with _cache.compile_notice(_LOG.warning):  # a first run compiles ~1 min
                    self._step_fn = _compiled(rows_kernel.step_sample, self._stepper,
                                              self._x1, self._y1)
        step_fn = self._step_fn
        assert step_fn is not None
        step_fn(self._stepper, self._x1, self._y1)
        self._mirror(self._rows[1], self._x1, 1)
        return dict(zip(columns, self._y1[:len(columns), 0].tolist(), strict=True))


class _Layout(NamedTuple):
    """A sample's channels as :meth:`Pipeline.step` read them: its keys, the sensors, the
    steering channel (``delta_fl`` for both front wheels' angles, ``delta`` or
    ``steering_wheel_angle``) and the output columns."""

    keys: set[str]
    sensors: rows_kernel.Sensors
    steering: str
    columns: tuple[str, ...]


class _Fast(NamedTuple):
    """What :meth:`Pipeline.step` precomputes per set of a sample's keys (``keys``, the
    sample's own, unknown names included) for its fast path: ``check`` reads ``t`` and the
    other channels :func:`~vestim.io.sanity.validate_sample` keeps but the sparse ones
    (``check_keys``, in that order), whose ranges are ``lo`` ≤ value ≤ ``hi`` (``t``'s
    unbounded: it is checked against the last one); ``sparse`` (name, low, high) of each
    sparse channel; ``read`` reads the values that go to the input row's columns ``dst``
    (the others stay as in ``base``: NaN for a channel the sample lacks, ``X_HELD`` 0);
    ``ratio`` the steering ratio where the steering channel is the steering-wheel angle
    (else 0); ``out`` the view of the output column that holds ``layout.columns``."""

    keys: frozenset[str]
    layout: _Layout
    check: Callable[[Mapping[str, Any]], tuple[Any, ...]]
    check_keys: tuple[str, ...]
    lo: tuple[float, ...]
    hi: tuple[float, ...]
    sparse: tuple[tuple[str, float, float], ...]
    read: Callable[[Mapping[str, Any]], tuple[Any, ...]]
    dst: np.ndarray
    base: np.ndarray
    ratio: float
    out: np.ndarray


def _fast_layout(last: _Fast | None, sample: Mapping[str, Any], layout: _Layout | None,
                 steering_ratio: float, y1: np.ndarray) -> _Fast | None:
    """``last`` if it is for ``sample``'s keys and ``layout``, else a new :class:`_Fast`
    (None for a sample that is not a dict: the fast path compares its keys as a set)."""
    if layout is None or type(sample) is not dict:
        return None
    if last is not None and last.layout is layout and sample.keys() == last.keys:
        return last
    checked = [k for k in sample if k in SAMPLE_RANGES and k not in SPARSE]
    check_keys = ("t", *checked)
    sensors = layout.sensors
    to_x: list[tuple[str, int]] = [("t", rows_kernel.X_T)]
    if sensors.omega:
        to_x += [(k, j) for j, k in enumerate(_OMEGA_KEYS, rows_kernel.X_OMEGA)]
    if sensors.torque:
        to_x += [(k, j) for j, k in enumerate(_TORQUES, rows_kernel.X_TORQUE)]
    to_x += [(k, j) for k, j in (("ax", rows_kernel.X_AX), ("ay", rows_kernel.X_AY),
                                 ("az", rows_kernel.X_AZ), ("yaw_rate", rows_kernel.X_R),
                                 ("roll_rate", rows_kernel.X_P), ("pitch_rate", rows_kernel.X_Q),
                                 ("gnss_speed", rows_kernel.X_GNSS),
                                 ("vehicle_speed", rows_kernel.X_VSPEED)) if k in sample]
    left, right = ("delta_fl", "delta_fr") if layout.steering == "delta_fl" else (
        layout.steering, layout.steering)
    to_x += [(left, rows_kernel.X_DELTA), (right, rows_kernel.X_DELTA + 1)]
    base = np.full(rows_kernel.N_X, np.nan)
    base[rows_kernel.X_HELD] = 0.0
    names = [k for k, _ in to_x]
    return _Fast(
        frozenset(sample.keys()), layout, operator.itemgetter(*check_keys), check_keys,
        (-math.inf, *(SAMPLE_RANGES[k][0] for k in checked)),
        (math.inf, *(SAMPLE_RANGES[k][1] for k in checked)),
        tuple((k, *SAMPLE_RANGES[k][:2]) for k in sample if k in SPARSE and k in SAMPLE_RANGES),
        operator.itemgetter(*names), np.array([j for _, j in to_x], dtype=np.intp), base,
        steering_ratio if layout.steering == "steering_wheel_angle" else 0.0,
        y1[:len(layout.columns), 0])


_FAST_TYPES = frozenset((float, np.float64))
"""The value types :meth:`Pipeline.step`'s fast path takes (others go through
:func:`~vestim.io.sanity.validate_sample`)."""

_TORQUES = tuple(f"torque_{c}" for c in CORNERS)

_SENSORS = {key: rows_kernel.Sensors(*key) for key in itertools.product((False, True), repeat=5)}
"""The :class:`~vestim.pipeline.rows.Sensors` of a sample, made once."""

_OMEGA_KEYS = tuple(f"omega_{c}" for c in CORNERS)

_LOG = logging.getLogger("vestim")
"""Where the library's compile notice goes (a warning: on stderr without a logging setup)."""

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
    """Estimate forces and velocities for a whole log: the library form of ``vestim estimate``,
    behind the same input gate (:func:`vestim.io.sanity.gate`).

    Args:
        log: a drive log (spec columns and SI units, docs/format.md) or the path of a
            ``.csv`` / ``.parquet`` file; it is only read.
        vehicle: a :class:`~vestim.io.vehicle.Vehicle`, a vehicle TOML file or a built-in name.
        config: the stages and their parameters (default: :class:`PipelineConfig`).

    Returns:
        One row per input sample: ``t`` and the estimate channels listed in this module's
        docstring (SI units); its ``attrs`` hold the metadata ``vestim estimate`` writes
        (:func:`vestim.pipeline.provenance.estimate_metadata`): the input gate's ``warnings``
        (with the consistency monitor's) and ``checks_not_run``, the input sources, the
        configuration and the vehicle's provenance.

    Raises:
        LogFormatError: the log fails the input gate (e.g. a yaw rate with the wrong sign);
            the message names the channel and the fix.
    """
    from vestim.io import load_vehicle, read_log
    from vestim.io.sanity import gate
    from vestim.pipeline.provenance import estimate_metadata

    veh = vehicle if isinstance(vehicle, Vehicle) else load_vehicle(vehicle)
    df = log if isinstance(log, pd.DataFrame) else read_log(
        log, require=["measured"], wheel_radius=veh.body.wheel_radius)
    checked = gate(df, veh, source="log" if isinstance(log, pd.DataFrame) else str(log))
    pipe = Pipeline(veh, config)
    with _cache.compile_notice(_LOG.warning):  # a first run compiles for about a minute
        out = pipe.run(df)
    out.attrs.update(estimate_metadata(pipe, vehicle,
                                       source="DataFrame" if log is df else str(log),
                                       log_attrs=df.attrs, checked=checked))
    return out
