"""Stiffness estimators (thin shells around the kernels) and the public entry point.

:class:`NoiseAdaptivePF` is Algorithm 1 of 002; :class:`AugmentedPF`,
:class:`RlsKalman` and :class:`AugmentedEKF` are the baselines of 002 Sec. V–VI.
Each is complete when constructed, validates its arguments, and ``run`` maps
:class:`~vestim.estimators.stiffness.inputs.StiffnessInputs` to a
:class:`StiffnessResult`; :func:`estimate_stiffness` does the whole job on a log.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
import pandas as pd

from vestim.estimators.registry import register, registered
from vestim.estimators.stiffness.augpf import AugPFParams, AugPFState, augpf_kernel
from vestim.estimators.stiffness.baselines import (
    RlsEstimates,
    RlsInputs,
    RlsParams,
    RlsState,
    ekf_kernel,
    rls_kf_kernel,
)
from vestim.estimators.stiffness.config import StiffnessConfig, StiffnessPrior
from vestim.estimators.stiffness.draws import seed_state
from vestim.estimators.stiffness.inputs import StiffnessInputs, prepare_inputs
from vestim.estimators.stiffness.model import (
    N_STATE,
    N_W,
    U_DT,
    W_CX,
    W_CYF,
    W_CYR,
    YAW_RATE,
    SingleTrackParams,
)
from vestim.estimators.stiffness.pf import (
    L00,
    L11,
    L22,
    N_LAM,
    N_PB,
    PRR,
    PXX,
    PYY,
    Estimates,
    PFParams,
    PFState,
    SeriesInputs,
    alg1_kernel,
    new_estimates,
    pack_particles,
)
from vestim.io.vehicle import Vehicle


@dataclass(frozen=True)
class StiffnessResult:
    """Estimates over time (SI). Stiffness columns are (cx_f, cx_r, cy_f, cy_r).

    Attributes:
        t: (K,) s.
        stiffness, stiffness_sd: (K, 4) axle-total stiffness C_n + ΔC (002 eq. (7), (27a))
            and its one-sigma (square root of the diagonal of eq. (27b) for the particle
            filters: the spread of the stiffness itself, 002 Fig. 4; the parameter
            standard error for RLS and EKF). The longitudinal component that is not
            estimated (cx_r for FWD and AWD, cx_f for RWD) follows the relative change of
            the cornering stiffness of its axle (see :mod:`~vestim.estimators.stiffness.model`).
        state, state_sd: (K, 3) [v_x, v_y, ψ̇] (m/s, m/s, rad/s) and one-sigma (eq. (42)).
        bias: (K, 3) sensor bias [a_x, a_y, ψ̇] in sensor units (m/s², m/s², rad/s);
            zeros for RLS, which does not estimate it.
        active: (K,) activation flags (002 Sec. V).
        ess: (K,) effective sample size (particle filters), else ``None``.
        n_resampled: resampling events (particle filters), else 0.
        method: "pf" | "augpf" | "rls" | "ekf".
        longitudinal: "cx_f" or "cx_r", the estimated longitudinal component.
    """

    t: np.ndarray
    stiffness: np.ndarray
    stiffness_sd: np.ndarray
    state: np.ndarray
    state_sd: np.ndarray
    bias: np.ndarray
    active: np.ndarray
    ess: np.ndarray | None
    n_resampled: int
    method: str
    longitudinal: str

    def to_frame(self) -> pd.DataFrame:
        """Spec-format estimate log (see :func:`estimate_stiffness` for the columns)."""
        names = ("cx_f", "cx_r", "cy_f", "cy_r")
        cols: dict[str, np.ndarray] = {"t": self.t}
        for j, name in enumerate(names):
            if name.startswith("cx") and name != self.longitudinal:
                continue
            cols[f"stiffness_{name}"] = self.stiffness[:, j]
            cols[f"sigma_stiffness_{name}"] = self.stiffness_sd[:, j]
        for j, name in enumerate(("vx", "vy", "yaw_rate")):
            cols[name] = self.state[:, j]
            cols[f"sigma_{name}"] = self.state_sd[:, j]
        for j, name in enumerate(("bias_ax", "bias_ay", "bias_yaw_rate")):
            cols[name] = self.bias[:, j]
        cols["stiffness_active"] = self.active.astype(np.float64)
        return pd.DataFrame(cols)


class _Setup:
    """Shared validation and packing: model parameters, bounds of w, noise, initial state."""

    def __init__(self, vehicle: Vehicle, prior: StiffnessPrior | None = None,
                 config: StiffnessConfig | None = None) -> None:
        if not isinstance(vehicle, Vehicle):
            raise TypeError(f"vehicle must be a vestim.io.Vehicle, got {type(vehicle).__name__}")
        self.vehicle = vehicle
        self.prior = prior if prior is not None else StiffnessPrior.for_vehicle(vehicle)
        self.config = config if config is not None else StiffnessConfig()
        self.params = SingleTrackParams.from_vehicle(vehicle, self.prior.nominal)
        self.p = self.params.pack()
        lo_ax = np.asarray(self.prior.lower, dtype=float)
        hi_ax = np.asarray(self.prior.upper, dtype=float)
        sd_ax = np.asarray(self.prior.sigma, dtype=float)
        self.lo = self.params.axles_to_deviation(lo_ax)
        self.hi = self.params.axles_to_deviation(hi_ax)
        ix = 1 if self.params.drivetrain == "rwd" else 0
        self.sigma_w = np.array([sd_ax[ix], sd_ax[2], sd_ax[3]])
        self.nominal_w = np.array([self.prior.nominal[ix], self.prior.nominal[2],
                                   self.prior.nominal[3]])
        c = self.config
        self.r_pk = np.array([c.accel_noise**2, 0.0, c.accel_noise**2, c.gyro_noise**2])
        self.r_diag = np.array([c.accel_noise**2, c.accel_noise**2, c.gyro_noise**2])

    def q_pk(self, inputs: StiffnessInputs) -> np.ndarray:
        """Bias random walk per step (eq. (11)) at the median step length."""
        ts = float(np.median(inputs.u[:, U_DT]))
        qa = self.config.accel_bias_walk**2 * ts
        return np.array([qa, 0.0, qa, self.config.gyro_bias_walk**2 * ts])

    def bias_inflation(self, inputs: StiffnessInputs) -> float:
        """Steps per ``bias_correlation_time`` (at least 1): the bias update's residual inflation."""
        ts = float(np.median(inputs.u[:, U_DT]))
        return max(1.0, self.config.bias_correlation_time / ts)

    def forgetting_period(self, inputs: StiffnessInputs) -> float:
        """Seconds over which the statistics forget by λ (eq. (20)); see :class:`StiffnessConfig`."""
        c = self.config
        if c.forgetting_period > 0.0:
            return c.forgetting_period
        return float(np.median(inputs.u[:, U_DT]))

    def x0(self, inputs: StiffnessInputs) -> np.ndarray:
        """Initial mean [v_x, v_y, ψ̇]: wheel-speed reference, 0, measured yaw rate."""
        return np.array([inputs.speed[0], 0.0, inputs.y[0, YAW_RATE]])

    def _estimates_result(self, inputs: StiffnessInputs, out: Estimates, method: str,
                          n_resampled: int) -> StiffnessResult:
        """:meth:`result` of a particle filter's :class:`~vestim.estimators.stiffness.pf.Estimates`."""
        w_sd = np.sqrt(np.maximum(np.diagonal(out.w_cov, axis1=1, axis2=2), 0.0))
        return self.result(inputs, out.w_hat, w_sd, out.x_hat, np.sqrt(out.x_var), out.b_hat,
                           method, out.ess, n_resampled)

    def result(self, inputs: StiffnessInputs, w_hat: np.ndarray, w_sd: np.ndarray,
               state: np.ndarray, state_sd: np.ndarray, bias: np.ndarray, method: str,
               ess: np.ndarray | None = None, n_resampled: int = 0) -> StiffnessResult:
        kf, kr, tf, tr = self.params.longitudinal_split
        stiff = self.params.deviation_to_axles(w_hat)
        sd = np.column_stack([np.hypot(kf * w_sd[:, W_CX], tf * w_sd[:, W_CYF]),
                              np.hypot(kr * w_sd[:, W_CX], tr * w_sd[:, W_CYR]),
                              w_sd[:, W_CYF], w_sd[:, W_CYR]])
        bias_raw = bias.copy()
        bias_raw[:, 0] *= inputs.accel_scale[:, 0]
        bias_raw[:, 1] *= inputs.accel_scale[:, 1]
        return StiffnessResult(t=inputs.t, stiffness=stiff, stiffness_sd=sd, state=state,
                               state_sd=state_sd, bias=bias_raw, active=inputs.active,
                               ess=ess, n_resampled=n_resampled, method=method,
                               longitudinal=self.params.longitudinal_name)


