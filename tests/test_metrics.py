"""Accuracy metrics: NRMS of 000 Sec. IV with the issue's floors, and the score table.

Expected values are computed by hand (stated in each test) or, for the simulator log,
with plain NumPy straight from the paper's formula, never with vestim.metrics itself.
"""

from __future__ import annotations

import json
import math

import numpy as np
import pandas as pd
import pytest
from hypothesis import assume, given, settings
from hypothesis import strategies as st

from vestim.constants import CORNERS
from vestim.errors import LogFormatError
from vestim.metrics import (
    FLOORS,
    SCORE_COLUMNS,
    channel_family,
    error_stats,
    floor_for,
    max_abs_error,
    nrms,
    rmse,
    score,
    to_json,
    to_markdown,
)
from vestim.sim import simulate

# ------------------------------------------------------------------ scalar metrics


def test_nrms_hand_computed() -> None:
    """e = p̂ − p = [0, 1, 2, 2]: mean e² = 9/4, RMSE = 1.5; p_m = max|p| = 2 → NRMS = 0.75."""
    est = [1.0, 2.0, 3.0, 4.0]
    ref = [1.0, 1.0, 1.0, 2.0]
    assert rmse(est, ref) == pytest.approx(1.5, rel=1e-15)
    assert nrms(est, ref) == pytest.approx(0.75, rel=1e-15)
    assert max_abs_error(est, ref) == pytest.approx(2.0, rel=1e-15)


def test_nrms_uses_max_abs_of_negative_reference() -> None:
    """p = [−4, 1], p̂ = [−1, 1]: e = [3, 0], RMSE = sqrt(9/2) = 2.1213; p_m = |−4| = 4."""
    assert nrms([-1.0, 1.0], [-4.0, 1.0]) == pytest.approx(math.sqrt(4.5) / 4.0, rel=1e-15)


def test_floor_replaces_small_reference_maximum() -> None:
    """p = [0.1, −0.2], p̂ = [0.4, 0.2]: e = [0.3, 0.4], RMSE = sqrt(0.125) = 0.35355.

    Without a floor p_m = 0.2 → NRMS = 1.7678; with floor 1 the denominator is 1 → 0.35355;
    a floor below p_m (0.1) changes nothing.
    """
    est, ref = [0.4, 0.2], [0.1, -0.2]
    assert nrms(est, ref) == pytest.approx(math.sqrt(0.125) / 0.2, rel=1e-14)
    assert nrms(est, ref, floor=1.0) == pytest.approx(math.sqrt(0.125), rel=1e-14)
    assert nrms(est, ref, floor=0.1) == pytest.approx(math.sqrt(0.125) / 0.2, rel=1e-14)
    stats = error_stats(est, ref, 1.0)
    assert stats.floored and stats.floor == 1.0 and stats.ref_max == pytest.approx(0.2)
    assert not error_stats(est, ref, 0.1).floored


def test_nan_pairs_are_skipped_and_counted() -> None:
    """p̂ = [1, NaN, 3, 5], p = [0, 2, NaN, 3]: only pairs 0 and 3 are valid, e = [1, 2].

    RMSE = sqrt(5/2); p_m over the valid pairs = 3; max error 2; 2 used, 2 skipped.
    """
    est = np.array([1.0, np.nan, 3.0, 5.0])
    ref = np.array([0.0, 2.0, np.nan, 3.0])
    stats = error_stats(est, ref)
    assert stats.samples == 2 and stats.skipped == 2
    assert stats.rmse == pytest.approx(math.sqrt(2.5), rel=1e-15)
    assert stats.nrms == pytest.approx(math.sqrt(2.5) / 3.0, rel=1e-15)
    assert stats.max_error == 2.0
    assert rmse(est, ref) == stats.rmse and max_abs_error(est, ref) == 2.0


def test_all_nan_gives_nan_and_zero_samples() -> None:
    stats = error_stats([np.nan, 1.0], [2.0, np.nan])
    assert stats.samples == 0 and stats.skipped == 2
    assert math.isnan(stats.nrms) and math.isnan(stats.rmse) and not stats.floored


def test_zero_reference_without_floor() -> None:
    """0/0 for a perfect estimate of an all-zero truth is reported as 0; any error as inf."""
    assert nrms([0.0, 0.0], [0.0, 0.0]) == 0.0
    assert nrms([0.1, 0.0], [0.0, 0.0]) == math.inf


def test_shape_mismatch_and_negative_floor_rejected() -> None:
    with pytest.raises(ValueError, match=r"shapes differ: \(3,\) vs \(2,\)"):
        nrms([1.0, 2.0, 3.0], [1.0, 2.0])
    with pytest.raises(ValueError, match="floor must be >= 0"):
        nrms([1.0], [1.0], floor=-1.0)


