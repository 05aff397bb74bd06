"""Algorithm 1 (002): the fused kernel against the generic filter functions, conformance, end to end."""

import math
from dataclasses import replace

import numpy as np
import pandas as pd
import pytest

from vestim.errors import LogFormatError
from vestim.estimators.stiffness import (
    AugmentedEKF,
    AugmentedPF,
    RlsKalman,
    StiffnessConfig,
    StiffnessPrior,
    estimate_stiffness,
    prepare_inputs,
)
from vestim.estimators.stiffness.draws import fill_normals, seed_state
from vestim.estimators.stiffness.model import SingleTrackParams, model_terms
from vestim.estimators.stiffness.pf import (
    C_B,
    C_LAM,
    C_MU,
    C_PB,
    C_X,
    L00,
    L01,
    L02,
    L11,
    L12,
    L22,
    PRR,
    PXX,
    PXY,
    PYY,
    Estimates,
    PFParams,
    PFState,
    SeriesInputs,
    alg1_kernel,
    bias_update,
    new_estimates,
    pack_particles,
)
from vestim.filters.linalg import chol_logdet, cholesky
from vestim.filters.niw import (
    moment_matched_scale,
    mvt_draw,
    mvt_log_kernel,
    niw_predict,
    niw_update,
    t_condition,
)
from vestim.io import load_vehicle
from vestim.io.vehicle import Stiffness

from .conftest import SUV_FWD

PACK = ((L00, 0, 0), (L01, 0, 1), (L02, 0, 2), (L11, 1, 1), (L12, 1, 2), (L22, 2, 2))


def _unpack(lam: np.ndarray) -> np.ndarray:
    full = np.empty((3, 3))
    for k, i, j in PACK:
        full[i, j] = full[j, i] = lam[k]
    return full


