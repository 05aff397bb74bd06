"""The [calibration] tables of a calibrated vehicle file: round trip, validation, and the
sensor corrections they imply."""

from __future__ import annotations

import math
import tomllib

import numpy as np
import pandas as pd
import pytest

from vestim.errors import VehicleFileError
from vestim.io.calibration import (
    Calibration,
    Identified,
    calibration_toml,
    corrected_log,
    parse_calibration,
)


def _cal() -> Calibration:
    return Calibration(
        {"wheels": {"radius_fl": Identified(0.34, 0.001, True, "x05: 40 s", "m"),
                    "radius_rr": Identified.not_excited(0.33, "no straight driving", "m")},
         "imu": {"bias_ax": Identified(0.05, 0.002, True, 'standstill "2 s"', "m/s^2"),
                 "accel_scale": Identified(0.98, 0.001, True, "standstill", "-")},
         "steering": {"steering_offset": Identified(0.01, 0.001, True, "straight", "rad")}},
        base="car.toml", sources=("a.parquet", "b.parquet"), vestim_version="0.1.0")


def test_round_trip_keeps_every_value_and_the_not_excited_ones():
    cal = _cal()
    back = parse_calibration(tomllib.loads(calibration_toml(cal))["calibration"])
    assert back.sources == cal.sources and back.base == "car.toml"
    assert back.get("wheels", "radius_fl") == cal.get("wheels", "radius_fl")
    ne = back.get("wheels", "radius_rr")
    assert ne is not None and not ne.excited and math.isnan(ne.sigma) and ne.value == 0.33
    assert back.excited("wheels", "radius_rr") is None
    assert back.get("imu", "bias_ax").evidence == 'standstill "2 s"'


@pytest.mark.parametrize(("table", "match"), [
    ({"wheels": {"radius_xx": 0.3}}, r"\[calibration.wheels\] unknown key\(s\) radius_xx"),
    ({"wheels": {"radius_fl": "big"}}, r"radius_fl = 'big' must be a number"),
    ({"wheels": {"sigma_radius_fl": 0.1}}, r"sigma_radius_fl without radius_fl"),
    ({"wheels": {"radius_fl": 0.3, "excited_radius_fl": True}}, r"needs a finite sigma"),
    ({"tyres": {}}, r"unknown key\(s\) tyres"),
])
def test_bad_tables_name_the_key(table: dict, match: str):
    with pytest.raises(VehicleFileError, match=match):
        parse_calibration(table)


def test_corrections_follow_the_file():
    """radius 0.34 against the file's 0.33 scales ω by 34/33; ax divided by the scale (its
    bias is reported, not applied); the steering offset subtracted; a not-excited radius
    changes nothing; input unchanged."""
    df = pd.DataFrame({"t": [0.0, 0.01], "omega_fl": [30.0, 30.0], "omega_rr": [30.0, 30.0],
                       "ax": [1.05, 0.05], "ay": [0.0, 0.0], "delta": [0.01, 0.02]})
    before = df.copy()
    out = corrected_log(df, _cal(), wheel_radius=0.33, steering_ratio=16.0)
    pd.testing.assert_frame_equal(df, before)
    np.testing.assert_allclose(out["omega_fl"], 30.0 * 0.34 / 0.33)
    np.testing.assert_array_equal(out["omega_rr"], 30.0)
    np.testing.assert_allclose(out["ax"], [1.05 / 0.98, 0.05 / 0.98], atol=1e-15)
    np.testing.assert_allclose(out["delta"], [0.0, 0.01], atol=1e-15)


def test_mounting_is_undone():
    """A sensor pitched 4° nose-down reads gravity partly on x; the correction puts it on z."""
    from vestim.io.channel_map import mounting_matrix

    g_body = np.array([0.0, 0.0, 9.81])
    r = mounting_matrix(0.0, 4.0, 0.0)  # sensor → body
    g_sensor = r.T @ g_body
    df = pd.DataFrame({"t": [0.0], "ax": [g_sensor[0]], "ay": [g_sensor[1]], "az": [g_sensor[2]]})
    cal = Calibration({"imu": {"mount_pitch": Identified(math.radians(4.0), 1e-4, True, "", "rad")}})
    out = corrected_log(df, cal, wheel_radius=0.33, steering_ratio=16.0)
    np.testing.assert_allclose(out[["ax", "ay", "az"]].to_numpy()[0], g_body, atol=1e-12)


def test_vehicle_file_with_calibration_loads(tmp_path):
    from pathlib import Path

    from vestim.io import load_vehicle

    base = (Path(__file__).resolve().parents[2] / "src" / "vestim" / "data" / "vehicles"
            / "hashemi_suv.toml").read_text(encoding="utf-8")
    p = tmp_path / "car.toml"
    p.write_text(base + "\n" + calibration_toml(_cal()), encoding="utf-8")
    veh = load_vehicle(p)
    assert veh.calibration is not None
    assert veh.calibration.excited("wheels", "radius_fl") == 0.34
    assert load_vehicle("hashemi_suv").calibration is None


def test_a_value_the_selection_rejected_is_not_applied_and_its_reason_round_trips():
    """Issue 31: ``used_<key> = false`` keeps the nominal value (``excited()`` None, ω not
    scaled); ``decision_<key>`` survives the round trip; a file written before the selection
    (no ``used_``) uses every excited value."""
    rejected = Identified(0.34, 0.001, True, "x05: 40 s", "m", used=False,
                          decision="nominal 0.33 m kept: 1.5σ ≤ 2σ")
    cal = Calibration({"wheels": {"radius_fl": rejected}})
    back = parse_calibration(tomllib.loads(calibration_toml(cal))["calibration"])
    assert back.get("wheels", "radius_fl") == rejected
    assert back.excited("wheels", "radius_fl") is None
    df = pd.DataFrame({"t": [0.0], "omega_fl": [30.0]})
    out = corrected_log(df, back, wheel_radius=0.33, steering_ratio=15.0)
    assert out["omega_fl"].iloc[0] == 30.0
    old = parse_calibration({"wheels": {"radius_fl": 0.34, "sigma_radius_fl": 0.001}})
    assert old.excited("wheels", "radius_fl") == 0.34
    with pytest.raises(VehicleFileError, match=r"used_radius_fl = 'no' must be true or false"):
        parse_calibration({"wheels": {"radius_fl": 0.34, "sigma_radius_fl": 0.001,
                                      "used_radius_fl": "no"}})
