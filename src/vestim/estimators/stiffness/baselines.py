"""Linear baselines of 002 Sec. V–VI: RLS with a Kalman filter for the lateral states, and an EKF.

Both use the single-track model of :mod:`~vestim.estimators.stiffness.model`
(:func:`~vestim.estimators.stiffness.model.terms`, the one place where the model
equations are coded); Jacobians with respect to the state come from central
differences of it, and with respect to the stiffness deviation from its exact
sensitivities g and d (the model is affine in w).

RLS + KF (002 Sec. VI-A, after ref. [8]). A Kalman filter estimates the lateral
states [v_y, ψ̇] from [a_y, ψ̇] with the current stiffness estimates and a given
v_x (002 uses the true v_x; :func:`vestim.estimators.stiffness.estimate_stiffness`
uses the wheel-speed reference). Its estimates feed a recursive least-squares
fit with forgetting of the axle forces (002 eq. (1b), (1c), (2)):

    m a_y − C^x_f λ_f sin δ = C^y_f α_f cos δ + C^y_r α_r
    I ψ̈ − l_f C^x_f λ_f sin δ = l_f C^y_f α_f cos δ − l_r C^y_r α_r
    m a_x + D + C^y_f α_f sin δ = C^x_f (λ_f cos δ + κ_r λ_r)

with ψ̈ from the low-passed gyro. Both sides of every regression pass through the
same causal low-pass (a state-variable filter), each equation is scaled by its
noise level, and the estimates are projected on the bounds (002 Sec. V). There
is no bias estimation (002 Sec. VI-A sets the bias to zero).

EKF (002 Sec. V, VII-A). The augmented state [v_x, v_y, ψ̇, ΔC^x, ΔC_f^y, ΔC_r^y,
b_x, b_y, b_ψ] with random-walk stiffness and bias, the same measurements and
noise as Algorithm 1, Joseph-form update and projection of ΔC on the bounds.

Both Kalman measurement updates are :func:`vestim.filters.kalman.kalman_update`
(Joseph form, Cholesky solve of S); the RLS keeps its own gain with forgetting.
"""

from __future__ import annotations

import math
from typing import Any, NamedTuple

import numpy as np
from numba import njit

from vestim.estimators.stiffness.model import (
    M_AX,
    M_AY,
    M_YAW_RATE,
    P_CXF,
    P_CXR,
    P_CYF,
    P_CYR,
    P_DRAG,
    P_IZ,
    P_KXF,
    P_KXR,
    P_LF,
    P_LR,
    P_M,
    P_TXF,
    P_TXR,
    U_DELTA,
    U_DT,
    U_OMEGA_F,
    U_OMEGA_R,
    VX,
    VY,
    W_CX,
    W_CYF,
    W_CYR,
    YAW_RATE,
    slips,
    terms,
)
from vestim.filters.kalman import kalman_update

_JIT: dict[str, Any] = {"cache": True, "error_model": "numpy"}

FD_STEP = (1e-4, 1e-5, 1e-6)
"""Central-difference steps for v_x (m/s), v_y (m/s) and ψ̇ (rad/s); the model is smooth
and nearly linear in v_y and ψ̇ at these scales."""


@njit(**_JIT)
def _predict_and_measure(x: np.ndarray, w: np.ndarray, uk: np.ndarray, p: np.ndarray,
                         out: np.ndarray) -> None:
    """out ← [x_{k+1} (3), a_x, a_y] = [f + g w, h_a + d_a w] at state ``x`` (eq. (9), (12))."""
    delta = uk[U_DELTA]
    ts = uk[U_DT]
    (f0, f1, f2, ax, ay, dxx, dxyf, dxyr, dyx, dyyf, dyyr, grx, gryf, gryr) = terms(
        x[VX], x[VY], x[YAW_RATE], delta, math.sin(delta), math.cos(delta), uk[U_OMEGA_F],
        uk[U_OMEGA_R], ts, p)
    axw = dxx * w[W_CX] + dxyf * w[W_CYF] + dxyr * w[W_CYR]
    ayw = dyx * w[W_CX] + dyyf * w[W_CYF] + dyyr * w[W_CYR]
    out[0] = f0 + ts * axw
    out[1] = f1 + ts * ayw
    out[2] = f2 + grx * w[W_CX] + gryf * w[W_CYF] + gryr * w[W_CYR]
    out[3] = ax + axw
    out[4] = ay + ayw