def _series(inputs: StiffnessInputs) -> SeriesInputs:
    """The particle filters' time series; the bias filter runs once the log has settled."""
    return SeriesInputs(y=inputs.y, u=inputs.u, active=inputs.active, bias_on=inputs.settled)


def _check_particles(particles: int) -> int:
    if isinstance(particles, bool) or not isinstance(particles, int | np.integer) or particles < 2:
        raise ValueError(f"particles = {particles!r} must be an integer >= 2")
    return int(particles)


@register("stiffness", "pf", "noise-adaptive Rao-Blackwellised particle filter of the stiffness "
          "and the sensor noise", cite="002 Alg. 1", default=True, params=StiffnessConfig)
class NoiseAdaptivePF(_Setup):
    """Algorithm 1 of 002 (see :mod:`~vestim.estimators.stiffness.pf`).

    Args:
        vehicle: geometry, inertia, drag, drivetrain and suspension (roll/pitch gradients).
        prior: nominal stiffness, initial sigma and bounds (default
            :meth:`StiffnessPrior.for_vehicle`).
        config: tuning (default :class:`StiffnessConfig`).
        particles: N.
    """

    def __init__(self, vehicle: Vehicle, prior: StiffnessPrior | None = None,
                 config: StiffnessConfig | None = None, particles: int = 500) -> None:
        super().__init__(vehicle, prior, config)
        self.particles = _check_particles(particles)

    def kernel_params(self, inputs: StiffnessInputs) -> PFParams:
        """The kernel's parameters for a run over ``inputs`` (Q, the bias inflation and the
        forgetting period at the median step length)."""
        c = self.config
        return PFParams(p=self.p, r_pk=self.r_pk, q_pk=self.q_pk(inputs),
                        bias_inflation=self.bias_inflation(inputs), lo=self.lo, hi=self.hi,
                        forgetting=c.forgetting, forgetting_period=self.forgetting_period(inputs),
                        n_thr=c.resample_threshold * self.particles,
                        model_error=np.asarray(c.model_error, dtype=float),
                        gyro_lookahead=c.gyro_lookahead)

    def run(self, inputs: StiffnessInputs, rng: np.random.Generator) -> StiffnessResult:
        """Filter the whole series; ``rng`` draws the initial particles and seeds the kernel's
        random stream (:mod:`~vestim.estimators.stiffness.draws`)."""
        n = self.particles
        c = self.config
        k = inputs.t.shape[0]
        x = self.x0(inputs) + rng.standard_normal((n, N_STATE)) * np.asarray(c.initial_state_sd)
        mu = rng.standard_normal((n, N_W)) * self.sigma_w
        mu = np.clip(mu, self.lo, self.hi)
        lam = np.zeros((n, N_LAM))
        sd0 = (self.sigma_w if c.initial_noise_sd <= 0.0
               else c.initial_noise_sd * self.nominal_w)
        lam[:, L00] = (c.nu0 - N_W - 1.0) * sd0[0] ** 2
        lam[:, L11] = (c.nu0 - N_W - 1.0) * sd0[1] ** 2
        lam[:, L22] = (c.nu0 - N_W - 1.0) * sd0[2] ** 2
        b = np.zeros((n, 3))
        pb = np.zeros((n, N_PB))
        pb[:, PXX] = c.accel_bias_sd**2
        pb[:, PYY] = c.accel_bias_sd**2
        pb[:, PRR] = c.gyro_bias_sd**2
        st = PFState(part=pack_particles(x, mu, lam, b, pb), logw=np.full(n, -math.log(n)),
                     shared=np.array([c.gamma0, c.nu0]), rng_state=seed_state(rng))
        out = new_estimates(k)
        n_res = alg1_kernel(self.kernel_params(inputs), st, _series(inputs), out)
        return self._estimates_result(inputs, out, "pf", n_res)


