"""Fewer sensors (issue 14): logs without ax, without wheel speeds, without roll/pitch rates.

Every case runs the default pipeline on the independent crossplant logs
(``../shared/crossplant/data``, each with the vehicle file its manifest names) with channels
removed, and checks the figures and the output metadata (``Pipeline.force.input_sources``,
which the CLI writes into the estimate file): ``ax_source``, ``speed_source``,
``outputs_unavailable``, ``roll_source``/``pitch_source``.

Sideslip β = atan2(v_y, v_x) is scored over the samples whose true speed |(ref_vx, ref_vy)|
is at least 3 m/s (β is undefined at standstill; every turning log is above it throughout).
"""

from __future__ import annotations

import json
from functools import cache
from pathlib import Path

import numpy as np
import pandas as pd
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from typer.testing import CliRunner

from vestim.cli import app
from vestim.errors import LogFormatError
from vestim.estimators.force.estimator import (
    AX_TAU,
    AX_TAU_SPARSE,
    new_speed_derivative_state,
    new_speed_hold_state,
    speed_derivative,
    speed_hold,
)
from vestim.io import load_vehicle, read_log, validate_log, write_log
from vestim.io.channels import WHEEL_SPEEDS
from vestim.io.vehicle import Vehicle
from vestim.pipeline import (
    WHEEL_ONLY_OUTPUTS,
    Pipeline,
    PipelineConfig,
    PipelineConfigError,
    estimate,
)

CROSSPLANT = Path(__file__).resolve().parents[1] / ".." / "shared" / "crossplant" / "data"
pytestmark = pytest.mark.skipif(not (CROSSPLANT / "manifest.json").is_file(),
                                reason="crossplant logs not available")

TURNING = ("x05_sine_steer_dry_rwd", "x06_ramp_steer_wet_fwd", "x07_brake_turn_dry_awd",
           "x08_slalom_snow_awd", "x09_accel_turn_mu_drop_rwd", "x10_mixed_drive_fwd",
           "x11_stiffness_step_rwd", "x12_stiffness_friction_step_fwd")
"""The crossplant logs with turning (max |a_y| > 1 m/s²; x01–x04 stay below 0.2 m/s²)."""

BETA_MAX_DEG = 0.3
"""The issue's sideslip target without wheel speeds, RMS in degrees."""

# Turning logs where the default misses the sideslip target without wheel speeds; the v_y
# part is the same filter with or without them. Measured (gnss_speed seed 0 /
# vehicle_speed), with all sensors in brackets: x06 1.37 / 1.29 (1.17) degrees: the wet
# ramp steer drives the front axle into saturation on a tire the nominal vehicle file does
# not know, and the integral drifts once both linear-tire bounds are rejected
# (docs/results.md); x10 0.311 with gnss_speed (0.268 with vehicle_speed, 0.208 with every
# sensor): the 120 s mixed drive slides to 6.9 degrees of sideslip, which the v_y bounds of
# a saturating axle hold only loosely, and the 10 Hz fixes carry less speed than a dense
# CAN speed.
X06 = ("measured 1.29 deg with gnss_speed, 1.21 with vehicle_speed (1.14 with every "
       "sensor; 1.37, 1.29, 1.17 before issue 29): front-axle saturation on an unknown wet "
       "tire, whose stiffness the ramp steer does not excite")
MISSES_GNSS = {"x06_ramp_steer_wet_fwd": X06}
MISSES_CAN = {"x06_ramp_steer_wet_fwd": X06}


def _cases(misses: dict[str, str]) -> list[object]:
    return [pytest.param(n, marks=pytest.mark.xfail(strict=True, reason=misses[n]))
            if n in misses else n for n in TURNING]


@cache
def _crossplant(name: str) -> tuple[pd.DataFrame, Vehicle]:
    maneuver = json.loads((CROSSPLANT / "manifest.json").read_text())["maneuvers"][name]
    return (read_log(CROSSPLANT / maneuver["file"], require=["measured"]),
            load_vehicle(CROSSPLANT / maneuver["vehicle_file"]))


def _measured(log: pd.DataFrame, drop: tuple[str, ...] = ()) -> pd.DataFrame:
    """The measured channels without ``drop`` (never a ref_ column)."""
    return log.drop(columns=[c for c in log.columns if c.startswith("ref_") or c in drop])


def _true_speed(log: pd.DataFrame) -> np.ndarray:
    return np.asarray(np.hypot(log["ref_vx"], log["ref_vy"]))


