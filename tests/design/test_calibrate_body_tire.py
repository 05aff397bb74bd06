"""Body and tire identification of ``vestim calibrate`` (:mod:`vestim.design.calibrate.body_tire`).

Cross-plant (commonroad MB, PAC2002 tires; /work/shared/crossplant/data), HOLD-OUT: each
vehicle file is calibrated from its logs other than the one scored, never from ``ref_``
columns (the identification drops them; one test proves it by dropping them itself and by
poisoning them). Truth, computed here only:

* roll gradient: ``ref_roll`` regressed on the true lateral acceleration of the scored log,
  a_y = cos φ·ay_m − sin φ·az_m (the plant's IMU rotates the heading-frame specific force
  into the rolled body, mbplant.Plant.imu; this inverts it exactly). Target 15 %.
* axle cornering stiffness: PAC2002 C_y = F_z·|p_ky1| unscaled (mbplant.scaled_tire), so the
  axle sum is |p_ky1| × the static axle load m g l_r/L (front), m g l_f/L (rear), with
  p_ky1 = −21.92 for all three CommonRoad parameter sets (checked below against x11/x12's
  ``ref_stiffness_cy_*``/ΣF_z). Target 10 %.
"""

from __future__ import annotations

import json

import numpy as np
import pandas as pd
import pytest

from tests._paths import CROSSPLANT_DATA
from vestim.constants import G
from vestim.design.calibrate.body_tire import identify_body, identify_tires
from vestim.errors import LogFormatError
from vestim.estimators.stiffness.config import StiffnessPrior
from vestim.io import load_vehicle
from vestim.io.vehicle import Vehicle
from vestim.sim import simulate

DATA = CROSSPLANT_DATA
P_KY1 = 21.92  # |p_ky1| of commonroad-vehicle-models 3.0.2 parameters_vehicle1/2/3
P_KX = 22.29  # C_x/F_z of the same tire at κ = 0 (x11/x12 ref_stiffness_cx over ΣF_z, checked)
needs_data = pytest.mark.skipif(not (DATA / "manifest.json").exists(),
                                reason="crossplant data not available")


@pytest.fixture(scope="module")
def crossplant() -> dict[str, tuple[pd.DataFrame, str]]:
    man = json.loads((DATA / "manifest.json").read_text())["maneuvers"]
    out = {}
    for key, m in man.items():
        log = pd.read_parquet(DATA / m["file"])
        log.attrs["name"] = key[:3]
        out[key[:3]] = (log, m["vehicle_file"])
    return out


def _holdout(crossplant: dict[str, tuple[pd.DataFrame, str]], scored: str
             ) -> tuple[list[pd.DataFrame], Vehicle]:
    vf = crossplant[scored][1]
    others = [log for k, (log, v) in crossplant.items() if v == vf and k != scored]
    return others, load_vehicle(str(DATA / vf))


def _true_roll_gradient(log: pd.DataFrame) -> float:
    phi = log["ref_roll"].to_numpy()
    ay = np.cos(phi) * log["ay"].to_numpy() - np.sin(phi) * log["az"].to_numpy()
    return float(np.polyfit(ay, phi, 1)[0])


# Measured hold-out roll-gradient errors (this implementation): x05 −2 %, x06 0 %, x07 +1 %,
# x08 +7 %, x09 +2 %, x10 +1 %, x12 +2 %; x11 (vehicle3) has only the straight x04 to learn
# from: not excited (tested below).
@needs_data
@pytest.mark.parametrize("scored", ["x05", "x06", "x07", "x08", "x09", "x10", "x12"])
def test_roll_gradient_holdout_within_15_percent(crossplant, scored: str) -> None:  # type: ignore[no-untyped-def]
    others, veh = _holdout(crossplant, scored)
    res = identify_body(others, veh)["roll_gradient"]
    truth = _true_roll_gradient(crossplant[scored][0])
    assert res.excited, res.evidence
    assert res.value == pytest.approx(truth, rel=0.15), (res.value, truth)
    assert 0 < res.sigma < 0.1 * res.value


