"""Compiled online step of the default pipeline: one sample through every stage in one call.

:meth:`vestim.pipeline.Pipeline.step` feeds the stages one sample at a time through the
same compiled kernels as :meth:`~vestim.pipeline.Pipeline.run`, but a call costs about a
millisecond of Python glue (a dozen kernel dispatches and NumPy calls on one-sample
arrays). :func:`step_kernel` is that glue compiled: it calls the same kernels
(attitude, longitudinal UKF, load split, lateral UKF, reference filters, LuGre corner
KF, fixed or adaptive axle fusion) on the same state arrays, with the NumPy glue of
:meth:`ForceEstimator.advance` and ``Pipeline._advance`` written out for one sample, so
the two paths give the same numbers (tested to 1e-12 against ``run``).

It covers the configurations an online user runs: force ``ukf``, normal loads
``dynamic`` or ``static``, velocity ``fused`` or ``reference``, fusion ``axle`` or
``adaptive``, and samples with wheel torques and ``az``; any other configuration or
sample takes the general path. The per-sample equations are those cited in
:mod:`vestim.estimators.force.estimator`, :mod:`vestim.estimators.force.normal` and
:mod:`vestim.pipeline`.
"""

from __future__ import annotations

from typing import TYPE_CHECKING, Any

import numpy as np
from numba import njit

