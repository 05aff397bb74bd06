"""Algorithm 1 on the independent cross-plant tire-stiffness logs (../shared/crossplant).

The log is used without its ``ref_`` columns and with its vehicle file exactly as given (no
``[stiffness]``, no ``[suspension]``, nominal LuGre values only); ``ref_`` columns serve only
as truth here. Scored like ``stiffness_score.py``: mean |relative error| over the steady
windows [20, 30) and [40, 60) s, with the band |apparent/truth − 1| + 5 points (the
least-squares linear-tire stiffness of the logged forces, camber thrust included).
"""

import sys
from pathlib import Path

import pandas as pd
import pytest

from vestim.estimators.stiffness import estimate_stiffness
from vestim.io import load_vehicle

CROSSPLANT = Path(__file__).resolve().parents[3] / ".." / "shared" / "crossplant"
DATA = CROSSPLANT / "data"

pytestmark = pytest.mark.skipif(not (DATA / "x12_stiffness_friction_step_fwd.parquet").is_file(),
                                reason=f"cross-plant data not found at {DATA}")


def _score(name: str, vehicle: str, seed: int = 0) -> dict:
    sys.path.insert(0, str(CROSSPLANT))
    try:
        import stiffness_score  # the project's independent scorer, next to the data
    finally:
        sys.path.pop(0)
    truth = pd.read_parquet(DATA / f"{name}.parquet")
    log = truth[[c for c in truth.columns if not c.startswith("ref_")]]
    est = estimate_stiffness(log, load_vehicle(DATA / vehicle), seed=seed)
    res = stiffness_score.score_stiffness(est, truth, 30.0, [(20.0, 30.0), (40.0, 60.0)], 0.10)
    t = est["t"].to_numpy()
    before, after = (t >= 20) & (t < 30), (t >= 40) & (t < 60)
    for ch, r in res["channels"].items():
        v = est[ch].to_numpy()
        r["ratio"] = v[after].mean() / v[before].mean()
        r["truth_ratio"] = r["windows"]["40-60"]["truth_mean"] / r["windows"]["20-30"]["truth_mean"]
    return res["channels"]


@pytest.fixture(scope="module")
def x12():
    return _score("x12_stiffness_friction_step_fwd", "vehicle1.toml")


@pytest.fixture(scope="module")
def x11():
    return _score("x11_stiffness_step_rwd", "vehicle3.toml")


def _band(window: dict) -> float:
    return abs(window["apparent_over_truth"] - 1.0) + 0.05


@pytest.mark.parametrize("ch", ["stiffness_cy_f", "stiffness_cy_r"])
def test_lateral_level_before_the_change(x11, x12, ch):
    """Before the change both logs' lateral stiffness is inside its band: x11 cy_f 4.7 % (band
    10.7 %), cy_r 5.7 % (9.9 %); x12 cy_f 6.1 % (11.9 %), cy_r 9.9 % (17.5 %), seed 0 (seeds
    0–4: x11 3.7–6.2 %, x12 3.8–13.8 %, all inside). Before the cross-plant fixes they were
    38–44 % low (the generic suspension's roll factor 1.25 against the plant's 1.11–1.15, the
    IMU bias locking onto the start-up transient), then 9–12 % low while the generic upper
    bound 25 F_z /rad truncated the draws around the plant's 21.9 F_z /rad."""
    for res in (x11, x12):
        w = res[ch]["windows"]["20-30"]
        assert w["mean_abs_rel"] <= _band(w), (ch, w["mean_abs_rel"], _band(w))


def test_longitudinal_level_in_both_windows(x11, x12):
    """The driven axle's longitudinal slip stiffness is inside its band before and after the
    change: x11 cx_r 5.8 / 6.0 % (bands 10.7 / 11.1 %), x12 cx_f 5.5 / 9.6 % (11.0 / 12.7 %),
    seed 0 (seeds 0–4: 3.7–9.7 %, all inside). With the undriven axle's C^x tied to its
    cornering stiffness through the prior's ratio C^x/C^y = 2 (the plant's is ≈ 1) they were
    20–56 % low. x12's step ratio within ±0.05 here (0.572 against 0.599); x11's, and x12's
    window before the change, are tested over five seeds below."""
    for w in x11["stiffness_cx_r"]["windows"].values():
        assert w["mean_abs_rel"] <= _band(w), (w["mean_abs_rel"], _band(w))
    w = x12["stiffness_cx_f"]["windows"]["40-60"]
    assert w["mean_abs_rel"] <= _band(w), (w["mean_abs_rel"], _band(w))
    r = x12["stiffness_cx_f"]
    assert abs(r["ratio"] - r["truth_ratio"]) <= 0.05, r["ratio"]


