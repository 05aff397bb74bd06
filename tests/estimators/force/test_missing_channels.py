"""Logs without wheel torques or without roll rate, pitch rate and az (issue 4, 001 Sec. VI).

Simulated logs with those columns removed, against the simulator's ground truth and
against the same log with every channel. The full accuracy table is produced by
benchmarks/missing_channels_table.py and reported in docs/results_missing_channels.md.
"""

import numpy as np
import pandas as pd
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from vestim.constants import CORNERS
from vestim.errors import LogFormatError
from vestim.estimators.force import ForceEstimator
from vestim.io import load_vehicle
from vestim.io.inputs import inputs_from_log
from vestim.models import chassis
from vestim.pipeline import Pipeline
from vestim.sim import SensorModel, get_maneuver, simulate

SUV = load_vehicle("hashemi_suv")
TORQUES = [f"torque_{c}" for c in CORNERS]
ATTITUDE = ["roll_rate", "pitch_rate", "az"]


def nrms(est: np.ndarray, ref: np.ndarray, floor: float = 0.0) -> float:
    """NRMS of 000 Sec. IV: RMS error over max |ref| (with the issue's 500 N floor for F_x)."""
    return float(np.sqrt(np.mean((est - ref) ** 2)) / max(np.max(np.abs(ref)), floor))


def worst(out: pd.DataFrame, log: pd.DataFrame, name: str, floor: float = 0.0) -> float:
    return max(nrms(out[f"{name}_{c}"].to_numpy(), log[f"ref_{name}_{c}"].to_numpy(), floor)
               for c in CORNERS)


def measured(log: pd.DataFrame, drop: tuple[str, ...] | list[str] = ()) -> pd.DataFrame:
    """The log's measured channels without ``drop`` (estimators never see ``ref_`` columns)."""
    return log.drop(columns=[c for c in log.columns if c.startswith("ref_")] + list(drop))


@pytest.fixture(scope="module")
def runs():
    """accel_brake (000 Fig. 6a, μ = 0.3), Magic Formula tire, AWD and RWD, seed 1; and the same
    maneuver with ideal sensors, whose difference from the noisy log is the run's IMU bias."""
    out = {}
    for drive in ("awd", "rwd"):
        veh = SUV.with_drivetrain(drive)
        m = get_maneuver("accel_brake", tire="magic", drivetrain=drive)
        out[drive] = (veh, simulate(m, veh, seed=1), simulate(m, veh, sensors=SensorModel.ideal()))
    return out


# ---------------------------------------------------------------- physics of the chassis path
@pytest.mark.parametrize("maneuver", ["accel_brake", "ait_dry"])
@pytest.mark.parametrize("drive", ["awd", "rwd"])
def test_chassis_torque_matches_the_plants_total_torque(maneuver, drive):
    """models.chassis eq. (2) against the simulator: Σ T_i from m f_x + drag + rolling resistance
    + steered drag + I_w Σ ω̇ equals the plant's commanded Σ T_i (ideal sensors).

    Measured RMS error 0.6–1.6 % of max |Σ T| (the filtered ω̇ lags wheel spin-up, the plant's
    5 ms load lag); 3 % leaves room for that and would catch a missing term (drag at 20 m/s
    is 5 % of the launch torque, the rotating-inertia term 3 %).
    """
    veh = SUV.with_drivetrain(drive)
    log = simulate(get_maneuver(maneuver, tire="magic", drivetrain=drive), veh,
                   sensors=SensorModel.ideal())
    res = ForceEstimator(veh).advance(inputs_from_log(measured(log, TORQUES), veh))
    true_total = log[TORQUES].to_numpy().sum(axis=1)
    err = res["torque"].sum(axis=1) - true_total
    assert np.sqrt(np.mean(err**2)) <= 0.03 * np.max(np.abs(true_total))


