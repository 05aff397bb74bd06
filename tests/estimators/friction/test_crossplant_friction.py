"""Road friction potential on the independent crossplant logs (../shared/crossplant: the MB
plant with PAC2002 tires, vehicle files as given, measured channels only).

Issue 13's figures: where a tire is flagged excited, μ̂ within 0.1 of ``ref_mu_*``; the
x09 drop (0.8 → 0.3) detected within 1 s of the tire first using 80 % of the new friction.
Measured with the default pipeline (per log: share of corner-samples flagged, largest
|μ̂ − μ| where flagged): x01 1.1 % / 0.052, x02 15.1 % / 0.090, x03 1.0 % / 0.040,
x04 2.3 % / 0.044, x09 0.6 % / 0.063, x06 (wet ramp steer) 637 corner-samples / 0.046 since
the lateral filter's re-acquisition (issue 29; 0.123 before, with v_y 0.4 m/s off), x05 x08
x10 x11 x12 never flagged (x10 was flagged at 5–7 m/s with slip angles 2–4° off, 0.733). Miss:
x07 (0.186: the rear-left force is estimated 0.13 low in the braking turn, and μ̂ with it).
"""

from __future__ import annotations

import json
from functools import cache
from pathlib import Path

import numpy as np
import pandas as pd
import pytest

from vestim.constants import CORNERS
from vestim.io import load_vehicle
from vestim.pipeline import Pipeline

DATA = Path(__file__).resolve().parents[3] / ".." / "shared" / "crossplant" / "data"
pytestmark = pytest.mark.skipif(not (DATA / "manifest.json").is_file(),
                                reason=f"crossplant data not found at {DATA}")


@cache
def _run(prefix: str) -> tuple[pd.DataFrame, pd.DataFrame]:
    manifest = json.loads((DATA / "manifest.json").read_text())["maneuvers"]
    name = next(k for k in manifest if k.startswith(prefix))
    log = pd.read_parquet(DATA / manifest[name]["file"])
    veh = load_vehicle(DATA / manifest[name]["vehicle_file"])
    est = Pipeline(veh).run(log[[c for c in log.columns if not c.startswith("ref_")]])
    return log, est


def _flagged_errors(prefix: str) -> np.ndarray:
    log, est = _run(prefix)
    mu = est[[f"mu_{c}" for c in CORNERS]].to_numpy()
    ex = est[[f"mu_{c}_excited" for c in CORNERS]].to_numpy() > 0
    ref = log[[f"ref_mu_{c}" for c in CORNERS]].to_numpy()
    assert np.all(np.isnan(mu[~ex])), "μ must be NaN wherever the tire is not flagged"
    return np.abs(mu - ref)[ex]


@pytest.mark.parametrize("prefix", ["x01", "x02", "x03", "x04", "x06", "x09"])
def test_where_excited_mu_is_within_0_1(prefix: str):
    err = _flagged_errors(prefix)
    assert err.size > 0, "the log saturates tires; the stage must flag some samples"
    assert err.max() <= 0.1


@pytest.mark.parametrize("prefix", ["x05", "x08", "x12"])
def test_tires_in_their_linear_range_give_no_friction(prefix: str):
    """x05/x08/x12 keep every tire below 50 % of its friction (x12: 0.28 of 0.6): μ cannot be
    told from them, and must be NaN (unknown), never a guess near the used friction."""
    assert _flagged_errors(prefix).size == 0


def test_x09_drop_detected_within_1_s_on_the_spinning_wheel():
    """x09: friction falls 0.8 → 0.3 at 6.7 s; the driven rear-left wheel first uses 80 % of
    the new friction at 6.69 s and is flagged with μ̂ within 0.1 of 0.3 at 6.74 s (0.05 s).
    The front wheels (1° of slip angle at 90 % use) are not flagged at all: that slip angle is
    not resolved by the estimates (0.2°)."""
    log, est = _run("x09")
    t = log["t"].to_numpy()
    ref = log["ref_mu_rl"].to_numpy()
    used = np.hypot(log["ref_fx_rl"], log["ref_fy_rl"]).to_numpy() / log["ref_fz_rl"].to_numpy()
    drop = t[np.argmax(ref <= 0.3 + 1e-9)]
    first_use = t[np.argmax((t >= drop) & (used >= 0.8 * 0.3))]
    ok = ((est["t"].to_numpy() >= drop) & (est["mu_rl_excited"].to_numpy() > 0)
          & (np.abs(est["mu_rl"].to_numpy() - 0.3) <= 0.1))
    assert ok.any()
    assert est["t"].to_numpy()[np.argmax(ok)] - first_use <= 1.0


@pytest.mark.xfail(strict=True, reason="measured max |μ̂ − μ| where flagged: x07 0.186 "
                   "(rear-left force 0.13 low): see module docstring")
@pytest.mark.parametrize("prefix", ["x07"])
def test_known_misses(prefix: str):
    assert _flagged_errors(prefix).max() <= 0.1
