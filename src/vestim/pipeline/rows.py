"""The pipeline composed in one compiled call: ``pipeline_rows(P, S, X, Y, start, stop)``.

Every stage of 001 Fig. 1 advances row by row inside one Numba kernel: the attitude and
normal loads, the longitudinal and lateral force UKFs, the online cornering stiffness, the
reference filter (and the fused one with the corner observers' measurement) or the kinematic
integrator, the corner observers (LuGre KF/UKF, LPV) with their fusion to the CG, then
friction, validity and uncertainty. ``P`` is one nested
tree of parameters and ``S`` one tree of states (NamedTuples of arrays), built from a
:class:`~vestim.pipeline.Pipeline` by :func:`build`; ``X`` holds the inputs (n, :data:`N_X`)
after the health stages and ``Y`` the outputs as their transpose (columns, n): pandas stores
a float block that way, so the frame is made without a copy. :meth:`Pipeline.run` calls it
over the rows of a chunk and :meth:`Pipeline.step` over one row, so the two give the same
numbers by construction.

It covers every registered configuration (force method, normal-load model, velocity method,
fusion; each chosen by its registry code, :attr:`~vestim.estimators.registry.Method.code`)
on every sensor set: with or without wheel torques (then from the chassis equation), ``ax``
(then from the wheel speeds or the speed), ``az`` (then the level-road value), ``gnss_speed``
and wheel speeds (then from ``vehicle_speed`` or the ``gnss_speed`` fixes). The per-sample
equations are those cited in :mod:`vestim.estimators.force.estimator`,
:mod:`vestim.estimators.force.normal` and :mod:`vestim.pipeline`.
"""

from __future__ import annotations

import functools
from typing import TYPE_CHECKING, Any, NamedTuple

import numpy as np
from numba import njit
from numba.core import types
from numba.experimental import structref
from numba.np.arraymath import _median_inner

from vestim.estimators import registry
from vestim.estimators.force.estimator import (
    AX_TAU,
    AX_TAU_SPARSE,
    LoadFilterState,
    SpeedDerivativeState,
    SpeedHoldState,
    load_specific_force,
    normalised,
    speed_derivative,
    speed_hold,
    wheel_reference_speed,
)
from vestim.estimators.force.lateral import (
    LateralKernelParams,
    LateralState,
    lateral_kernel,
    split_weights,
)
from vestim.estimators.force.longitudinal import (
    LongitudinalParams,
    LongitudinalState,
    longitudinal_rows,
)
from vestim.estimators.force.normal import (
    DYNAMIC,
    AttitudeKernelParams,
    AttitudeState,
    NormalLoadKernelParams,
    attitude_kernel,
    normal_load_params,
    normal_loads_kernel,
)
from vestim.estimators.friction import FrictionKernelParams, FrictionState, friction_step
from vestim.estimators.fusion.axle import adaptive_axle_kernel, fixed_axle_kernel
from vestim.estimators.fusion.opinion import opinion_kernel
from vestim.estimators.health import (
    HealthKernelParams,
    HealthState,
    ImuHealthKernelParams,
    ImuHealthState,
    imu_health_step,
    wheel_health_step,
)
from vestim.estimators.uncertainty import N_OUT as N_SIGMA
from vestim.estimators.uncertainty import OUTPUT_NAMES as SIGMA_NAMES
from vestim.estimators.uncertainty import (
    UncertaintyKernelParams,
    UncertaintyState,
    uncertainty_step,
)
from vestim.estimators.validity import GROUPS as VALIDITY_GROUPS
from vestim.estimators.validity import (
    ConsistencyState,
    ValidityKernelParams,
    consistency_step,
    load_resolved,
    validity_step,
)
from vestim.estimators.velocity.corner import CornerVelocityEstimator, corner_rows, seed_corners
from vestim.estimators.velocity.corner_common import (
    CornerInputs,
    CornerOutputs,
    CornerParams,
    CornerState,
)
from vestim.estimators.velocity.kinematic import KinematicState, kinematic_kernel
from vestim.estimators.velocity.reference import (
    RadiusKernelParams,
    RadiusState,
    ReferenceKernelParams,
    ReferenceState,
    StiffnessKernelParams,
    StiffnessState,
    _reference_rows,
    _stiffness_rows,
    copy_reference_state,
    gnss_calibration,
)
from vestim.filters.lowpass import LowpassParams
from vestim.models.chassis import (
    ChassisKernelParams,
    chassis_params,
    chassis_torque_kernel,
    torque_less_rolling_resistance,
)
from vestim.models.kinematics import (
    corner_acc_kernel,
    level_road_az,
    road_specific_force,
    rotate_kernel,
    slip_angle_kernel,
    slip_ratio_kernel,
    transport_kernel,
    yaw_acceleration_kernel,
)

if TYPE_CHECKING:
    from vestim.pipeline import Pipeline  # the package this module belongs to

_JIT: dict[str, Any] = {"cache": True, "error_model": "numpy"}

CORNER_KEYS = ("fl", "fr", "rl", "rr")

# --- the input row X[k] -------------------------------------------------------------------
X_T, X_OMEGA, X_TORQUE, X_AX, X_AY, X_AZ, X_R, X_P, X_Q, X_DELTA = 0, 1, 5, 9, 10, 11, 12, 13, 14, 15
X_HELD, X_HEALTH_OMEGA, X_HEALTH_IMU, X_GNSS, X_VSPEED = 17, 18, 22, 25, 26
N_X = 27
# X's columns: t, omega_fl … omega_rr, torque_fl … torque_rr, ax, ay, az, yaw_rate,
# roll_rate, pitch_rate, delta_fl, delta_fr (the log's channels), then whether an input was
# held (1/0), the wheel-speed health (4) and the IMU health (3) (1.0 healthy), gnss_speed (NaN
# between fixes) and vehicle_speed. A channel the Sensors say is not measured is not read.

# --- the output row, in the kernel's order (Params.col places each in Y) -------------------
_PER_CORNER = ("vx", "vy", "vxt", "vyt", "slip_ratio", "slip_angle", "fx", "fy", "fz", "mu_x",
               "mu_y", "sigma_fx", "sigma_fy")
ROW_NAMES: tuple[str, ...] = (
    "t", "vx", "vy",
    *(f"{q}_{c}" for q in _PER_CORNER for c in CORNER_KEYS),
    "roll", "pitch", "bias_ax", "cornering_stiffness", "radius_scale", "gnss_latency",
    *(n for c in CORNER_KEYS for n in (f"mu_{c}", f"sigma_mu_{c}", f"mu_{c}_excited")),
    *(n for g in VALIDITY_GROUPS for n in (f"valid_{g}", f"reason_{g}")),
    *(f"health_omega_{c}" for c in CORNER_KEYS), "health_ax", "health_ay", "health_yaw_rate",
    *SIGMA_NAMES, *(f"confidence_{c}" for c in CORNER_KEYS))
"""Every quantity one row computes, in the order the kernel writes them."""


def _corners(*quantities: str) -> list[str]:
    return [f"{q}_{c}" for q in quantities for c in CORNER_KEYS]


OUTPUT_COLUMNS: tuple[str, ...] = (
    "t", "vx", "vy", "sigma_vx", "sigma_vy",
    *_corners("sigma_vx", "sigma_vy", "sigma_vxt", "sigma_vyt", "sigma_slip_angle",
              "sigma_slip_ratio", "sigma_fz"), "sigma_roll", "sigma_pitch",
    *_corners("vx", "vy", "vxt", "vyt", "slip_ratio", "slip_angle", "fx", "fy", "fz", "mu_x",
              "mu_y", "sigma_fx", "sigma_fy"), "roll", "pitch",
    "bias_ax", "cornering_stiffness", "radius_scale", "gnss_latency", *_corners("confidence"),
    *_corners("mu", "sigma_mu"), *(f"mu_{c}_excited" for c in CORNER_KEYS),
    *(n for g in VALIDITY_GROUPS for n in (f"valid_{g}", f"reason_{g}")),
    *_corners("health_omega"), "health_ax", "health_ay", "health_yaw_rate")