def test_x12_front_longitudinal_level_before_the_change(x12):
    """x12's driven-axle C^x before the change inside its band (11.0 %) on at least 4 of seeds
    0–4: 5.5, 3.7, 4.0, 4.6, 8.6 % with the gyro look-ahead (Algorithm 1 as printed: 11.1, 10.5,
    6.1, 8.7, 3.0 %; the stack of constraints.txt). One seed is not a test of this filter: it
    amplifies rounding, so a seed moves by a point or two with the order its kernels were
    compiled in."""
    windows = [x12["stiffness_cx_f"]["windows"]["20-30"]]
    windows += [_score("x12_stiffness_friction_step_fwd", "vehicle1.toml", seed)
                ["stiffness_cx_f"]["windows"]["20-30"] for seed in range(1, 5)]
    inside = [w["mean_abs_rel"] <= _band(w) for w in windows]
    assert sum(inside) >= 4, [round(w["mean_abs_rel"], 4) for w in windows]


def test_x11_driven_axle_step_ratio(x11):
    """x11's rear (driven) C^x step after/before within ±0.05 of the truth 0.701 on at least 4
    of seeds 0–4: 0.666, 0.699, 0.676, 0.651, 0.659 with the gyro look-ahead (Algorithm 1 as
    printed: 0.648, 0.666, 0.722, 0.665, 0.704; the stack of constraints.txt): 4 % low on
    average, ±0.02 from seed to seed; a seed moves by about 0.01 with the order the kernels
    were compiled in."""
    ratios = [x11["stiffness_cx_r"]["ratio"]]
    for seed in range(1, 5):
        r = _score("x11_stiffness_step_rwd", "vehicle3.toml", seed)["stiffness_cx_r"]
        ratios.append(r["ratio"])
    truth = x11["stiffness_cx_r"]["truth_ratio"]
    assert sum(abs(r - truth) <= 0.05 for r in ratios) >= 4, [round(r, 3) for r in ratios]


def test_front_lateral_step_ratio(x11, x12):
    """The front cornering-stiffness step (after/before) is within ±0.05 of the truth: x11
    0.684 vs 0.699, x12 0.577 vs 0.599 (seed 0; seeds 0–4: 0.684–0.694 and 0.562–0.577).
    Before the cross-plant fixes: 0.91 and 0.90."""
    for res in (x11, x12):
        r = res["stiffness_cy_f"]
        assert abs(r["ratio"] - r["truth_ratio"]) <= 0.05, (r["ratio"], r["truth_ratio"])


def test_x11_levels_and_ratios(x11):
    """x11 (RWD Vanagon, stiffness × 0.7): every channel's steady windows inside their bands and
    the lateral ratios within ±0.05 (seed 0: cy_f 0.684, cy_r 0.660 against 0.70; seeds 0–4
    0.684–0.694 and 0.660–0.686; rear lateral after the change 3.9 % against a 7.5 % band).
    Seeds 0–4 meet the windows; the cx_r ratio is tested over five seeds above."""
    for ch, r in x11.items():
        if ch != "stiffness_cx_r":
            assert abs(r["ratio"] - r["truth_ratio"]) <= 0.05, (ch, r["ratio"], r["truth_ratio"])
        for w in r["windows"].values():
            assert w["mean_abs_rel"] <= _band(w), (ch, w["mean_abs_rel"], _band(w))


def test_x11_rear_lateral_reenters_within_5_s(x11):
    """After the change x11's rear cornering stiffness is back within ±10 % of the truth within
    5 s on seeds 0–4: 2.75, 3.84, 2.24, 2.11, 3.91 s with the gyro look-ahead (w_k conditioned
    on the next gyro sample, ``pf.alg1_kernel``). Algorithm 1 as printed: 8.44, 8.82, 3.98,
    3.78, 4.03 s: w_k is drawn from y_k, whose gyro row of d is zero, so the yaw dynamics
    (the only measurement of the front/rear split in a steering step) reached the statistics
    only through the particle weights of the next step."""
    enters = [x11["stiffness_cy_r"]["reconverge_enters_s"]]
    for seed in range(1, 5):
        enters.append(_score("x11_stiffness_step_rwd", "vehicle3.toml", seed)
                      ["stiffness_cy_r"]["reconverge_enters_s"])
    assert all(e is not None and e <= 5.0 for e in enters), enters


