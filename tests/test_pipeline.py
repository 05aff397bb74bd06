"""The corner-based pipeline: composition, batch == online, no ground truth read, config."""

from pathlib import Path

import numpy as np
import pandas as pd
import pytest
from typer.testing import CliRunner

from vestim.cli import app
from vestim.io import load_vehicle, read_log, write_log
from vestim.models.kinematics import slip_ratio
from vestim.pipeline import Pipeline, PipelineConfig, PipelineConfigError, estimate
from vestim.sim import get_maneuver, simulate

SUV = load_vehicle("hashemi_suv")


@pytest.fixture(scope="module")
def log():
    return simulate(get_maneuver("bit_slippery"), SUV, seed=4)


def strip(log: pd.DataFrame) -> pd.DataFrame:
    return log.drop(columns=[c for c in log.columns if c.startswith("ref_")])


@pytest.mark.parametrize(("velocity", "fusion"), [("kf", "adaptive"), ("lpv", "opinion")])
def test_step_equals_run(log, velocity, fusion):
    """Feeding the log sample by sample gives the batch result exactly, with two non-default
    stages together (tests/test_conformance.py runs each registered method alone)."""
    part = strip(log).iloc[:200]
    batch = Pipeline(SUV, PipelineConfig(velocity=velocity, fusion=fusion)).run(part)
    online = Pipeline(SUV, PipelineConfig(velocity=velocity, fusion=fusion))
    rows = pd.DataFrame([online.step(r) for r in part.to_dict("records")])[batch.columns]
    np.testing.assert_allclose(rows.to_numpy(), batch.to_numpy(), rtol=1e-12, atol=1e-9)


def test_reference_filter_beats_mean_wheel_speed_on_abs_braking(log):
    """Brake-in-turn on μ = 0.25 with ABS: every wheel slips; the filter's CG v_x error must stay
    below the naive R·ω̄ (measured 3.9 % vs 4.7 % NRMS at seed 1)."""
    out = Pipeline(SUV).run(log)
    ref = log["ref_vx"].to_numpy()
    naive = SUV.body.wheel_radius * log[[f"omega_{c}" for c in ("fl", "fr", "rl", "rr")]].mean(axis=1)
    err = np.sqrt(np.mean((out["vx"] - ref) ** 2))
    err_naive = np.sqrt(np.mean((naive - ref) ** 2))
    assert err < err_naive


def test_reference_filter_survives_an_ice_launch_that_defeats_wheel_speeds():
    """Full-throttle AWD launch on ice, no TC: R·ω̄ is off by ~900 %; the reference filter
    rejects the slipping wheels and integrates: CG v_x NRMS ≤ 3 % (measured 2.5 %)."""
    log = simulate(get_maneuver("launch_ice"), SUV, seed=1)
    out = Pipeline(SUV).run(log)
    ref = log["ref_vx"].to_numpy()
    assert np.sqrt(np.mean((out["vx"] - ref) ** 2)) / np.abs(ref).max() <= 0.03


def _nrms(est: pd.Series, ref: pd.Series, floor: float = 0.0) -> float:
    return float(np.sqrt(np.mean((est - ref) ** 2)) / max(np.abs(ref).max(), floor))


def test_default_tracks_a_spinning_rwd_car():
    """RWD acceleration in a turn on dry asphalt: the car spins (v_y to −10 m/s, r ≈ 1 rad/s),
    so r·v_y dominates v̇_x and a poor v_y corrupts v_x (9.6 % before the lateral bounds and
    the correlated-error inflation). With them: CG v_x NRMS ≤ 1 % (measured 0.60 %) and
    v_y ≤ 5 % of max(|v_y|, 1 m/s) (measured 1.35 %)."""
    run = simulate(get_maneuver("ait_dry", drivetrain="rwd"), SUV, seed=1)
    out = Pipeline(SUV).run(strip(run))
    assert _nrms(out["vx"], run["ref_vx"]) <= 0.01
    assert _nrms(out["vy"], run["ref_vy"], 1.0) <= 0.05