def test_metrics_do_not_modify_inputs() -> None:
    est = np.array([1.0, np.nan, 3.0])
    ref = np.array([0.5, 2.0, 2.0])
    e0, r0 = est.copy(), ref.copy()
    error_stats(est, ref, 1.0)
    np.testing.assert_array_equal(est, e0)
    np.testing.assert_array_equal(ref, r0)


# ------------------------------------------------------------------ floor table


@pytest.mark.parametrize(
    ("channel", "family", "floor"),
    [
        ("fx_fl", "fx", 500.0), ("fy_rr", "fy", 500.0), ("fz_rl", "fz", 500.0),
        ("vy", "vy", 1.0), ("vy_fr", "vy", 1.0), ("vx", "vx", 0.0), ("vx_rl", "vx", 0.0),
        ("slip_ratio_fl", "slip_ratio", 0.05), ("slip_angle_rr", "slip_angle", 0.02),
        ("roll", "roll", 0.01), ("pitch", "pitch", 0.01),
        ("stiffness_cx_f", "stiffness", 0.0), ("stiffness_cy_r", "stiffness", 0.0),
        ("mu_x_fl", "mu_x", 0.1), ("mu_y_rr", "mu_y", 0.1), ("mu_fl", "mu", 0.0),
        ("something_else", "something_else", 0.0),
    ],
)
def test_floor_table(channel: str, family: str, floor: float) -> None:
    """The issue's floors: forces 500 N, v_y 1 m/s, v_x 0, slip ratio 0.05, slip angle
    0.02 rad, roll/pitch 0.01 rad, stiffness 0; unknown families 0."""
    assert channel_family(channel) == family
    assert floor_for(channel) == floor
    assert all(v >= 0.0 for v in FLOORS.values())


# ------------------------------------------------------------------ score() alignment


def _ramp_logs(t_est: np.ndarray) -> tuple[pd.DataFrame, pd.DataFrame]:
    """Reference vx = 10 + 2t on a 10 Hz grid over [0, 1] s; estimate vx = 10 + 2t + 0.5."""
    t_ref = np.linspace(0.0, 1.0, 11)
    reference = pd.DataFrame({"t": t_ref, "ref_vx": 10.0 + 2.0 * t_ref})
    estimate = pd.DataFrame({"t": t_est, "vx": 10.0 + 2.0 * t_est + 0.5})
    return estimate, reference


def test_score_interpolates_reference_onto_estimate_times() -> None:
    """Estimate at t = 0.05, 0.15, …, 1.45 s; the reference spans only [0, 1] s.

    Linear interpolation of a linear truth is exact, so the error is 0.5 at all ten
    samples inside [0, 1] s (t = 0.05 … 0.95); the five after 1 s are dropped, not
    extrapolated. p_m = 10 + 2·0.95 = 11.9 → NRMS = 0.5 / 11.9 = 4.2017 %.
    """
    estimate, reference = _ramp_logs(0.05 + 0.1 * np.arange(15))
    table = score(estimate, reference)
    row = table.iloc[0]
    assert row["channel"] == "vx" and row["unit"] == "m/s"
    assert row["samples"] == 10 and row["skipped"] == 0
    assert row["rmse"] == pytest.approx(0.5, rel=1e-12)
    assert row["ref_max"] == pytest.approx(11.9, rel=1e-12)
    assert row["nrms_pct"] == pytest.approx(100 * 0.5 / 11.9, rel=1e-12)


def test_score_exact_time_match_pairs_row_by_row() -> None:
    """Identical t: no interpolation, so a reference wiggle between samples is irrelevant."""
    t = np.linspace(0.0, 1.0, 11)
    reference = pd.DataFrame({"t": t, "ref_vx": np.where(np.arange(11) % 2 == 0, 10.0, 12.0)})
    estimate = pd.DataFrame({"t": t.copy(), "vx": reference["ref_vx"] + 0.25})
    row = score(estimate, reference).iloc[0]
    assert row["samples"] == 11
    assert row["rmse"] == pytest.approx(0.25, rel=1e-12)
    assert row["nrms_pct"] == pytest.approx(100 * 0.25 / 12.0, rel=1e-12)


def test_score_non_overlapping_logs_names_both_ranges() -> None:
    estimate, reference = _ramp_logs(np.linspace(5.0, 6.0, 11))
    with pytest.raises(LogFormatError,
                       match=r"est\.csv \(t = 5 … 6 s\) and ref\.csv \(t = 0 … 1 s\) do not overlap"):
        score(estimate, reference, estimate_name="est.csv", reference_name="ref.csv")