def _true_pitch_gradient(log: pd.DataFrame) -> float:
    """c_θ = −θ/a_x with the heading-frame a_x = cos θ·ax_m + sin θ·(sin φ·ay_m + cos φ·az_m)."""
    th, phi = log["ref_pitch"].to_numpy(), log["ref_roll"].to_numpy()
    fz1 = np.sin(phi) * log["ay"].to_numpy() + np.cos(phi) * log["az"].to_numpy()
    ax = np.cos(th) * log["ax"].to_numpy() + np.sin(th) * fz1
    return -float(np.polyfit(ax, th, 1)[0])


def _axle_truth(veh: Vehicle, axle: str) -> float:
    b = veh.body
    arm = b.lr if axle == "f" else b.lf
    return P_KY1 * b.mass * G * arm / (b.lf + b.lr)


@needs_data
def test_pac2002_constant_matches_the_plant_truth(crossplant) -> None:  # type: ignore[no-untyped-def]
    """|p_ky1| = 21.92 and C_x/F_z = 22.29: x11/x12's ref_stiffness over the axle load,
    before the change (C ∝ F_z in this PAC2002 subset)."""
    for k in ("x11", "x12"):
        log = crossplant[k][0]
        e = log[log["t"] < 30]
        for a in "fr":
            fz = e[f"ref_fz_{a}l"] + e[f"ref_fz_{a}r"]
            assert float((e[f"ref_stiffness_cy_{a}"] / fz).mean()) == pytest.approx(P_KY1, rel=1e-6)
            assert float((e[f"ref_stiffness_cx_{a}"] / fz).mean()) == pytest.approx(P_KX, rel=1e-3)


# Measured hold-out ratios identified/truth (front, rear): x04 0.962/1.006, x06 0.922/1.007,
# x09 0.914/0.899, x10 0.933/1.018, x12 0.905/0.995, x07 0.677/0.729. Not excited (tested
# below): x05 (x09: one steer-in), x08 (x07: 2 s of linear cornering), x11 (x04: straight).
# Misses, strict xfail with the figure and the reason:
_CY_MISS = {
    ("x07", "f"): "0.677: vehicle3_awd learns from x08 only (snow μ 0.3, a_y to 86 % of μg): "
                  "the fit rises as the |a_y| range shrinks (0.68, 0.73, 0.75 at 3, 1.5, "
                  "0.75 m/s²) but never by the 2σ + 5 % that would stop it at a smaller range",
    ("x07", "r"): "0.729: same (x08 only: snow, non-linear range)",
    ("x09", "r"): "0.899: vehicle2 learns from x05 only (8 s of 0.5 Hz sine steer); 0.1 % "
                  "outside the target",
}
_CY_CASES = [(k, a) for k in ("x04", "x06", "x07", "x09", "x10", "x12") for a in "fr"]


@needs_data
@pytest.mark.parametrize(("scored", "axle"), [
    pytest.param(k, a, marks=pytest.mark.xfail(strict=True, reason=_CY_MISS[(k, a)]))
    if (k, a) in _CY_MISS else (k, a) for k, a in _CY_CASES])
def test_cornering_stiffness_holdout_within_10_percent(crossplant, scored: str, axle: str) -> None:  # type: ignore[no-untyped-def]
    others, veh = _holdout(crossplant, scored)
    res = identify_tires(others, veh, lugre=False)[f"cy_{axle}"]
    truth = _axle_truth(veh, axle)
    assert res.excited, res.evidence
    assert res.value == pytest.approx(truth, rel=0.10), res.value / truth


