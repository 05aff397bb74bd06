"""Shared simulator logs for the stiffness tests (simulated once per session)."""

import pytest

from vestim.io import load_vehicle
from vestim.sim import SensorModel, get_maneuver, simulate

SUV_FWD = load_vehicle("hashemi_suv").with_drivetrain("fwd")


@pytest.fixture(scope="session")
def study_log_ideal():
    """002 Sec. VI-A maneuver on the MF plant, ideal sensors."""
    return simulate(get_maneuver("stiffness_study", tire="magic"), SUV_FWD, seed=0,
                    sensors=SensorModel.ideal())


@pytest.fixture(scope="session")
def study_log():
    """002 Sec. VI-A maneuver on the MF plant: default IMU noise, no IMU bias, exact wheel speeds
    (002's setting, as in benchmarks/study_002.py)."""
    return simulate(get_maneuver("stiffness_study", tire="magic"), SUV_FWD, seed=3,
                    sensors=SensorModel(accel_bias=0.0, gyro_bias=0.0, wheel_speed_noise=0.0))