@settings(max_examples=50, deadline=None)
@given(total=st.floats(-5e3, 5e3), front_drive=st.floats(0, 1), front_brake=st.floats(0, 1))
def test_distribution_conserves_the_total_and_splits_left_right_equally(total, front_drive,
                                                                        front_brake):
    """Σ corners = total; left = right (open differential); front share by the sign of the total."""
    t = chassis.distribute_torque(np.array([total]), front_drive, front_brake)[0]
    assert t.sum() == pytest.approx(total, abs=1e-9)
    assert t[0] == t[1] and t[2] == t[3]
    share = front_drive if total > 0 else front_brake
    assert t[0] + t[1] == pytest.approx(share * total, abs=1e-9)


def test_drivetrain_sets_which_axle_drives(runs):
    """RWD: the chassis path gives the front wheels no torque while the car drives (Σ T > 0)."""
    veh, log, _ = runs["rwd"]
    u = inputs_from_log(measured(log, TORQUES), veh)
    ForceEstimator(veh).advance(u)
    driving = u.torque.sum(axis=1) > 0
    assert driving.any()
    assert np.all(u.torque[driving, :2] == 0.0)
    assert np.all(u.torque[driving, 2:] > 0.0)


# ------------------------------------------------------------------ accuracy without channels
@pytest.mark.parametrize("drive", ["awd", "rwd"])
def test_fx_without_torques_is_within_the_accelerometer_bias_of_the_measured_case(runs, drive):
    """F_x per corner from the chassis equation vs from measured torques, accel_brake.

    The chassis path reads m·a_x, so an accelerometer bias b puts m·b of force error on the
    total, s·m·b on a corner whose axle share is s (0.31 per AWD wheel under the 0.62
    front brake balance, 0.5 per RWD rear wheel); nothing in a log without torques can tell
    that bias from a road grade (both shift a_x; grade is part of the specific force the
    tires carry). The bound is the measured-torque NRMS + that bias term for this run's bias
    (read from the ideal-sensor twin) + 1 point for the accelerometer's white noise, the
    attitude filter's pitch error (g·Δθ) and the two ω̇ filters; over seeds 0–5 the
    remainder measured ≤ 0.3 points. Seed 1: AWD 1.7 → 2.4 %, RWD 3.1 → 3.4 %.
    """
    veh, log, ideal = runs[drive]
    with_t = worst(ForceEstimator(veh).run(measured(log)), log, "fx", 500.0)
    without = worst(ForceEstimator(veh).run(measured(log, TORQUES)), log, "fx", 500.0)
    bias = abs(float(np.mean(log["ax"] - ideal["ax"])))
    share = 0.5 if drive == "rwd" else 0.5 * veh.powertrain.brake_front_share
    denom = max(max(np.max(np.abs(log[f"ref_fx_{c}"])) for c in CORNERS), 500.0)
    assert without <= with_t + share * veh.body.mass * bias / denom + 0.01, (with_t, without)


@pytest.mark.parametrize("maneuver", ["accel_brake", "ait_dry", "dlc_snow"])
def test_fz_without_roll_pitch_rates_and_az(maneuver):
    """F_z with quasi-static attitude and level-road a_z ≤ 2.5 % NRMS per corner.

    2 % is the issue's F_z target with every channel; what is lost is the suspension's
    response to a load change: the ζ ≈ 0.5 roll and pitch modes overshoot the quasi-static
    elastic transfer by 16 % for about half a period (0.3 s) after each step of a_x or a_y,
    a few hundred newtons on a wheel for a fraction of the run, hence +0.5 point. Measured
    (seed 1): 1.2 % accel_brake, 2.0 % ait_dry, 0.6 % dlc_snow (with rates 1.7, 1.4, 1.4:
    the rate-based filter carries the gyro bias, the missing a_z drops the accelerometer's
    bias and noise on this flat road); seeds 0–5 ≤ 2.3 %.
    """
    log = simulate(get_maneuver(maneuver, tire="magic"), SUV, seed=1)
    est = ForceEstimator(SUV)
    out = est.run(measured(log, ATTITUDE))
    assert est.input_sources == {"torque_source": "measured", "roll_source": "quasi_static",
                                 "pitch_source": "quasi_static", "az_source": "level_road"}
    assert worst(out, log, "fz") <= 0.025


