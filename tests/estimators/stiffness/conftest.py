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


@pytest.fixture(scope="session")
def single_track_data(study_log_ideal):
    """002 Sec. VI-A's own setting: the single-track estimation model generates the data.

    Inputs (δ, ω_f, ω_r) of the ideal MF run; axle stiffness drawn per step around the level
    C(0) (before 30 s) or C(0)/2 (after) with 5 % standard deviation; x0 ~ N([22, 0, 0],
    diag(1, 1, (π/180)²)); IMU noise of the default sensor model; a_x, a_y scaled by the
    roll/pitch factors a body-fixed IMU sees (the estimator divides them out). The same
    construction as ``benchmarks/study_002.py``.

    Returns:
        (log, level (K, 4) axle stiffness the per-step values scatter around, C(0) (4,)).
    """
    import numpy as np
    import pandas as pd

    from vestim.constants import G
    from vestim.estimators.stiffness.model import SingleTrackParams, pitch_gradient, roll_gradient
    from vestim.estimators.stiffness.model import simulate as st_simulate

    src = study_log_ideal
    rng = np.random.default_rng(10_000)
    c0 = src[[f"ref_stiffness_{c}" for c in ("cx_f", "cx_r", "cy_f", "cy_r")]].to_numpy()[0]
    params = SingleTrackParams.from_vehicle(SUV_FWD, tuple(c0))
    t = src["t"].to_numpy()
    level = np.where(t[:, None] < 30.0, 1.0, 0.5) * c0
    w = params.axles_to_deviation(level * (1.0 + 0.05 * rng.standard_normal((t.size, 4))))
    delta = 0.5 * (src["delta_fl"].to_numpy() + src["delta_fr"].to_numpy())
    om_f = 0.5 * (src["omega_fl"].to_numpy() + src["omega_fr"].to_numpy())
    om_r = 0.5 * (src["omega_rl"].to_numpy() + src["omega_rr"].to_numpy())
    u = np.column_stack([delta, om_f, om_r, np.diff(t, append=2 * t[-1] - t[-2])])
    x0 = np.array([22.0, 0.0, 0.0]) + rng.standard_normal(3) * np.array([1.0, 1.0, np.pi / 180])
    x, y = st_simulate(x0, u, w, params)
    sens = SensorModel()
    y = y + rng.standard_normal(y.shape) * np.array([sens.accel_noise, sens.accel_noise, sens.gyro_noise])
    log = pd.DataFrame({"t": t, "omega_fl": om_f, "omega_fr": om_f, "omega_rl": om_r, "omega_rr": om_r,
                        "ax": y[:, 0] * (1.0 + pitch_gradient(SUV_FWD) * G),
                        "ay": y[:, 1] * (1.0 + roll_gradient(SUV_FWD) * G), "yaw_rate": y[:, 2],
                        "delta_fl": delta, "delta_fr": delta, "ref_vy": x[:, 1]})
    return log, level, c0