"""The output columns, in the order of the estimate's frame (the order every configuration's
output follows, less what :func:`output_columns` leaves out); the same names as
:data:`ROW_NAMES`."""
assert sorted(OUTPUT_COLUMNS) == sorted(ROW_NAMES)

_WHEEL_ONLY = ("slip_ratio_", "fx_", "mu_x_", "sigma_fx_", "sigma_slip_ratio_", "health_omega_",
               "radius_scale", "gnss_latency")
_VELOCITY_SIGMA = ("sigma_vx", "sigma_vy", "sigma_vxt_", "sigma_vyt_", "sigma_slip_angle_",
                   "sigma_slip_ratio_")


@functools.cache
def output_columns(wheels: bool, force_sigma: bool, velocity_sigma: bool, bias: bool,
                   confidence: bool) -> tuple[str, ...]:
    """The output columns of a log with or without wheel speeds (no per-wheel F_x, slip ratio,
    radius scale, GNSS latency nor wheel health without them), for a longitudinal force
    method with or without a σ, a velocity method with or without a filter σ (the velocity
    σ columns) and an accelerometer bias (``bias_ax``), and a fusion with or without
    confidences (opinion dynamics). Made once: the same tuple for the same arguments."""
    return tuple(c for c in OUTPUT_COLUMNS
                 if (wheels or not c.startswith(_WHEEL_ONLY))
                 and (force_sigma or not c.startswith("sigma_fx_"))
                 and (velocity_sigma or not c.startswith(_VELOCITY_SIGMA))
                 and (bias or c != "bias_ax")
                 and (confidence or not c.startswith("confidence_")))
_R_MU = 3 + 4 * len(_PER_CORNER) + 6
_N_GROUPS = len(VALIDITY_GROUPS)
_R_HEALTH = _R_MU + 12 + 2 * _N_GROUPS
_R_SIGMA = _R_HEALTH + 7
_R_CONF = _R_SIGMA + N_SIGMA
_R_UTIL = 3 + 4 * _PER_CORNER.index("mu_x")  # mu_x_fl … mu_x_rr, then mu_y_fl … mu_y_rr
_S_FZ = SIGMA_NAMES.index("sigma_fz_fl")
N_ROW = _R_CONF + 4


class Sensors(NamedTuple):
    """Which of the optional channels the log measures (the others are derived: ``ax`` from
    the wheel speeds or the speed, ``az`` for a level road, the wheel torques from the
    chassis equation, the wheel speeds from ``vehicle_speed`` or the ``gnss_speed`` fixes)."""

    ax: bool
    az: bool
    torque: bool
    omega: bool
    vehicle_speed: bool


class ForceParams(NamedTuple):
    """The force stage's parameters (SI): the attitude, normal loads, the longitudinal method
    (:func:`~vestim.estimators.force.longitudinal.longitudinal_rows`'s) and the lateral UKF
    (:func:`~vestim.estimators.force.lateral.lateral_kernel`'s)."""

    radius: float  # effective wheel radius, m
    rolling_moment: float  # rolling-resistance coefficient × radius, m
    drag_coef: float  # aerodynamic drag per speed², N s²/m²
    load_exponent: float  # the lateral split's load exponent
    slip_scale: float  # the lateral split's slip scale
    normal: NormalLoadKernelParams
    dynamic: bool  # normal loads "dynamic" (else "static")
    attitude: AttitudeKernelParams
    lon: LongitudinalParams  # the longitudinal method (and the chassis torques' ω̇ filter)
    xw: np.ndarray  # corner positions ahead of the CG, m
    yw: np.ndarray  # corner positions left of the CG, m
    lateral: LateralKernelParams
    chassis: ChassisKernelParams  # the wheel torques of a log without them
    load_filter: LowpassParams  # the specific force's low-pass for the force stage
    load_filter_on: bool


class ForceState(NamedTuple):
    """The force stage's states (shared with :class:`~vestim.estimators.force.ForceEstimator`)."""

    attitude: AttitudeState
    lon: LongitudinalState
    lateral: LateralState
    ax_state: SpeedDerivativeState  # the wheel-speed a_x's filter (logs without ax)
    inertia: LongitudinalState  # the longitudinal method on zero torque: the chassis
    # torques' ω̇ (logs without torques)
    hold_state: SpeedHoldState  # the speed between gnss_speed fixes (logs without wheel speeds)
    load_filter: LoadFilterState  # load_specific_force's


class VelocityParams(NamedTuple):
    """The velocity stage's parameters: the online cornering stiffness, the reference filter,
    the method (its registry code: ``fused``, the fused filter takes the corner observer's
    CG v_x while ≥ 3 corners slip; ``reference``; ``kinematic``; the corner observers ``kf``,
    ``ukf``, ``lpv`` fused to the CG), the corner observer and the fusion (its code: fixed or
    adaptive axle weights, or opinion dynamics with ``k1`` … ``gamma``)."""

    stiffness: StiffnessKernelParams
    radius: RadiusKernelParams
    reference: ReferenceKernelParams
    sigma_gnss: float  # a fix's σ, m/s
    sigma_vehicle_speed: float  # vehicle_speed's σ (logs without wheel speeds), m/s
    tau_wheel: float  # the filter's inflation time of an extra speed measurement, s
    method: int
    corner: CornerParams
    fusion: int
    eta_front: float
    w_s: float
    w_range: float
    rho: float
    threshold: float
    k1: float
    k2: float
    w_floor: float
    band: float
    gamma: float


PREV_T, PREV_R, PREV_FUSED_SAME, N_PREV = range(4)
"""Entries of :attr:`VelocityState.prev`: the previous sample's time (s) and yaw rate (rad/s),
whose ṙ the corner observers take (:func:`~vestim.models.kinematics.yaw_acceleration_kernel`
reads ``prev[:2]`` in this order), and whether the fused filter is still the plain one (1/0)."""


class VelocityState(NamedTuple):
    """The velocity stage's states: ``prev`` (:data:`N_PREV`,) = the previous sample's t and
    yaw rate (ṙ) and whether the fused filter is still the plain one (1/0), at the
    ``PREV_*`` indices; ``t_gnss`` (1,) the previous sample's time (a fix's weight), s."""

    stiffness: StiffnessState
    radius: RadiusState
    t_gnss: np.ndarray
    reference: ReferenceState
    fused: ReferenceState
    prev: np.ndarray
    corner: CornerState
    kinematic: KinematicState  # the kinematic integrator's state
    seeded: np.ndarray  # (1,) 1.0 once the corner observers took the reference's velocity


class PostParams(NamedTuple):
    """Friction, validity and uncertainty parameters."""

    friction: FrictionKernelParams
    validity: ValidityKernelParams
    uncertainty: UncertaintyKernelParams


class PostState(NamedTuple):
    """Friction and uncertainty states; ``t_start`` (1,) the first sample's time, s (NaN
    before it); the consistency test's state (validity bit 128)."""

    friction: FrictionState
    uncertainty: UncertaintyState
    t_start: np.ndarray
    consistency: ConsistencyState


class Params(NamedTuple):
    """The whole pipeline's parameters; ``col`` (N_ROW,) places each quantity of
    :data:`ROW_NAMES` in Y (−1: not written)."""

    sensors: Sensors
    force: ForceParams
    velocity: VelocityParams
    post: PostParams
    col: np.ndarray