def test_score_rejects_bad_time_and_unpairable_channels() -> None:
    estimate, reference = _ramp_logs(np.linspace(0.0, 1.0, 11))
    with pytest.raises(LogFormatError, match="reference: no time column 't'"):
        score(estimate, reference.drop(columns="t"))
    with pytest.raises(LogFormatError, match="estimate: column 't' is not strictly increasing"):
        score(estimate.iloc[::-1], reference)
    with pytest.raises(LogFormatError, match="no column 'ref_vy' to score 'vy'"):
        score(estimate.assign(vy=0.0), reference, channels=["vy"])
    with pytest.raises(LogFormatError, match="estimate: no column 'fx_fl'"):
        score(estimate, reference, channels=["fx_fl"])
    with pytest.raises(LogFormatError, match="no estimated channel has a reference"):
        score(estimate.rename(columns={"vx": "vy"}), reference)
    with pytest.raises(LogFormatError, match="'sigma_vx' is not an estimated channel"):
        score(estimate.assign(sigma_vx=1.0), reference, channels=["sigma_vx"])


# ------------------------------------------------------------------ score() on a simulator log


@pytest.fixture(scope="module")
def sim_log() -> pd.DataFrame:
    return simulate("step_steer", "hashemi_suv", seed=0)


def _paper_nrms(est: np.ndarray, ref: np.ndarray, floor: float) -> float:
    """000 Sec. IV written out: sqrt(Σ(p̂ − p)²/N) / max(max|p|, floor)."""
    n = est.size
    return math.sqrt(float(np.sum((est - ref) ** 2)) / n) / max(float(np.max(np.abs(ref))), floor)


def _fabricated_estimate(log: pd.DataFrame) -> pd.DataFrame:
    """Known offsets on some ref channels: +0.2 m/s on vx, −0.05 m/s on vy, 100 N sine on
    fx_fl, +10 % on fy_fr, +1 mrad on pitch (whose truth, |pitch| ≤ 3.5 mrad, is below the
    0.01 rad floor), the exact mu_x_fl = F_x/F_z, and a sigma column that must not be scored."""
    t = log["t"].to_numpy()
    return pd.DataFrame({
        "t": t,
        "vx": log["ref_vx"] + 0.2,
        "vy": log["ref_vy"] - 0.05,
        "fx_fl": log["ref_fx_fl"] + 100.0 * np.sin(t),
        "fy_fr": 1.1 * log["ref_fy_fr"],
        "pitch": log["ref_pitch"] + 1e-3,
        "mu_x_fl": log["ref_fx_fl"] / log["ref_fz_fl"],
        "sigma_vx": 0.1,
    })


def test_score_on_simulator_log(sim_log: pd.DataFrame) -> None:
    estimate = _fabricated_estimate(sim_log)
    before_est, before_ref = estimate.copy(), sim_log.copy()
    table = score(estimate, sim_log)
    pd.testing.assert_frame_equal(estimate, before_est)
    pd.testing.assert_frame_equal(sim_log, before_ref)

    assert list(table.columns) == list(SCORE_COLUMNS)
    assert list(table["channel"]) == ["vx", "vy", "fx_fl", "fy_fr", "pitch", "mu_x_fl"]
    rows = table.set_index("channel")
    floors = {"vx": 0.0, "vy": 1.0, "fx_fl": 500.0, "fy_fr": 500.0, "pitch": 0.01}
    for name, floor in floors.items():
        expected = _paper_nrms(estimate[name].to_numpy(), sim_log["ref_" + name].to_numpy(), floor)
        # both sides evaluate the same sums in float64; 1e-12 allows only summation order
        assert rows.loc[name, "nrms_pct"] == pytest.approx(100 * expected, rel=1e-12), name
        assert rows.loc[name, "floor"] == floor
        assert rows.loc[name, "samples"] == len(sim_log)
    # constant offsets: RMSE and max error equal the offset
    assert rows.loc["vx", "rmse"] == pytest.approx(0.2, rel=1e-9)
    assert rows.loc["vy", "max_error"] == pytest.approx(0.05, rel=1e-9)
    # pitch: NRMS = 1 mrad / 10 mrad floor = 10 %, flagged as floored
    assert rows.loc["pitch", "nrms_pct"] == pytest.approx(10.0, rel=1e-9)
    assert rows.loc["pitch", "floored"] and not rows.loc["vx", "floored"]
    assert rows.loc["mu_x_fl", "nrms_pct"] == 0.0  # derived reference F_x/F_z
    assert rows.loc["fx_fl", "unit"] == "N" and rows.loc["pitch", "unit"] == "rad"