@register("stiffness", "augpf", "particle filter on the state augmented with the stiffness",
          cite="002 Sec. VI-A", params=StiffnessConfig)
class AugmentedPF(_Setup):
    """State-augmented particle filter of 002 Sec. VI-A (see :mod:`~vestim.estimators.stiffness.augpf`)."""

    def __init__(self, vehicle: Vehicle, prior: StiffnessPrior | None = None,
                 config: StiffnessConfig | None = None, particles: int = 500) -> None:
        super().__init__(vehicle, prior, config)
        self.particles = _check_particles(particles)
        if self.config.augpf_var_walk <= 0.0:
            raise ValueError("StiffnessConfig.augpf_var_walk must be > 0 for the AUGPF")

    def kernel_params(self, inputs: StiffnessInputs) -> AugPFParams:
        """The kernel's parameters for a run over ``inputs`` (Q at the median step length)."""
        c = self.config
        return AugPFParams(p=self.p, r_pk=self.r_pk, q_pk=self.q_pk(inputs), lo=self.lo,
                           hi=self.hi, mean_walk=c.augpf_mean_walk * self.nominal_w,
                           var_shape=2.0 + 1.0 / c.augpf_var_walk**2,
                           n_thr=c.resample_threshold * self.particles,
                           model_error=np.asarray(c.model_error, dtype=float))

    def run(self, inputs: StiffnessInputs, rng: np.random.Generator) -> StiffnessResult:
        """Filter the whole series; ``rng`` draws the initial particles and every random number."""
        n = self.particles
        c = self.config
        k = inputs.t.shape[0]
        x = self.x0(inputs) + rng.standard_normal((n, N_STATE)) * np.asarray(c.initial_state_sd)
        m = np.clip(rng.standard_normal((n, N_W)) * self.sigma_w, self.lo, self.hi)
        pb = np.zeros((n, N_PB))
        pb[:, PXX] = c.accel_bias_sd**2
        pb[:, PYY] = c.accel_bias_sd**2
        pb[:, PRR] = c.gyro_bias_sd**2
        st = AugPFState(x=x, m=m, s=np.tile((c.augpf_initial_sd * self.nominal_w) ** 2, (n, 1)),
                        b=np.zeros((n, 3)), pb=pb, logw=np.full(n, -math.log(n)))
        out = new_estimates(k)
        n_res = augpf_kernel(self.kernel_params(inputs), st, _series(inputs), rng, out)
        return self._estimates_result(inputs, out, "augpf", n_res)