(A_T, A_AX, A_AY, A_AZ, A_R, A_P_RATE, A_Q_RATE, A_CHAN, A_V_W, A_ROLL, A_PITCH,
 A_ROLL_ACC, A_PITCH_ACC, A_FY_SD, A_FXA, A_DRAG, A_SPEED, A_C_Y, A_SCALE, A_LATENCY,
 A_GNSS, A_VX_CG, A_VY_CG, A_DELTA_FRONT, A_YAW_ACC, A_AXC, A_AYC, A_VG, A_VXR, A_VYR,
 A_VX_F, N_A) = range(32)
"""Rows of :attr:`Scratch.one`: one value per sample."""
(B_AXLE, B_EXTRA, B_EXTRA_VAR, B_V_REF, B_SIG_REF, B_V, B_SIG, B_V_FUSED, B_SIG_FUSED,
 N_B) = range(10)
"""Rows of :attr:`Scratch.two`: (v_x, v_y), the axle pair, the extra speed measurements."""
(C_OMEGA, C_OMEGA_V, C_TORQUE, C_DELTA, C_FX, C_SIG_FX, C_FY, C_SIG_FY, C_BIAS_REF, C_BIAS,
 C_BIAS_FUSED, C_TRUST, C_CONF, C_VXT, C_VYT, C_SR, C_SA, C_F_INERTIA, C_ZERO4, C_NAN4,
 C_OMEGA_DOT, C_A_XT, C_A_YT, C_VXT_G, C_VYT_IN, C_VXT_R, C_VYT_R, C_SLIP, C_VX_B, C_VY_B,
 C_PHI, C_FW, C_K_VXT, C_K_VYT, C_K_SIGMA, C_K_VRX, C_K_ZX, C_K_ZDOT, C_K_VRY, C_K_ZY,
 N_C) = range(41)
"""Rows of :attr:`Scratch.four`: one value per corner (``C_BIAS*``: the reference filter's
four biases); ``C_K_*`` the corner observers' outputs (:class:`CornerOutputs`)."""
D_MED, D_MU, D_SMU, D_EX, D_FZ = 0, 4, 8, 12, 16
D_VALID = 20
D_REASON = D_VALID + _N_GROUPS
D_SIGMA = D_REASON + _N_GROUPS
N_D = D_SIGMA + N_SIGMA
"""Offsets in :attr:`Scratch.sample`, one sample's: the median's workspace (4), friction's
μ, σ_μ, excitation (4 each), F_z (4), the validity flags and reasons, the σ outputs."""


class Scratch(NamedTuple):
    """Working arrays of :func:`pipeline_rows`, allocated once (:func:`new_scratch`) and
    reused by every block: a block of m samples uses the views ``[j, :m]`` of these (…, BLOCK,
    …) arrays, so it allocates none of its intermediates. Few arrays, each a bank of rows
    named by the ``A_`` … ``D_`` indices: every array in the State tree costs a reference
    count increment and decrement at each compiled call that takes the tree (a tree of one
    array per intermediate made :meth:`Pipeline.step` slower than allocating them). Each holds
    only values of the block in hand; units are those of the quantity the row's name gives
    (the stages' own: s, rad/s, N m, m/s², rad, N, m/s)."""

    one: np.ndarray  # (N_A, BLOCK)
    two: np.ndarray  # (N_B, BLOCK, 2)
    four: np.ndarray  # (N_C, BLOCK, 4)
    flags: np.ndarray  # (2, BLOCK, 4) bool: the observers' hint (False) and high-slip flags
    n_high: np.ndarray  # (BLOCK,) int64: corners in high slip
    sample: np.ndarray  # (N_D,)


def new_scratch() -> Scratch:
    """A :class:`Scratch` for blocks of up to :data:`BLOCK` samples (its values unset)."""
    return Scratch(np.empty((N_A, BLOCK)), np.empty((N_B, BLOCK, 2)), np.empty((N_C, BLOCK, 4)),
                   np.zeros((2, BLOCK, 4), dtype=np.bool_), np.zeros(BLOCK, dtype=np.int64),
                   np.empty(N_D))


class State(NamedTuple):
    """The whole pipeline's state, and the blocks' working arrays (:class:`Scratch`)."""

    force: ForceState
    velocity: VelocityState
    post: PostState
    scratch: Scratch


FUSED, REFERENCE, KINEMATIC = (registry.lookup("velocity", n).code
                                for n in ("fused", "reference", "kinematic"))
FIXED, ADAPTIVE, OPINION = (registry.lookup("fusion", n).code
                            for n in ("axle", "adaptive", "opinion"))
"""The methods' registry codes that :func:`pipeline_rows` dispatches on (``kf``, ``ukf`` and
``lpv`` are the other velocity codes: a corner observer fused to the CG)."""

SEED_AT = 0.5
"""After a (re)start the corner observers (``kf``, ``ukf``, ``lpv``, and ``fused``'s) start
free rolling (v_r = 0, v̂_xt = R ω): on a spinning or locked wheel that is wrong by the slip
and their slip-ratio estimate never corrects it (the ice launch x02 after a 2 s gap: 1.45 m/s
off to the end of the log). At ``SEED_AT`` × ``validity.converge_s`` after it they take the
reference filter's velocity mapped to each corner (:func:`seed_corners`): the reference
filter rejects the slipping wheels and has converged by then (its v_x within 0.08 m/s of the
truth from the first row after every 2 s gap of the crossplant sweep,
``benchmarks/fault_table.py``), and the observers have the other half of the window to
settle before the rows are valid again."""

BLOCK = 1024
"""Samples per stage pass of :func:`pipeline_rows`: each stage runs over a block before the
next (the intermediates stay in cache, the kernels' scratch is allocated once a block)."""


@njit(**_JIT)
def pipeline_rows(P: Params, S: State, X: np.ndarray, Y: np.ndarray, start: int,
                  stop: int) -> None:
    """Samples [start, stop) through every stage: sample k's inputs are ``X[k - start]``
    (X: (≥ stop − start, :data:`N_X`)) and its quantities go to ``Y[P.col[j], k]`` (Y:
    (columns, n), the transpose of the output frame). ``S`` is advanced; the result does
    not depend on how the samples are split between calls."""
    sensors, fp, fs, vp, vs = P.sensors, P.force, S.force, P.velocity, S.velocity
    pp, ps, sc, col = P.post, S.post, S.scratch, P.col
    for a in range(start, stop, BLOCK):
        b = min(a + BLOCK, stop)
        _block(sensors, fp, fs, vp, vs, pp, ps, sc, col, X[a - start:b - start], Y, a)


@njit(**_JIT)
def _put(Y: np.ndarray, col: np.ndarray, j: int, values: np.ndarray, k0: int) -> None:
    """Quantity j of :data:`ROW_NAMES` (values (m,)) into Y's columns k0 … k0 + m − 1."""
    row = col[j]
    if row >= 0:
        for i in range(values.shape[0]):
            Y[row, k0 + i] = values[i]


@njit(**_JIT)
def _put4(Y: np.ndarray, col: np.ndarray, j: int, values: np.ndarray, k0: int) -> None:
    """Quantities j … j + 3 (values (m, 4), one per corner) into Y (see :func:`_put`)."""
    for c in range(4):
        row = col[j + c]
        if row >= 0:
            for i in range(values.shape[0]):
                Y[row, k0 + i] = values[i, c]