def _reference_alg1(y, u, active, bias_on, p, r_pk, q_pk, forget, model_error, x, mu, lam, b, pb,
                    logw, gamma, nu, blocks, lookahead=False):
    """Algorithm 1 without resampling, composed from :mod:`vestim.filters.niw` and dense numpy.

    ``lookahead``: the gyro row of the measurement that conditions w_k and weighs the particles
    is the gyro sample of step k + 1, ψ̇_{k+1} = f_ψ̇ + g_ψ̇ w_k (eq. (9)): its row of d is the
    yaw row of g, its noise R_ψ̇ + P_ψ̇ + (T_s σ_me,ψ̇)²; at the last step it carries nothing.

    ``blocks[k]`` is the (N, 7) block of normals the kernel draws at the start of step k
    (and ``blocks[K]`` at the end): columns 0–3 the Student-t draw of step k, columns 4–6
    the model-error noise of step k − 1 on [v_y, ψ̇, v_x]. ``lam`` is a list of dense 3 × 3 Λ.
    """
    n = x.shape[0]
    r_full = np.diag(r_pk[[PXX, PYY, PRR]])
    r_full[0, 1] = r_full[1, 0] = r_pk[PXY]
    out = {k: [] for k in ("xh", "xv", "wh", "wc", "bh", "ess")}
    pbf = [np.array([[v[PXX], v[PXY], 0], [v[PXY], v[PYY], 0], [0, 0, v[PRR]]]) for v in pb]
    x, mu, b, logw = x.copy(), mu.copy(), b.copy(), logw.copy()
    for k in range(y.shape[0]):
        dof = nu - 2.0
        xn, ds = np.empty_like(x), []
        for i in range(n):
            f, g, h, d = np.empty(3), np.empty((3, 3)), np.empty(3), np.empty((3, 3))
            model_terms(x[i], u[k], p, f, g, h, d)
            lam_e, low_e = np.empty((3, 3)), np.empty((3, 3))
            d_c, noise, z = d.copy(), r_full + pbf[i], y[k] - h - b[i] - d @ mu[i]
            if lookahead:
                d_c[2] = g[2] if k + 1 < y.shape[0] else 0.0
                noise = noise.copy()
                if k + 1 < y.shape[0]:
                    noise[2, 2] += (u[k, 3] * model_error[2]) ** 2
                    z[2] = y[k + 1, 2] - f[2] - b[i][2] - g[2] @ mu[i]
                else:
                    z[2] = 0.0
            moment_matched_scale(d_c, lam[i], gamma, dof, noise, lam_e)             # (35)
            cholesky(lam_e, low_e)
            mu_c, scale_c, low_c = np.empty(3), np.empty((3, 3)), np.empty((3, 3))
            dof_c, maha = t_condition(mu[i], (1 + gamma) / dof * lam[i], d_c, low_e, z, dof, mu_c,
                                      scale_c, np.empty((3, 3)), np.empty(3))         # (40)–(41)
            logw[i] += mvt_log_kernel(maha, chol_logdet(low_e), dof, 3)             # (36)
            cholesky(scale_c, low_c)
            a = 2.0 / (9.0 * dof_c)
            chi2 = dof_c * max(1.0 - a + math.sqrt(a) * blocks[k][i, 3], 1e-3) ** 3
            w = np.empty(3)
            mvt_draw(mu_c, low_c, dof_c, blocks[k][i, :3], chi2, w)                 # (39)
            if active[k]:
                niw_update(gamma, nu, mu[i], lam[i], w)                              # (19)
            xn[i] = f + g @ w                                                        # (9)
            if lookahead and k + 1 < y.shape[0]:
                # eq. (30) sees the look-ahead row: its innovation and its Σ̂ term
                d_b, y_b, h_b = d_c, np.array([*y[k, :2], y[k + 1, 2]]), np.array([*h[:2], f[2]])
                me_b = (u[k, 3] * model_error[2]) ** 2
            else:
                d_b, y_b, h_b, me_b = d, y[k], h, 0.0
            ds.append((d_b, y_b, h_b, me_b))
        if active[k]:
            gamma, nu = gamma / (1 + gamma), nu + 1
        q = np.exp(logw - logw.max())
        out["ess"].append(q.sum() ** 2 / (q**2).sum())
        q /= q.sum()
        logw = np.log(q)
        xh = q @ x
        px = (x - xh).T @ (q[:, None] * (x - xh))
        wh = q @ mu
        out["xh"].append(xh)
        out["xv"].append(np.diag(px))
        out["wh"].append(wh)
        out["wc"].append(sum(qi * (li / (nu - 4) + np.outer(m - wh, m - wh))
                             for qi, li, m in zip(q, lam, mu, strict=True)))        # (27)
        hx = np.zeros((3, 3))
        for j, step in enumerate((1e-3, 1e-4, 1e-5)):
            hp, hm = np.empty(3), np.empty(3)
            for sign, dest in ((1, hp), (-1, hm)):
                xs = xh.copy()
                xs[j] += sign * step
                model_terms(xs, u[k], p, np.empty(3), np.empty((3, 3)), dest, np.empty((3, 3)))
            hx[:, j] = (hp - hm) / (2 * step)
        x_unc = hx @ px @ hx.T
        x_unc[:2, 2] = x_unc[2, :2] = 0.0     # the kernel keeps P block-diagonal
        for i in range(n):
            if bias_on[k]:                                                           # (30)
                d, y_b, h_b, me_b = ds[i]
                s_w = d @ (lam[i] / (nu - 4)) @ d.T
                s_w[:2, 2] = s_w[2, :2] = 0.0     # the kernel keeps P block-diagonal
                s_cov = pbf[i] + r_full + s_w + x_unc
                s_cov[2, 2] += me_b
                gain = pbf[i] @ np.linalg.inv(s_cov)
                b[i] = b[i] + gain @ (y_b - h_b - d @ mu[i] - b[i])
                pbf[i] = pbf[i] - gain @ s_cov @ gain.T + np.diag(q_pk[[PXX, PYY, PRR]])  # (29)
            if active[k]:
                niw_predict(gamma, nu, lam[i], forget)                               # (20)
            x[i] = xn[i] + u[k, 3] * model_error * blocks[k + 1][i, [6, 4, 5]]
        out["bh"].append(q @ b)
        if active[k]:
            gamma, nu = gamma / forget, forget * nu
    return x, mu, lam, b, pbf, logw, gamma, nu, {k: np.array(v) for k, v in out.items()}