def test_lateral_velocity_in_a_wet_lane_change():
    """Lane change on wet road: the rear tires pass their linear range (true slip angle 0.07
    rad against a linear-tire 0.033), so the linear v_y pseudo-measurement is a bound, not a
    value; as a bound, with the integral carrying v_y: ≤ 5 % (measured 1.9 %; 19.7 % when the
    linear-tire value was used as a measurement)."""
    run = simulate(get_maneuver("lc_wet"), SUV, seed=1)
    out = Pipeline(SUV).run(strip(run))
    assert _nrms(out["vy"], run["ref_vy"], 1.0) <= 0.05


def test_corner_outputs_are_consistent_with_cg(log):
    """v_x,i = v_x − r y_i (rigid body), and slip ratios follow the spec's definition."""
    out = Pipeline(SUV).run(log)
    r = log["yaw_rate"].to_numpy()
    assert np.allclose(out["vx_fl"], out["vx"] - r * SUV.body.track_f / 2)
    sr = slip_ratio(log[["omega_rl"]].to_numpy(), out[["vxt_rl"]].to_numpy(), SUV.body.wheel_radius)
    assert np.allclose(out["slip_ratio_rl"], sr[:, 0])


def test_config_from_toml_and_errors(tmp_path):
    f = tmp_path / "p.toml"
    f.write_text('[pipeline]\nforce = "pid"\nvelocity = "kinematic"\n')
    cfg = PipelineConfig.from_toml(f)
    assert cfg.force == "pid" and cfg.velocity == "kinematic"
    f.write_text('[pipeline]\nspeed = "fast"\n')
    with pytest.raises(PipelineConfigError, match="speed"):
        PipelineConfig.from_toml(f)
    with pytest.raises(PipelineConfigError, match="velocity method 'warp'"):
        PipelineConfig(velocity="warp")


def test_cli_estimate_writes_the_spec_channels(tmp_path, log):
    src = tmp_path / "in.parquet"
    write_log(log, src)
    out = tmp_path / "est.csv"
    res = CliRunner().invoke(app, ["estimate", "--vehicle", "hashemi_suv", str(src), "--out", str(out)])
    assert res.exit_code == 0, res.output
    est = read_log(out)
    for col in ("vx", "vy", "vx_fl", "fx_rr", "fz_fl", "slip_ratio_fl", "slip_angle_rr"):
        assert col in est.columns
    bad = CliRunner().invoke(app, ["estimate", "--vehicle", "hashemi_suv",
                                   str(src), "--out", str(out), "--force", "magic"])
    assert bad.exit_code == 2 and "force method 'magic'" in bad.output


def test_cli_estimate_names_a_missing_column(tmp_path, log):
    src = tmp_path / "in.csv"
    write_log(log.drop(columns=["omega_fr"]), src)
    res = CliRunner().invoke(app, ["estimate", "--vehicle", "hashemi_suv",
                                   str(src), "--out", str(tmp_path / "o.csv")])
    assert res.exit_code == 2 and "omega_fr" in res.output and "Traceback" not in res.output


def test_cli_estimate_without_torques_says_so(tmp_path, log):
    """A CAN-style log without wheel torques is estimated; the metadata and console say how."""
    src = tmp_path / "in.parquet"
    write_log(strip(log).drop(columns=[f"torque_{c}" for c in ("fl", "fr", "rl", "rr")]), src)
    out = tmp_path / "est.parquet"
    res = CliRunner().invoke(app, ["estimate", "--vehicle", "hashemi_suv", str(src), "--out", str(out)])
    assert res.exit_code == 0, res.output
    assert "chassis equation" in res.output
    est = read_log(out)
    assert est.attrs["torque_source"] == "chassis" and est.attrs["roll_source"] == "rate"
    assert np.isfinite(est["vx"]).all()


def test_opinion_fusion_writes_confidences_and_downweights_a_spinning_corner():
    """RWD launch on split μ: the rear-left wheel spins on ice (slip ratio ≈ 0.9 against
    the vehicle speed) while the others roll. 003 eq. (6) gives it W = 25(1 − 0.9) ≈ 2.5
    (bounded by ±20 %), the rolling corners the cap 25 of γ = 29 (eq. (13)), so the spinning
    corner's mean confidence during the launch is under a fifth of the others'."""
    run = simulate(get_maneuver("launch_split_mu", tire="lugre", drivetrain="rwd"), SUV, seed=1)
    est = Pipeline(SUV, PipelineConfig(velocity="kf", fusion="opinion")).run(strip(run))
    launch = (run["t"] > 1.5) & (run["t"] < 5.5)
    conf = est.loc[launch, [f"confidence_{c}" for c in ("fl", "fr", "rl", "rr")]].mean()
    spinning = conf.idxmin()
    assert run.loc[launch, f"ref_slip_ratio_{spinning[-2:]}"].mean() > 0.5
    assert conf[spinning] < 0.2 * conf.drop(spinning).min()
    assert conf.drop(spinning).min() == pytest.approx(25.0, abs=1.0)