@njit(**_JIT)
def _block(sensors: Sensors, fp: ForceParams, fs: ForceState, vp: VelocityParams,
           vs: VelocityState, pp: PostParams, ps: PostState, sc: Scratch, col: np.ndarray,
           x: np.ndarray, Y: np.ndarray, k0: int) -> None:
    """The samples ``x`` (m, :data:`N_X`) through the stages, stage by stage, into Y's
    columns k0 … k0 + m − 1 (the sample-by-sample recursions of each stage: the split into
    blocks changes no number). The intermediates are views of ``sc`` (State.scratch).

    It takes the trees' parts (Params.sensors, .force, .velocity, .post, .col; State.force,
    .velocity, .post, .scratch), not the two trees: each array of a tree that a compiled
    function takes, or reads into a variable, costs a reference count increment and
    decrement per call (≈ 200 arrays a level; :func:`step_sample` reads them from the
    :class:`Stepper` straight into this call)."""
    m = x.shape[0]
    t = sc.one[A_T, :m]
    omega = sc.four[C_OMEGA, :m]
    torque = sc.four[C_TORQUE, :m]
    ay = sc.one[A_AY, :m]
    r = sc.one[A_R, :m]
    p_rate = sc.one[A_P_RATE, :m]
    q_rate = sc.one[A_Q_RATE, :m]
    delta = sc.four[C_DELTA, :m]
    for i in range(m):
        t[i] = x[i, X_T]
        ay[i] = x[i, X_AY]
        r[i] = x[i, X_R]
        p_rate[i] = x[i, X_P]
        q_rate[i] = x[i, X_Q]
        for c in range(4):
            omega[i, c] = x[i, X_OMEGA + c]
            torque[i, c] = x[i, X_TORQUE + c]
        delta[i, 0] = x[i, X_DELTA]
        delta[i, 1] = x[i, X_DELTA + 1]
        delta[i, 2] = delta[i, 3] = 0.0
    radius = fp.radius
    xw, yw = fp.xw, fp.yw
    att = fp.attitude
    # --- force stage (ForceEstimator.advance) ---
    ax = sc.one[A_AX, :m]
    chan = sc.one[A_CHAN, :m]
    if sensors.ax:
        ax[:] = x[:, X_AX]
    elif sensors.omega:  # from the wheel speeds (ForceEstimator._speed_inputs)
        wheel_reference_speed(t, omega, r, yw, radius, att.undriven_axle, AX_TAU[0], AX_TAU[1],
                              fs.ax_state, ax)
    else:  # from the speed
        if sensors.vehicle_speed:
            chan[:] = x[:, X_VSPEED]
            speed_derivative(t, chan, AX_TAU[0], AX_TAU[1], fs.ax_state, ax)
        else:
            chan[:] = x[:, X_GNSS]
            speed_derivative(t, chan, AX_TAU_SPARSE[0], AX_TAU_SPARSE[1], fs.ax_state, ax)
    if not sensors.omega:  # the wheels roll at the speed
        v_w = sc.one[A_V_W, :m]
        if sensors.vehicle_speed:
            v_w[:] = x[:, X_VSPEED]
        else:
            chan[:] = x[:, X_GNSS]
            speed_hold(t, chan, ax, fs.hold_state, v_w)
        for i in range(m):
            w = v_w[i] / radius
            for c in range(4):
                omega[i, c] = w
    roll = sc.one[A_ROLL, :m]
    pitch = sc.one[A_PITCH, :m]
    roll_acc = sc.one[A_ROLL_ACC, :m]
    pitch_acc = sc.one[A_PITCH_ACC, :m]
    fy_sd = sc.one[A_FY_SD, :m]
    attitude_kernel(t, ax, ay, p_rate, q_rate, r, omega, att, fs.attitude, roll, pitch,
                    roll_acc, pitch_acc, fy_sd)
    # the attitude's gravity as the accelerometers read it (none in an INS's output)
    g_roll, g_pitch = att.gravity * roll, att.gravity * pitch
    if sensors.az:
        az = sc.one[A_AZ, :m]
        az[:] = x[:, X_AZ]
    else:
        az = level_road_az(ax, ay, g_roll, g_pitch)
    fxa, fya, fza = road_specific_force(ax, ay, az, g_roll, g_pitch)
    if not sensors.ax:  # a speed's derivative is already the road-plane acceleration
        fxa = sc.one[A_FXA, :m]
        fxa[:] = ax
    lxa, lya, lza, noise = load_specific_force(fp.load_filter, fp.load_filter_on, fs.load_filter,
                                               t, fxa, fya, fza, r)
    fz = normal_loads_kernel(lxa, lya, lza, roll, pitch, p_rate, q_rate, roll_acc, pitch_acc,
                             fp.normal, fp.dynamic)
    if not sensors.torque:
        torque = _chassis_torques(fp.lon, fs.inertia, fp.chassis, sc, t, omega, fxa, fya,
                                  delta, fz)
    teff = torque_less_rolling_resistance(torque, omega, fz, fp.rolling_moment)
    fx = sc.four[C_FX, :m]
    sig_fx = sc.four[C_SIG_FX, :m]
    sig_fx[:] = np.nan
    longitudinal_rows(fp.lon, fs.lon, t, omega, teff, fx, sig_fx)
    drag = sc.one[A_DRAG, :m]
    speed = sc.one[A_SPEED, :m]
    med = sc.sample[D_MED:D_MED + 4]
    for i in range(m):
        w_mean = 0.25 * (omega[i, 0] + omega[i, 1] + omega[i, 2] + omega[i, 3])
        drag[i] = fp.drag_coef * (radius * w_mean) ** 2
        for c in range(4):
            med[c] = omega[i, c]
        speed[i] = radius * _median_inner(med, 4)  # np.median's own, on a reused workspace
    weights = split_weights(fz, omega, torque, r, radius, yw, fp.load_exponent, fp.slip_scale)
    fy = sc.four[C_FY, :m]
    sig_fy = sc.four[C_SIG_FY, :m]
    lateral_kernel(fp.lateral, fs.lateral, t, fx, delta, weights, fxa, fya, r, noise, drag, fz,
                   speed, fy, sig_fy)
    if not sensors.omega:  # per-corner F_x needs the wheels' own speeds
        fx[:] = np.nan
        sig_fx[:] = np.nan
    # --- velocity stage ---
    mu_x = normalised(fx, fz)
    mu_y = normalised(fy, fz)
    axle = sc.two[B_AXLE, :m]
    c_y = sc.one[A_C_Y, :m]
    _stiffness_rows(vp.stiffness, vs.stiffness, 0, m, t, omega, r, delta, fy, fz, axle, c_y)
    # The wheel speeds at the effective radius that the GNSS speed shows, and the fixes
    # brought forward by the receiver's latency (scale 1 and no fix without gnss_speed).
    scale = sc.one[A_SCALE, :m]
    latency = sc.one[A_LATENCY, :m]
    gnss = sc.one[A_GNSS, :m]
    extra = sc.two[B_EXTRA, :m]
    extra_var = sc.two[B_EXTRA_VAR, :m]
    omega_v = omega
    if sensors.omega:
        chan[:] = x[:, X_GNSS]
        gnss_calibration(vp.radius, vs.radius, t, omega, chan, scale, latency, gnss)
        for i in range(m):
            if scale[i] != 1.0:
                omega_v = sc.four[C_OMEGA_V, :m]
                for k in range(m):
                    for c in range(4):
                        omega_v[k, c] = omega[k, c] * scale[k]
                break
    else:  # no wheel speeds to scale nor to find the latency against; ω unknown to the filter
        scale[:] = np.nan
        latency[:] = np.nan
        gnss[:] = x[:, X_GNSS]
        omega_v = sc.four[C_OMEGA_V, :m]
        omega_v[:] = np.nan
    # A fix's error is white at the receiver's rate: undo the τ_wheel/T_s inflation the
    # filter gives every extra CG-speed measurement, so its weight does not depend on the
    # log's sample rate.
    t_prev = vs.t_gnss[0]
    var_gnss = vp.sigma_gnss ** 2
    for i in range(m):
        dt = t[i] - t_prev
        t_prev = t[i]
        inflate = max(vp.tau_wheel / (dt if dt > 0 else np.inf), 1.0)
        extra[i, 0] = gnss[i]
        extra_var[i, 0] = var_gnss / inflate if np.isfinite(gnss[i]) else np.nan
        if sensors.vehicle_speed and not sensors.omega:  # a dense speed enters like a wheel
            extra[i, 1] = x[i, X_VSPEED]
            extra_var[i, 1] = vp.sigma_vehicle_speed ** 2
        else:
            extra[i, 1] = extra_var[i, 1] = np.nan
    vs.t_gnss[0] = t_prev
    v_ref = sc.two[B_V_REF, :m]
    sig_ref = sc.two[B_SIG_REF, :m]
    bias_ref = sc.four[C_BIAS_REF, :m]
    trust = sc.four[C_TRUST, :m]
    method = vp.method
    conf = sc.four[C_CONF, :m]
    conf[:] = np.nan  # the opinion fusion's confidences
    if method == KINEMATIC:
        v = sc.two[B_V, :m]
        kinematic_kernel(t, omega_v, fxa, fya, r, radius, vs.kinematic, v)
        sig = sc.two[B_SIG, :m]
        sig[:] = np.nan
        bias = sc.four[C_BIAS, :m]
        bias[:] = np.nan
    else:
        prev = vs.prev
        same = method == FUSED and prev[PREV_FUSED_SAME] == 1.0
        if same:
            # While it is the plain filter the fused filter's state is not used: it holds the
            # plain filter's state before this block, the start of its first own step.
            copy_reference_state(vs.fused, vs.reference)
        n_extra = 1 if sensors.omega else 2
        _reference_rows(vp.reference, vs.reference, 0, m, t, omega_v, torque, mu_x, axle, fxa,
                        fya, fy_sd, r, delta, extra[:, :n_extra], extra_var[:, :n_extra],
                        v_ref, sig_ref, bias_ref, trust)
        v = v_ref
        sig = sig_ref
        bias = bias_ref
        if method != REFERENCE and sensors.omega:  # without them "fused" is the reference
            vx_f, n_high = _corners_vx(vp, fp, vs.corner, prev, vs.seeded, ps.t_start,
                                       SEED_AT * pp.validity.converge_s, sc, t, omega_v,
                                       delta, r, fxa, fya, mu_x, mu_y, v_ref, bias_ref, conf)
            if method == FUSED:
                v, sig, bias = _fused(vp.reference, vs.fused, prev, sc, t, omega_v, torque,
                                      delta, r, fxa, fya, fy_sd, mu_x, axle, extra, extra_var,
                                      same, vx_f, n_high)
            else:  # a corner observer: CG v_x by the fusion, v_y from the reference filter
                v = sc.two[B_V, :m]
                for i in range(m):
                    v[i, 0] = vx_f[i]
                    v[i, 1] = v_ref[i, 1]
                sig = sc.two[B_SIG, :m]
                sig[:] = np.nan
    # --- the corners' kinematics ---
    vx_cg = sc.one[A_VX_CG, :m]
    vy_cg = sc.one[A_VY_CG, :m]
    for i in range(m):
        vx_cg[i] = v[i, 0]
        vy_cg[i] = v[i, 1]
    vx_o, vy_o = transport_kernel(vx_cg, vy_cg, r, xw, yw, 1.0)
    vxt = sc.four[C_VXT, :m]
    vyt = sc.four[C_VYT, :m]
    rotate_kernel(vx_o.reshape(-1), vy_o.reshape(-1), delta.reshape(-1), 1.0, vxt.reshape(-1),
                  vyt.reshape(-1))
    sr = sc.four[C_SR, :m]
    slip_ratio_kernel(omega_v.reshape(-1), vxt.reshape(-1), radius, 0.1, sr.reshape(-1))
    if not sensors.omega:
        sr[:] = np.nan
        omega_v = omega  # the speed's, as the uncertainty stage reads them
    sa = sc.four[C_SA, :m]
    slip_angle_kernel(vxt.reshape(-1), vyt.reshape(-1), 0.5, sa.reshape(-1))
    _put(Y, col, 0, t, k0)
    _put(Y, col, 1, vx_cg, k0)
    _put(Y, col, 2, vy_cg, k0)
    j = 3
    for block in (vx_o, vy_o, vxt, vyt, sr, sa, fx, fy, fz, mu_x, mu_y, sig_fx, sig_fy):
        _put4(Y, col, j, block, k0)
        j += 4
    _put(Y, col, j, roll, k0)
    _put(Y, col, j + 1, pitch, k0)
    _put(Y, col, j + 2, bias[:, 0], k0)
    _put(Y, col, j + 3, c_y, k0)
    _put(Y, col, j + 4, scale, k0)
    _put(Y, col, j + 5, latency, k0)
    _put4(Y, col, _R_CONF, conf, k0)
    _post(pp, ps, sc, x, t, ax, v, sig, c_y, bias[:, 3],
          Corners(fx, fy, fz, sig_fx, sig_fy, sr, sa, vxt, vyt, delta, omega_v), radius, Y, col,
          k0)


