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
from vestim.estimators.stiffness.model import SingleTrackParams, model_terms
from vestim.estimators.stiffness.pf import (
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
    alg1_kernel,
    bias_update,
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


def test_kernel_step_equals_the_generic_functions():
    """One step of the fused kernel equals eq. (35), (36), (40)–(41), (19), (20), (9) composed from
    :mod:`vestim.filters.niw` with the same random numbers (1e-10 relative: operation order).

    Bias filter frozen (settled = False), no model error and N_thr = 0 so that only the
    w draws consume random numbers: per particle three normals and one Wilson–Hilferty normal.
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
    logw = np.full(n, -math.log(n))
    gamma, nu = 0.1, 20.0
    y = np.array([[0.8, 2.1, 0.09]])
    u = np.array([[0.015, 68.0, 67.0, 0.005]])
    r_pk = np.array([0.05**2, 0.0, 0.05**2, 0.003**2])
    lo = np.full(3, -1e9)
    hi = np.full(3, 1e9)
    forget = 0.99
    # --- reference, generic functions, same generator stream
    rng = np.random.default_rng(7)
    ref_x, ref_mu, ref_lam, ref_w, ref_logw = x.copy(), mu.copy(), [], np.empty((n, 3)), logw.copy()
    dof = nu - 2.0
    for i in range(n):
        f, g, h, d = np.empty(3), np.empty((3, 3)), np.empty(3), np.empty((3, 3))
        model_terms(x[i], u[0], p, f, g, h, d)
        lam_i = _unpack(lam[i])
        noise = np.diag(r_pk[[PXX, PYY, PRR]]) + np.array(
            [[pb[i, PXX], pb[i, PXY], 0], [pb[i, PXY], pb[i, PYY], 0], [0, 0, pb[i, PRR]]])
        lam_e = np.empty((3, 3))
        moment_matched_scale(d, lam_i, gamma, dof, noise, lam_e)
        low_e = np.empty((3, 3))
        cholesky(lam_e, low_e)
        z = y[0] - h - b[i] - d @ mu[i]
        mu_c, scale_c = np.empty(3), np.empty((3, 3))
        dof_c, maha = t_condition(mu[i], (1 + gamma) / dof * lam_i, d, low_e, z, dof, mu_c, scale_c,
                                  np.empty((3, 3)), np.empty(3))
        ref_logw[i] += mvt_log_kernel(maha, chol_logdet(low_e), dof, 3)
        low_c = np.empty((3, 3))
        cholesky(scale_c, low_c)
        normals = np.array([rng.standard_normal() for _ in range(3)])
        a = 2.0 / (9.0 * dof_c)
        chi2 = dof_c * max(1.0 - a + math.sqrt(a) * rng.standard_normal(), 1e-3) ** 3
        w = np.empty(3)
        mvt_draw(mu_c, low_c, dof_c, normals, chi2, w)
        ref_w[i] = w
        m_i = mu[i].copy()
        niw_update(gamma, nu, m_i, lam_i, w)
        niw_predict(gamma, nu, lam_i, forget)
        ref_mu[i] = m_i
        ref_lam.append(lam_i)
        ref_x[i] = f + g @ w
    ref_logw -= np.log(np.exp(ref_logw).sum())
    # --- kernel
    out = {k: np.empty(s) for k, s in (("xh", (1, 3)), ("xv", (1, 3)), ("wh", (1, 3)),
                                        ("wc", (1, 3, 3)), ("bh", (1, 3)), ("ess", (1,)))}
    shared = np.array([gamma, nu])
    xk, muk, lamk, bk, pbk, wk, logwk = x.copy(), mu.copy(), lam.copy(), b.copy(), pb.copy(), \
        np.empty((n, 3)), logw.copy()
    alg1_kernel(y, u, np.array([True]), np.array([False]), p, r_pk, np.zeros(4), lo, hi, forget, 0.0,
                np.zeros(3), xk, muk, lamk, bk, pbk, wk, logwk, shared, np.random.default_rng(7),
                out["xh"], out["xv"], out["wh"], out["wc"], out["bh"], out["ess"])
    np.testing.assert_allclose(wk, ref_w, rtol=1e-10)
    np.testing.assert_allclose(muk, ref_mu, rtol=1e-10)
    np.testing.assert_allclose(np.array([_unpack(r) for r in lamk]), np.array(ref_lam), rtol=1e-10)
    np.testing.assert_allclose(xk, ref_x, rtol=1e-12)
    np.testing.assert_allclose(logwk, ref_logw, rtol=1e-10, atol=1e-12)
    np.testing.assert_array_equal(bk, b)  # frozen
    assert shared[1] == pytest.approx(forget * (nu + 1))
    q = np.exp(logwk)
    assert q.sum() == pytest.approx(1.0)
    assert out["ess"][0] == pytest.approx(1.0 / (q**2).sum())
    np.testing.assert_allclose(out["wh"][0], q @ muk, rtol=1e-12)


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
    assert generic.lower[2] == pytest.approx(2.0 * fz_f) and generic.upper[2] == pytest.approx(25.0 * fz_f)
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
    ``ref_stiffness_*`` for every component. Justification of 15 %: the single-track model
    misses the Magic-Formula plant by −2 % (lateral) to −8 % (longitudinal) even with exact
    states (docs/results_stiffness.md, model mismatch), and with 100 particles these time
    means spread over −12 … +7 % across seeds 0–7 (this seed: within 7 %); 15 % bounds the
    worst of them with margin, while a filter that did not converge from the prior or did
    not follow the drop misses by 20–100 %.
    """
    log = study_log
    out = estimate_stiffness(_measured(log), SUV_FWD, particles=100, seed=3)
    t = log["t"].to_numpy()
    for c in ("cx_f", "cy_f", "cy_r"):
        err = (out[f"stiffness_{c}"] - log[f"ref_stiffness_{c}"]) / log[f"ref_stiffness_{c}"]
        for window in ((t >= 20) & (t < 30), t >= 40):
            assert abs(err[window].mean()) < 0.15, c
    assert np.sqrt(np.mean((out["vy"] - log["ref_vy"]) ** 2)) < 0.15
    ratio = out["stiffness_cy_f"][t >= 40].mean() / out["stiffness_cy_f"][(t >= 20) & (t < 30)].mean()
    assert 0.4 < ratio < 0.6  # the 50 % drop is tracked