def test_score_same_frame_as_reference(sim_log: pd.DataFrame) -> None:
    """A simulator log that also carries estimates is its own reference."""
    log = sim_log.copy()
    for c in CORNERS:
        log[f"fz_{c}"] = log[f"ref_fz_{c}"] + 50.0  # constant 50 N error
    table = score(log, log)
    assert list(table["channel"]) == [f"fz_{c}" for c in CORNERS]
    for c in CORNERS:
        row = table.set_index("channel").loc[f"fz_{c}"]
        expected = 50.0 / max(float(np.max(np.abs(sim_log[f"ref_fz_{c}"]))), 500.0)
        assert row["nrms_pct"] == pytest.approx(100 * expected, rel=1e-9)


def test_score_channel_selection_and_nan_count(sim_log: pd.DataFrame) -> None:
    estimate = _fabricated_estimate(sim_log)
    estimate.loc[estimate.index[:100], "vx"] = np.nan
    table = score(estimate, sim_log, channels=["pitch", "vx"])
    assert list(table["channel"]) == ["pitch", "vx"]
    vx = table.set_index("channel").loc["vx"]
    assert vx["samples"] == len(sim_log) - 100 and vx["skipped"] == 100


# ------------------------------------------------------------------ output helpers


def test_markdown_and_json_shapes(sim_log: pd.DataFrame) -> None:
    table = score(_fabricated_estimate(sim_log), sim_log)
    md = to_markdown(table)
    lines = md.strip().splitlines()
    table_lines = [ln for ln in lines if ln.startswith("|")]
    assert len(table_lines) == 2 + len(table)  # header, separator, one per channel
    assert table_lines[0].startswith("| channel | unit | NRMS [%] |")
    assert all(ln.count("|") == 9 for ln in table_lines)
    pitch_line = next(ln for ln in table_lines if ln.startswith("| pitch "))
    assert "| 10.0* |" in pitch_line  # 3 significant figures (metrics.significant)
    assert "floor was the denominator" in lines[-1]

    records = json.loads(to_json(table))
    assert isinstance(records, list) and len(records) == len(table)
    assert all(list(r) == list(SCORE_COLUMNS) for r in records)
    vx = next(r for r in records if r["channel"] == "vx")
    assert vx["rmse"] == 0.2  # rounded to 6 significant figures
    assert isinstance(vx["samples"], int) and isinstance(vx["floored"], bool)


def test_json_and_markdown_handle_nan() -> None:
    estimate = pd.DataFrame({"t": [0.0, 1.0], "vx": [np.nan, np.nan]})
    reference = pd.DataFrame({"t": [0.0, 1.0], "ref_vx": [1.0, 2.0]})
    table = score(estimate, reference)
    record = json.loads(to_json(table))[0]
    assert record["nrms_pct"] is None and record["samples"] == 0 and record["skipped"] == 2
    assert "| vx | m/s | – |" in to_markdown(table)
    with pytest.raises(ValueError, match="not a score table"):
        to_markdown(table.drop(columns="floor"))


# ------------------------------------------------------------------ properties and equivalences


@settings(max_examples=50, deadline=None)
@given(
    st.lists(st.tuples(st.floats(-1e3, 1e3), st.floats(-1e3, 1e3)), min_size=1, max_size=30),
    st.floats(1e-3, 1e3),
)
def test_nrms_scale_invariant_and_rmse_symmetric(pairs: list[tuple[float, float]], k: float) -> None:
    """NRMS is dimensionless: scaling estimate and truth by k > 0 leaves it unchanged
    (without a floor); RMSE is symmetric in its arguments and bounded by the max error."""
    est = np.array([p[0] for p in pairs])
    ref = np.array([p[1] for p in pairs])
    assume(np.max(np.abs(ref)) > 1e-6)
    assert nrms(k * est, k * ref) == pytest.approx(nrms(est, ref), rel=1e-9, abs=1e-12)
    assert rmse(est, ref) == pytest.approx(rmse(ref, est), rel=1e-12)
    assert rmse(est, ref) <= max_abs_error(est, ref) * (1 + 1e-12)


def test_interpolation_at_reference_knots_equals_exact_pairing(sim_log: pd.DataFrame) -> None:
    """An estimate on every other reference sample takes the interpolation path, which at
    the reference's own knots returns the knot values: same table as pairing those rows."""
    estimate = _fabricated_estimate(sim_log)
    sub = estimate.iloc[::2].reset_index(drop=True)
    via_interp = score(sub, sim_log)
    exact = score(sub, sim_log.iloc[::2].reset_index(drop=True))
    pd.testing.assert_frame_equal(via_interp, exact, rtol=1e-12)


