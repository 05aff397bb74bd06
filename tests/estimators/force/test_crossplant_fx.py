"""Longitudinal force on the independent crossplant logs (../shared/crossplant, MB plant, PAC2002).

The figure is ../shared/crossplant/targets.py's: pooled F_x NRMS over the four corners with
the 500 N floor, first 0.5 s skipped. The estimator sees the log without its ref_ columns and
the vehicle file as shipped (no [aerodynamics] table, so no rolling-resistance moment: the
plant has none).
"""

import json
import math
from pathlib import Path

import numpy as np
import pandas as pd
import pytest

from vestim.constants import CORNERS
from vestim.estimators.force import ForceEstimator
from vestim.io import load_vehicle

DATA = Path(__file__).resolve().parents[3] / ".." / "shared" / "crossplant" / "data"
pytestmark = pytest.mark.skipif(not (DATA / "manifest.json").is_file(),
                                reason=f"crossplant data not found at {DATA}")


def pooled_fx_nrms(name: str) -> float:
    manifest = json.loads((DATA / "manifest.json").read_text())["maneuvers"][name]
    veh = load_vehicle(DATA / manifest["vehicle_file"])
    log = pd.read_parquet(DATA / manifest["file"])
    est = ForceEstimator(veh).run(log[[c for c in log.columns if not c.startswith("ref_")]])
    keep = log["t"].to_numpy() >= 0.5
    mse = np.mean([np.mean((est[f"fx_{c}"].to_numpy()[keep]
                            - log[f"ref_fx_{c}"].to_numpy()[keep]) ** 2) for c in CORNERS])
    peak = max(np.abs(log[f"ref_fx_{c}"].to_numpy()[keep]).max() for c in CORNERS)
    return 100 * math.sqrt(mse) / max(peak, 500.0)


def test_fx_on_a_limited_log():
    """x07 (ABS-like limiter in a turn, AWD): measured 2.3 %; the target is 8 % and the
    previous default reached 3.5 % (it subtracted the simulator's default rolling-resistance
    moment, ≈ 40 N per corner, that this vehicle file does not state), so 3.0 % holds both
    the rolling-resistance fix and the innovation-driven switch of the ω̇ intensity."""
    assert pooled_fx_nrms("x07_brake_turn_dry_awd") <= 3.0


def test_fx_on_an_unlimited_log():
    """x10 (120 s mixed driving, FWD, no limiter chopping): measured 1.4 %; target 4 %; the
    previous default reached 2.4 %, mostly the same rolling-resistance bias, so 2.0 %."""
    assert pooled_fx_nrms("x10_mixed_drive_fwd") <= 2.0


# Measured with the online noise estimate and the torque-innovation switch (longitudinal.py,
# ukf_kernel; docs/methods.md): before them 9.2/11.8/9.7/4.3/5.1/5.2/2.3/5.1/3.5/1.4/4.1/5.1 %.
# Each bound is the measured figure plus about 0.5 point (never above the log's target:
# 8 % where a slip limiter chops the torque within a sample, x01–x04 and x07, 4 % elsewhere).
MEASURED_FX = {
    "x01_launch_snow_fwd": (4.9, 5.5),
    "x02_launch_ice_rwd": (5.8, 6.5),
    "x03_brake_ice_awd": (6.7, 7.2),
    "x04_brake_splitmu_rwd": (3.4, 4.0),
    "x05_sine_steer_dry_rwd": (2.1, 2.7),
    "x06_ramp_steer_wet_fwd": (2.3, 2.9),
    "x07_brake_turn_dry_awd": (2.05, 2.5),
    "x08_slalom_snow_awd": (2.1, 2.7),
    "x09_accel_turn_mu_drop_rwd": (2.05, 2.6),
    "x10_mixed_drive_fwd": (0.88, 1.3),
    "x11_stiffness_step_rwd": (2.7, 3.2),
    "x12_stiffness_friction_step_fwd": (3.2, 3.7),
}


@pytest.mark.parametrize("name", sorted(MEASURED_FX))
def test_fx_with_the_sensor_noise_estimated_from_the_log(name):
    """Every crossplant log within its F_x target with margin. The causes removed: the UKF
    assumed our simulator's sensors (σ_ω 0.42 rad/s, σ_T 5.7 N m) on σ_ω 0.06 rad/s,
    σ_T 20 N m, so it followed the torque noise (x05/x06/x08/x12: 5 %) and ignored the
    wheel speed; the noise levels are now estimated online, and the sharp ω then lets the
    torque-innovation switch follow limiter chops (x01–x03: 9–12 % → 5–7 %) and torque
    ramps (x11/x12). Bound = measured + ≈ 0.5 point."""
    measured, bound = MEASURED_FX[name]
    assert pooled_fx_nrms(name) <= bound, f"measured {measured} % at the change"