@njit(**_JIT)
def _chassis_torques(lon: LongitudinalParams, inertia: LongitudinalState,
                     ch: ChassisKernelParams, sc: Scratch, t: np.ndarray, omega: np.ndarray,
                     fxa: np.ndarray, fya: np.ndarray, delta: np.ndarray,
                     fz: np.ndarray) -> np.ndarray:
    """Net wheel torques (m, 4), N m, for a log without them (ForceEstimator.advance): the
    chassis equation with ω̇ from the longitudinal method run on zero torque (its output is
    −I_w ω̇̂/R, so the main run subtracts the same ω̇̂ and a wheel spinning up keeps only its
    share of the tire force). ``lon`` ForceParams.lon, ``inertia`` ForceState.inertia, ``ch``
    ForceParams.chassis (the parts read, not the force trees: each array taken is
    reference-counted per call)."""
    m = t.shape[0]
    f_inertia = sc.four[C_F_INERTIA, :m]
    zero = sc.four[C_ZERO4, :m]
    zero[:] = 0.0
    unused = sc.four[C_NAN4, :m]
    unused[:] = np.nan
    longitudinal_rows(lon, inertia, t, omega, zero, f_inertia, unused)
    gain = -ch.radius / ch.wheel_inertia
    omega_dot = sc.four[C_OMEGA_DOT, :m]
    delta_front = sc.one[A_DELTA_FRONT, :m]
    for i in range(m):
        delta_front[i] = (delta[i, 0] + delta[i, 1]) / 2.0
        for c in range(4):
            omega_dot[i, c] = gain * f_inertia[i, c]
    return chassis_torque_kernel(fxa, fya, delta_front, fz, omega, omega_dot, ch)