def gnss_only(log: pd.DataFrame, seed: int = 0) -> pd.DataFrame:
    """The log without wheel speeds, with the issue's gnss_speed: |(ref_vx, ref_vy)| +
    N(0, 0.05 m/s) at 10 Hz on the row nearest each fix, NaN between (the spec's sparse
    channel)."""
    rng = np.random.default_rng(seed)
    t = log["t"].to_numpy()
    rows = np.unique(np.searchsorted(t, np.arange(t[0], t[-1] + 1e-9, 0.1)).clip(0, len(t) - 1))
    gnss = np.full(len(t), np.nan)
    gnss[rows] = np.maximum(_true_speed(log)[rows] + rng.normal(0.0, 0.05, rows.size), 0.0)
    out = _measured(log, WHEEL_SPEEDS)
    out["gnss_speed"] = gnss
    return out


def can_speed_only(log: pd.DataFrame) -> pd.DataFrame:
    """The log without wheel speeds, with a dense CAN vehicle_speed: the true speed quantised
    to 0.1 km/h (a cluster speed's resolution)."""
    out = _measured(log, WHEEL_SPEEDS)
    out["vehicle_speed"] = np.round(_true_speed(log) * 36.0) / 36.0
    return out


@cache
def _estimate(name: str, case: str) -> tuple[pd.DataFrame, dict[str, str]]:
    log, veh = _crossplant(name)
    make = {"gnss": gnss_only, "can": can_speed_only, "full": _measured}[case]
    pipe = Pipeline(veh)
    return pipe.run(make(log)), pipe.force.input_sources


def _beta_rms_deg(est: pd.DataFrame, log: pd.DataFrame) -> float:
    moving = _true_speed(log) >= 3.0
    err = np.arctan2(est["vy"], est["vx"]) - np.arctan2(log["ref_vy"], log["ref_vx"])
    return float(np.degrees(np.sqrt(np.mean(np.asarray(err)[moving] ** 2))))


def _rmse(a: pd.Series, b: pd.Series) -> float:
    return float(np.sqrt(np.mean((np.asarray(a) - np.asarray(b)) ** 2)))


# --- no wheel speeds ----------------------------------------------------------------------


@pytest.mark.parametrize("name", _cases(MISSES_GNSS))
def test_gnss_only_sideslip_within_0_3_deg(name: str) -> None:
    """v_y from a_y, r, δ and gnss_speed only: β RMS ≤ 0.3°. Measured (seed 0): x05 0.059,
    x07 0.194, x08 0.160, x09 0.150, x10 0.195, x11 0.103, x12 0.094 degrees (with every
    sensor 0.059, 0.190, 0.156, 0.143, 0.174, 0.103, 0.099); x06 misses, see MISSES_GNSS."""
    est, _ = _estimate(name, "gnss")
    assert _beta_rms_deg(est, _crossplant(name)[0]) <= BETA_MAX_DEG


@pytest.mark.parametrize("name", _cases(MISSES_CAN))
def test_can_vehicle_speed_only_sideslip_within_0_3_deg(name: str) -> None:
    """The same with a dense vehicle_speed (0.1 km/h resolution) instead of gnss_speed.
    Measured: x05 0.059, x07 0.183, x08 0.159, x09 0.148, x10 0.183, x11 0.102, x12 0.094
    degrees; x06 misses as above."""
    est, _ = _estimate(name, "can")
    assert _beta_rms_deg(est, _crossplant(name)[0]) <= BETA_MAX_DEG


@pytest.mark.parametrize("name", TURNING)
def test_gnss_only_vx_within_the_gnss_target(name: str) -> None:
    """v_x from a_x integrated with the 10 Hz fixes: RMSE ≤ 0.06 m/s, docs/results.md's
    v_x target with gnss_speed. Measured 0.024–0.028 m/s (the fixes' 0.05 m/s noise,
    averaged by the filter over its ~1 s correlation with a_x)."""
    est, _ = _estimate(name, "gnss")
    assert _rmse(est["vx"], _crossplant(name)[0]["ref_vx"]) <= 0.06