@njit(**_JIT)
def _state_jacobian(x: np.ndarray, w: np.ndarray, uk: np.ndarray, p: np.ndarray,
                    jac: np.ndarray) -> None:
    """jac (5, 3) ← ∂[f + g w, h_a + d_a w]/∂x by central differences."""
    xp = x.copy()
    op = np.empty(5)
    om = np.empty(5)
    for j in range(3):
        hstep = FD_STEP[j]
        xp[:] = x
        xp[j] = x[j] + hstep
        _predict_and_measure(xp, w, uk, p, op)
        xp[j] = x[j] - hstep
        _predict_and_measure(xp, w, uk, p, om)
        for i in range(5):
            jac[i, j] = (op[i] - om[i]) / (2.0 * hstep)


@njit(**_JIT)
def _sensitivities(x: np.ndarray, uk: np.ndarray, p: np.ndarray, gmat: np.ndarray,
                   dmat: np.ndarray) -> None:
    """gmat (3, 3) ← g = ∂x_{k+1}/∂w; dmat (2, 3) ← ∂[a_x, a_y]/∂w (exact, eq. (10), (12))."""
    delta = uk[U_DELTA]
    ts = uk[U_DT]
    (_, _, _, _, _, dxx, dxyf, dxyr, dyx, dyyf, dyyr, grx, gryf, gryr) = terms(
        x[VX], x[VY], x[YAW_RATE], delta, math.sin(delta), math.cos(delta), uk[U_OMEGA_F],
        uk[U_OMEGA_R], ts, p)
    dmat[0, 0] = dxx
    dmat[0, 1] = dxyf
    dmat[0, 2] = dxyr
    dmat[1, 0] = dyx
    dmat[1, 1] = dyyf
    dmat[1, 2] = dyyr
    for j in range(3):
        gmat[0, j] = ts * dmat[0, j]
        gmat[1, j] = ts * dmat[1, j]
    gmat[2, 0] = grx
    gmat[2, 1] = gryf
    gmat[2, 2] = gryr


@njit(**_JIT)
def ekf_kernel(y: np.ndarray, u: np.ndarray, active: np.ndarray, p: np.ndarray,
               r_diag: np.ndarray, q_diag: np.ndarray, lo: np.ndarray, hi: np.ndarray,
               xa: np.ndarray, pa: np.ndarray, x_out: np.ndarray, sd_out: np.ndarray) -> None:
    """EKF on the augmented state [v_x, v_y, ψ̇, w (3), b (3)] over K steps.

    Args:
        y: (K, 3), u: (K, 4), active: (K,), p: as in Algorithm 1.
        r_diag: (3,) measurement noise variances. q_diag: (9,) process noise variances per
            step (model error, stiffness walk, bias walk); the stiffness walk is applied
            only on active steps (002 Sec. V).
        lo, hi: (3,) bounds of w. xa: (9,) initial mean, pa: (9, 9) initial covariance
            (both updated in place).
        x_out, sd_out: (K, 9) ← filtered mean and one-sigma after each update.
    """
    n = 9
    jac = np.empty((5, 3))
    gmat = np.empty((3, 3))
    dmat = np.empty((2, 3))
    pred = np.empty(5)
    fmat = np.eye(n)
    hmat = np.zeros((3, n))
    eye = np.eye(n)
    rmat = np.zeros((3, 3))
    for j in range(3):
        rmat[j, j] = r_diag[j]
    innov = np.empty(3)
    ph = np.empty((n, 3))
    smat = np.empty((3, 3))
    lmat = np.empty((3, 3))
    gain = np.empty((n, 3))
    mwork = np.empty((n, n))
    for k in range(y.shape[0]):
        uk = u[k]
        xs = xa[0:3].copy()
        ws = xa[3:6].copy()
        # ---- update with y_k = h + d w + b + e
        _predict_and_measure(xs, ws, uk, p, pred)
        _state_jacobian(xs, ws, uk, p, jac)
        _sensitivities(xs, uk, p, gmat, dmat)
        hmat[:, :] = 0.0
        for j in range(3):
            hmat[0, j] = jac[3, j]
            hmat[1, j] = jac[4, j]
            hmat[0, 3 + j] = dmat[0, j]
            hmat[1, 3 + j] = dmat[1, j]
        hmat[2, YAW_RATE] = 1.0
        hmat[0, 6] = 1.0
        hmat[1, 7] = 1.0
        hmat[2, 8] = 1.0
        innov[0] = y[k, M_AX] - pred[3] - xa[6]
        innov[1] = y[k, M_AY] - pred[4] - xa[7]
        innov[2] = y[k, M_YAW_RATE] - xa[YAW_RATE] - xa[8]
        kalman_update(xa, pa, hmat, rmat, innov, ph, smat, lmat, gain, mwork)
        for j in range(3):
            xa[3 + j] = min(max(xa[3 + j], lo[j]), hi[j])
        for i in range(n):
            x_out[k, i] = xa[i]
            sd_out[k, i] = math.sqrt(max(pa[i, i], 0.0))
        # ---- predict x_{k+1} = f + g w; w, b random walks
        xs[:] = xa[0:3]
        ws[:] = xa[3:6]
        _predict_and_measure(xs, ws, uk, p, pred)
        _state_jacobian(xs, ws, uk, p, jac)
        _sensitivities(xs, uk, p, gmat, dmat)
        fmat[:, :] = eye
        for i in range(3):
            for j in range(3):
                fmat[i, j] = jac[i, j]
                fmat[i, 3 + j] = gmat[i, j]
        xa[0] = pred[0]
        xa[1] = pred[1]
        xa[2] = pred[2]
        pa[:, :] = fmat @ pa @ fmat.T
        for i in range(n):
            if 3 <= i < 6 and not active[k]:
                continue
            pa[i, i] += q_diag[i]


