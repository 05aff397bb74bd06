"""Issue 31's selection of calibrated values (``vestim.design.calibrate.select``): the two
tests in closed form, then the figures on independent data (../shared/crossplant)."""

from __future__ import annotations

import json
from dataclasses import replace
from pathlib import Path

import numpy as np
import pandas as pd
import pytest

from vestim.design.calibrate import calibrate
from vestim.design.calibrate.select import K_SIGMA, Fold, couple, decide, nominal_values
from vestim.io import load_vehicle
from vestim.io.calibration import Identified
from vestim.pipeline import Pipeline

DATA = Path(__file__).resolve().parents[2] / ".." / "shared" / "crossplant" / "data"


def _v(value: float, sigma: float) -> Identified:
    return Identified(value, sigma, True, "test", "N/rad")


def test_a_value_within_k_sigma_of_the_nominal_keeps_the_nominal():
    """|1.15 − 1| / 0.1 = 1.5σ ≤ 2σ: the logs do not show the nominal is wrong, whatever
    the folds say."""
    good = [Fold(_v(1.15, 0.1), _v(1.15, 0.1))] * 2
    out = decide("cy_f", _v(1.15, 0.1), 1.0, good)
    assert not out.used and "within 1.5σ ≤ 2σ" in out.decision
    assert K_SIGMA == 2.0


def test_held_out_residuals_decide_a_significant_value():
    """Value 1.5 ± 0.1 (5σ from nominal 1). Folds whose held-out logs find 1.5 ± 0.1 from
    training values 1.45, 1.55: χ² (0.5² + 0.5²) = 0.5 against the nominal's 25 + 25 = 50:
    used. Held-out logs that find 1.0 (the value is one manoeuvre's): χ² 2·(4.5² … 5.5²)
    against 0: the nominal stays. A training set that did not excite it predicts with the
    nominal (equal χ²: not an improvement); no scored fold: the nominal stays."""
    used = decide("cy_f", _v(1.5, 0.1), 1.0, [Fold(_v(1.45, 0.1), _v(1.5, 0.1)),
                                               Fold(_v(1.55, 0.1), _v(1.5, 0.1))])
    assert used.used and "held-out χ² 0.5 against the nominal's 50 (2 folds)" in used.decision
    other = decide("cy_f", _v(1.5, 0.1), 1.0, [Fold(_v(1.45, 0.1), _v(1.0, 0.1)),
                                                Fold(_v(1.55, 0.1), _v(1.0, 0.1))])
    assert not other.used and "nominal 1 N/rad kept" in other.decision
    lone = decide("cy_f", _v(1.5, 0.1), 1.0,
                  [Fold(Identified.not_excited(1.0, "straight", "N/rad"), _v(1.5, 0.1)),
                   Fold(_v(1.5, 0.1), Identified.not_excited(1.0, "straight", "N/rad"))])
    assert not lone.used and "held-out χ² 25 against the nominal's 25 (1 fold)" in lone.decision
    none = decide("cy_f", _v(1.5, 0.1), 1.0, [])
    assert not none.used and "no held-out log excites it" in none.decision
    reported = decide("gnss_latency", _v(0.1, 0.01), None, [])
    assert reported.used and reported.decision.startswith("reported only")


def test_kappa_y_follows_the_cornering_stiffness_it_implies():
    """σ0y/κy is the Pipeline's cornering-stiffness prior unless cy_f and cy_r are used: a
    κ_y that passed its own tests is not used where cy_f was refused (the back door of the
    campaign's s1_021: κ_y 4.0 against 12, v_y 0.090 → 0.185 m/s), and is where both are
    used."""
    ky = Identified(4.0, 0.04, True, "fit", "1/m", used=True, decision="used: 200σ")
    cy = Identified(9e4, 1e3, True, "fit", "N/rad", used=True, decision="used")
    refused = couple({"kappa_y": ky, "cy_f": replace(cy, used=False), "cy_r": cy})
    assert not refused["kappa_y"].used and "cy_f (its direct" in refused["kappa_y"].decision
    assert couple({"kappa_y": ky, "cy_f": cy, "cy_r": cy})["kappa_y"].used


needs_data = pytest.mark.skipif(not (DATA / "manifest.json").is_file(),
                                reason=f"crossplant data not found at {DATA}")


