"""Lateral tire forces of the default force stage on the independent crossplant logs.

The logs come from another plant (CommonRoad multi-body model, PAC2002 tires; see
shared/crossplant/README.md). In the straight launches the truth F_y is near zero and the
500 N floor of the pooled NRMS makes the filter's own noise the whole error: with a fixed
force random walk of 10⁶ N²/s the snow launch x01 scored 6.5 %, with the innovation-matched
walk of :mod:`vestim.estimators.force.lateral` 4.96 %. x12 (square-wave steering with a
friction/stiffness drop) exercises the transients: 5.8 % before, 4.98 % now. Both must stay
within the cross-plant target of 5 %.
"""

import json
import math
from pathlib import Path

import numpy as np
import pandas as pd
import pytest

from vestim.constants import CORNERS
from vestim.estimators.force import ForceConfig, ForceEstimator
from vestim.io import load_vehicle

DATA = Path(__file__).resolve().parents[3] / ".." / "shared" / "crossplant" / "data"

pytestmark = pytest.mark.skipif(not (DATA / "manifest.json").exists(),
                                reason=f"crossplant data not found at {DATA}")


def pooled_fy(name: str) -> float:
    man = json.loads((DATA / "manifest.json").read_text())["maneuvers"]
    key = next(k for k in man if k.startswith(name))
    d = pd.read_parquet(DATA / man[key]["file"])
    veh = load_vehicle(DATA / man[key]["vehicle_file"])
    out = ForceEstimator(veh, ForceConfig()).run(d[[c for c in d.columns
                                                   if not c.startswith("ref_")]])
    keep = d["t"].to_numpy() >= 0.5
    mse = np.mean([np.mean((out[f"fy_{c}"].to_numpy()[keep] - d[f"ref_fy_{c}"].to_numpy()[keep])
                           ** 2) for c in CORNERS])
    den = max(max(np.abs(d[f"ref_fy_{c}"].to_numpy()[keep]).max() for c in CORNERS), 500.0)
    return 100 * math.sqrt(mse) / den


@pytest.mark.parametrize("name", ["x01", "x12"])
def test_pooled_fy_within_the_cross_plant_target(name):
    """Pooled F_y NRMS (500 N floor, first 0.5 s skipped, as targets.py) ≤ 5 %."""
    assert pooled_fy(name) <= 5.0


def test_kinematic_front_split_brings_x10_within_target():
    """x10 (FWD, parallel steering, large δ at 5–24 m/s): the F_z-based front split alone
    gave 5.61 %; the kinematic slip-angle difference Δα = δ_fr − δ_fl + r t_f sin δ̄/v_x with
    the nominal c₀ = σ0y/κy (faded with the axle's utilisation) gives 4.19 %."""
    assert pooled_fy("x10") <= 4.5