@pytest.mark.xfail(strict=True, reason="known miss (docs/results_stiffness.md): no channel stays "
                   "within 10 % from 5 s after the change on (excursions of 0.3-1 s at the "
                   "steering and torque steps until 27-30 s after the change)")
def test_full_verdict_x11(x11):
    """The whole target on x11: every channel's ratio within ±0.05, both windows in band,
    and within 10 % for good from at most 5 s after the change."""
    for r in x11.values():
        assert abs(r["ratio"] - r["truth_ratio"]) <= 0.05
        for w in r["windows"].values():
            assert w["mean_abs_rel"] <= _band(w)
        assert r["reconverge_stays_s"] is not None and r["reconverge_stays_s"] <= 5.0


def _score_ekf(name: str, vehicle: str) -> dict:
    sys.path.insert(0, str(CROSSPLANT))
    try:
        import stiffness_score
    finally:
        sys.path.pop(0)
    truth = pd.read_parquet(DATA / f"{name}.parquet")
    log = truth[[c for c in truth.columns if not c.startswith("ref_")]]
    est = estimate_stiffness(log, load_vehicle(DATA / vehicle), method="ekf")
    res = stiffness_score.score_stiffness(est, truth, 30.0, [(20.0, 30.0), (40.0, 60.0)], 0.10)
    t = est["t"].to_numpy()
    before, after = (t >= 20) & (t < 30), (t >= 40) & (t < 60)
    for ch, r in res["channels"].items():
        v = est[ch].to_numpy()
        r["ratio"] = v[after].mean() / v[before].mean()
        r["truth_ratio"] = r["windows"]["40-60"]["truth_mean"] / r["windows"]["20-30"]["truth_mean"]
    return res["channels"]


def test_ekf_meets_the_step_targets_on_x11():
    """The augmented-state EKF (002 Sec. V, the baseline of the verdict in
    docs/results_stiffness.md) on x11: every ratio within ±0.05 of the truth (measured 0.699 /
    0.697 / 0.698 against 0.701 / 0.699 / 0.701 for cx_r / cy_f / cy_r), every steady window
    inside its band (3.2–8.3 % against 7.5–11.1 %) and every channel back inside ±10 % within
    5 s of the change (first re-entry 0.1 / 1.1 / 1.7 s; Algorithm 1: cy_r 8.4–8.8 s on seeds 0
    and 1). Deterministic (no random draws). The gyro corrects the stiffness states through
    their covariance with ψ̇ at every step, which Algorithm 1's draw of w_k from y_k does not."""
    res = _score_ekf("x11_stiffness_step_rwd", "vehicle3.toml")
    for ch, r in res.items():
        assert abs(r["ratio"] - r["truth_ratio"]) <= 0.05, (ch, r["ratio"], r["truth_ratio"])
        for w in r["windows"].values():
            assert w["mean_abs_rel"] <= _band(w), (ch, w["mean_abs_rel"], _band(w))
        assert r["reconverge_enters_s"] is not None and r["reconverge_enters_s"] <= 5.0, \
            (ch, r["reconverge_enters_s"])


def test_ekf_step_ratios_and_reentry_on_x12():
    """EKF on x12 (μ 0.6 and stiffness × 0.6): ratios 0.569 / 0.593 / 0.590 against 0.599 /
    0.599 / 0.601 (Algorithm 1, seeds 0–4: cx_f 0.542–0.629, cy_r 0.538–0.616, three of
    fifteen outside ±0.05), first re-entry within 10 % 0.3 / 1.1 / 1.7 s. Its front cornering
    stiffness after the change is 6.4 % off against a 5.2 % band (Algorithm 1: 8.7–10.8 %), so
    that window is not asserted here (docs/results_stiffness.md, verdict)."""
    res = _score_ekf("x12_stiffness_friction_step_fwd", "vehicle1.toml")
    for ch, r in res.items():
        assert abs(r["ratio"] - r["truth_ratio"]) <= 0.05, (ch, r["ratio"], r["truth_ratio"])
        assert r["reconverge_enters_s"] is not None and r["reconverge_enters_s"] <= 5.0, \
            (ch, r["reconverge_enters_s"])
    w = res["stiffness_cy_f"]["windows"]["40-60"]
    assert 0.05 <= w["mean_abs_rel"] <= 0.08, w["mean_abs_rel"]
