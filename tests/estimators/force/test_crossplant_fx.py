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