def test_pipeline_velocity_without_torques(runs):
    """The whole pipeline on a torque-less log: CG v_x NRMS ≤ 3 % (loose, physical).

    v_x comes from wheel speeds and the integrated acceleration; the torques only weight the
    wheels' slip evidence, so losing them should cost little. Measured 0.28 % AWD and
    0.23 % RWD (0.28 and 0.22 % with torques); 3 % is the bound a naive R·ω̄ already meets
    off the slip-heavy maneuvers, so the test does not tie the pipeline's tuning.
    """
    for drive in ("awd", "rwd"):
        veh, log, _ = runs[drive]
        pipe = Pipeline(veh)
        out = pipe.run(measured(log, TORQUES))
        assert pipe.force.torque_source == "chassis"
        assert nrms(out["vx"].to_numpy(), log["ref_vx"].to_numpy()) <= 0.03, drive


# --------------------------------------------------------------------------- errors and modes
def test_partial_torque_columns_are_named_with_the_fix(runs):
    _, log, _ = runs["awd"]
    partial = measured(log, ["torque_rl", "torque_rr"])
    with pytest.raises(LogFormatError, match=r"torque_fl, torque_fr but not torque_rl, "
                                             r"torque_rr.*all four.*or drop every torque_\*"):
        ForceEstimator(SUV).run(partial)
    sample = partial.iloc[0].to_dict()
    with pytest.raises(LogFormatError, match=r"sample has wheel torque\(s\).*not torque_rl"):
        ForceEstimator(SUV).step(sample)


@pytest.mark.parametrize("drop", [TORQUES, ATTITUDE, TORQUES + ATTITUDE, ["pitch_rate"]])
def test_step_equals_run_without_channels(runs, drop):
    """Online step() on samples lacking the channels gives the batch run() result."""
    veh, log, _ = runs["rwd"]
    part = measured(log, drop).iloc[1000:1300]  # spans the brake release at 6 s
    batch = ForceEstimator(veh).run(part)
    online = ForceEstimator(veh)
    rows = [online.step(row) for row in part.to_dict("records")]
    pd.testing.assert_frame_equal(batch, pd.DataFrame(rows)[batch.columns], check_exact=False,
                                  rtol=1e-12, atol=1e-9)
    assert online.torque_source == ("chassis" if "torque_fl" in drop else "measured")


def test_pipeline_step_equals_run_without_torques(runs):
    """The chassis torques reach the velocity stage the same way online and in batch."""
    veh, log, _ = runs["awd"]
    part = measured(log, TORQUES + ATTITUDE).iloc[1000:1200]
    batch = Pipeline(veh).run(part)
    online = Pipeline(veh)
    rows = pd.DataFrame([online.step(row) for row in part.to_dict("records")])[batch.columns]
    pd.testing.assert_frame_equal(batch, rows, check_exact=False, rtol=1e-10, atol=1e-8)


def test_sources_report_mixed_streams(runs):
    """A stream that loses its torques part-way says "mixed" (metadata must not claim either)."""
    veh, log, _ = runs["awd"]
    rows = measured(log).iloc[:4].to_dict("records")
    est = ForceEstimator(veh)
    assert est.torque_source is None
    est.step(rows[0])
    est.step({k: v for k, v in rows[1].items() if k not in TORQUES})
    assert est.torque_source == "mixed"
    est.reset()
    assert est.input_sources == {}


def test_level_road_az_gives_g_normal_to_the_road():
    """kinematics.level_road_az inverts road_specific_force for f_z = g at any body angle."""
    from vestim.constants import G
    from vestim.models import kinematics as kin
    rng = np.random.default_rng(0)
    ax, ay = rng.normal(0, 4, 50), rng.normal(0, 4, 50)
    roll, pitch = rng.normal(0, 0.05, 50), rng.normal(0, 0.05, 50)
    az = kin.level_road_az(ax, ay, roll, pitch)
    _, _, f_z = kin.road_specific_force(ax, ay, az, roll, pitch)
    np.testing.assert_allclose(f_z, G, rtol=1e-12)