@njit(**_JIT)
def _corners_vx(vp: VelocityParams, fp: ForceParams, cs: CornerState, prev: np.ndarray,
                seeded: np.ndarray, t_start: np.ndarray, seed_s: float, sc: Scratch,
                t: np.ndarray, omega: np.ndarray, delta: np.ndarray, r: np.ndarray,
                fxa: np.ndarray, fya: np.ndarray, mu_x: np.ndarray, mu_y: np.ndarray,
                v_ref: np.ndarray, bias_ref: np.ndarray,
                conf: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The corner observers of a block (001 text after eq. (21); Pipeline._corners) and their
    fusion to the CG (003 Alg. 2, 001 eq. (33)–(35)). Returns the
    fused CG v_x (m,), m/s, and the number of corners in high slip (m,); ``conf`` (m, 4)
    gets the opinion fusion's confidences.

    The reference filter's v_y sets the tire-frame transport term, and its accelerometer
    biases b_x, b_y are removed from the accelerations the observers integrate. The slip that
    sets the fusion weights is taken against the reference filter's velocity mapped to each
    corner, not against the corner's own v̂_xt (a corner observer that has drifted towards
    R·ω would report a small slip and keep its weight).

    It takes the subtrees it reads, not the whole trees (each array of an argument is
    reference-counted at every call): the velocity and force parameters, the observers'
    state, ``prev`` = VelocityState.prev, ``seeded`` = VelocityState.seeded, ``t_start`` =
    PostState.t_start and ``seed_s`` = :data:`SEED_AT` × the validity's ``converge_s``, s."""
    cp = vp.corner
    xw, yw = fp.xw, fp.yw
    radius = fp.radius
    m = t.shape[0]
    yaw_acc = sc.one[A_YAW_ACC, :m]
    yaw_acceleration_kernel(t, r, prev, yaw_acc)  # prev[PREV_T], prev[PREV_R]: (t, r)
    axc = sc.one[A_AXC, :m]
    ayc = sc.one[A_AYC, :m]
    for i in range(m):
        axc[i] = fxa[i] - bias_ref[i, 0]
        ayc[i] = fya[i] - bias_ref[i, 1]
    ax_i, ay_i = corner_acc_kernel(axc, ayc, r, yaw_acc, xw, yw)
    a_xt = sc.four[C_A_XT, :m]
    a_yt = sc.four[C_A_YT, :m]
    rotate_kernel(ax_i.reshape(-1), ay_i.reshape(-1), delta.reshape(-1), 1.0, a_xt.reshape(-1),
                  a_yt.reshape(-1))
    vg = sc.one[A_VG, :m]
    for i in range(m):
        vg[i] = radius * (0.25 * (omega[i, 0] + omega[i, 1] + omega[i, 2] + omega[i, 3]))
    vyr = sc.one[A_VYR, :m]
    vyr[:] = v_ref[:, 1]
    vx_i, vy_i = transport_kernel(vg, vyr, r, xw, yw, 1.0)
    vxt_g = sc.four[C_VXT_G, :m]
    vyt_in = sc.four[C_VYT_IN, :m]
    rotate_kernel(vx_i.reshape(-1), vy_i.reshape(-1), delta.reshape(-1), 1.0,
                  vxt_g.reshape(-1), vyt_in.reshape(-1))
    vxr = sc.one[A_VXR, :m]
    vxr[:] = v_ref[:, 0]
    vxr_i, vyr_i = transport_kernel(vxr, vyr, r, xw, yw, 1.0)
    vxt_r = sc.four[C_VXT_R, :m]
    vyt_r = sc.four[C_VYT_R, :m]
    rotate_kernel(vxr_i.reshape(-1), vyr_i.reshape(-1), delta.reshape(-1), 1.0,
                  vxt_r.reshape(-1), vyt_r.reshape(-1))
    f4 = sc.four
    k = CornerOutputs(f4[C_K_VXT, :m], f4[C_K_VYT, :m], f4[C_K_SIGMA, :m], sc.flags[1, :m],
                      f4[C_K_VRX, :m], f4[C_K_ZX, :m], f4[C_K_ZDOT, :m], f4[C_K_VRY, :m],
                      f4[C_K_ZY, :m])
    k.vyt[:] = 0.0  # what an observer does not estimate is left as given: v_yt 0
    hint = sc.flags[0, :m]
    hint[:] = False
    inp = CornerInputs(t, omega, mu_x, mu_y, a_xt, a_yt, delta, r, hint, vyt_in)
    seed = -1  # the row after which the observers take the reference's velocity (SEED_AT)
    if seeded[0] == 0.0:
        t0 = t_start[0] if not np.isnan(t_start[0]) else t[0]
        for i in range(m):
            if t[i] - t0 >= seed_s:
                seed = i
                break
    if seed < 0:
        corner_rows(cp, cs, inp, k)
    else:
        corner_rows(cp, cs, _corner_inputs_rows(inp, 0, seed + 1),
                    _corner_outputs_rows(k, 0, seed + 1))
        seed_corners(cp, cs, omega[seed], vxt_r[seed])
        seeded[0] = 1.0
        corner_rows(cp, cs, _corner_inputs_rows(inp, seed + 1, m),
                    _corner_outputs_rows(k, seed + 1, m))
    k_vxt, k_vyt, k_high = k.vxt, k.vyt, k.high
    if cp.lpv:  # the KFs leave v_yt at 0; the LPV's is NaN without its lateral observer
        for i in range(m):
            for c in range(4):
                if np.isnan(k_vyt[i, c]):
                    k_vyt[i, c] = 0.0
    slip = sc.four[C_SLIP, :m]
    slip_ratio_kernel(omega.reshape(-1), vxt_r.reshape(-1), radius, 0.1, slip.reshape(-1))
    vx_b = sc.four[C_VX_B, :m]
    vy_b = sc.four[C_VY_B, :m]
    rotate_kernel(k_vxt.reshape(-1), k_vyt.reshape(-1), delta.reshape(-1), -1.0,
                  vx_b.reshape(-1), vy_b.reshape(-1))
    phi = sc.four[C_PHI, :m]
    for i in range(m):
        for c in range(4):
            phi[i, c] = vx_b[i, c] + r[i] * yw[c]
    vx_f = sc.one[A_VX_F, :m]
    fw = sc.four[C_FW, :m]
    if vp.fusion == ADAPTIVE:
        adaptive_axle_kernel(phi, slip, vp.w_s, vp.w_range, vp.rho, vp.threshold, vx_f, fw)
    elif vp.fusion == OPINION:
        opinion_kernel(phi, slip, vp.k1, vp.k2, vp.w_floor, vp.band, vp.gamma, vx_f, fw, conf)
    else:
        fixed_axle_kernel(phi, vp.eta_front, vx_f, fw)
    n_high = sc.n_high[:m]
    n_high[:] = 0
    for i in range(m):
        for c in range(4):
            n_high[i] += 1 if k_high[i, c] else 0
    return vx_f, n_high


@njit(**_JIT)
def _corner_inputs_rows(a: CornerInputs, i: int, j: int) -> CornerInputs:
    """Rows [i, j) of ``a`` (views)."""
    return CornerInputs(a.t[i:j], a.omega[i:j], a.mu_x[i:j], a.mu_y[i:j], a.a_xt[i:j],
                        a.a_yt[i:j], a.delta[i:j], a.yaw_rate[i:j], a.hint[i:j], a.vyt_in[i:j])


@njit(**_JIT)
def _corner_outputs_rows(a: CornerOutputs, i: int, j: int) -> CornerOutputs:
    """Rows [i, j) of ``a`` (views: the observers write through them)."""
    return CornerOutputs(a.vxt[i:j], a.vyt[i:j], a.sigma[i:j], a.high[i:j], a.vrx[i:j],
                         a.zx[i:j], a.zdot[i:j], a.vry[i:j], a.zy[i:j])