@register("stiffness", "rls", "RLS for the stiffness fed by a Kalman filter of the lateral "
          "states", cite="002 Sec. VI-A", params=StiffnessConfig)
class RlsKalman(_Setup):
    """RLS for the stiffness fed by a Kalman filter of the lateral states (002 Sec. VI-A).

    See :mod:`~vestim.estimators.stiffness.baselines`. ``run`` takes an optional
    longitudinal speed (002 gives RLS the true v_x); by default the wheel-speed
    reference R·ω of the slower axle.
    """

    def kernel_params(self, inputs: StiffnessInputs) -> RlsParams:
        """The kernel's parameters for a run over ``inputs`` (the lateral process noise per
        step at the median step length)."""
        c = self.config
        ts = float(np.median(inputs.u[:, U_DT]))
        return RlsParams(p=self.p, r_diag=self.r_diag,
                         q_lat=(np.asarray(c.model_error[1:], dtype=float) * ts) ** 2,
                         lo=self.lo, hi=self.hi, forgetting=c.rls_forgetting, cutoff=c.rls_cutoff)

    def run(self, inputs: StiffnessInputs, vx: np.ndarray | None = None) -> StiffnessResult:
        """Filter the whole series (deterministic)."""
        c = self.config
        k = inputs.t.shape[0]
        v = inputs.speed if vx is None else np.asarray(vx, dtype=float)
        if v.shape != (k,) or not np.all(np.isfinite(v)):
            raise ValueError(f"vx must be a finite array of shape ({k},)")
        st = RlsState(theta=np.zeros(N_W), p_rls=np.diag(self.sigma_w**2),
                      z=np.array([0.0, inputs.y[0, YAW_RATE]]),
                      p_kf=np.diag([c.initial_state_sd[1] ** 2, c.initial_state_sd[2] ** 2]))
        out = RlsEstimates(x=np.empty((k, N_STATE)), x_sd=np.empty((k, N_STATE)),
                           w=np.empty((k, N_W)), w_sd=np.empty((k, N_W)))
        rls_kf_kernel(self.kernel_params(inputs), st,
                      RlsInputs(y=inputs.y, u=inputs.u, vx=v, active=inputs.active), out)
        return self.result(inputs, out.w, out.w_sd, out.x, out.x_sd, np.zeros((k, 3)), "rls")


@register("stiffness", "ekf", "EKF on [v_x, v_y, ψ̇, ΔC, bias]", cite="002 Sec. V",
          params=StiffnessConfig)
