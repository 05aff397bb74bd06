"""Root causes of the cross-plant misses (issue 11), checked on the independent plant."""


from dataclasses import replace
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


def test_pitch_uses_the_euler_rate_on_a_crossplant_ramp_steer() -> None:
    """x06 (Ford Escort ramp steer to 0.33 rad/s at 4.4° of roll): the pitch gyro reads
    r sin φ ≈ 0.025 rad/s that is not pitch. Integrated as the plain q it made the pitch
    0.76° where the truth is −0.05°, and through r tan θ a 0.6° roll error whose gravity
    drove v_y to −0.87 m/s. With θ̇ = q cos φ − r sin φ the RMS pitch error is ≤ 0.1°
    (measured 0.056°) and the roll within 10 % of the truth (measured 7 %)."""
    log = pd.read_parquet(DATA / "x06_ramp_steer_wet_fwd.parquet")
    out = ForceEstimator(load_vehicle(str(DATA / "vehicle1.toml"))).run(_measured(log))

    def rms(a: np.ndarray) -> float:
        return float(np.sqrt(np.mean(a**2)))

    assert rms(out["pitch"].to_numpy() - log["ref_pitch"].to_numpy()) <= np.radians(0.1)
    ref = log["ref_roll"].to_numpy()
    assert rms(out["roll"].to_numpy() - ref) <= 0.1 * rms(ref)


def test_cornering_stiffness_identified_on_a_crossplant_sine_steer() -> None:
    """x05: the [tire] table's σ0y/κy = 15/rad is the prior; the plant's PAC2002 tire has
    C_y/F_z = 21.9/rad. The slip-difference regression must move at least half way from the
    prior in the last 2 s (measured 19.9: camber thrust makes the apparent value lower)."""
    log = pd.read_parquet(DATA / "x05_sine_steer_dry_rwd.parquet")
    out = Pipeline(load_vehicle(str(DATA / "vehicle2.toml"))).run(_measured(log))
    c = out["cornering_stiffness"].to_numpy()[-400:]
    assert 15.0 + 0.5 * (21.9 - 15.0) <= c.mean() <= 21.9 * 1.1


@pytest.mark.parametrize("factor", [0.7, 1.3])
def test_vy_within_target_with_the_cornering_stiffness_30_percent_off(factor: float) -> None:
    """x05 and x11 with the [tire] table's σ0y (the cornering-stiffness prior) at ×0.7 and
    ×1.3: CG v_y RMSE within the issue-11 limit max(0.04 m/s, ½ RMSE of v_y = 0), because
    the stiffness is identified from the log's yaw transients (measured 0.012–0.016 m/s on
    x05 against 0.040, 0.04–0.05 on x11 against 0.083)."""
    for name, vfile in (("x05_sine_steer_dry_rwd", "vehicle2.toml"),
                        ("x11_stiffness_step_rwd", "vehicle3.toml")):
        log = pd.read_parquet(DATA / f"{name}.parquet")
        veh = load_vehicle(str(DATA / vfile))
        veh = replace(veh, tire=replace(veh.tire, sigma0_y=veh.tire.sigma0_y * factor))
        out = Pipeline(veh).run(_measured(log))
        s = log["t"].to_numpy() >= 0.5
        ref = log["ref_vy"].to_numpy()[s]
        err = np.sqrt(np.mean((out["vy"].to_numpy()[s] - ref) ** 2))
        assert err <= max(0.04, 0.5 * np.sqrt(np.mean(ref**2))), name


def test_braking_loads_need_the_pitch_inertia_term() -> None:
    """x03 (AWD ABS braking on ice): the quasi-static load transfer alone leaves the ABS
    cycling's pitch dynamics in the F_z error; less the body's I_y q̇ (from the pitch gyro)
    the pooled F_z NRMS is ≤ 2 % (measured 1.79 %; 2.87 % without the inertia term, 2.23 %
    with the default suspension's dynamic transfer at the session start)."""
    log = pd.read_parquet(DATA / "x03_brake_ice_awd.parquet")
    out = ForceEstimator(load_vehicle(str(DATA / "vehicle3_awd.toml"))).run(_measured(log))
    s = log["t"].to_numpy() >= 0.5
    corners = ("fl", "fr", "rl", "rr")
    mse = np.mean([np.mean((out[f"fz_{c}"].to_numpy()[s] - log[f"ref_fz_{c}"].to_numpy()[s])
                           ** 2) for c in corners])
    peak = max(log[f"ref_fz_{c}"].abs().max() for c in corners)
    assert 100 * np.sqrt(mse) / peak <= 2.0


def test_gnss_speed_finds_the_rav4_wheel_radius() -> None:
    """The RAV4 log's CAN wheel speeds read 0.86 % low against the pose reference
    (shared/real/README.md); from its sparse 10 Hz gnss_speed the radius scale must end
    within 0.3 % of 1.0087 (measured 1.008), and the receiver latency near the 0.156 s that
    a least-squares fit of the fixes against the pose reference shows (measured 0.12 s;
    within 0.06 s)."""
    rav4 = DATA.parents[1] / "real" / "comma2k19_rav4"
    if not rav4.exists():
        pytest.skip(f"RAV4 log not found at {rav4}")
    log = pd.read_parquet(rav4 / "seg40.parquet")
    out = Pipeline(load_vehicle(str(rav4 / "vehicle.toml"))).run(_measured(log))
    assert abs(out["radius_scale"].iloc[-1] - 1.0087) <= 0.003
    assert abs(out["gnss_latency"].iloc[-1] - 0.156) <= 0.06