def test_no_wheel_speeds_states_what_it_cannot_give() -> None:
    """Per-wheel quantities that need ω are left out and listed in outputs_unavailable (a log
    holds no NaN outside its sparse channels); the CG and kinematic per-corner quantities
    and the forces from the accelerations are finite."""
    est, meta = _estimate("x08_slalom_snow_awd", "gnss")
    assert meta["speed_source"] == "gnss_speed"
    assert meta["ax_source"] == "measured"
    listed = meta["outputs_unavailable"].split(",")
    assert listed == list(WHEEL_ONLY_OUTPUTS)
    assert set(listed).isdisjoint(est.columns)
    assert not any(c.startswith(("slip_ratio_", "fx_", "mu_x_", "sigma_fx_"))
                   for c in est.columns)
    for col in ("vx", "vy", "vx_fl", "vyt_rr", "slip_angle_fl", "fy_fl", "fz_rr", "mu_y_fl",
                "roll", "pitch", "bias_ax"):
        assert est[col].notna().all(), col
    _, can_meta = _estimate("x08_slalom_snow_awd", "can")
    assert can_meta["speed_source"] == "vehicle_speed"


@pytest.mark.parametrize("name", ["x05_sine_steer_dry_rwd", "x08_slalom_snow_awd"])
def test_no_wheel_speeds_forces_from_the_accelerations_unchanged(name: str) -> None:
    """F_z per corner and F_y per axle come from the accelerations, so without wheel speeds
    their NRMS (RMS / max |truth|) stays within 0.25 point of the full-sensor figure.
    Measured: F_z worst corner 2.53 / 1.54 % in both cases; F_y worst axle 4.05 vs 3.97 %
    (x05), 5.17 vs 5.14 % (x08): the speed reference of the lateral split only."""
    log, _ = _crossplant(name)
    est, _ = _estimate(name, "gnss")
    full, _ = _estimate(name, "full")

    def nrms(e: pd.DataFrame, cols: list[str], ref: list[str]) -> float:
        return 100.0 * _rmse(e[cols].sum(axis=1), log[ref].sum(axis=1)) / float(
            log[ref].sum(axis=1).abs().max())

    for cols in (["fz_fl"], ["fz_fr"], ["fz_rl"], ["fz_rr"], ["fy_fl", "fy_fr"],
                 ["fy_rl", "fy_rr"]):
        ref = ["ref_" + c for c in cols]
        assert nrms(est, cols, ref) <= nrms(full, cols, ref) + 0.25, cols


@pytest.mark.parametrize("case", ["gnss", "can", "no_ax"])
def test_reduced_log_online_steps_give_the_batch_result(case: str) -> None:
    """Sample by sample (Pipeline.step) the reduced log gives run()'s result exactly: every
    state (the a_x derivative, the speed hold, the reference filter) carries over."""
    log, veh = _crossplant("x05_sine_steer_dry_rwd")
    reduced = {"gnss": gnss_only, "can": can_speed_only,
               "no_ax": lambda g: _measured(g, ("ax",))}[case](log)
    part = reduced.iloc[:300].reset_index(drop=True)
    batch = Pipeline(veh).run(part)
    pipe = Pipeline(veh)
    # gnss_speed stays in every sample, NaN between fixes (the sparse channel as logged).
    rows = [pipe.step({str(k): float(v) for k, v in row.items()})
            for row in part.to_dict("records")]
    online = pd.DataFrame(rows)[batch.columns]
    np.testing.assert_array_equal(online.to_numpy(), batch.to_numpy())


def test_no_wheel_speeds_needs_a_velocity_method_without_them() -> None:
    log, veh = _crossplant("x05_sine_steer_dry_rwd")
    with pytest.raises(PipelineConfigError, match=r"'kinematic' needs the wheel speeds.*"
                                                  r"reference"):
        Pipeline(veh, PipelineConfig(velocity="kinematic")).run(gnss_only(log).iloc[:50])


# --- no ax ----------------------------------------------------------------------------------


@pytest.mark.parametrize("name", ["x01_launch_snow_fwd", "x02_launch_ice_rwd",
                                  "x04_brake_splitmu_rwd", "x05_sine_steer_dry_rwd",
                                  "x06_ramp_steer_wet_fwd", "x08_slalom_snow_awd",
                                  "x09_accel_turn_mu_drop_rwd", "x10_mixed_drive_fwd",
                                  "x11_stiffness_step_rwd", "x12_stiffness_friction_step_fwd"])