@pytest.mark.parametrize("lookahead", [False, True])
def test_kernel_equals_the_generic_functions(lookahead):
    """Three steps of the fused kernel equal Algorithm 1 composed from :mod:`vestim.filters.niw`
    (eq. (35), (36), (39)–(41), (19), (20), (9)), a dense bias Kalman filter (eq. (29)–(30))
    and dense moments (eq. (27), (42)), with the same normals (1e-8 relative: the kernel
    reorders operations and contracts multiply-adds; three steps amplify the round-off).
    With ``lookahead`` the gyro row of the conditioning measurement is the next step's gyro
    sample (Theorem 1 with the yaw row of g as that row of d); the generic functions take
    the full 3 × 3 d, so the same composition checks the kernel's 3 × 3 inverse.

    Steps: inactive (statistics frozen, bias filter frozen), then two active steps with the
    bias filter and model-error noise on; N_thr = 0, so nothing is resampled.
    """
    rng0 = np.random.default_rng(42)
    n = 6
    params = SingleTrackParams.from_vehicle(SUV_FWD, (220e3, 215e3, 140e3, 135e3))
    p = params.pack()
    x = np.column_stack([22 + rng0.normal(0, 0.3, n), rng0.normal(0, 0.2, n), rng0.normal(0, 0.02, n)])
    mu = rng0.normal(0, 1, (n, 3)) * [30e3, 20e3, 20e3]
    lam = np.zeros((n, 6))
    lam[:, L00], lam[:, L11], lam[:, L22] = 16 * 30e3**2, 16 * 20e3**2, 16 * 20e3**2
    lam[:, L01] = 16 * 0.3 * 30e3 * 20e3
    b = rng0.normal(0, 0.05, (n, 3))
    pb = np.tile([0.05**2, 1e-4, 0.05**2, 0.002**2], (n, 1))
    logw = rng0.normal(0, 0.3, n) - math.log(n)
    gamma, nu = 0.1, 20.0
    y = np.array([[0.8, 2.1, 0.09], [0.7, 2.3, 0.1], [0.75, 2.2, 0.095]])
    u = np.array([[0.015, 68.0, 67.0, 0.005], [0.016, 68.1, 67.0, 0.005], [0.016, 68.1, 67.1, 0.005]])
    active = np.array([False, True, True])
    bias_on = np.array([False, True, True])
    r_pk = np.array([0.05**2, 0.0, 0.05**2, 0.003**2])
    q_pk = np.array([1e-6, 0.0, 1e-6, 1e-9])
    lo, hi = np.full(3, -1e9), np.full(3, 1e9)
    forget = 0.99
    model_error = np.array([0.2, 0.3, 0.1])
    state = seed_state(np.random.default_rng(7))
    stream = state.copy()
    blocks = []
    for _ in range(len(y) + 1):
        blk = np.empty((n, 7))
        fill_normals(stream, blk)
        blocks.append(blk)
    ref = _reference_alg1(y, u, active, bias_on, p, r_pk, q_pk, forget, model_error, x, mu,
                          [_unpack(v) for v in lam], b, pb, logw, gamma, nu, blocks, lookahead)
    k = len(y)
    out = {name: np.empty(shape) for name, shape in (("xh", (k, 3)), ("xv", (k, 3)), ("wh", (k, 3)),
                                                     ("wc", (k, 3, 3)), ("bh", (k, 3)), ("ess", (k,)))}
    part = pack_particles(x, mu, lam, b, pb)
    shared = np.array([gamma, nu])
    logwk = logw.copy()
    prm = PFParams(p=p, r_pk=r_pk, q_pk=q_pk, bias_inflation=1.0, lo=lo, hi=hi, forgetting=forget,
                   forgetting_period=0.005, n_thr=0.0, model_error=model_error,
                   gyro_lookahead=lookahead)
    alg1_kernel(prm, PFState(part=part, logw=logwk, shared=shared, rng_state=state),
                SeriesInputs(y=y, u=u, active=active, bias_on=bias_on),
                Estimates(out["xh"], out["xv"], out["wh"], out["wc"], out["bh"], out["ess"]))
    x_r, mu_r, lam_r, b_r, pb_r, logw_r, gamma_r, nu_r, est = ref
    np.testing.assert_allclose(part[:, C_X:C_X + 3], x_r, rtol=1e-8)
    np.testing.assert_allclose(part[:, C_MU:C_MU + 3], mu_r, rtol=1e-8)
    np.testing.assert_allclose(np.array([_unpack(v) for v in part[:, C_LAM:C_LAM + 6]]),
                               np.array(lam_r), rtol=1e-8)
    np.testing.assert_allclose(part[:, C_B:C_B + 3], b_r, rtol=1e-8, atol=1e-12)
    np.testing.assert_allclose(part[:, C_PB:C_PB + 4],
                               [[v[0, 0], v[0, 1], v[1, 1], v[2, 2]] for v in pb_r], rtol=1e-8)
    np.testing.assert_allclose(logwk, logw_r, rtol=1e-8, atol=1e-10)
    np.testing.assert_allclose(shared, [gamma_r, nu_r], rtol=1e-12)
    for name in out:
        np.testing.assert_allclose(out[name], est[name], rtol=1e-8, atol=1e-12, err_msg=name)
    np.testing.assert_array_equal(stream, state)   # the kernel drew exactly K + 1 blocks


