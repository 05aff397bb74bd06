"""Validity flags (issue 15): each reason raised exactly where its condition holds, in run()
and step() alike."""

from __future__ import annotations

from dataclasses import fields

import numpy as np
import pytest

from vestim.estimators.validity import (
    HIGH_SLIP,
    INPUT_FAULTY,
    NOT_CONVERGED,
    REVERSE,
    STANDSTILL,
    UNOBSERVABLE,
    VY_UNVERIFIED,
    ValidityKernelParams,
    ValidityParams,
    validity,
    validity_params,
)


def _flags(vx, slip=0.0, alpha=0.0, delta=0.05, ay=2.0, held=False, t=5.0, unverified=0.0):
    one = lambda v: np.array([v], dtype=float)  # noqa: E731
    return validity(one(t), 0.0, one(vx), np.full((1, 4), slip), np.full((1, 4), alpha),
                    np.full((1, 2), delta), one(ay), np.array([held]), ValidityParams(),
                    one(unverified))


@pytest.mark.parametrize(("kw", "group", "bit"), [
    ({"t": 1.0}, "velocity", NOT_CONVERGED),
    ({"vx": 0.2}, "slip", STANDSTILL),
    ({"vx": -3.0}, "velocity", REVERSE),
    ({"slip": 0.3}, "velocity", HIGH_SLIP),
    ({"alpha": -0.2}, "velocity", HIGH_SLIP),
    ({"delta": 0.0, "ay": 0.0}, "force", UNOBSERVABLE),
    ({"held": True}, "force", INPUT_FAULTY),
    ({"unverified": 1.0}, "velocity", VY_UNVERIFIED),  # 1 s: ValidityParams.unverified_s
    ({"unverified": 1.0}, "slip", VY_UNVERIFIED),
])
def test_each_reason(kw: dict, group: str, bit: int):
    args = {"vx": 20.0, **kw}
    out = _flags(**args)
    assert int(out[f"reason_{group}"][0]) & bit
    assert out[f"valid_{group}"][0] == 0.0


def test_a_clean_row_is_valid_everywhere_and_bits_stay_in_their_groups():
    out = _flags(20.0)
    assert all(out[f"valid_{g}"][0] == 1.0 for g in ("velocity", "force", "slip"))
    hs = _flags(20.0, slip=0.3)  # high slip concerns velocity, not the force or slip rows
    assert hs["valid_force"][0] == 1.0 and hs["valid_slip"][0] == 1.0
    assert hs["valid_velocity"][0] == 0.0
    late = _flags(20.0, unverified=0.99)  # just under the 1 s of validity.unverified_s
    assert late["valid_velocity"][0] == 1.0
    un = _flags(20.0, unverified=5.0)  # v_y unverified says nothing about the forces
    assert un["valid_force"][0] == 1.0 and un["valid_velocity"][0] == 0.0


def test_pipeline_writes_the_flags_and_step_matches_run():
    from vestim.io import load_vehicle
    from vestim.pipeline import Pipeline
    from vestim.sim import get_maneuver, simulate

    veh = load_vehicle("hashemi_suv")
    full = simulate(get_maneuver("step_steer"), veh, seed=0).iloc[:700]
    log = full[[c for c in full.columns if not c.startswith("ref_")]]
    est = Pipeline(veh).run(log)
    t = est["t"].to_numpy()
    # The first 2 s are "not converged". The simulator's step steer then drives the tires to
    # 8° of slip angle (0.14 rad): every row whose true slip angle exceeds 0.16 rad must be
    # flagged high slip, and a valid row has none beyond 0.15 rad.
    assert np.all(est["reason_velocity"].to_numpy()[t - t[0] < 2.0].astype(int) & NOT_CONVERGED)
    true_alpha = np.abs(full[[f"ref_slip_angle_{c}" for c in ("fl", "fr", "rl", "rr")]]
                        .to_numpy()).max(axis=1)
    reason = est["reason_velocity"].to_numpy().astype(int)
    assert np.all(reason[true_alpha > 0.16] & HIGH_SLIP)
    valid = est["valid_velocity"].to_numpy() == 1.0
    assert valid.any() and true_alpha[valid].max() <= 0.15
    pipe = Pipeline(veh)
    rows = [pipe.step(s) for s in log.to_dict("records")]
    for k in ("valid_velocity", "reason_velocity", "reason_force", "valid_slip"):
        np.testing.assert_array_equal([r[k] for r in rows], est[k].to_numpy())


def test_params_are_packed_from_the_config_and_reach_the_kernel() -> None:
    """Every :class:`ValidityKernelParams` field is the config's (non-default values), and a
    changed threshold moves the flag: v_x = 0.8 m/s is moving with the default
    standstill_speed 0.5 m/s and standstill with 1.0 m/s (bit 2 in the slip group)."""
    cfg = ValidityParams(converge_s=3.0, standstill_speed=1.0, high_slip_ratio=0.2,
                         high_slip_angle=0.1, straight_delta=0.01, straight_ay=0.4)
    prm = validity_params(cfg)
    assert isinstance(prm, ValidityKernelParams)
    for f in fields(ValidityParams):
        assert getattr(prm, f.name) == getattr(cfg, f.name), f.name
    one = lambda v: np.array([v], dtype=float)  # noqa: E731
    args = (one(5.0), 0.0, one(0.8), np.zeros((1, 4)), np.zeros((1, 4)), np.full((1, 2), 0.05),
            one(2.0), np.array([False]))
    assert validity(*args, ValidityParams())["reason_slip"][0] == 0.0
    assert validity(*args, ValidityParams(standstill_speed=1.0))["reason_slip"][0] == STANDSTILL


def test_reason_names_decode_every_bit() -> None:
    """Each bit decodes to its REASONS name, in bit order; a mask of several bits to all of
    them; 0 to none; a bit no reason has, a fraction or a negative value is an error."""
    from vestim.estimators.validity import REASONS, reason_names

    for bit, name in REASONS.items():
        assert reason_names(bit) == [name]
    assert reason_names(1 + 8 + 64) == ["not converged", "high slip", "v_y unverified"]
    assert reason_names(0.0) == [] and reason_names(float(sum(REASONS))) == list(REASONS.values())
    with pytest.raises(ValueError, match="holds bit"):
        reason_names(256)
    with pytest.raises(ValueError, match="not a non-negative whole number"):
        reason_names(1.5)
    with pytest.raises(ValueError, match="not a non-negative whole number"):
        reason_names(-1)


def test_an_unresolved_load_makes_the_force_group_unobservable() -> None:
    """A corner's F_z below 2 σ_Fz (a wheel nearly lifted) sets bit 16 on the force group
    only, in a turn that sets nothing else; 600 N with σ 310 N is not resolved, 620 N is
    (the boundary of load_resolved), and a NaN σ leaves the load resolved."""
    from vestim.estimators.validity import FZ_RESOLVED, load_resolved

    one = np.array([1.0])
    args = (np.array([5.0]), 0.0, 20.0 * one, np.zeros((1, 4)), np.zeros((1, 4)),
            np.full((1, 2), 0.05), 2.0 * one, np.array([False]), ValidityParams())
    flags = validity(*args, load_unresolved=np.array([True]))
    assert flags["reason_force"][0] == UNOBSERVABLE and flags["valid_force"][0] == 0.0
    assert flags["reason_velocity"][0] == 0.0 and flags["reason_slip"][0] == 0.0
    assert validity(*args)["reason_force"][0] == 0.0
    assert FZ_RESOLVED == 2.0
    assert not load_resolved(600.0, 310.0) and load_resolved(620.0, 310.0)
    assert load_resolved(600.0, np.nan)