def test_unknown_fusion_is_named():
    with pytest.raises(PipelineConfigError, match="fusion method 'mean'"):
        PipelineConfig(fusion="mean")


@pytest.mark.parametrize("velocity", ["fused", "kf"])
def test_chunked_run_equals_one_chunk(log, velocity):
    """run() processes the log in chunks; the chunk size must not change the result."""
    part = strip(log).iloc[:1000]
    cfg = PipelineConfig(velocity=velocity, fusion="opinion")
    whole = Pipeline(SUV, cfg).run(part, chunk=10_000)
    chunked = Pipeline(SUV, cfg).run(part, chunk=37)
    pd.testing.assert_frame_equal(whole, chunked, rtol=1e-12, atol=1e-9)


def test_corner_kf_integrates_bias_corrected_acceleration():
    """AWD ice launch whose accelerometer reads +0.10 m/s² of bias (seed 3): every wheel
    spins for 9 s, so the corner KF's high-slip mode integrates the acceleration. Given the
    reference filter's bias estimate (learnt at standstill) it stays within 3 % CG v_x NRMS
    (measured 1.4 %); integrating the raw acceleration it drifted to 10.3 %."""
    run = simulate(get_maneuver("launch_ice", tire="magic"), SUV, seed=3)
    out = Pipeline(SUV, PipelineConfig(velocity="kf")).run(strip(run))
    assert run.loc[run["t"] < 1.0, "ax"].mean() == pytest.approx(0.10, abs=0.01)
    assert _nrms(out["vx"], run["ref_vx"]) <= 0.03


@pytest.mark.parametrize("velocity", ["fused", "reference"])
def test_online_step_is_compiled_and_exact(velocity):
    """The default configurations step through one compiled call (vestim.pipeline.rows) and give
    the batch result bit for bit, also through the fused filter's switch to the corner
    measurement (AWD ice launch: every wheel spins)."""
    run = strip(simulate(get_maneuver("launch_ice", tire="magic"), SUV, seed=1)).iloc[:1600]
    batch = Pipeline(SUV, PipelineConfig(velocity=velocity)).run(run)
    online = Pipeline(SUV, PipelineConfig(velocity=velocity))
    rows = []
    for r in run.to_dict("records"):
        rows.append(online.step(r))
        assert online._rows is not None  # the compiled path was taken
    if velocity == "fused":
        assert not online._fused_is_reference  # the corner measurement did enter
    np.testing.assert_array_equal(pd.DataFrame(rows)[batch.columns].to_numpy(), batch.to_numpy())


_WHEELS = ("omega_fl", "omega_fr", "omega_rl", "omega_rr")
_TORQUES = ("torque_fl", "torque_fr", "torque_rl", "torque_rr")


@pytest.mark.parametrize("missing", [(), ("ax",), ("az",), ("roll_rate", "pitch_rate"), _TORQUES,
                                     _WHEELS + _TORQUES, (*_WHEELS, *_TORQUES, "ax")])
@pytest.mark.parametrize(("velocity", "force", "fusion"), [
    ("fused", "ukf", "axle"), ("reference", "ukf", "axle"), ("fused", "pid", "opinion"),
    ("reference", "naive", "axle"), ("kf", "ukf_rw", "adaptive"), ("ukf", "uio", "opinion"),
    ("lpv", "ukf", "axle"), ("kinematic", "ukf", "axle")])