def test_resampling_copies_whole_particles():
    """Line 9 of Algorithm 1: with N_thr = N every step resamples, and each particle is a copy
    of a particle of the run without resampling (same normals: the resampling uniform is
    drawn after the step's block), statistics and bias filter included, with systematic
    resampling's ancestor counts ⌊N q_i⌋ or ⌈N q_i⌉. Deterministic finish (no model error)
    so that the rows can be compared exactly; one step = one buffer swap, so this also
    checks that the caller's array receives the result."""
    rng0 = np.random.default_rng(3)
    n = 40
    params = SingleTrackParams.from_vehicle(SUV_FWD, (220e3, 215e3, 140e3, 135e3))
    x = np.column_stack([22 + rng0.normal(0, 0.3, n), rng0.normal(0, 0.3, n), rng0.normal(0, 0.02, n)])
    mu = rng0.normal(0, 1, (n, 3)) * [30e3, 20e3, 20e3]
    lam = np.zeros((n, 6))
    lam[:, L00], lam[:, L11], lam[:, L22] = 16 * 30e3**2, 16 * 20e3**2, 16 * 20e3**2
    pb = np.tile([0.05**2, 0.0, 0.05**2, 0.002**2], (n, 1))
    inp = SeriesInputs(y=np.array([[0.8, 2.1, 0.09]]), u=np.array([[0.015, 68.0, 67.0, 0.005]]),
                       active=np.array([True]), bias_on=np.array([True]))
    results = []
    for n_thr in (0.0, float(n)):
        part = pack_particles(x, mu, lam, np.zeros((n, 3)), pb)
        logw = np.full(n, -math.log(n))
        outs = Estimates(np.empty((1, 3)), np.empty((1, 3)), np.empty((1, 3)), np.empty((1, 3, 3)),
                         np.empty((1, 3)), np.empty(1))
        prm = PFParams(p=params.pack(), r_pk=np.array([0.05**2, 0.0, 0.05**2, 0.003**2]),
                       q_pk=np.zeros(4), bias_inflation=1.0, lo=np.full(3, -1e9), hi=np.full(3, 1e9),
                       forgetting=0.99, forgetting_period=0.005, n_thr=n_thr, model_error=np.zeros(3),
                       gyro_lookahead=False)
        n_res = alg1_kernel(prm, PFState(part=part, logw=logw, shared=np.array([0.1, 20.0]),
                                         rng_state=seed_state(np.random.default_rng(11))), inp, outs)
        results.append((part, logw, n_res, outs))
    (plain, logw_plain, n0, _), (resampled, logw_res, n1, _) = results
    assert (n0, n1) == (0, 1)
    np.testing.assert_allclose(logw_res, -math.log(n))
    ancestors = [int(np.flatnonzero((plain == row).all(axis=1))[0]) for row in resampled]
    counts = np.bincount(ancestors, minlength=n)
    q = np.exp(logw_plain)
    assert np.all((counts == np.floor(n * q)) | (counts == np.ceil(n * q)))


