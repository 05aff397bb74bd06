"""Root causes of the cross-plant misses (issue 11), checked on the independent plant."""

from pathlib import Path

import numpy as np
import pandas as pd
import pytest

from vestim.estimators.force import ForceEstimator
from vestim.io import load_vehicle
from vestim.pipeline import Pipeline

DATA = Path(__file__).resolve().parents[3].parent / "shared" / "crossplant" / "data"
pytestmark = pytest.mark.skipif(not DATA.exists(), reason=f"crossplant data not found at {DATA}")


def _measured(log: pd.DataFrame) -> pd.DataFrame:
    return log[[c for c in log.columns if not c.startswith(("ref_", "_"))]]


def test_roll_within_15_percent_on_a_crossplant_sine_steer() -> None:
    """x05 (BMW 320i RWD sine steer, roll to 4.2°): the default [suspension] made the
    roll 1.14 × the truth (1.16–1.85 × on the other turns); the gyro/gravity filter needs no
    suspension: RMS error ≤ 15 % of the RMS roll (measured 9 %)."""
    log = pd.read_parquet(DATA / "x05_sine_steer_dry_rwd.parquet")
    out = ForceEstimator(load_vehicle(str(DATA / "vehicle2.toml"))).run(_measured(log))
    ref = log["ref_roll"].to_numpy()
    err = np.sqrt(np.mean((out["roll"].to_numpy() - ref) ** 2))
    assert err <= 0.15 * np.sqrt(np.mean(ref**2))


def test_cornering_stiffness_identified_on_a_crossplant_sine_steer() -> None:
    """x05: the [tire] table's σ0y/κy = 15/rad is the prior; the plant's PAC2002 tire has
    C_y/F_z = 21.9/rad. The slip-difference regression must move at least half way from the
    prior in the last 2 s (measured 19.9: camber thrust makes the apparent value lower)."""
    log = pd.read_parquet(DATA / "x05_sine_steer_dry_rwd.parquet")
    out = Pipeline(load_vehicle(str(DATA / "vehicle2.toml"))).run(_measured(log))
    c = out["cornering_stiffness"].to_numpy()[-400:]
    assert 15.0 + 0.5 * (21.9 - 15.0) <= c.mean() <= 21.9 * 1.1