def test_one_compiled_composition_for_run_and_step(velocity, force, fusion, missing):
    """pipeline.rows composes every stage in one compiled call over blocks of samples, run()
    over chunks and step() over one row: an AWD ice launch (the fused filter switches to the
    corner measurement) with a 10 Hz gnss_speed (the radius scale and latency), less the
    channels in ``missing`` (a_x from the wheel speeds, the level-road a_z, the quasi-static
    attitude, the chassis torques, no wheel speeds: the GNSS speed alone). The split into
    chunks and blocks changes no number: run() in chunks of 300 (not a multiple of the 1024
    block) and step() give the default run's numbers bit for bit. (Before the stage-by-stage
    path was deleted, this test held these 8 configurations × 7 sensor sets bit-identical to
    it.)"""
    if velocity not in ("fused", "reference") and "omega_fl" in missing:
        pytest.skip("the corner observers and the kinematic integrator need wheel speeds")
    run = strip(simulate(get_maneuver("launch_ice", tire="magic"), SUV, seed=1)).iloc[:1600]
    run = run.drop(columns=list(missing))
    fix = np.arange(len(run)) % 20 == 0
    raw = simulate(get_maneuver("launch_ice", tire="magic"), SUV, seed=1)["ref_vx"]
    run["gnss_speed"] = np.where(fix, 1.01 * raw.to_numpy()[:1600], np.nan)
    cfg = PipelineConfig(velocity=velocity, force=force, fusion=fusion)
    batch = Pipeline(SUV, cfg).run(run)
    assert np.isfinite(batch["vx"]).all()
    chunked = Pipeline(SUV, cfg).run(run, chunk=300)
    np.testing.assert_array_equal(chunked.to_numpy(), batch.to_numpy())
    online = Pipeline(SUV, cfg)
    rows = pd.DataFrame([online.step(r) for r in run.to_dict("records")])
    assert list(rows.columns) == list(batch.columns)
    np.testing.assert_array_equal(rows.to_numpy(), batch.to_numpy())


def test_cli_estimate_fusion_flag(tmp_path, log):
    """`--fusion opinion` with a corner observer writes the confidences; an unknown fusion is
    named in the error."""
    src = tmp_path / "in.parquet"
    write_log(strip(log).iloc[:600], src)
    out = tmp_path / "est.parquet"
    res = CliRunner().invoke(app, ["estimate", "--vehicle", "hashemi_suv",
                                   str(src), "--out", str(out), "--velocity", "kf",
                                   "--fusion", "opinion"])
    assert res.exit_code == 0, res.output
    est = read_log(out)
    assert {f"confidence_{c}" for c in ("fl", "fr", "rl", "rr")} <= set(est.columns)
    assert est.attrs["fusion"] == "opinion"
    bad = CliRunner().invoke(app, ["estimate", "--vehicle", "hashemi_suv",
                                   str(src), "--out", str(out), "--fusion", "vote"])
    assert bad.exit_code == 2 and "fusion method 'vote'" in bad.output


def test_run_reports_progress_and_the_result_does_not_depend_on_it():
    """progress(fraction) after each chunk: increasing, ending at exactly 1; same output."""
    from vestim.io import load_vehicle
    from vestim.sim import get_maneuver, simulate

    veh = load_vehicle("hashemi_suv")
    log = simulate(get_maneuver("step_steer"), veh, seed=0).iloc[:1000]
    seen: list[float] = []
    a = Pipeline(veh).run(log, chunk=300, progress=seen.append)
    b = Pipeline(veh).run(log, chunk=300)
    assert seen == [0.3, 0.6, 0.9, 1.0]
    np.testing.assert_array_equal(a.to_numpy(), b.to_numpy())


def test_calibrated_file_undoes_the_sensor_errors_it_states():
    """A log with a 2 % large front-left radius, an accelerometer reading 2 % high and a
    0.01 rad steering offset, estimated with a file whose [calibration] states exactly those,
    gives the clean log's estimate (to float rounding); run and step agree on it."""
    from dataclasses import replace

    from vestim.io import load_vehicle
    from vestim.io.calibration import Calibration, Identified
    from vestim.sim import get_maneuver, simulate

    veh = load_vehicle("hashemi_suv")
    clean = simulate(get_maneuver("step_steer"), veh, seed=0).iloc[:600]
    clean = clean[[c for c in clean.columns if not c.startswith("ref_")]]
    bad = clean.copy()
    bad["omega_fl"] = bad["omega_fl"] / 1.02  # a larger wheel turns slower
    for c in ("ax", "ay", "az"):
        bad[c] = bad[c] * 1.02
    for c in ("delta_fl", "delta_fr", "delta"):
        if c in bad:
            bad[c] = bad[c] + 0.01
    r = veh.body.wheel_radius
    cal = Calibration({
        "wheels": {"radius_fl": Identified(1.02 * r, 1e-4, True, "test", "m")},
        "imu": {"accel_scale": Identified(1.02, 1e-3, True, "test", "-")},
        "steering": {"steering_offset": Identified(0.01, 1e-4, True, "test", "rad")}})
    calibrated = replace(veh, calibration=cal)
    want = Pipeline(veh).run(clean)
    got = Pipeline(calibrated).run(bad)
    np.testing.assert_allclose(got.to_numpy(), want.to_numpy(), rtol=1e-9, atol=1e-9)
    pipe = Pipeline(calibrated)
    rows = [pipe.step(s) for s in bad.to_dict("records")[:50]]
    for k in ("vx", "vy", "fx_fl", "fz_rr"):
        np.testing.assert_allclose([row[k] for row in rows], got[k].to_numpy()[:50],
                                   rtol=1e-12, atol=1e-12)