def test_forgetting_per_period():
    """Eq. (20) with λ per ``forgetting_period``: a step of T_s forgets by λ^(T_s/period), so two
    steps of 5 ms at period 10 ms forget like one step at 002's per-step λ."""
    n = 4
    params = SingleTrackParams.from_vehicle(SUV_FWD, (220e3, 215e3, 140e3, 135e3))
    x = np.tile([22.0, 0.1, 0.02], (n, 1))
    lam = np.zeros((n, 6))
    lam[:, L00], lam[:, L11], lam[:, L22] = 16 * 30e3**2, 16 * 20e3**2, 16 * 20e3**2
    k = 2
    y = np.tile([0.8, 2.1, 0.02], (k, 1))
    u = np.tile([0.015, 68.0, 67.0, 0.005], (k, 1))
    shared = np.array([0.1, 20.0])
    prm = PFParams(p=params.pack(), r_pk=np.array([2.5e-3, 0, 2.5e-3, 9e-6]), q_pk=np.zeros(4),
                   bias_inflation=1.0, lo=np.full(3, -1e9), hi=np.full(3, 1e9), forgetting=0.99,
                   forgetting_period=0.010, n_thr=0.0, model_error=np.zeros(3), gyro_lookahead=False)
    st = PFState(part=pack_particles(x, np.zeros((n, 3)), lam, np.zeros((n, 3)), np.zeros((n, 4))),
                 logw=np.full(n, -math.log(n)), shared=shared,
                 rng_state=seed_state(np.random.default_rng(0)))
    alg1_kernel(prm, st, SeriesInputs(y=y, u=u, active=np.ones(k, bool), bias_on=np.zeros(k, bool)),
                new_estimates(k))
    lam_step = math.sqrt(0.99)
    nu = 20.0
    gamma = 0.1
    for _ in range(k):
        gamma, nu = gamma / (1 + gamma) / lam_step, lam_step * (nu + 1)
    np.testing.assert_allclose(shared, [gamma, nu], rtol=1e-12)


def test_bias_update_is_a_kalman_update():
    """Eq. (30): b ← b + P S⁻¹ e, P ← P − P S⁻¹ P with S = P + R + dΣ̂dᵀ + H P_x Hᵀ (numpy, 1e-12)."""
    b = np.array([0.01, -0.02, 0.001])
    pb = np.array([0.003, 0.0004, 0.002, 4e-6])
    r = np.array([0.0025, 0.0, 0.0025, 9e-6])
    x_unc = np.array([0.01, 0.002, 0.03, 1e-6])
    e = np.array([0.1, -0.05, 0.002])
    extra = (0.02, 0.004, 0.05)
    p_full = np.array([[pb[0], pb[1], 0], [pb[1], pb[2], 0], [0, 0, pb[3]]])
    s_full = p_full + np.diag([r[0], r[2], r[3]]) + np.array(
        [[extra[0] + x_unc[0], extra[1] + x_unc[1], 0], [extra[1] + x_unc[1], extra[2] + x_unc[2], 0],
         [0, 0, x_unc[3]]])
    gain = p_full @ np.linalg.inv(s_full)
    b_ref = b + gain @ e
    p_ref = p_full - gain @ s_full @ gain.T
    bias_update(b, pb, *e, *extra, r, x_unc)
    np.testing.assert_allclose(b, b_ref, rtol=1e-12)
    np.testing.assert_allclose(pb, [p_ref[0, 0], p_ref[0, 1], p_ref[1, 1], p_ref[2, 2]], rtol=1e-12)


def _short(log: pd.DataFrame, seconds: float) -> pd.DataFrame:
    return log[log["t"] <= seconds].reset_index(drop=True)


def _measured(log: pd.DataFrame) -> pd.DataFrame:
    return log[[c for c in log.columns if not c.startswith("ref_")]]


def test_seeded_determinism_and_inputs_not_mutated(study_log):
    """Same seed → bit-identical output; another seed differs; the log is not modified."""
    log = _short(_measured(study_log), 5.0)
    before = log.copy()
    a = estimate_stiffness(log, SUV_FWD, particles=50, seed=1)
    b = estimate_stiffness(log, SUV_FWD, particles=50, seed=1)
    c = estimate_stiffness(log, SUV_FWD, particles=50, seed=2)
    pd.testing.assert_frame_equal(a, b)
    assert not np.allclose(a["stiffness_cy_f"], c["stiffness_cy_f"])
    pd.testing.assert_frame_equal(log, before)


def test_no_ref_column_is_read(study_log):
    """Dropping every ref_ column, or poisoning them with NaN, leaves the estimate unchanged."""
    log = _short(study_log, 4.0)
    poisoned = log.copy()
    for c in poisoned.columns:
        if c.startswith("ref_"):
            poisoned[c] = np.nan
    base = estimate_stiffness(_measured(log), SUV_FWD, particles=40, seed=0)
    for variant in (log, poisoned):
        pd.testing.assert_frame_equal(estimate_stiffness(variant, SUV_FWD, particles=40, seed=0), base)