def _log(prefix: str) -> pd.DataFrame:
    man = json.loads((DATA / "manifest.json").read_text())["maneuvers"]
    return pd.read_parquet(DATA / next(v["file"] for k, v in man.items() if k.startswith(prefix)))


@needs_data
def test_x09_no_longer_worse_with_the_file_calibrated_from_x02_and_x05():
    """Issue 31 on independent data: x09 (accelerating turn into a friction drop, RWD,
    vehicle2) scored with vehicle2 calibrated from x02 and x05. Every excited value used:
    v_y RMSE 0.036 → 0.059 m/s (docs/results.md, the cornering stiffness x05's sine steer
    finds, 117 kN/rad against the nominal prior's 88, is not seen on x02: no held-out
    evidence). With the selection the stiffness stays nominal and v_y is within the issue's
    0.005 m/s of the nominal file's."""
    result = calibrate([_log("x02"), _log("x05")], str(DATA / "vehicle2.toml"))
    for key in ("cy_f", "cy_r"):
        v = result.values[key]
        assert v.excited and not v.used, v.decision
    log = _log("x09")
    meas = log[[c for c in log.columns if not c.startswith("ref_")]]
    keep = log["t"].to_numpy() >= 0.5

    def vy_rmse(veh) -> float:
        est = Pipeline(veh).run(meas)
        return float(np.sqrt(np.mean((est["vy"].to_numpy() - log["ref_vy"].to_numpy())[keep] ** 2)))

    nominal = vy_rmse(load_vehicle(str(DATA / "vehicle2.toml")))
    assert vy_rmse(result.vehicle) <= nominal + 0.005


@needs_data
def test_nominal_values_are_what_the_estimators_use_without_a_calibration():
    """vehicle2's cornering-stiffness prior σ0y/κy = 15 per unit load on the static axle
    loads m·g·l_r/L, m·g·l_f/L; the radii are [vehicle] wheel_radius."""
    veh = load_vehicle(str(DATA / "vehicle2.toml"))
    nom = nominal_values(veh)
    b, t = veh.body, veh.tire
    front = b.mass * 9.81 * b.lr / (b.lf + b.lr)
    assert nom["cy_f"] == pytest.approx(t.sigma0_y / t.kappa_y * front, rel=1e-12)
    assert nom["radius_rl"] == b.wheel_radius and nom["steering_offset"] == 0.0


RAV4 = Path(__file__).resolve().parents[2] / ".." / "shared" / "real" / "comma2k19_rav4"
needs_rav4 = pytest.mark.skipif(not (RAV4 / "seg40.parquet").is_file(),
                                reason=f"RAV4 log not found at {RAV4}")


def _rav4_vx_rmse() -> tuple[float, float]:
    """v_x RMSE (m/s) of the RAV4 log estimated without gnss_speed, nominal and with the
    file calibrated (with the selection) from seg40 itself."""
    log = pd.read_parquet(RAV4 / "seg40.parquet")
    meas = log[[c for c in log.columns if not c.startswith("ref_")]]
    result = calibrate([meas], str(RAV4 / "vehicle.toml"), names=["seg40"])
    for c in ("fl", "fr", "rl", "rr"):  # both halves find the same 0.86 % scale: used
        assert result.values[f"radius_{c}"].used, result.values[f"radius_{c}"].decision
    nognss = meas.drop(columns=["gnss_speed"])

    def rmse(veh) -> float:
        est = Pipeline(veh).run(nognss)
        e = np.interp(log["t"], est["t"], est["vx"]) - log["ref_vx"]
        return float(np.sqrt(np.mean(e ** 2)))

    return rmse(load_vehicle(str(RAV4 / "vehicle.toml"))), rmse(result.vehicle)


@needs_rav4
def test_rav4_vx_with_the_selected_calibration():
    """The real car (independent data): nominal 0.142 m/s, calibrated 0.070 m/s: the wheel
    scale from gnss_speed is kept by the selection, so nothing of issue 13's gain is lost."""
    nominal, calibrated = _rav4_vx_rmse()
    assert nominal == pytest.approx(0.142, abs=0.005)
    assert calibrated <= 0.075


@needs_rav4
@pytest.mark.xfail(strict=True, reason="issue 31's target 0.06 m/s is missed: 0.070 m/s (see "
                   "docs/calibration.md: the remainder is not a calibration error)")
def test_rav4_vx_target_0p06():
    assert _rav4_vx_rmse()[1] <= 0.06