def test_a_nan_burst_through_step_is_held_not_propagated():
    """Issue 15: one NaN in ax used to make every later row NaN. A 3-sample NaN burst in ax
    (15 ms at 200 Hz) is held at the last finite value: every row stays finite, and 0.1 s
    after the burst v_x is within 1 mm/s of the clean run (a held ax differs by at most
    its change over 15 ms)."""
    from vestim.errors import LogFormatError
    from vestim.io import load_vehicle
    from vestim.sim import get_maneuver, simulate

    veh = load_vehicle("hashemi_suv")
    log = simulate(get_maneuver("step_steer"), veh, seed=0).iloc[:400]
    log = log[[c for c in log.columns if not c.startswith("ref_")]]
    clean = Pipeline(veh).run(log)
    bad = log.copy()
    bad.loc[200:202, "ax"] = np.nan
    pipe = Pipeline(veh)
    rows = [pipe.step(s) for s in bad.to_dict("records")]
    vx = np.array([r["vx"] for r in rows])
    assert np.all(np.isfinite(vx))
    assert abs(vx[222] - clean["vx"].to_numpy()[222]) < 1e-3
    with pytest.raises(LogFormatError, match=r"Pipeline\.run input: column 'ax' is missing"):
        Pipeline(veh).run(bad)
    long = log.copy()
    long.loc[100:300, "ax"] = np.nan  # 1 s: longer than HOLD_S
    pipe = Pipeline(veh)
    with pytest.raises(LogFormatError, match="channel 'ax' is nan and has had no finite value"):
        for s in long.to_dict("records"):
            pipe.step(s)


def test_a_time_gap_restarts_the_filters_instead_of_integrating_across_it():
    """Issue 15: a 2 s recording gap is a restart, not a prediction across it. v_x stays
    within 2 × the clean run's error + 0.1 m/s from 2 s after the gap (the issue's bound;
    measured 0.17 m/s, 0.23 without the restart), the gap is listed, the rows after it are
    "not converged", and step() does the same."""
    from vestim.estimators.validity import NOT_CONVERGED
    from vestim.io import load_vehicle
    from vestim.sim import get_maneuver, simulate

    veh = load_vehicle("hashemi_suv")
    full = simulate(get_maneuver("accel_brake"), veh, seed=0)
    t = full["t"].to_numpy()
    keep = (t < 4.0) | (t >= 6.0)  # 2 s missing from the middle of the acceleration
    gap = full[keep].reset_index(drop=True)
    meas = gap[[c for c in gap.columns if not c.startswith("ref_")]]
    clean = Pipeline(veh).run(full[[c for c in full.columns if not c.startswith("ref_")]])
    pipe = Pipeline(veh)
    est = pipe.run(meas)
    assert pipe.gaps == [(pytest.approx(t[t < 4.0][-1]), pytest.approx(6.0))]
    tg = est["t"].to_numpy()
    after = tg >= 8.0
    err = np.abs(est["vx"].to_numpy() - gap["ref_vx"].to_numpy())[after]
    clean_err = np.abs(clean["vx"].to_numpy() - full["ref_vx"].to_numpy())[t >= 8.0]
    assert err.max() <= 2 * clean_err.max() + 0.1
    reason = est["reason_velocity"].to_numpy().astype(int)
    assert np.all(reason[(tg >= 6.0) & (tg < 8.0)] & NOT_CONVERGED)
    stepper = Pipeline(veh)
    rows = [stepper.step(s) for s in meas.to_dict("records")]
    np.testing.assert_allclose([r["vx"] for r in rows], est["vx"].to_numpy(), rtol=1e-9, atol=1e-9)
    assert len(stepper.gaps) == 1