def test_output_columns_and_units(study_log):
    """Columns of the spec (stiffness axle totals, states, biases, sigmas), all finite."""
    out = estimate_stiffness(_short(_measured(study_log), 3.0), SUV_FWD, particles=30, seed=0)
    expected = ["t", "stiffness_cx_f", "sigma_stiffness_cx_f", "stiffness_cy_f", "sigma_stiffness_cy_f",
                "stiffness_cy_r", "sigma_stiffness_cy_r", "vx", "sigma_vx", "vy", "sigma_vy",
                "yaw_rate", "sigma_yaw_rate", "bias_ax", "bias_ay", "bias_yaw_rate",
                "stiffness_active"]
    assert list(out.columns) == expected
    assert np.all(np.isfinite(out.to_numpy()))
    assert out["stiffness_active"].iloc[0] == 0.0  # settling period (config.settle_time)
    rwd = estimate_stiffness(_short(_measured(study_log), 2.0), SUV_FWD.with_drivetrain("rwd"),
                             particles=20, seed=0)
    assert "stiffness_cx_r" in rwd.columns and "stiffness_cx_f" not in rwd.columns


@pytest.mark.parametrize("column", ["ay", "omega_rl", "yaw_rate", "t"])
def test_missing_column_is_named(study_log, column):
    log = _short(_measured(study_log), 1.0).drop(columns=[column])
    with pytest.raises(LogFormatError, match=f"'{column}'"):
        estimate_stiffness(log, SUV_FWD, particles=10)


def test_missing_steering_and_bad_rows_are_errors(study_log):
    log = _short(_measured(study_log), 1.0)
    with pytest.raises(LogFormatError, match="steering"):
        estimate_stiffness(log.drop(columns=["delta_fl", "delta_fr", "steering_wheel_angle"]),
                           SUV_FWD, particles=10)
    bad = log.copy()
    bad.loc[5, "ax"] = np.nan
    with pytest.raises(LogFormatError, match=r"'ax'.*row 5"):
        estimate_stiffness(bad, SUV_FWD, particles=10)
    with pytest.raises(ValueError, match="method"):
        estimate_stiffness(log, SUV_FWD, method="ukf")
    with pytest.raises(ValueError, match="particles"):
        estimate_stiffness(log, SUV_FWD, particles=1)
    with pytest.raises(ValueError, match="forgetting"):
        StiffnessConfig(forgetting=1.5)
    with pytest.raises(TypeError):
        StiffnessConfig(lambda_=0.9)  # type: ignore[call-arg]


def test_prior_from_vehicle_table_or_generic():
    """[stiffness] table → nominal (±30 %); without it the generic load-based prior (documented)."""
    suv = load_vehicle("hashemi_suv")
    generic = StiffnessPrior.for_vehicle(suv)
    fz_f = suv.body.mass * 9.81 * suv.body.lr / suv.body.wheelbase
    assert generic.nominal[2] == pytest.approx(10.0 * fz_f)
    assert generic.lower[2] == pytest.approx(2.0 * fz_f) and generic.upper[2] == pytest.approx(40.0 * fz_f)
    with_table = replace(suv, stiffness=Stiffness(cx_f=2e5, cx_r=1.9e5, cy_f=1.4e5, cy_r=1.3e5))
    prior = StiffnessPrior.for_vehicle(with_table)
    assert prior.nominal == (2e5, 1.9e5, 1.4e5, 1.3e5)
    assert prior.sigma[2] == pytest.approx(0.3 * 1.4e5)
    with pytest.raises(ValueError, match="lower < nominal < upper"):
        StiffnessPrior(nominal=(1, 1, 1, 1), sigma=(1, 1, 1, 1), lower=(2, .5, .5, .5),
                       upper=(3, 2, 2, 2))


def test_baselines_run_and_are_finite(study_log):
    """AUGPF, RLS + KF and EKF on 5 s: finite estimates within the projection bounds."""
    log = _short(_measured(study_log), 5.0)
    prior = StiffnessPrior.for_vehicle(SUV_FWD)
    for method in ("augpf", "rls", "ekf"):
        out = estimate_stiffness(log, SUV_FWD, particles=50, seed=0, method=method)
        assert np.all(np.isfinite(out.to_numpy())), method
        for j, c in ((0, "cx_f"), (2, "cy_f"), (3, "cy_r")):
            assert out[f"stiffness_{c}"].between(prior.lower[j] - 1e-6, prior.upper[j] + 1e-6).all()
    inputs = prepare_inputs(log, SUV_FWD, StiffnessConfig())
    r1 = RlsKalman(SUV_FWD).run(inputs)
    r2 = AugmentedEKF(SUV_FWD).run(inputs)
    r3 = AugmentedPF(SUV_FWD, particles=20).run(inputs, np.random.default_rng(0))
    assert r1.method == "rls" and r2.method == "ekf" and r3.n_resampled > 0
    with pytest.raises(ValueError, match="vx"):
        RlsKalman(SUV_FWD).run(inputs, vx=np.zeros(3))