def test_no_ax_from_the_wheel_speeds(name: str) -> None:
    """a_x from a reference wheel speed: flagged ax_source = wheel_speeds, and v_x RMSE
    ≤ 0.05 m/s (docs/results.md's 0.06 m/s target with gnss_speed, less a margin: the
    wheels still measure v_x, only the integral between them is lagged). Measured: x01
    0.022, x02 0.015, x04 0.042, x05 0.007, x06 0.011, x08 0.012, x09 0.015, x10 0.020,
    x11 0.046, x12 0.037 m/s (with ax 0.004–0.069). Left out: x03 and x07, braking on every
    wheel (0.082, 0.080 m/s; docs/fewer-sensors.md), where no wheel rolls freely."""
    log, veh = _crossplant(name)
    pipe = Pipeline(veh)
    est = pipe.run(_measured(log, ("ax",)))
    assert pipe.force.input_sources["ax_source"] == "wheel_speeds"
    assert pipe.force.input_sources["outputs_unavailable"] == "none"
    assert _rmse(est["vx"], log["ref_vx"]) <= 0.05


# --- no roll or pitch rates ------------------------------------------------------------------


@pytest.mark.parametrize("name", ["x05_sine_steer_dry_rwd", "x09_accel_turn_mu_drop_rwd"])
def test_no_rates_quasi_static_attitude_is_stated(name: str) -> None:
    """Without roll_rate and pitch_rate the attitude is quasi-static, and the metadata says so.
    β RMS stays ≤ 0.3° on these two logs (measured 0.145 and 0.213°; 0.038 and 0.134 with
    the rates). It does not on x07/x08/x11 (10.1, 0.40, 0.48°): the quasi-static roll
    c_roll a_y of the file's default suspension is off by 1–1.6° there, which enters f_y
    as g sin φ (docs/fewer-sensors.md)."""
    log, veh = _crossplant(name)
    pipe = Pipeline(veh)
    est = pipe.run(_measured(log, ("roll_rate", "pitch_rate")))
    src = pipe.force.input_sources
    assert src["roll_source"] == "quasi_static" and src["pitch_source"] == "quasi_static"
    assert est["roll"].notna().all() and est["pitch"].notna().all()
    assert _beta_rms_deg(est, log) <= BETA_MAX_DEG


# --- full sensors unchanged ----------------------------------------------------------------


def test_full_sensors_ignore_vehicle_speed_and_state_every_output() -> None:
    """With wheel speeds a vehicle_speed column changes nothing (bit for bit), and the
    metadata says every output is given."""
    log, veh = _crossplant("x06_ramp_steer_wet_fwd")
    full, meta = _estimate("x06_ramp_steer_wet_fwd", "full")
    with_speed = _measured(log)
    with_speed["vehicle_speed"] = _true_speed(log)
    np.testing.assert_array_equal(Pipeline(veh).run(with_speed).to_numpy(), full.to_numpy())
    assert meta["outputs_unavailable"] == "none"
    assert meta["ax_source"] == "measured" and meta["speed_source"] == "wheel_speeds"


# --- reading reduced logs --------------------------------------------------------------------


def _obd_log(tmp_path: Path, drop: tuple[str, ...]) -> tuple[Path, pd.DataFrame]:
    """x08 without wheel speeds and ``drop``, with gnss_speed, written to a Parquet file."""
    log, _ = _crossplant("x08_slalom_snow_awd")
    reduced = gnss_only(log).drop(columns=list(drop))
    return write_log(reduced, tmp_path / "obd.parquet"), log


def test_read_log_and_estimate_accept_a_gnss_only_log_without_ax(tmp_path: Path) -> None:
    """The library form of `vestim estimate` (read_log(require=["measured"]) + Pipeline) on
    x08 without wheel speeds and ax (a_x from the fixes): β RMS 0.159° (≤ 0.3°), v_x RMSE
    0.043 m/s. (Without az and the rates as well β is 0.41°: see the no-rates test.)"""
    path, log = _obd_log(tmp_path, ("ax",))
    assert len(read_log(path, require=["measured"])) == len(log)
    maneuver = json.loads((CROSSPLANT / "manifest.json").read_text())["maneuvers"][
        "x08_slalom_snow_awd"]
    est = estimate(path, CROSSPLANT / maneuver["vehicle_file"])
    assert "slip_ratio_fl" not in est.columns and est["vy"].notna().all()
    assert _beta_rms_deg(est, log) <= BETA_MAX_DEG


def test_cli_accepts_a_gnss_only_log_without_ax(tmp_path: Path) -> None:
    """`vestim estimate` (its input checks included) on x08 without wheel speeds, ax, az and
    rates: exit 0, and the metadata names every source and what is left out."""
    path, _ = _obd_log(tmp_path, ("ax", "az", "roll_rate", "pitch_rate"))
    out = tmp_path / "est.parquet"
    maneuver = json.loads((CROSSPLANT / "manifest.json").read_text())["maneuvers"][
        "x08_slalom_snow_awd"]
    result = CliRunner().invoke(app, ["estimate", str(path), "--vehicle",
                                      str(CROSSPLANT / maneuver["vehicle_file"]),
                                      "--out", str(out)])
    assert result.exit_code == 0, result.output
    est = read_log(out)
    assert est.attrs["ax_source"] == "gnss_speed"
    assert est.attrs["speed_source"] == "gnss_speed"
    assert est.attrs["outputs_unavailable"].split(",") == list(WHEEL_ONLY_OUTPUTS)
    assert "slip_ratio_fl" not in est.columns and est["vy"].notna().all()