# No brief target for C_x; this test holds 15 %: the cornering target (10 %) plus the plant's
# own apparent/truth gap of a linear C_x fit (0.94, crossplant README). Measured hold-out:
# x10 1.060 (from x06, x12's dry half), x12 0.880 (from x06, x10), x04 1.102 (from x11's dry
# half: vehicle3's only driving log).
@needs_data
@pytest.mark.parametrize(("scored", "axle"), [("x10", "f"), ("x12", "f"), ("x04", "r")])
def test_longitudinal_stiffness_holdout_within_15_percent(crossplant, scored: str, axle: str) -> None:  # type: ignore[no-untyped-def]
    others, veh = _holdout(crossplant, scored)
    res = identify_tires(others, veh, lugre=False)[f"cx_{axle}"]
    b = veh.body
    truth = P_KX * b.mass * G * (b.lr if axle == "f" else b.lf) / (b.lf + b.lr)
    assert res.excited, res.evidence
    assert res.value == pytest.approx(truth, rel=0.15), res.value / truth
    # the undriven axle has no free-rolling reference: not excited, base kept
    other = identify_tires(others, veh, lugre=False)["cx_r" if axle == "f" else "cx_f"]
    assert not other.excited and "not driven" in other.evidence


@needs_data
@pytest.mark.parametrize("scored", ["x05", "x08"])
def test_too_little_cornering_is_not_excited(crossplant, scored: str) -> None:  # type: ignore[no-untyped-def]
    """x05's hold-out has x09 (one steer-in, then steady: the axles are not separated to
    10 %), x08's has x07 (2 s of cornering below 3 m/s² before the braking): not excited."""
    others, veh = _holdout(crossplant, scored)
    res = identify_tires(others, veh, lugre=False)
    prior = StiffnessPrior.for_vehicle(veh).nominal
    for key, base in (("cy_f", prior[2]), ("cy_r", prior[3])):
        assert not res[key].excited and res[key].value == base and res[key].evidence


@needs_data
def test_straight_line_logs_do_not_excite_cornering_or_roll(crossplant) -> None:  # type: ignore[no-untyped-def]
    """vehicle3 scored on x11 learns from x04 only (straight split-μ braking, |a_y| ≤ 0.2):
    cornering stiffness and roll gradient are "not excited" and keep the base values; the
    AWD vehicle has no free-rolling axle for a slip stiffness."""
    others, veh = _holdout(crossplant, "x11")
    body = identify_body(others, veh)
    tires = identify_tires(others, veh, lugre=False)
    for res in (body["roll_gradient"], tires["cy_f"], tires["cy_r"]):
        assert not res.excited and np.isnan(res.sigma) and res.evidence
    assert "no cornering" in tires["cy_f"].evidence
    assert "|ay| reaching" in body["roll_gradient"].evidence
    awd, veh_awd = _holdout(crossplant, "x07")
    t_awd = identify_tires(awd, veh_awd, lugre=False)
    assert not t_awd["cx_f"].excited and "free-rolling" in t_awd["cx_f"].evidence


def test_bad_time_column_is_a_clear_error() -> None:
    log = simulate("step_steer", seed=1)
    veh = load_vehicle("hashemi_suv")
    with pytest.raises(LogFormatError, match="'t'"):
        identify_body([log.drop(columns=["t"])], veh)
    t = log["t"].to_numpy().copy()
    t[10] = t[9]
    swapped = log.assign(t=t)
    with pytest.raises(LogFormatError, match="row 10"):
        identify_tires([swapped], veh, lugre=False)


@needs_data
def test_ref_columns_are_never_read(crossplant) -> None:  # type: ignore[no-untyped-def]
    """Same result with the ref_ columns dropped and with them replaced by garbage."""
    others, veh = _holdout(crossplant, "x06")
    dropped = [log[[c for c in log.columns if not c.startswith("ref_")]] for log in others]
    poisoned = [log.assign(**{c: 1e6 for c in log.columns if c.startswith("ref_")})
                for log in others]
    for d, p in zip(dropped, poisoned, strict=True):
        d.attrs = dict(others[0].attrs)
        p.attrs = dict(others[0].attrs)
    ref = {**identify_body(others, veh), **identify_tires(others, veh, lugre=False)}
    for logs in (dropped, poisoned):
        got = {**identify_body(logs, veh), **identify_tires(logs, veh, lugre=False)}
        for k, v in ref.items():
            assert got[k].value == pytest.approx(v.value, rel=1e-12), k


