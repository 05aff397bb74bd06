"""The reference filter's wheel-slip model on independent data (issue 11).

Each wheel's speed is corrected for its expected slip μ_x/C (C = 20, ReferenceParams.
slip_bias) and trusted with a σ of 100 % of that slip (k_mu). The earlier σ = |μ_x| v (k_mu
= 1, no correction) de-weighted every wheel while braking, and v_x became the a_x integral.
"""

from dataclasses import replace
from pathlib import Path

import numpy as np
import pandas as pd
import pytest

from vestim.estimators.velocity.reference import ReferenceParams
from vestim.io import load_vehicle
from vestim.pipeline import Pipeline, PipelineConfig
from vestim.sim import get_maneuver, simulate

SHARED = Path(__file__).resolve().parents[3].parent / "shared"
XP = SHARED / "crossplant" / "data"
RAV4 = SHARED / "real" / "comma2k19_rav4"


def _measured(log: pd.DataFrame) -> pd.DataFrame:
    return log[[c for c in log.columns if not c.startswith(("ref_", "_"))]]


def _run(log: pd.DataFrame, vehicle: str, **reference: float) -> np.ndarray:
    """CG v_x (m/s) of the default pipeline with ``reference`` changed from the defaults."""
    cfg = PipelineConfig(reference=replace(ReferenceParams(), **reference))
    return Pipeline(load_vehicle(vehicle), cfg).run(_measured(log))["vx"].to_numpy()


def _nrms(vx: np.ndarray, log: pd.DataFrame, skip: float = 0.0) -> float:
    """CG v_x NRMS, % of the largest |v_x|, from ``skip`` s on."""
    keep = log["t"].to_numpy() >= skip
    ref = log["ref_vx"].to_numpy()[keep]
    return float(100 * np.sqrt(np.mean((vx[keep] - ref) ** 2)) / np.abs(ref).max())


@pytest.mark.skipif(not RAV4.exists(), reason=f"RAV4 log not found at {RAV4}")
def test_rav4_vx_within_target_without_gnss() -> None:
    """Real RAV4 log without torques or gnss_speed: v_x RMSE ≤ 0.155 m/s (the issue's target,
    the mean wheel speed's 0.156 less its rounding; measured 0.142). Its remaining error is the
    file's loaded radius (the mean wheel speed reads 0.15 m/s low at cruise), which only
    gnss_speed can find. The slip-free model (k_mu 1, no correction) has 0.243 (0.255 with the
    20 N m torque dead zone alone)."""
    log = pd.read_parquet(RAV4 / "seg40.parquet").drop(columns=["gnss_speed"])
    ref = log["ref_vx"].to_numpy()

    def rmse(vx: np.ndarray) -> float:
        return float(np.sqrt(np.mean((vx - ref) ** 2)))

    assert rmse(_run(log, str(RAV4 / "vehicle.toml"))) <= 0.155
    assert rmse(_run(log, str(RAV4 / "vehicle.toml"), k_mu=1.0, slip_bias=0.0)) > 0.2  # before


@pytest.mark.skipif(not XP.exists(), reason=f"crossplant data not found at {XP}")
@pytest.mark.parametrize(("name", "vehicle", "without"), [
    ("x04_brake_splitmu_rwd", "vehicle3.toml", 0.23),
    ("x07_brake_turn_dry_awd", "vehicle3_awd.toml", 0.46)])
def test_expected_slip_correction_on_crossplant_braking(name: str, vehicle: str,
                                                        without: float) -> None:
    """Braking on every wheel (x07 AWD on dry at 4 m/s² in a turn, x04 3 m/s² on split
    μ 0.2 / 0.9): all wheels read slow by their slip, so with the same σ and no correction
    the CG v_x follows them (NRMS ``without`` %, measured); removing μ_x/C with the prior
    C = 20 brings it under 0.1 % (measured 0.06 and 0.05 %; x07 0.02 and, without the
    correction, 0.38 % before the r-coupled covariance of issue 29, 0.42 % before issue 31's
    wheel evidence). The plant's PAC2002
    tire is not the prior's."""
    log = pd.read_parquet(XP / f"{name}.parquet")
    assert _nrms(_run(log, str(XP / vehicle)), log, 0.5) < 0.1
    without_correction = _nrms(_run(log, str(XP / vehicle), slip_bias=0.0), log, 0.5)
    assert without_correction == pytest.approx(without, abs=0.03)


def test_steady_drive_torque_does_not_bias_vx() -> None:
    """Our simulator's AWD lane change on wet at 19.4 m/s: every wheel carries ≈ 50 N m of
    drive torque against the drag. Above the 20 N m noise floor of the torque dead zone the
    slip-signed inflation was on all the time, and on noise-sized innovations (σ ≈ 0.15 m/s
    a sample) it de-weighted the wheels reading above v̂_x and not those below: CG v_x NRMS
    1.25 % (−0.3 m/s). With the dead zone at 5 % of the static wheel load (92 N m for this
    SUV) it is ≤ 0.2 % (measured 0.08 %). Without the dead zone it is 0.63 % (1.25 % before
    issue 31's soft gate, which now also de-weights part of the wheels it had trusted)."""
    log = simulate(get_maneuver("lc_wet", tire="lugre", drivetrain="awd"),
                   load_vehicle("hashemi_suv"), seed=1)
    assert _nrms(_run(log, "hashemi_suv"), log) <= 0.2
    assert _nrms(_run(log, "hashemi_suv", torque_dead_mu=0.0), log) > 0.5  # the bias removed