from vestim.estimators.force.estimator import normalised
from vestim.estimators.force.lateral import lateral_kernel, split_weights
from vestim.estimators.force.longitudinal import UKFKernelParams, ukf_kernel
from vestim.estimators.force.normal import (
    AttitudeKernelParams,
    NormalLoadKernelParams,
    attitude_kernel,
    normal_load_params,
    normal_loads_kernel,
)
from vestim.estimators.friction import FrictionKernelParams, FrictionState, friction_step
from vestim.estimators.fusion.axle import adaptive_axle_kernel, fixed_axle_kernel
from vestim.estimators.uncertainty import N_OUT as N_SIGMA
from vestim.estimators.uncertainty import (
    UncertaintyKernelParams,
    UncertaintyState,
    uncertainty_step,
)
from vestim.estimators.validity import GROUPS as VALIDITY_GROUPS
from vestim.estimators.validity import ValidityKernelParams, validity_step
from vestim.estimators.velocity.lugre_kf import KFParams, lugre_kf_kernel
from vestim.estimators.velocity.reference import (
    ReferenceKernelParams,
    ReferenceState,
    StiffnessKernelParams,
    StiffnessState,
    copy_reference_state,
    reference_step,
    stiffness_step,
)
from vestim.models.chassis import torque_less_rolling_resistance
from vestim.models.kinematics import (
    corner_acc_kernel,
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

# Sample vector layout.
S_T, S_OMEGA, S_TORQUE, S_AX, S_AY, S_AZ, S_R, S_P, S_Q, S_DELTA = 0, 1, 5, 9, 10, 11, 12, 13, 14, 15
N_SAMPLE = 17
SAMPLE_KEYS = ("t", "omega_fl", "omega_fr", "omega_rl", "omega_rr", "torque_fl", "torque_fr",
               "torque_rl", "torque_rr", "ax", "ay", "az", "yaw_rate", "roll_rate",
               "pitch_rate")


@njit(**_JIT)
def step_kernel(s: np.ndarray, out: np.ndarray, fprm: np.ndarray,
                nl_prm: NormalLoadKernelParams,
                dynamic: bool,
                att: np.ndarray, att_prm: AttitudeKernelParams, lon_prm: UKFKernelParams,
                lon_wm: np.ndarray, lon_wc: np.ndarray, lon_tau: float,
                lon_x: np.ndarray, lon_P: np.ndarray, lon_ht: np.ndarray, lon_hw: np.ndarray,
                xw: np.ndarray, yw: np.ndarray, q_lat: np.ndarray, r_lat: np.ndarray,
                w4: np.ndarray, c4: np.ndarray, tau4: float, lat_x: np.ndarray,
                lat_P: np.ndarray, lat_state: np.ndarray, stiff_prm: StiffnessKernelParams,
                stiff_st: StiffnessState, ref_prm: ReferenceKernelParams, ref_st: ReferenceState,
                fused: bool, fus_st: ReferenceState, pstate: np.ndarray,
                kf_prm: np.ndarray, kf_q: np.ndarray, kf_qh: np.ndarray, kf_p0: np.ndarray,
                kf_window: int, kf_ukf: bool, kf_wm: np.ndarray, kf_wc: np.ndarray,
                kf_tau: float, kf_x: np.ndarray, kf_P: np.ndarray, kf_hold: np.ndarray,
                kf_acc: np.ndarray, kf_stats: np.ndarray, kf_wbuf: np.ndarray,
                kf_tbuf: np.ndarray, kf_ring: np.ndarray, adaptive: bool,
                fusion_prm: np.ndarray) -> None:
    """One sample ``s`` (layout :data:`SAMPLE_KEYS` + δ_fl, δ_fr) through the pipeline; the
    output row (the column order of ``Pipeline.run``) is written to ``out``.

    ``att_prm`` and ``nl_prm`` as :func:`~vestim.estimators.force.normal.attitude_kernel`'s and
    :func:`~vestim.estimators.force.normal.normal_loads_kernel`'s ``prm``;
    ``fprm`` = [unused ×4, f_rr, R, drag coefficient, I_z,
    load exponent, slip scale, C_y/F_z]; ``nl_prm`` from
    :func:`~vestim.estimators.force.normal.normal_load_params`; ``lon_prm``, ``lon_wm``, ``lon_wc``,
    ``lon_tau`` as :func:`~vestim.estimators.force.longitudinal.ukf_kernel`'s ``prm``, ``wm``,
    ``wc``, ``tau``;
    ``kf_prm`` = [κ, σ0, σ1, σ2,
    r, r_high, step_ref, λ_u, λ_l, β_e, ω̇_th, min speed, μ release]; ``pstate`` =
    [t_prev, r_prev, fused filter still identical to the plain one (1/0)]; ``stiff_prm``,
    ``stiff_st``, ``ref_prm``, ``ref_st`` and ``fus_st`` (the fused filter's state) as
    :func:`~vestim.estimators.velocity.reference.stiffness_step`'s and
    :func:`~vestim.estimators.velocity.reference.reference_step`'s (``ref_prm.kin_fx``
    false: the sample has ``ax``);
    ``fusion_prm`` = [η_front, w_s, w_range, ρ, λ_th].
    """
    t1 = s[S_T:S_T + 1]
    omega = s[S_OMEGA:S_OMEGA + 4].reshape(1, 4)
    torque = s[S_TORQUE:S_TORQUE + 4].reshape(1, 4)
    r = s[S_R]
    r1 = s[S_R:S_R + 1]
    delta = np.zeros((1, 4))
    delta[0, 0] = s[S_DELTA]
    delta[0, 1] = s[S_DELTA + 1]
    radius = fprm[5]
    # --- force stage (ForceEstimator.advance) ---
    roll = np.empty(1)
    pitch = np.empty(1)
    roll_acc = np.empty(1)
    pitch_acc = np.empty(1)
    fy_sd = np.empty(1)
    attitude_kernel(t1, s[S_AX:S_AX + 1], s[S_AY:S_AY + 1], s[S_P:S_P + 1], s[S_Q:S_Q + 1],
                    r1, omega, att_prm, att, roll, pitch, roll_acc, pitch_acc, fy_sd)
    fxa, fya, fza = road_specific_force(s[S_AX:S_AX + 1], s[S_AY:S_AY + 1], s[S_AZ:S_AZ + 1],
                                        att_prm.gravity * roll, att_prm.gravity * pitch)
    f_x, f_y = fxa[0], fya[0]
    fz = normal_loads_kernel(fxa, fya, fza, roll, pitch, s[S_P:S_P + 1], s[S_Q:S_Q + 1],
                             roll_acc, pitch_acc, nl_prm, dynamic)
    m = nl_prm.mass
    teff = torque_less_rolling_resistance(torque, omega, fz, fprm[4] * radius)
    fx = np.empty((1, 4))
    sig_fx = np.full((1, 4), np.nan)
    high = np.empty((1, 4), dtype=np.bool_)
    ukf_kernel(t1, omega, teff, lon_prm, lon_wm, lon_wc, lon_tau, lon_x, lon_P, lon_ht, lon_hw,
               fx, sig_fx, high)
    w_mean = 0.25 * (omega[0, 0] + omega[0, 1] + omega[0, 2] + omega[0, 3])
    drag = np.empty(1)
    drag[0] = fprm[6] * (radius * w_mean) ** 2
    weights = split_weights(fz, omega, torque, r1, radius, yw, fprm[8], fprm[9])
    fy = np.empty((1, 4))
    sig_fy = np.empty((1, 4))
    speed = np.empty(1)
    speed[0] = radius * np.median(omega[0])
    lateral_kernel(t1, fx, delta, weights, fxa, fya, r1, drag, fz, speed, m, fprm[7], xw, yw,
                   q_lat, r_lat, w4, c4, tau4, lat_x, lat_P, lat_state, fy, sig_fy)
    # --- velocity stage (Pipeline._advance) ---
    mu_x = normalised(fx, fz)
    mu_y = normalised(fy, fz)
    axle = np.empty((1, 2))
    c_y = np.empty(1)
    stiffness_step(stiff_prm, stiff_st, 0, t1, omega, r1, delta, fy, fz, axle, c_y)
    none_v = np.full((1, 0), np.nan)
    v_ref = np.empty((1, 2))
    sig_ref = np.empty((1, 2))
    bias_ref = np.empty((1, 4))
    trust = np.empty((1, 4))
    same = fused and pstate[2] == 1.0
    if same:
        # While it is the plain filter the fused filter's state is not used: it holds the
        # plain filter's state before this sample, the start of its first own step.
        copy_reference_state(fus_st, ref_st)
    reference_step(ref_prm, ref_st, 0, t1, omega, torque, mu_x, axle, fxa, fya, fy_sd, r1, delta,
                   none_v, none_v, v_ref, sig_ref, bias_ref, trust)
    v = v_ref
    sig = sig_ref
    bias = bias_ref
    if fused:
        yaw_acc = np.empty(1)
        yaw_acceleration_kernel(t1, r1, pstate, yaw_acc)  # pstate[:2]: the previous (t, r)
        axc = np.empty(1)
        ayc = np.empty(1)
        axc[0] = f_x - bias_ref[0, 0]
        ayc[0] = f_y - bias_ref[0, 1]
        ax_i, ay_i = corner_acc_kernel(axc, ayc, r1, yaw_acc, xw, yw)
        a_xt = np.empty((1, 4))
        a_yt = np.empty((1, 4))
        rotate_kernel(ax_i.reshape(-1), ay_i.reshape(-1), delta.reshape(-1), 1.0, a_xt.reshape(-1),
                a_yt.reshape(-1))
        vg = np.empty(1)
        vg[0] = radius * w_mean
        vyr = v_ref[0, 1:2].copy()
        vx_i, vy_i = transport_kernel(vg, vyr, r1, xw, yw, 1.0)
        vxt_g = np.empty((1, 4))
        vyt_in = np.empty((1, 4))
        rotate_kernel(vx_i.reshape(-1), vy_i.reshape(-1), delta.reshape(-1), 1.0, vxt_g.reshape(-1),
                vyt_in.reshape(-1))
        hint = np.zeros((1, 4), dtype=np.bool_)
        k_vxt = np.empty((1, 4))
        k_sig = np.empty((1, 4))
        k_high = np.empty((1, 4), dtype=np.bool_)
        k_vr = np.empty((1, 4))
        k_z = np.empty((1, 4))
        k_zd = np.empty((1, 4))
        lugre_kf_kernel(t1, omega, mu_x, a_xt, a_yt, delta, r1, hint, vyt_in, radius,
                        kf_prm[0], kf_prm[1], kf_prm[2], kf_prm[3], xw, kf_q, kf_prm[4], kf_qh,
                        kf_prm[5], kf_p0, kf_prm[6], kf_prm[7], kf_prm[8], kf_prm[9],
                        kf_prm[10], kf_prm[11], kf_prm[12], kf_window, kf_ukf, kf_wm, kf_wc,
                        kf_tau, kf_x, kf_P, kf_hold, kf_acc, kf_stats, kf_wbuf, kf_tbuf,
                        kf_ring, k_vxt, k_sig, k_high, k_vr, k_z, k_zd)
        # Fusion (Pipeline._fuse_corners): slip against the reference speed.
        vxr_i, vyr_i = transport_kernel(v_ref[0, 0:1].copy(), vyr, r1, xw, yw, 1.0)
        vxt_r = np.empty((1, 4))
        vyt_r = np.empty((1, 4))
        rotate_kernel(vxr_i.reshape(-1), vyr_i.reshape(-1), delta.reshape(-1), 1.0, vxt_r.reshape(-1),
                vyt_r.reshape(-1))
        slip = np.empty((1, 4))
        slip_ratio_kernel(omega.reshape(-1), vxt_r.reshape(-1), radius, 0.1, slip.reshape(-1))
        vx_b = np.empty((1, 4))
        vy_b = np.empty((1, 4))
        rotate_kernel(k_vxt.reshape(-1), np.zeros(4), delta.reshape(-1), -1.0, vx_b.reshape(-1),
                vy_b.reshape(-1))
        phi = np.empty((1, 4))
        for i in range(4):
            phi[0, i] = vx_b[0, i] + r * yw[i]
        vx_f = np.empty(1)
        fw = np.empty((1, 4))
        if adaptive:
            adaptive_axle_kernel(phi, slip, fusion_prm[1], fusion_prm[2], fusion_prm[3],
                                 fusion_prm[4], vx_f, fw)
        else:
            fixed_axle_kernel(phi, fusion_prm[0], vx_f, fw)
        n_high = 0
        for i in range(4):
            n_high += 1 if k_high[0, i] else 0
        if not (same and n_high < 3):
            if same:
                pstate[2] = 0.0
            extra = np.full((1, 1), np.nan)
            var = np.full((1, 1), np.nan)
            if n_high >= 3:
                extra[0, 0] = vx_f[0]
                var[0, 0] = ref_prm.sigma_corner_slip ** 2
            v = np.empty((1, 2))
            sig = np.empty((1, 2))
            bias = np.empty((1, 4))
            reference_step(ref_prm, fus_st, 0, t1, omega, torque, mu_x, axle, fxa, fya, fy_sd, r1,
                           delta, extra, var, v, sig, bias, trust)
    # --- outputs (Pipeline._groups order) ---
    vx_o, vy_o = transport_kernel(v[0, 0:1].copy(), v[0, 1:2].copy(), r1, xw, yw, 1.0)
    vxt = np.empty((1, 4))
    vyt = np.empty((1, 4))
    rotate_kernel(vx_o.reshape(-1), vy_o.reshape(-1), delta.reshape(-1), 1.0, vxt.reshape(-1),
            vyt.reshape(-1))
    sr = np.empty((1, 4))
    slip_ratio_kernel(omega.reshape(-1), vxt.reshape(-1), radius, 0.1, sr.reshape(-1))
    sa = np.empty((1, 4))
    slip_angle_kernel(vxt.reshape(-1), vyt.reshape(-1), 0.5, sa.reshape(-1))
    k = 0
    out[k] = t1[0]
    out[k + 1] = v[0, 0]
    out[k + 2] = v[0, 1]
    out[k + 3] = sig[0, 0]
    out[k + 4] = sig[0, 1]
    k = 5
    for block in (vx_o, vy_o, vxt, vyt, sr, sa):
        for i in range(4):
            out[k + i] = block[0, i]
        k += 4
    for block in (fx, fy, fz, mu_x, mu_y, sig_fx, sig_fy):
        for i in range(4):
            out[k + i] = block[0, i]
        k += 4
    out[k] = roll[0]
    out[k + 1] = pitch[0]
    out[k + 2] = bias[0, 0]
    out[k + 3] = c_y[0]


STEP_PSTATE = 29  # position of pstate in build_step's tuple


def build_step(pipe: Pipeline) -> tuple[Any, ...] | None:
    """The state and parameter arguments of :func:`step_kernel` for ``pipe`` as it is now
    (its arrays, shared, not copied), or None if its configuration is not covered."""
    cfg = pipe.config
    if (cfg.force != "ukf" or cfg.velocity not in ("fused", "reference")
            or cfg.fusion not in ("axle", "adaptive")):
        return None
    fe = pipe.force
    veh = pipe.vehicle
    b = veh.body
    fc = fe.config
    lp = fc.lateral
    fprm = np.array([0.0, 0.0, 0.0, 0.0, fe.rolling_resistance,
                     b.wheel_radius, fe._drag_coef, b.yaw_inertia, lp.load_exponent,
                     lp.slip_scale, 0.0])
    lon = fe._lon
    lon_prm = lon.kernel_params
    ref, fus = pipe.reference, pipe.fused
    fused = cfg.velocity == "fused"
    corner = pipe.corner
    if fused:
        assert corner is not None
        tire = veh.tire
        kp = corner.params
        if not isinstance(kp, KFParams):
            return None
        hs = corner._slip
        kf_prm = np.array([tire.kappa_x, tire.sigma0_x, tire.sigma1_x, tire.sigma2_x, kp.r,
                           kp.r_high, kp.step_ref, hs.lambda_upper, hs.lambda_lower, hs.beta_e,
                           hs.omega_dot_threshold, hs.min_speed, hs.mu_release])
        kf = (kf_prm, np.array(kp.q), np.array(kp.q_high), np.array(kp.p0),
              int(hs.release_window), corner.method == "lugre_ukf", corner._wm, corner._wc,
              float(corner._tau), corner._x, corner._P, corner._hold, corner._acc_buf,
              corner._stats, corner._w_buf, corner._t_buf, corner._ring)
    else:
        z1, z2 = np.zeros(1), np.zeros((1, 1))
        kf = (np.zeros(13), z1, z1, z1, 0, False, z1, z1, 0.0, z2, np.zeros((1, 1, 1)), z2,
              z1, z1, z2, z1, np.zeros(1, dtype=np.int64))
    ap = cfg.fusion_params.adaptive
    fusion_prm = np.array([cfg.fusion_params.eta_front, ap.w_s, ap.w_range, ap.rho,
                           ap.threshold])
    pstate = np.array([pipe._prev[0], pipe._prev[1], 1.0 if pipe._fused_is_reference else 0.0])
    force = (fprm, normal_load_params(veh), fc.normal == "dynamic", fe._att, fe._att_prm,
             lon_prm, lon._wm, lon._wc, lon._tau, lon._x, lon._P, lon._hist_t, lon._hist_w,
             fe._xw, fe._yw, fe._q_lat,
             fe._r_lat, fe._w4, fe._c4, float(fe._tau4), fe._lat_x, fe._lat_P, fe._lat_state,
             pipe._stiff_prm, pipe._stiff_state)
    velocity = (ref.kernel_params, ref.state, fused, fus.state, pstate)
    assert len(force) + 4 == STEP_PSTATE
    return (*force, *velocity, *kf, cfg.fusion == "adaptive", fusion_prm)


N_GROUPS = len(VALIDITY_GROUPS)
N_POST = 3 * 4 + 2 * N_GROUPS + 4 + 3 + N_SIGMA
"""Length of :func:`post_step_kernel`'s ``post`` row (see there)."""


@njit(**_JIT)
def post_step_kernel(fp: FrictionKernelParams, fs: FrictionState, vp: ValidityKernelParams,
                     up: UncertaintyKernelParams, us: UncertaintyState, out: np.ndarray,
                     ix: np.ndarray, ix_unc: np.ndarray, s: np.ndarray, held: bool,
                     t_start: float, vy_unverified: float, wheel_health: np.ndarray,
                     imu_health: np.ndarray, post: np.ndarray) -> None:
    """The friction, validity and uncertainty stages of one sample of :func:`step_kernel`'s
    output row ``out`` (their steps, as the batch kernels call them, so step equals run),
    and the row's health flags, into ``post`` (:data:`N_POST`,): per corner μ, σ_μ and the
    excitation flag; per validity group ``valid`` and ``reason``; the wheel-speed health
    (4) and the IMU health (3) copied from ``wheel_health`` and ``imu_health``; the
    uncertainty stage's σ (in :data:`~vestim.estimators.uncertainty.OUTPUT_NAMES` order).

    ``vy_unverified``: the time since the reference filter last accepted a v_y
    pseudo-measurement, s (the validity stage's "v_y unverified").
    ``ix`` holds the positions in ``out`` of t, v_x, σ_vy, the cornering stiffness, then per
    corner F_x, F_y, F_z, σ_Fx, σ_Fy, slip ratio, slip angle (4 each); ``ix_unc`` those of
    v_x, σ_vx, σ_vy (the filter's), the cornering stiffness, then per corner F_z, v_xt,
    v_yt, slip ratio (4 each). ``s`` is the sample (layout :data:`SAMPLE_KEYS` + δ_fl, δ_fr);
    ``held`` an input value was held over a dropout; ``t_start`` the first sample's time (s).
    """
    t, vx = out[ix[0]], out[ix[1]]
    fx, fy, fz = np.empty(4), np.empty(4), np.empty(4)
    sfx, sfy, sr, sa = np.empty(4), np.empty(4), np.empty(4), np.empty(4)
    for c in range(4):
        fx[c], fy[c], fz[c] = out[ix[4 + c]], out[ix[8 + c]], out[ix[12 + c]]
        sfx[c], sfy[c] = out[ix[16 + c]], out[ix[20 + c]]
        sr[c], sa[c] = out[ix[24 + c]], out[ix[28 + c]]
    sig = max(out[ix[2]], fp.sigma_vy_floor) / max(abs(vx), 1.0)
    sig_a = sig if np.isfinite(sig) else 0.0
    mu, smu, ex = np.empty(4), np.empty(4), np.empty(4)
    friction_step(fp, fs, t, fx, fy, fz, sfx, sfy, sr, sa, sig_a, out[ix[3]], mu, smu, ex)
    for c in range(4):
        post[3 * c], post[3 * c + 1], post[3 * c + 2] = mu[c], smu[c], ex[c]
    n_g = N_GROUPS
    valid, reason = np.empty(n_g), np.empty(n_g)
    validity_step(vp, t, t_start, vx, sr, sa, s[S_DELTA], s[S_DELTA + 1], s[S_AY],
                  vy_unverified, held, valid, reason)
    for g in range(n_g):
        post[12 + 2 * g], post[13 + 2 * g] = valid[g], reason[g]
    j = 12 + 2 * n_g
    for c in range(4):
        post[j + c] = wheel_health[c]
    for c in range(3):
        post[j + 4 + c] = imu_health[c]
    delta = np.zeros(4)
    delta[0], delta[1] = s[S_DELTA], s[S_DELTA + 1]
    omega, vxt, vyt = np.empty(4), np.empty(4), np.empty(4)
    for c in range(4):
        omega[c] = s[S_OMEGA + c]
        fz[c], vxt[c] = out[ix_unc[4 + c]], out[ix_unc[8 + c]]
        vyt[c], sr[c] = out[ix_unc[12 + c]], out[ix_unc[16 + c]]
    uncertainty_step(up, us, s[S_T], out[ix_unc[0]], out[ix_unc[1]], out[ix_unc[2]], delta,
                     omega, s[S_AX], s[S_AY], fz, vxt, vyt, sr, out[ix_unc[3]], post[j + 7:])
