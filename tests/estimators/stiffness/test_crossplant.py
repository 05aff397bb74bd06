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
    """Before the change both logs' lateral stiffness is inside its band: x11 cy_f 8.7 % (band
    10.7 %), cy_r 8.5 % (9.9 %); x12 cy_f 5.0 % (11.9 %), cy_r 5.2 % (17.5 %), seed 0 (seeds
    0–4: 4.0–10.1 %, all inside). Before the fix they were 38–44 % low (the generic suspension's
    roll factor 1.25 against the plant's 1.11–1.15, and the IMU bias locking onto the
    start-up transient)."""
    for res in (x11, x12):
        w = res[ch]["windows"]["20-30"]
        assert w["mean_abs_rel"] <= _band(w), (ch, w["mean_abs_rel"], _band(w))


def test_front_lateral_step_ratio(x11, x12):
    """The front cornering-stiffness step (after/before) is within ±0.05 of the truth: x11
    0.743 vs 0.699, x12 0.590 vs 0.599 (seed 0; seeds 0–4: 0.729–0.752, i.e. seed 2 misses
    by 0.003, and 0.583–0.618). Before
    the fix: 0.91 and 0.90."""
    for res in (x11, x12):
        r = res["stiffness_cy_f"]
        assert abs(r["ratio"] - r["truth_ratio"]) <= 0.05, (r["ratio"], r["truth_ratio"])


@pytest.mark.xfail(strict=True, reason="known miss (docs/results_stiffness.md): after the change "
                   "the rear cornering stiffness of x11 reads 7-11 % off (band 7.5 %), C^x "
                   "31-41 % low, and no channel stays within 10 % from 5 s after the change "
                   "on (excursions until 26-29 s)")
def test_full_verdict_x11(x11):
    """The whole target on x11: every channel's ratio within ±0.05, both windows in band,
    and within 10 % for good from at most 5 s after the change."""
    for r in x11.values():
        assert abs(r["ratio"] - r["truth_ratio"]) <= 0.05
        for w in r["windows"].values():
            assert w["mean_abs_rel"] <= _band(w)
        assert r["reconverge_stays_s"] is not None and r["reconverge_stays_s"] <= 5.0
