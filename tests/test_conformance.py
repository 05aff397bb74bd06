"""Conformance of every registered method (:mod:`vestim.estimators.registry`).

Each method of each stage runs in the pipeline with the other stages at their defaults, and
must: never read a ``ref_`` column, leave its input untouched, give the same rows sample by
sample (:meth:`Pipeline.step`) as over the log (:meth:`Pipeline.run`), report positive σ,
stay finite at standstill and reversing, run on a log without wheel torques, and on a log
without wheel speeds either run or refuse with a message that names the missing channels.
A newly registered method joins these tests by being registered.
"""

import numpy as np
import pandas as pd
import pytest

from vestim.constants import CORNERS
from vestim.estimators import registry
from vestim.io import load_vehicle
from vestim.pipeline import Pipeline, PipelineConfig, PipelineConfigError
from vestim.sim import get_maneuver, simulate

SUV = load_vehicle("hashemi_suv")
FIELD = {"force": "force", "normal": "normal", "velocity": "velocity", "fusion": "fusion"}

CONFIGS = [PipelineConfig(**{FIELD[m.stage]: m.name})
           for stage in registry.STAGES for m in registry.methods(stage)
           if not (m.default and stage != registry.STAGES[0])]  # the all-default config once
IDS = [f"{c.force}-{c.normal}-{c.velocity}-{c.fusion}" for c in CONFIGS]


def _measured(log: pd.DataFrame) -> pd.DataFrame:
    return log.drop(columns=[c for c in log.columns if c.startswith("ref_")])


@pytest.fixture(scope="module")
def turning() -> pd.DataFrame:
    """Brake-in-turn on μ 0.25 with ABS (wheel slip, sideslip), 3 s from the start."""
    log = simulate(get_maneuver("bit_slippery"), SUV, seed=4)
    return log.iloc[:600].reset_index(drop=True)


@pytest.fixture(scope="module")
def launch() -> tuple[pd.DataFrame, pd.DataFrame]:
    """A standstill, then a full-throttle launch on ice (6 s), and the same launch driven
    backwards: ω, T and a_x negated (yaw rate, a_y and steering are zero going straight), a
    physical reverse launch on the same road."""
    sim = simulate(get_maneuver("launch_ice"), SUV, seed=1).iloc[:1200]
    assert sim["ref_vx"].iloc[:50].abs().max() < 0.01  # a standstill first
    forward = _measured(sim).reset_index(drop=True)
    backward = forward.copy()
    flip = [f"omega_{c}" for c in CORNERS] + [f"torque_{c}" for c in CORNERS] + ["ax"]
    backward[flip] = -backward[flip]
    return forward, backward


@pytest.mark.parametrize("cfg", CONFIGS, ids=IDS)
def test_no_ref_columns_read_and_input_untouched(cfg, turning):
    """Scrambling every ref_ column changes no output, and the input frame is unchanged."""
    scrambled = turning.copy()
    rng = np.random.default_rng(0)
    for c in scrambled.columns:
        if c.startswith("ref_"):
            scrambled[c] = rng.normal(size=len(scrambled)) * 1e3
    before = scrambled.copy()
    a = Pipeline(SUV, cfg).run(scrambled)
    pd.testing.assert_frame_equal(scrambled, before)
    b = Pipeline(SUV, cfg).run(_measured(turning))
    pd.testing.assert_frame_equal(a, b)


@pytest.mark.parametrize("cfg", CONFIGS, ids=IDS)
def test_step_equals_run(cfg, turning):
    """Sample by sample == the whole log: same kernels, same state (to 1e-12 relative)."""
    part = _measured(turning).iloc[:200]
    batch = Pipeline(SUV, cfg).run(part)
    online = Pipeline(SUV, cfg)
    rows = pd.DataFrame([online.step(r) for r in part.to_dict("records")])[batch.columns]
    np.testing.assert_allclose(rows.to_numpy(), batch.to_numpy(), rtol=1e-12, atol=1e-9)


UNTIL_EXCITED = tuple(f"{q}_{c}" for q in ("mu", "sigma_mu") for c in CORNERS)
"""The road-friction potential and its σ are NaN ("not known") until the tire is excited."""


def _check_finite_and_sigma(out: pd.DataFrame, label: str) -> None:
    """Every output finite (a channel a method does not estimate is absent or all NaN, the
    friction potential NaN until excited), every σ channel > 0."""
    for c in out.columns:
        v = out[c].to_numpy()
        if c in UNTIL_EXCITED:
            v = v[~np.isnan(v)]
        if v.size and np.isnan(v).all():
            assert c.startswith("sigma_"), (label, c, "an estimate channel is all NaN")
            continue
        assert np.isfinite(v).all(), (label, c, int((~np.isfinite(v)).sum()))
        if c.startswith("sigma_"):
            assert (v > 0).all(), (label, c, float(v.min()))


@pytest.mark.parametrize("cfg", CONFIGS, ids=IDS)
def test_finite_with_positive_sigma_turning_standstill_and_reverse(cfg, turning, launch):
    """Finite outputs and σ > 0 in a brake-in-turn, from standstill and reversing; the reverse
    launch's v_x mirrors the forward one's: max |v̂_x,back + v̂_x,fwd| measured 0.0004 m/s
    (lpv) to 0.020 m/s (kf, ukf) against 2.3 m/s reached; the bound 0.05 m/s. (Mirrored, not
    accurate: lpv follows the spinning wheels to 48 m/s in both directions, a known failure
    of its constant gains on ice, docs/results.md.)"""
    _check_finite_and_sigma(Pipeline(SUV, cfg).run(_measured(turning)), "turning")
    forward, backward = launch
    fwd = Pipeline(SUV, cfg).run(forward)
    back = Pipeline(SUV, cfg).run(backward)
    _check_finite_and_sigma(back, "reversing")
    mirror = np.abs(back["vx"].to_numpy() + fwd["vx"].to_numpy())
    assert mirror.max() < 0.05, mirror.max()


@pytest.mark.parametrize("cfg", CONFIGS, ids=IDS)
def test_runs_without_wheel_torques(cfg, turning):
    log = _measured(turning).drop(columns=[f"torque_{c}" for c in CORNERS])
    out = Pipeline(SUV, cfg).run(log)
    assert np.isfinite(out[["vx", *(f"fx_{c}" for c in CORNERS)]].to_numpy()).all()


@pytest.mark.parametrize("cfg", CONFIGS, ids=IDS)
def test_without_wheel_speeds_runs_or_names_them(cfg, turning):
    """The velocity methods registered as needing no wheel speeds run from a_x and the GNSS
    speed; the others refuse, naming the channels and the methods that would run."""
    log = _measured(turning).drop(columns=[f"omega_{c}" for c in CORNERS])
    speed = np.full(len(log), np.nan)
    speed[::20] = turning["ref_vx"].to_numpy()[::20]  # a 10 Hz receiver
    log["gnss_speed"] = speed
    if registry.lookup("velocity", cfg.velocity).needs_wheel_speeds:
        with pytest.raises(PipelineConfigError, match="needs the wheel speeds omega_fl"):
            Pipeline(SUV, cfg).run(log)
    else:
        out = Pipeline(SUV, cfg).run(log)
        assert np.isfinite(out["vx"]).all() and "slip_ratio_fl" not in out.columns