@njit(**_JIT)
def _fused(rp: ReferenceKernelParams, fused: ReferenceState, prev: np.ndarray, sc: Scratch,
           t: np.ndarray, omega: np.ndarray, torque: np.ndarray, delta: np.ndarray,
           r: np.ndarray, fxa: np.ndarray, fya: np.ndarray, fy_sd: np.ndarray,
           mu_x: np.ndarray, axle: np.ndarray, extra: np.ndarray, extra_var: np.ndarray,
           same: bool, vx_f: np.ndarray,
           n_high: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The fused filter of a block (velocity "fused"): the second reference filter
    that takes the corner observers' fused CG v_x ``vx_f`` (into ``extra[:, 1]``,
    ``extra_var[:, 1]``; column 0 holds the GNSS fixes) while ≥ 3 corners are in high slip
    (``n_high``). Returns its (v, σ, bias), the reference filter's while the fused one has
    not yet diverged from it (the reference filter's are the views B_V_REF, B_SIG_REF,
    C_BIAS_REF of ``sc``). ``rp`` the reference filter's parameters, ``fused`` the fused
    filter's state, ``prev`` = VelocityState.prev (its [PREV_FUSED_SAME] set to 0 once
    they differ)."""
    m = t.shape[0]
    any_slip = False
    for i in range(m):
        slipping = n_high[i] >= 3
        any_slip = any_slip or slipping
        extra[i, 1] = vx_f[i] if slipping else np.nan
        extra_var[i, 1] = rp.sigma_corner_slip ** 2 if slipping else np.nan
    if same and not any_slip:
        return sc.two[B_V_REF, :m], sc.two[B_SIG_REF, :m], sc.four[C_BIAS_REF, :m]
    prev[PREV_FUSED_SAME] = 0.0
    v = sc.two[B_V_FUSED, :m]
    sig = sc.two[B_SIG_FUSED, :m]
    bias = sc.four[C_BIAS_FUSED, :m]
    trust = sc.four[C_TRUST, :m]  # the reference filter's, not read: written over
    _reference_rows(rp, fused, 0, m, t, omega, torque, mu_x, axle, fxa, fya, fy_sd, r, delta,
                    extra, extra_var, v, sig, bias, trust)
    return v, sig, bias


class Corners(NamedTuple):
    """A block's per-corner quantities (m, 4) that the last stages read: forces (N) and their
    σ, slip ratio and angle (rad), tire-frame velocities (m/s), road-wheel angles (rad),
    wheel speeds (rad/s)."""

    fx: np.ndarray
    fy: np.ndarray
    fz: np.ndarray
    sig_fx: np.ndarray
    sig_fy: np.ndarray
    sr: np.ndarray
    sa: np.ndarray
    vxt: np.ndarray
    vyt: np.ndarray
    delta: np.ndarray
    omega: np.ndarray


@njit(**_JIT)
def _post(p: PostParams, st: PostState, sc: Scratch, x: np.ndarray, t: np.ndarray,
          ax: np.ndarray, v: np.ndarray, sig: np.ndarray, c_y: np.ndarray,
          vy_unverified: np.ndarray, corners: Corners, radius: float, Y: np.ndarray,
          col: np.ndarray, k0: int) -> None:
    """Friction, validity and uncertainty of a block (their per-sample steps) and its health
    flags, into Y (quantities from :data:`_R_MU` on). ``v``, ``sig`` (m, 2) the filter's
    velocity and σ, m/s; ``vy_unverified`` the time since the reference filter last accepted
    a v_y pseudo-measurement, s; ``radius`` the wheel radius, m (the consistency test's
    R ω); ``sc`` the one sample's working arrays."""
    fx, fy, fz, sig_fx, sig_fy = (corners.fx, corners.fy, corners.fz, corners.sig_fx,
                                  corners.sig_fy)
    sr, sa, vxt, vyt = corners.sr, corners.sa, corners.vxt, corners.vyt
    delta, omega = corners.delta, corners.omega
    m = t.shape[0]
    if np.isnan(st.t_start[0]):
        st.t_start[0] = t[0]
    d = sc.sample
    mu, smu, ex, fz_i = d[D_MU:D_MU + 4], d[D_SMU:D_SMU + 4], d[D_EX:D_EX + 4], d[D_FZ:D_FZ + 4]
    valid, reason = d[D_VALID:D_VALID + _N_GROUPS], d[D_REASON:D_REASON + _N_GROUPS]
    sigma = d[D_SIGMA:D_SIGMA + N_SIGMA]
    for i in range(m):
        k = k0 + i
        vx = v[i, 0]
        floor = p.friction.sigma_vy_floor  # a method without a filter σ (NaN) gets the floor
        s_a = (sig[i, 1] if sig[i, 1] > floor else floor) / max(abs(vx), 1.0)
        s_a = s_a if np.isfinite(s_a) else 0.0
        friction_step(p.friction, st.friction, t[i], fx[i], fy[i], fz[i], sig_fx[i], sig_fy[i],
                      sr[i], sa[i], s_a, c_y[i], mu, smu, ex)
        for c in range(4):
            for j, value in ((_R_MU + 3 * c, mu[c]), (_R_MU + 3 * c + 1, smu[c]),
                             (_R_MU + 3 * c + 2, ex[c])):
                if col[j] >= 0:
                    Y[col[j], k] = value
        for c in range(4):
            fz_i[c] = fz[i, c]
        uncertainty_step(p.uncertainty, st.uncertainty, t[i], vx, sig[i, 0], sig[i, 1],
                         delta[i], omega[i], ax[i], x[i, X_AY], fz_i, vxt[i], vyt[i],
                         sr[i], c_y[i], sigma)
        for c in range(N_SIGMA):
            if col[_R_SIGMA + c] >= 0:
                Y[col[_R_SIGMA + c], k] = sigma[c]
        # A load not resolved from zero: μ_x, μ_y written 0 (no friction use; validity bit 16).
        lifted = False
        for c in range(4):
            if not load_resolved(fz_i[c], sigma[_S_FZ + c]):
                lifted = True
                for j in (_R_UTIL + c, _R_UTIL + 4 + c):
                    if col[j] >= 0:
                        Y[col[j], k] = 0.0
        consistent = consistency_step(p.validity, st.consistency, t[i], radius, vx, omega[i],
                                      vxt[i])
        validity_step(p.validity, t[i], st.t_start[0], vx, sr[i], sa[i], delta[i, 0],
                      delta[i, 1], x[i, X_AY], vy_unverified[i], x[i, X_HELD] != 0.0,
                      consistent, lifted, valid, reason)
        for g in range(_N_GROUPS):
            j = _R_MU + 12 + 2 * g
            if col[j] >= 0:
                Y[col[j], k] = valid[g]
            if col[j + 1] >= 0:
                Y[col[j + 1], k] = reason[g]
        for c in range(7):
            if col[_R_HEALTH + c] >= 0:
                Y[col[_R_HEALTH + c], k] = x[i, X_HEALTH_OMEGA + c]


def _corner_trees(pipe: Pipeline) -> tuple[CornerParams, CornerState]:
    """The corner observer's parameter and state trees (those of an idle LuGre KF, never
    read, where the velocity method runs none)."""
    corner = pipe.corner or CornerVelocityEstimator(pipe.vehicle)
    return corner.kernel_params, corner.state


@structref.register
class _StepperType(types.StructRef):
    def preprocess_fields(self, fields: Any) -> Any:
        return tuple((name, types.unliteral(typ)) for name, typ in fields)


class Health(NamedTuple):
    """The health stages' parameters and states (:mod:`vestim.estimators.health`) and
    :func:`step_sample`'s buffers for them: ``w`` (4,) the wheel speeds, ``delta`` (4,) the
    road-wheel angles, ``out`` (4,) the readings with the faulty ones replaced, ``health``
    (4,) their health."""

    wheel: HealthKernelParams
    wheel_state: HealthState
    imu: ImuHealthKernelParams
    imu_state: ImuHealthState
    w: np.ndarray
    delta: np.ndarray
    out: np.ndarray
    health: np.ndarray