@njit(**_JIT)
def _lp_step(state: np.ndarray, j: int, value: float, a: float) -> float:
    state[j] += a * (value - state[j])
    return state[j]


class RlsParams(NamedTuple):
    """What :func:`rls_kf_kernel` holds fixed over a run (packed by
    :meth:`~vestim.estimators.stiffness.estimator.RlsKalman.kernel_params`).

    Attributes:
        p: model parameters (nominal stiffness and geometry, ``model.P_*``).
        r_diag: (3,) measurement noise variances [a_x, a_y, ψ̇] (m²/s⁴, m²/s⁴, rad²/s²).
        q_lat: (2,) process noise variances per step of [v_y, ψ̇] (m²/s², rad²/s²).
        lo, hi: (3,) bounds of the deviation w (absolute stiffness = nominal + w; N per unit
            slip, N/rad, N/rad).
        forgetting: RLS forgetting factor (per step). cutoff: Hz of the regression low-pass.
    """

    p: np.ndarray
    r_diag: np.ndarray
    q_lat: np.ndarray
    lo: np.ndarray
    hi: np.ndarray
    forgetting: float
    cutoff: float


class RlsState(NamedTuple):
    """What :func:`rls_kf_kernel` advances in place.

    Attributes:
        theta: (3,) stiffness deviation [ΔC^x, ΔC_f^y, ΔC_r^y].
        p_rls: (3, 3) RLS covariance (the longitudinal term is decoupled).
        z: (2,) lateral state [v_y, ψ̇] (m/s, rad/s). p_kf: (2, 2) its covariance.
    """

    theta: np.ndarray
    p_rls: np.ndarray
    z: np.ndarray
    p_kf: np.ndarray


class RlsInputs(NamedTuple):
    """The time series :func:`rls_kf_kernel` reads, one row per step.

    Attributes:
        y: (K, 3) measurements [a_x, a_y, ψ̇]. u: (K, 4) inputs [δ, ω_f, ω_r, T_s].
        vx: (K,) longitudinal speed used by both filters (m/s).
        active: (K,) activation (the RLS updates only on active steps).
    """

    y: np.ndarray
    u: np.ndarray
    vx: np.ndarray
    active: np.ndarray


class RlsEstimates(NamedTuple):
    """The outputs of :func:`rls_kf_kernel`, one row per step.

    Attributes:
        x, x_sd: (K, 3) [v_x, v_y, ψ̇] (m/s, m/s, rad/s) and one-sigma (v_x given: sd 0).
        w, w_sd: (K, 3) estimate of the deviation w and its one-sigma.
    """

    x: np.ndarray
    x_sd: np.ndarray
    w: np.ndarray
    w_sd: np.ndarray