def test_end_to_end_on_the_stiffness_study(study_log):
    """Generic prior (the SUV file has no [stiffness] table), 100 particles, default settings.

    The prior starts C^y 21 % below the plant's axle stiffness; the plant stiffness falls
    50 % at 30 s. Checked: time-mean error over [20, 30) s and [40, 60] s within 15 % of
    ``ref_stiffness_*`` for every component, and v_y RMSE below 0.25 m/s. Justification: the
    single-track model misses the Magic-Formula plant by −2 % (lateral) to −8 %
    (longitudinal) even with exact states (docs/results_stiffness.md, model mismatch), and
    with 100 particles the largest of these time-mean errors is 8–12 % over filter seeds
    0–7 (this seed: 8 %) and the v_y RMSE 0.02–0.16 m/s (this seed: 0.16); the bounds hold
    the worst of them with margin, while a filter that did not converge from the prior or
    did not follow the drop misses by 20–100 % and one that lost the lateral state has a
    v_y RMSE above 0.5 m/s.
    """
    log = study_log
    out = estimate_stiffness(_measured(log), SUV_FWD, particles=100, seed=3)
    t = log["t"].to_numpy()
    for c in ("cx_f", "cy_f", "cy_r"):
        err = (out[f"stiffness_{c}"] - log[f"ref_stiffness_{c}"]) / log[f"ref_stiffness_{c}"]
        for window in ((t >= 20) & (t < 30), t >= 40):
            assert abs(err[window].mean()) < 0.15, c
    assert np.sqrt(np.mean((out["vy"] - log["ref_vy"]) ** 2)) < 0.25
    ratio = out["stiffness_cy_f"][t >= 40].mean() / out["stiffness_cy_f"][(t >= 20) & (t < 30)].mean()
    assert 0.4 < ratio < 0.6  # the 50 % drop is tracked


def test_meets_the_targets_on_002_single_track_data(single_track_data):
    """002 Sec. VI-A's own setting (the estimation model generates the data; fixture): 200
    particles, prior 70 % of the truth with 30 % sigma, eq. (9) without model error and the
    bias known to be zero (002 sets it to zero in this study).

    Checked over the steady state t ∈ [10, 30) ∪ [33, 60] s (3 s after the 50 % drop): the
    time-mean |error| of every component is below the issue's 2 % (filter seeds 0–7 give
    0.4–1.4 %; this seed 0.4–0.7 %), no sample is off by more than 10 % (seeds 0–7: at most
    6 %, the first seconds after the drop, while the slip is small), and v_y is not lost
    (RMSE below 0.25 m/s; seeds 0–7: 0.02–0.14 m/s). The error is against the level the
    per-step stiffness scatters around (5 % per step).
    """
    log, level, c0 = single_track_data
    config = StiffnessConfig(wheel_speed_cutoff=0.0, model_error=(0.0, 0.0, 0.0), accel_bias_sd=0.0,
                             gyro_bias_sd=0.0, accel_bias_walk=0.0, gyro_bias_walk=0.0)
    prior = StiffnessPrior(nominal=tuple(0.7 * c0), sigma=tuple(0.3 * c0), lower=tuple(0.05 * c0),
                           upper=tuple(2.5 * c0))
    out = estimate_stiffness(log.drop(columns=["ref_vy"]), SUV_FWD, particles=200, seed=0,
                             prior=prior, config=config)
    t = log["t"].to_numpy()
    steady = ((t >= 10) & (t < 30)) | (t >= 33)
    for j, c in ((0, "cx_f"), (2, "cy_f"), (3, "cy_r")):
        err = np.abs(out[f"stiffness_{c}"].to_numpy() - level[:, j]) / level[:, j]
        assert err[steady].mean() < 0.02, c
        assert err[steady].max() < 0.10, c
    assert np.sqrt(np.mean((out["vy"] - log["ref_vy"]) ** 2)) < 0.25