def new_health_buffers(wheel: HealthKernelParams, wheel_state: HealthState,
                       imu: ImuHealthKernelParams, imu_state: ImuHealthState) -> Health:
    """:class:`Health` for these parameters and states (the buffers new)."""
    return Health(wheel, wheel_state, imu, imu_state, np.empty(4), np.zeros(4), np.empty(4),
                  np.empty(4))


class Stepper(structref.StructRefProxy):
    """The trees held by compiled code, as the parts :func:`_block` takes (the pipeline's
    parameters and state, :class:`Params` and :class:`State`, field by field) and the
    health stages' :class:`Health`: a call of :func:`step_sample` unboxes one pointer
    instead of the ≈ 200 arrays of the trees (≈ 20 µs a call), and reads each part once
    into the block's call. It shares the trees' arrays."""

    sensors: Sensors  # the fields, for the type checker (define_proxy makes the properties)
    force_p: ForceParams
    force_s: ForceState
    velocity_p: VelocityParams
    velocity_s: VelocityState
    post_p: PostParams
    post_s: PostState
    scratch: Scratch
    col: np.ndarray
    H: Health


structref.define_proxy(Stepper, _StepperType, ["sensors", "force_p", "force_s", "velocity_p",
                                               "velocity_s", "post_p", "post_s", "scratch",
                                               "col", "H"])


@njit(**_JIT)
def new_stepper(P: Params, S: State, H: Health) -> Stepper:
    """The :class:`Stepper` of ``P``, ``S`` and ``H``, made by compiled code that is cached:
    StructRefProxy's own constructor is compiled anew in every process (≈ 6 s at a
    process's first step())."""
    return Stepper(P.sensors, P.force, S.force, P.velocity, S.velocity, P.post, S.post,
                   S.scratch, P.col, H)


@njit(**_JIT)
def step_sample(h: Stepper, X: np.ndarray, Y: np.ndarray) -> None:
    """One live sample, ``X`` (1, :data:`N_X`) with its channels as measured, through the
    health stages (the per-sample steps of the kernels :meth:`Pipeline.run` calls over a
    piece: the faulty readings replaced in ``X``, their health into its health columns,
    ``X_HELD`` set where one was replaced) and then :func:`pipeline_rows` into Y's column
    0: what :meth:`Pipeline.step` calls. A channel the Sensors do not measure is NaN in
    ``X`` (the wheel speeds, ``ax``). Each part of the trees is read from ``h`` once,
    straight into :func:`_block`'s call: every read of a tree takes and later drops a
    reference to each of its arrays (≈ 200 in all), and that reference counting, not
    allocation, is the largest cost of this call (``perf``: 40 % of its compiled time in
    ``NRT_incref``/``NRT_decref`` before the block took the parts instead of the trees)."""
    H = h.H
    sensors = h.sensors
    x = X[0]
    t = x[X_T]
    held = x[X_HELD] != 0.0
    w, out, health = H.w, H.out, H.health
    for c in range(4):
        w[c] = x[X_OMEGA + c]
        x[X_HEALTH_OMEGA + c] = 1.0
    if sensors.omega:
        wheel_health_step(H.wheel, H.wheel_state, t, w, out, health)
        if health[0] + health[1] + health[2] + health[3] < 4.0:
            held = True
            for c in range(4):
                w[c] = x[X_OMEGA + c] = out[c]
        for c in range(4):
            x[X_HEALTH_OMEGA + c] = health[c]
    H.delta[0], H.delta[1] = x[X_DELTA], x[X_DELTA + 1]
    imu_health_step(H.imu, H.imu_state, t, x[X_AX], x[X_AY], x[X_R], w, H.delta, out,
                    health)
    if min(health[0], health[1], health[2]) != 1.0:
        held = True
        if sensors.ax:
            x[X_AX] = out[0]
        x[X_AY], x[X_R] = out[1], out[2]
    for c in range(3):
        x[X_HEALTH_IMU + c] = health[c]
    x[X_HELD] = 1.0 if held else 0.0
    # pipeline_rows(P, S, X, Y, 0, 1): one block, X[0:1] = X
    _block(sensors, h.force_p, h.force_s, h.velocity_p, h.velocity_s, h.post_p, h.post_s,
           h.scratch, h.col, X, Y, 0)


def columns(names: tuple[str, ...]) -> np.ndarray:
    """Params.col for a Y whose rows are ``names``: each quantity of :data:`ROW_NAMES`'s
    row in Y, −1 where ``names`` lacks it."""
    at = {name: j for j, name in enumerate(names)}
    return np.array([at.get(name, -1) for name in ROW_NAMES], dtype=np.int64)


def build(pipe: Pipeline, names: tuple[str, ...], sensors: Sensors) -> tuple[Params, State]:
    """The parameter and state trees of ``pipe`` as it is now (its state arrays shared, not
    copied) for a log with ``sensors``, writing the quantities of :data:`ROW_NAMES` to Y's
    rows in the order of ``names``."""
    cfg = pipe.config
    fe = pipe.force
    veh = pipe.vehicle
    b = veh.body
    lp = fe.config.lateral
    lon = fe._lon
    force_p = ForceParams(
        float(b.wheel_radius), float(fe.rolling_resistance * b.wheel_radius),
        float(fe._drag_coef), float(lp.load_exponent), float(lp.slip_scale),
        normal_load_params(veh), registry.lookup("normal", fe.config.normal).code == DYNAMIC,
        fe._att_prm, lon.params, fe._xw, fe._yw, fe.lateral_params, chassis_params(veh),
        fe.load_filter_params, fe.config.load_filter.enabled)
    inertia = fe._lon_inertia  # the same method and parameters as lon, its own state
    force_s = ForceState(fe._att, lon.state, fe.lateral_state, fe._ax_state, inertia.state,
                         fe._hold_state, fe.load_filter_state)
    corner_p, corner_s = _corner_trees(pipe)
    fp = cfg.fusion_params
    ap = fp.adaptive
    ref = pipe.reference
    p_ref = cfg.reference
    velocity_p = VelocityParams(
        pipe._stiff_prm, pipe._radius_prm,
        ref.kernel_params if sensors.ax else ref.kernel_params_speed,
        float(p_ref.sigma_gnss), float(p_ref.sigma_vehicle_speed), float(p_ref.tau_wheel),
        registry.lookup("velocity", cfg.velocity).code, corner_p,
        registry.lookup("fusion", cfg.fusion).code, float(fp.eta_front), float(ap.w_s),
        float(ap.w_range), float(ap.rho), float(ap.threshold), float(fp.k1), float(fp.k2),
        float(fp.w_floor), float(fp.band), float(fp.gamma))
    prev = np.empty(N_PREV)
    prev[PREV_T], prev[PREV_R] = pipe._prev[PREV_T], pipe._prev[PREV_R]
    prev[PREV_FUSED_SAME] = 1.0 if pipe._fused_is_reference else 0.0
    velocity_s = VelocityState(pipe._stiff_state, pipe._radius_state, pipe._t_gnss, ref.state,
                               pipe.fused.state, prev, corner_s, pipe.kinematic._state,
                               pipe._corner_seeded)
    post_p = PostParams(pipe._friction_prm, pipe._validity_prm, pipe._unc_prm)
    post_s = PostState(pipe._friction_state, pipe._unc_state, pipe._t_start,
                       pipe._consistency_state)
    return (Params(sensors, force_p, velocity_p, post_p, columns(names)),
            State(force_s, velocity_s, post_s, new_scratch()))