@njit(**_JIT)
def rls_kf_kernel(prm: RlsParams, st: RlsState, inp: RlsInputs, out: RlsEstimates) -> None:
    """Lateral Kalman filter + recursive least squares for the axle stiffness, K steps.

    Args:
        prm: the run's parameters (:class:`RlsParams`).
        st: θ, the RLS covariance and the lateral Kalman filter (:class:`RlsState`), in place.
        inp: y, u, v_x, activation over the K steps (:class:`RlsInputs`).
        out: ← the estimates of each step (:class:`RlsEstimates`).
    """
    p, r_diag, q_lat, lo, hi = prm.p, prm.r_diag, prm.q_lat, prm.lo, prm.hi
    forgetting, cutoff = prm.forgetting, prm.cutoff
    theta, p_rls, z, p_kf = st.theta, st.p_rls, st.z, st.p_kf
    y, u, vx, active = inp.y, inp.u, inp.vx, inp.active
    x_out, x_sd, c_out, c_sd = out.x, out.x_sd, out.w, out.w_sd
    m = p[P_M]
    iz = p[P_IZ]
    lf = p[P_LF]
    lr = p[P_LR]
    xs = np.empty(3)
    pred = np.empty(5)
    jac = np.empty((5, 3))
    lp = np.zeros(12)
    # lateral Kalman filter: H = [[∂a_y/∂v_y, ∂a_y/∂ψ̇], [0, 1]], R = diag(r_ay, r_ψ̇)
    hkf = np.zeros((2, 2))
    hkf[1, 1] = 1.0
    rkf = np.zeros((2, 2))
    rkf[0, 0] = r_diag[M_AY]
    rkf[1, 1] = r_diag[M_YAW_RATE]
    ekf = np.empty(2)
    phkf = np.empty((2, 2))
    skf = np.empty((2, 2))
    lkf = np.empty((2, 2))
    kkf = np.empty((2, 2))
    mkf = np.empty((2, 2))
    ts0 = u[0, U_DT]
    a_lp = 1.0 - math.exp(-2.0 * math.pi * cutoff * ts0)
    rho = 1.0 - a_lp
    # noise of the low-passed a_y, a_x and of the low-passed yaw-rate difference quotient
    sa = math.sqrt(r_diag[M_AY] * (1.0 - rho) / (1.0 + rho))
    sx = math.sqrt(r_diag[M_AX] * (1.0 - rho) / (1.0 + rho))
    sr = (1.0 - rho) * math.sqrt(r_diag[M_YAW_RATE] * 2.0 / (1.0 + rho)) / ts0
    r_prev = y[0, M_YAW_RATE]
    lp[11] = y[0, M_YAW_RATE]
    for k in range(y.shape[0]):
        uk = u[k]
        delta = uk[U_DELTA]
        ts = uk[U_DT]
        sdl = math.sin(delta)
        cdl = math.cos(delta)
        # ---- Kalman update of [v_y, ψ̇] with [a_y, ψ̇] (Joseph form, vestim.filters.kalman)
        xs[VX] = vx[k]
        xs[VY] = z[0]
        xs[YAW_RATE] = z[1]
        _predict_and_measure(xs, theta, uk, p, pred)
        _state_jacobian(xs, theta, uk, p, jac)
        hkf[0, 0] = jac[4, VY]
        hkf[0, 1] = jac[4, YAW_RATE]
        ekf[0] = y[k, M_AY] - pred[4]
        ekf[1] = y[k, M_YAW_RATE] - z[1]
        kalman_update(z, p_kf, hkf, rkf, ekf, phkf, skf, lkf, kkf, mkf)
        n00 = p_kf[0, 0]
        n11 = p_kf[1, 1]
        x_out[k, VX] = vx[k]
        x_out[k, VY] = z[0]
        x_out[k, YAW_RATE] = z[1]
        x_sd[k, VX] = 0.0
        x_sd[k, VY] = math.sqrt(max(n00, 0.0))
        x_sd[k, YAW_RATE] = math.sqrt(max(n11, 0.0))
        # ---- regressions (both sides low-passed)
        lam_f, lam_r, alpha_f, alpha_r = slips(vx[k], z[0], z[1], delta, uk[U_OMEGA_F],
                                               uk[U_OMEGA_R], p)
        cxf = p[P_CXF] + p[P_KXF] * theta[W_CX] + p[P_TXF] * theta[W_CYF]
        cxr_known = p[P_CXR] + p[P_TXR] * theta[W_CYR]
        cxf_known = p[P_CXF] + p[P_TXF] * theta[W_CYF]
        cyf = p[P_CYF] + theta[W_CYF]
        fxs = cxf * lam_f * sdl
        rdot = (y[k, M_YAW_RATE] - r_prev) / ts
        r_prev = y[k, M_YAW_RATE]
        # lateral, force balance and yaw moment; longitudinal
        y1 = _lp_step(lp, 0, m * y[k, M_AY] - fxs, a_lp)
        f11 = _lp_step(lp, 1, alpha_f * cdl, a_lp)
        f12 = _lp_step(lp, 2, alpha_r, a_lp)
        y2 = _lp_step(lp, 3, iz * rdot - lf * fxs, a_lp)
        f21 = _lp_step(lp, 4, lf * alpha_f * cdl, a_lp)
        f22 = _lp_step(lp, 5, -lr * alpha_r, a_lp)
        y3 = _lp_step(lp, 6, m * y[k, M_AX] + p[P_DRAG] * vx[k] * abs(vx[k])
                      + cyf * alpha_f * sdl, a_lp)
        f3 = _lp_step(lp, 7, lam_f * cdl * p[P_KXF] + lam_r * p[P_KXR], a_lp)
        f3n = _lp_step(lp, 8, lam_f * cdl * cxf_known + lam_r * cxr_known, a_lp)
        if active[k]:
            # nominal parts move to the left: regress the deviation
            rows_y = (y1 - p[P_CYF] * f11 - p[P_CYR] * f12, y2 - p[P_CYF] * f21 - p[P_CYR] * f22)
            rows_f = ((f11, f12), (f21, f22))
            scales = (m * sa, iz * sr)
            for e in range(2):
                phi0 = rows_f[e][0] / scales[e]
                phi1 = rows_f[e][1] / scales[e]
                yy = rows_y[e] / scales[e]
                q0 = p_rls[1, 1] * phi0 + p_rls[1, 2] * phi1
                q1 = p_rls[2, 1] * phi0 + p_rls[2, 2] * phi1
                den = forgetting + phi0 * q0 + phi1 * q1
                g0 = q0 / den
                g1 = q1 / den
                err = yy - (phi0 * theta[W_CYF] + phi1 * theta[W_CYR])
                theta[W_CYF] += g0 * err
                theta[W_CYR] += g1 * err
                n11_ = (p_rls[1, 1] - g0 * q0) / forgetting
                n12_ = (p_rls[1, 2] - g0 * q1) / forgetting
                n22_ = (p_rls[2, 2] - g1 * q1) / forgetting
                p_rls[1, 1] = n11_
                p_rls[1, 2] = n12_
                p_rls[2, 1] = n12_
                p_rls[2, 2] = n22_
            # y3 = [force of the known stiffness parts] + w φ: regress w on the difference
            phi = f3 / (m * sx)
            yy = (y3 - f3n) / (m * sx)
            qx = p_rls[0, 0] * phi
            den = forgetting + phi * qx
            gx = qx / den
            theta[W_CX] += gx * (yy - phi * theta[W_CX])
            p_rls[0, 0] = (p_rls[0, 0] - gx * qx) / forgetting
            for j in range(3):
                theta[j] = min(max(theta[j], lo[j]), hi[j])
        for j in range(3):
            c_out[k, j] = theta[j]
            c_sd[k, j] = math.sqrt(max(p_rls[j, j], 0.0))
        # ---- Kalman prediction of [v_y, ψ̇]
        xs[VX] = vx[k]
        xs[VY] = z[0]
        xs[YAW_RATE] = z[1]
        _predict_and_measure(xs, theta, uk, p, pred)
        _state_jacobian(xs, theta, uk, p, jac)
        f00 = jac[VY, VY]
        f01 = jac[VY, YAW_RATE]
        f10 = jac[YAW_RATE, VY]
        f11_ = jac[YAW_RATE, YAW_RATE]
        z[0] = pred[VY]
        z[1] = pred[YAW_RATE]
        p00 = p_kf[0, 0]
        p01 = p_kf[0, 1]
        p11 = p_kf[1, 1]
        t00 = f00 * p00 + f01 * p01
        t01 = f00 * p01 + f01 * p11
        t10 = f10 * p00 + f11_ * p01
        t11 = f10 * p01 + f11_ * p11
        p_kf[0, 0] = t00 * f00 + t01 * f01 + q_lat[0]
        p_kf[0, 1] = t00 * f10 + t01 * f11_
        p_kf[1, 0] = p_kf[0, 1]
        p_kf[1, 1] = t10 * f10 + t11 * f11_ + q_lat[1]
