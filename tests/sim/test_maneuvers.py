"""Maneuver library: every name runs, options are validated, papers' inputs are reproduced."""

import numpy as np
import pytest

from tests.sim.conftest import SUV
from vestim.errors import ManeuverError
from vestim.io import validate_log
from vestim.io.channels import REFERENCE
from vestim.sim import SensorModel, get_maneuver, maneuver_names, simulate

REQUIRED = {"accel_brake", "ait_dry", "ait_slippery", "ait_004_dry", "ait_004_slippery",
            "step_steer", "bit_slippery", "launch_ice", "launch_split_mu", "dlc_snow", "lc_wet",
            "oval", "full_turn_dry_wet", "ait_wet_dry", "stiffness_study"}


def test_library_has_every_maneuver_of_the_issue():
    assert set(maneuver_names()) >= REQUIRED


@pytest.mark.parametrize("name", maneuver_names())
@pytest.mark.parametrize("tire", ["magic", "lugre"])
def test_every_maneuver_gives_a_valid_spec_log(name, tire):
    """Each maneuver, on both tire plants, yields a finite log with all measured and ref_ channels."""
    log = simulate(get_maneuver(name, tire=tire), SUV, seed=3)
    validate_log(log, require=["measured"])
    missing = set(REFERENCE) - set(log.columns)
    assert not missing
    assert np.isfinite(log.to_numpy()).all()
    assert log["t"].iloc[1] == pytest.approx(0.005)  # 200 Hz


def test_step_steer_reproduces_000_inputs():
    """000 Sec. IV-B: 60 km/h, steering-wheel angle 2 rad at t = 2 s."""
    log = simulate("step_steer", SUV, sensors=SensorModel.ideal())
    assert log["ref_vx"].iloc[0] == pytest.approx(60 / 3.6)
    assert log.loc[log["t"] < 1.99, "steering_wheel_angle"].abs().max() == 0.0
    assert log.loc[log["t"] > 2.2, "steering_wheel_angle"].min() == pytest.approx(2.0)


def test_bit_slippery_reproduces_004_inputs():
    """004 Fig. 9: μ = 0.25, road-wheel angle 0.06 rad from 2 s, full brake at 5 s."""
    log = simulate("bit_slippery", SUV, sensors=SensorModel.ideal())
    mean_delta = 0.5 * (log["delta_fl"] + log["delta_fr"])
    assert mean_delta[log["t"] > 3].mean() == pytest.approx(0.06, rel=0.02)
    assert (log[[c for c in log if c.startswith("ref_mu_")]] == 0.25).all().all()
    braking = log.loc[log["t"] > 6.0, "torque_fl"]
    assert (braking <= 0).all() and braking.mean() < -200.0  # ABS modulates, never drives


def test_split_mu_launch_has_dry_left_and_icy_right():
    log = simulate("launch_split_mu", SUV, sensors=SensorModel.ideal())
    assert (log["ref_mu_fl"] == 1.0).all() and (log["ref_mu_rr"] == 0.2).all()


def test_distance_transition_reaches_front_wheels_first():
    """full_turn_dry_wet changes the surface at 120 m: the front wheels meet it lf + lr earlier."""
    log = simulate("full_turn_dry_wet", SUV, sensors=SensorModel.ideal(), extras=True)
    t_front = log.loc[log["ref_mu_fl"] < 0.99, "t"].iloc[0]
    t_rear = log.loc[log["ref_mu_rl"] < 0.99, "t"].iloc[0]
    d_front = np.interp(t_front, log["t"], log["distance"])
    assert d_front == pytest.approx(120.0 - SUV.body.lf, abs=0.2)
    assert (t_rear - t_front) * log["ref_vx"].mean() == pytest.approx(SUV.body.wheelbase, abs=0.3)


def test_launch_on_ice_without_tc_spins_the_wheels_and_with_tc_does_not():
    no_tc = simulate(get_maneuver("launch_ice", tc=False), SUV, sensors=SensorModel.ideal())
    with_tc = simulate(get_maneuver("launch_ice", tc=True), SUV, sensors=SensorModel.ideal())
    late = no_tc["t"] > 3
    assert no_tc.loc[late, "ref_slip_ratio_fl"].mean() > 0.5
    assert with_tc.loc[late, "ref_slip_ratio_fl"].abs().mean() < 0.2


@pytest.mark.parametrize("kwargs, match", [
    ({"name": "nope"}, "unknown maneuver 'nope'.*accel_brake"),
    ({"name": "launch_ice", "mu": 3.0}, "mu = 3.0"),
    ({"name": "launch_ice", "drivetrain": "4wd"}, "drivetrain '4wd'"),
    ({"name": "launch_ice", "tire": "brush"}, "tire 'brush'"),
    ({"name": "coast", "v0": -1.0}, "v0 = -1.0"),
])
def test_bad_options_are_named(kwargs, match):
    with pytest.raises(ManeuverError, match=match):
        get_maneuver(**kwargs)


def test_drivetrain_option_moves_the_drive_torque():
    """RWD puts all drive torque on the rear wheels, FWD on the front."""
    for dt, driven, idle in (("rwd", "torque_rl", "torque_fl"), ("fwd", "torque_fl", "torque_rl")):
        log = simulate(get_maneuver("ait_dry", drivetrain=dt), SUV, sensors=SensorModel.ideal())
        assert log[driven].max() > 500.0
        assert log[idle].max() <= 0.0 + 1e-9