def test_own_simulator_recovers_stiffness_and_roll_within_2_sigma() -> None:
    """vestim.sim's stiffness_study (hashemi_suv): C_y per axle 138.8 kN/rad until 30 s,
    then half (the road changes); the identification cuts the log at the change and recovers
    the first level (measured 134.5 ± 4.1 and 134.6 ± 4.0 kN/rad: 1.0 σ, 1.0 σ). Roll
    gradient against ref_roll on a_y (measured 3.006e-3 ± 0.08e-3 vs 2.981e-3); pitch
    gradient against −ref_pitch on a_x (measured 4.16e-3 ± 0.16e-3 vs 4.08e-3)."""
    log = simulate("stiffness_study", seed=1)
    veh = load_vehicle("hashemi_suv")
    tires = identify_tires([log], veh, lugre=False)
    t = log["t"].to_numpy()
    for a in "fr":
        truth = float(log[f"ref_stiffness_cy_{a}"].to_numpy()[t < 30].mean())
        res = tires[f"cy_{a}"]
        assert res.excited, res.evidence
        assert abs(res.value - truth) <= 2 * res.sigma, (res.value, res.sigma, truth)
        assert res.sigma < 0.05 * truth
        assert "cut" in res.evidence
    body = identify_body([log], veh)
    roll = body["roll_gradient"]
    truth = _true_roll_gradient(log)
    assert roll.excited
    assert abs(roll.value - truth) <= 2 * roll.sigma, (roll.value, roll.sigma, truth)
    pitch = body["pitch_gradient"]
    truth = _true_pitch_gradient(log)
    assert pitch.excited
    assert abs(pitch.value - truth) <= 2 * pitch.sigma, (pitch.value, pitch.sigma, truth)


@pytest.mark.xfail(strict=True, reason="lc_wet (μ 0.5, a_y to 4.8 m/s²): 100 ± 4.1 vs 138 kN/rad "
                   "(front), 9 σ low and called excited: 6 s of a wet lane change whose "
                   "smaller |a_y| ranges do not determine the fit, so the linearity test "
                   "cannot stop it; the secant of the saturating tire is read as stiffness")
def test_own_simulator_wet_lane_change_within_2_sigma() -> None:
    log = simulate("lc_wet", seed=1)
    res = identify_tires([log], load_vehicle("hashemi_suv"), lugre=False)["cy_f"]
    truth = float(log["ref_stiffness_cy_f"].mean())
    assert not res.excited or abs(res.value - truth) <= 2 * res.sigma, (res.value, res.sigma)


@pytest.mark.xfail(strict=True, reason="cx_f 183 ± 9.9 kN vs the 222 kN tangent: 3.9 σ low. On "
                   "the same samples the plant's own F_x against its true slip gives 199 kN "
                   "(curvature, combined slip), the rest is the slip estimate from the free axle")
def test_own_simulator_longitudinal_stiffness_within_2_sigma() -> None:
    """stiffness_study (FWD, free rear axle): C_x,f before the 30 s road change."""
    log = simulate("stiffness_study", seed=1)
    veh = load_vehicle("hashemi_suv").with_drivetrain("fwd")
    res = identify_tires([log], veh, lugre=False)["cx_f"]
    t = log["t"].to_numpy()
    truth = float(log["ref_stiffness_cx_f"].to_numpy()[t < 30].mean())
    assert res.excited, res.evidence
    assert abs(res.value - truth) <= 2 * res.sigma, (res.value, res.sigma, truth)


def test_lugre_values_come_from_fit_lugre_from_log() -> None:
    """A launch on ice (own simulator, lugre tire) excites C_x, hence κ_x; σ1 and α are
    transient-only: not excited, base kept."""
    veh = load_vehicle("hashemi_suv")
    log = simulate("accel_brake", seed=3)
    res = identify_tires([log], veh)
    assert not res["sigma1_x"].excited and res["sigma1_x"].value == veh.tire.sigma1_x
    assert not res["alpha"].excited and res["alpha"].value == veh.tire.alpha
    assert not res["sigma0_x"].excited
    k = res["kappa_x"]
    assert k.excited, k.evidence
    assert 0 < k.sigma < 0.2 * k.value