class AugmentedEKF(_Setup):
    """EKF on [v_x, v_y, ψ̇, ΔC (3), bias (3)] (002 Sec. V).

    See :mod:`~vestim.estimators.stiffness.baselines`.
    """

    def run(self, inputs: StiffnessInputs) -> StiffnessResult:
        """Filter the whole series (deterministic)."""
        c = self.config
        k = inputs.t.shape[0]
        ts = float(np.median(inputs.u[:, U_DT]))
        xa = np.zeros(9)
        xa[0:3] = self.x0(inputs)
        pa = np.diag(np.concatenate([np.asarray(c.initial_state_sd) ** 2, self.sigma_w**2,
                                     [c.accel_bias_sd**2, c.accel_bias_sd**2,
                                      c.gyro_bias_sd**2]]))
        q = np.concatenate([(np.asarray(c.model_error) * ts) ** 2,
                            (c.stiffness_walk * self.nominal_w) ** 2 * ts,
                            [c.accel_bias_walk**2 * ts, c.accel_bias_walk**2 * ts,
                             c.gyro_bias_walk**2 * ts]])
        x_out = np.empty((k, 9))
        sd_out = np.empty((k, 9))
        ekf_kernel(inputs.y, inputs.u, inputs.active, self.p, self.r_diag, q, self.lo, self.hi,
                   xa, pa, x_out, sd_out)
        return self.result(inputs, x_out[:, 3:6], sd_out[:, 3:6], x_out[:, 0:3], sd_out[:, 0:3],
                           x_out[:, 6:9], "ekf")


_REGISTERED = registered("stiffness")
METHODS: tuple[str, ...] = tuple(_REGISTERED)
"""Names accepted by :func:`estimate_stiffness`, in the registry's order: Algorithm 1, AUGPF,
RLS + KF, EKF (each registered on its estimator class)."""
PF, AUGPF, RLS, EKF = (_REGISTERED[name].code for name in ("pf", "augpf", "rls", "ekf"))
"""The estimators' registry codes."""


def estimate_stiffness(
    log: pd.DataFrame,
    vehicle: Vehicle,
    *,
    particles: int = 500,
    seed: int = 0,
    method: str = "pf",
    prior: StiffnessPrior | None = None,
    config: StiffnessConfig | None = None,
) -> pd.DataFrame:
    """Tire stiffness and vehicle state from a drive log (002; Algorithm 1 by default).

    Reads ``t``, ``omega_fl`` … ``omega_rr``, ``ax``, ``ay``, ``yaw_rate`` and a steering
    channel (``delta_fl``/``delta_fr``, ``delta`` or ``steering_wheel_angle`` with
    ``vehicle.body.steering_ratio``); never a ``ref_`` column.

    Args:
        log: spec log, one row per sample, SI units.
        vehicle: the vehicle; ``vehicle.stiffness`` gives the nominal stiffness when
            present, otherwise the generic prior of :meth:`StiffnessPrior.generic`.
        particles: N for the particle filters (ignored by "rls" and "ekf").
        seed: seeds the ``numpy.random.Generator`` of the particle filters.
        method: "pf" (Algorithm 1), "augpf", "rls" (RLS + lateral KF) or "ekf".
        prior: overrides the nominal stiffness, its sigma and bounds.
        config: overrides the tuning (:class:`StiffnessConfig`).

    Returns:
        DataFrame with ``t``; ``stiffness_cx_f`` (``stiffness_cx_r`` for RWD; N per unit
        slip ratio), ``stiffness_cy_f``, ``stiffness_cy_r`` (N/rad), each axle
        totals with ``sigma_stiffness_*``; ``vx``, ``vy`` (m/s), ``yaw_rate`` (rad/s)
        with ``sigma_*``; ``bias_ax``, ``bias_ay`` (m/s², accelerometer bias in sensor
        units: measured = true specific force + bias), ``bias_yaw_rate`` (rad/s, gyro
        bias); ``stiffness_active`` (1.0 where the parameter update was active, 002
        Sec. V). ``df.attrs`` holds method, particles, seed and resampling count.

    Raises:
        LogFormatError: a required column is missing or invalid (the message names it).
        ValueError: unknown method or invalid particle count.
    """
    if method not in METHODS:
        raise ValueError(f"method {method!r} is not one of {', '.join(METHODS)}")
    cfg = config if config is not None else StiffnessConfig()
    inputs = prepare_inputs(log, vehicle, cfg)
    result: StiffnessResult
    estimator = _REGISTERED[method]
    cls = estimator.impl
    assert cls is not None  # every stiffness estimator registers its class above
    if estimator.code in (PF, AUGPF):
        result = cls(vehicle, prior, cfg, particles).run(inputs, np.random.default_rng(seed))
    else:
        result = cls(vehicle, prior, cfg).run(inputs)
    out = result.to_frame()
    out.attrs.update({"method": method, "particles": str(particles), "seed": str(seed),
                      "resampled": str(result.n_resampled)})
    return out


__all__ = ["METHODS", "AugmentedEKF", "AugmentedPF", "NoiseAdaptivePF", "RlsKalman",
           "StiffnessResult", "estimate_stiffness"]