@pytest.mark.parametrize(
    ("drop", "match"),
    [(WHEEL_SPEEDS, r"no speed channel.*omega_fl.*gnss_speed.*vehicle_speed"),
     (("omega_rl",), r"missing: omega_rl \[rad/s\]"),
     (("ay",), r"missing: ay \[m/s²\]"),
     (("yaw_rate",), r"missing: yaw_rate"),
     (("delta_fl", "delta_fr", "steering_wheel_angle"), r"no steering channel")],
)
def test_reduced_log_missing_what_it_cannot_do_without(drop: tuple[str, ...],
                                                       match: str) -> None:
    log, _ = _crossplant("x05_sine_steer_dry_rwd")
    with pytest.raises(LogFormatError, match=match):
        validate_log(_measured(log, drop), require=["measured"])


def test_partial_wheel_speeds_with_a_speed_channel_is_an_error() -> None:
    """Three wheel speeds and a gnss_speed: the set is incomplete, not absent."""
    log, veh = _crossplant("x05_sine_steer_dry_rwd")
    reduced = gnss_only(log)
    reduced[["omega_fl", "omega_fr", "omega_rl"]] = log[["omega_fl", "omega_fr", "omega_rl"]]
    with pytest.raises(LogFormatError, match=r"missing: omega_rr"):
        validate_log(reduced, require=["measured"])
    with pytest.raises(LogFormatError, match=r"but not omega_rr.*drop every omega_\*"):
        Pipeline(veh).run(reduced)


# --- the a_x and speed kernels ---------------------------------------------------------------


@settings(max_examples=40, deadline=None)
@given(slope=st.floats(-9.0, 9.0), v0=st.floats(0.0, 40.0), rate=st.sampled_from([10.0, 100.0,
                                                                                 200.0]))
def test_speed_derivative_of_a_ramp_is_its_slope(slope: float, v0: float, rate: float) -> None:
    """A speed ramp v0 + a t gives a_x = a once both low-passes have settled (10 s: the
    derivative's low-pass closes its gap by (1 − T_s/τ) a sample, 0.8⁹⁹ ≈ 3e-10 for the
    sparse constants at 10 Hz): a first-order low-pass of a ramp is the ramp delayed, whose
    difference is the slope; 1e-6 m/s² is that residue plus float round-off."""
    t = np.arange(0.0, 10.0, 1.0 / rate)
    out = np.empty_like(t)
    tau = AX_TAU if rate > 10.0 else AX_TAU_SPARSE
    speed_derivative(t, v0 + slope * t, tau[0], tau[1], new_speed_derivative_state(), out)
    assert out[-1] == pytest.approx(slope, abs=1e-6)


@settings(max_examples=40, deadline=None)
@given(split=st.integers(1, 198), seed=st.integers(0, 1000))
def test_speed_kernels_do_not_depend_on_the_chunking(split: int, seed: int) -> None:
    """speed_derivative and speed_hold carry their state: two chunks give one's result."""
    rng = np.random.default_rng(seed)
    t = np.cumsum(rng.uniform(0.004, 0.006, 200))
    v = np.where(rng.random(200) < 0.1, 10.0 + rng.normal(0.0, 1.0, 200), np.nan)
    ax = rng.normal(0.0, 1.0, 200)
    whole_a, parts_a, whole_h, parts_h = np.empty((4, 200))
    speed_derivative(t, v, 0.0, 0.5, new_speed_derivative_state(), whole_a)
    speed_hold(t, v, ax, new_speed_hold_state(), whole_h)
    sa, sh = new_speed_derivative_state(), new_speed_hold_state()
    for a, b in ((0, split), (split, 200)):
        speed_derivative(t[a:b], v[a:b], 0.0, 0.5, sa, parts_a[a:b])
        speed_hold(t[a:b], v[a:b], ax[a:b], sh, parts_h[a:b])
    np.testing.assert_array_equal(parts_a, whole_a)
    np.testing.assert_array_equal(parts_h, whole_h)