def test_coverage_of_a_gaussian_error_is_68_and_95_percent():
    """Errors drawn from N(0, σ) with the σ written: 68.3 % within 1σ, 95.4 % within 2σ
    (20 000 samples: the binomial standard error is 0.33 %, so ±1 % is 3 standard errors)."""
    from vestim.metrics import coverage

    rng = np.random.default_rng(7)
    n = 20_000
    truth = rng.normal(10.0, 1.0, n)
    sigma = rng.uniform(0.05, 0.5, n)
    est = pd.DataFrame({"t": np.arange(n) * 0.01, "vx": truth + sigma * rng.normal(size=n),
                        "sigma_vx": sigma, "vy": truth, "sigma_vy": 2 * sigma})
    ref = pd.DataFrame({"t": est["t"], "ref_vx": truth, "ref_vy": truth + sigma * 3.0})
    table = coverage(est, ref).set_index("channel")
    assert abs(table.loc["vx", "within_1sigma"] - 0.683) < 0.01
    assert abs(table.loc["vx", "within_2sigma"] - 0.954) < 0.01
    # errors of 3σ against a stated 2σ: outside 1 stated σ, inside 2 stated σ (4σ)
    assert table.loc["vy", "within_1sigma"] == 0.0
    assert table.loc["vy", "within_2sigma"] == 1.0
    assert table.loc["vx", "samples"] == n


def test_significant_figures():
    """NRMS is written to 3 significant figures, never as 0.00 or in exponent form."""
    from vestim.metrics import significant

    assert significant(0.004) == "0.00400"  # 0.004 %: two decimals would print 0.00
    assert significant(0.01234) == "0.0123"
    assert significant(5.0) == "5.00"
    assert significant(12.345) == "12.3"
    assert significant(1234.6) == "1235"
    assert significant(-0.5) == "-0.500"
    assert significant(0.0) == "0" and significant(math.nan) == "–"
    assert significant(math.inf) == "inf"


def test_coverage_of_named_channels():
    """channels= picks and orders the rows; a channel without a σ or a reference is an
    error that names it."""
    from vestim.metrics import coverage

    t = np.arange(5) * 0.1
    est = pd.DataFrame({"t": t, "vx": t, "sigma_vx": 1.0, "vy": t, "sigma_vy": 1.0, "fx_fl": t})
    ref = pd.DataFrame({"t": t, "ref_vx": t + 0.5, "ref_vy": t + 1.5, "ref_fx_fl": t})
    table = coverage(est, ref, channels=["vy", "vx"])
    assert list(table["channel"]) == ["vy", "vx"]
    assert list(table["within_1sigma"]) == [0.0, 1.0] and list(table["within_2sigma"]) == [1.0, 1.0]
    with pytest.raises(LogFormatError, match="'fx_fl' needs a sigma_fx_fl column"):
        coverage(est, ref, channels=["fx_fl"])


def test_scores_with_coverage_beside_them():
    """``vestim score --coverage``'s table: each channel's scores with its σ coverage beside
    them, "–" where the channel has no σ. vx is off by 0.5 against σ 1 (all within 1σ), vy
    by 1.5 (outside 1σ, inside 2σ), fx_fl has no σ."""
    from vestim.metrics import coverage, score, to_json, to_markdown, with_coverage

    t = np.arange(5) * 0.1
    est = pd.DataFrame({"t": t, "vx": t, "sigma_vx": 1.0, "vy": t, "sigma_vy": 1.0,
                        "fx_fl": t + 100.0})
    ref = pd.DataFrame({"t": t, "ref_vx": t + 0.5, "ref_vy": t + 1.5, "ref_fx_fl": t})
    table = with_coverage(score(est, ref), coverage(est, ref)).set_index("channel")
    assert table.loc["vx", "rmse"] == pytest.approx(0.5)
    assert (table.loc["vx", "within_1sigma"], table.loc["vy", "within_1sigma"],
            table.loc["vy", "within_2sigma"]) == (1.0, 0.0, 1.0)
    assert math.isnan(table.loc["fx_fl", "within_1sigma"])
    text = to_markdown(table.reset_index())
    assert "| within 1σ % | within 2σ % |" in text
    vy_row = next(line for line in text.splitlines() if line.startswith("| vy |"))
    assert vy_row.endswith("| 0.0 | 100.0 |")
    fx_row = next(line for line in text.splitlines() if line.startswith("| fx_fl |"))
    assert fx_row.endswith("| – | – |")
    assert '"within_2sigma": 1.0' in to_json(table.reset_index())