def test_the_library_announces_a_slow_first_compilation(monkeypatch, caplog):
    """vestim.estimate() (and step()'s first call) say that they compile, as the CLI does: a
    Numba compilation still running after 1 s is a warning on the "vestim" logger (stderr
    without a logging setup). Made deterministic: the injected compilation lasts until the
    warning was given; loading from the cache says nothing (the second run)."""
    import logging
    import threading

    from numba.core import event

    said = threading.Event()
    real_run = Pipeline.run

    class Flag(logging.Handler):
        def emit(self, record: logging.LogRecord) -> None:
            said.set()

    def slow_run(self, log, *args, **kwargs):
        event.start_event("numba:compile")
        try:
            assert said.wait(30.0), "no compile notice"
        finally:
            event.end_event("numba:compile")
        return real_run(self, log, *args, **kwargs)

    handler = Flag()
    logging.getLogger("vestim").addHandler(handler)
    try:
        log = strip(simulate(get_maneuver("step_steer"), SUV, seed=0)).iloc[:400]
        monkeypatch.setattr(Pipeline, "run", slow_run)
        with caplog.at_level(logging.WARNING, logger="vestim"):
            estimate(log, SUV)
        assert any("compiling vestim's kernels" in r.getMessage() for r in caplog.records)
        monkeypatch.setattr(Pipeline, "run", real_run)
        caplog.clear()
        with caplog.at_level(logging.WARNING, logger="vestim"):
            estimate(log, SUV)
        assert not any("compiling" in r.getMessage() for r in caplog.records)
    finally:
        logging.getLogger("vestim").removeHandler(handler)


_CAMPAIGN = Path(__file__).resolve().parents[1].parent / "shared" / "crossplant" / "data_campaign"


@pytest.mark.skipif(not _CAMPAIGN.exists(), reason=f"campaign logs not found at {_CAMPAIGN}")
def test_utilisation_of_a_nearly_lifted_wheel_is_flagged_not_reported(tmp_path: Path) -> None:
    """Campaign s1_014 (ramp steer into the limit, independent plant): the rear wheels carry
    down to 580–710 N (static 2530 N) and the estimate's F_z there is 540–620 N with σ_Fz
    470–500 N. F/F_z of a load not resolved from zero is no friction use: it read 41.7 where
    the plant's own μ stays below 1.1. Where F_z < 2 σ_Fz (measured on 1026 and 1354 rear
    rows of 5929) μ_x, μ_y are 0 and the row's force group is not valid with reason bit 16
    "unobservable"; elsewhere |μ| stays within the physical 1.2 (measured 1.12), and the
    estimate still writes (every value finite, as the log format requires)."""
    from vestim.estimators.validity import FZ_RESOLVED, UNOBSERVABLE

    truth = pd.read_parquet(_CAMPAIGN / "s1_014_ramp_steer.parquet")
    log = truth[[c for c in truth.columns if not c.startswith(("ref_", "_"))]]
    est = Pipeline(load_vehicle(_CAMPAIGN / "s1_014_ramp_steer.toml")).run(log)
    worst = 0.0
    any_unresolved = np.zeros(len(est), dtype=bool)
    for c in ("fl", "fr", "rl", "rr"):
        unresolved = (est[f"fz_{c}"] < FZ_RESOLVED * est[f"sigma_fz_{c}"]).to_numpy()
        any_unresolved |= unresolved
        for q in ("mu_x", "mu_y"):
            assert (est[f"{q}_{c}"].to_numpy()[unresolved] == 0.0).all(), (q, c)
        mu = np.hypot(est[f"mu_x_{c}"], est[f"mu_y_{c}"]).to_numpy()
        worst = max(worst, float(mu[~unresolved].max()))
    assert any_unresolved.sum() > 1000
    assert (est["valid_force"].to_numpy()[any_unresolved] == 0.0).all()
    assert ((est["reason_force"].to_numpy()[any_unresolved].astype(int) & UNOBSERVABLE) > 0).all()
    assert worst <= 1.2
    write_log(est, tmp_path / "estimate.parquet")  # the format's checks (NaN μ was refused)
