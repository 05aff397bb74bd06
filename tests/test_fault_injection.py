"""Fault injection (issue 15, "must show"): each sensor fault, injected into three crossplant
logs (independent MB plant) and two simulator maneuvers, is flagged within 0.5 s, the v_x
estimate stays within 2 × the clean run's max error + 0.1 m/s, and it recovers (flag
cleared, error back in that bound) within 2 s after the fault ends. Sign and unit mistakes are
refused or warned about before estimating, naming the channel.

The injectors and the measurement are ``benchmarks/fault_table.py``'s (which writes
docs/faults.md from the same figures); the sign and unit mistakes are
``benchmarks/input_checks_table.py``'s. Truth is the logs' ``ref_vx`` (dropped before
estimating). A missed target is a strict xfail with the figure measured at commit time.
"""

from __future__ import annotations

import json
import math
import sys
from pathlib import Path

import numpy as np
import pytest

from vestim.constants import CORNERS
from vestim.pipeline import HOLD_S, Pipeline

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "benchmarks"))
import fault_table as ft  # noqa: E402

HAVE_CROSSPLANT = (ft.DATA / "manifest.json").is_file()


def _needs(name: str) -> list[pytest.MarkDecorator]:
    if name.startswith("sim:") or HAVE_CROSSPLANT:
        return []
    return [pytest.mark.skip(reason=f"crossplant data not at {ft.DATA}")]


# Misses measured today: (case, log) -> the figure. The IMU bias test runs only while the
# car drives steadily (docs/faults.md): these steps start inside a manoeuvre (or within the
# simulator's wheel-derivative noise) and are not flagged by it; the test of the estimate
# itself (bit 128) sees them only once they make v_x wrong by more than 0.2 m/s + 3 % of
# v_x, which none of them does (on x07 the a_x step during the braked turn pushes v_x
# 0.287 m/s off, beyond the clean bound but within the test's 0.5 m/s at 10 m/s; all four
# wheels are braked then, so no wheel says otherwise).
MISSES: dict[tuple[str, str], str] = {
    **{("bias_ax", n): "never flagged" for n in ft.LOGS},
    **{(c, n): "never flagged" for c in ("bias_ay", "bias_r") for n in ft.LOGS
       if n != "sim:accel_brake"},
}
MISSES[("bias_ax", "x07_brake_turn_dry_awd")] += ("; max v_x error 0.287 m/s > bound 0.143, "
                                                  "1.78 s valid while wrong")


def _cases() -> list[object]:
    out: list[object] = []
    for case in ft.CASES:
        for name in ft.LOGS:
            marks = _needs(name)
            if (case, name) in MISSES:
                marks.append(pytest.mark.xfail(
                    strict=True, reason=f"measured: {MISSES[(case, name)]}; target: flagged "
                    "≤ 0.5 s and max v_x error ≤ 2 × clean + 0.1 m/s"))
            out.append(pytest.param(case, name, marks=marks, id=f"{case}-{name}"))
    return out


@pytest.mark.parametrize(("case", "name"), _cases())
def test_fault_is_flagged_bounded_and_recovers(case: str, name: str) -> None:
    g = ft.run_case(case, name)
    # flagged within 0.5 s of the fault's start (a gap's end): the latency target
    assert g.latency <= ft.FLAG_S, f"flagged {g.latency} s after the fault's start"
    # no flag before the fault: the clean part of the log is not called faulty
    assert g.false == 0.0, f"{g.false} s flagged before the fault"
    # bounded: the 2 × the clean run's max |v_x error| + 0.1 m/s
    assert g.err <= g.bound, f"max v_x error {g.err:.3f} m/s > bound {g.bound:.3f}"
    # recovered within 2 s of the fault's end (nan: the fault lasts to the end of the log)
    assert math.isnan(g.recovery) or g.recovery <= ft.RECOVER_S, f"recovered after {g.recovery} s"
    # issue 30: no row valid while v_x is beyond the bound
    assert g.valid_wrong == 0.0, f"{g.valid_wrong} s valid while wrong"


@pytest.mark.parametrize("name", [pytest.param(n, marks=_needs(n)) for n in ft.LOGS])
def test_a_clean_run_flags_nothing(name: str) -> None:
    # the clean logs have no fault: every wheel healthy and no "input faulty" bit anywhere
    est = ft.clean(name)
    assert np.all(est[[f"health_omega_{c}" for c in CORNERS]].to_numpy() == 1.0)
    assert not np.any(est["reason_velocity"].to_numpy().astype(np.int64) & ft.INPUT_FAULTY)


@pytest.mark.parametrize("case", ["stuck", "dropout", "spikes"])
@pytest.mark.parametrize("name", [pytest.param(n, marks=_needs(n)) for n in ft.LOGS])
def test_a_wheel_fault_leaves_the_other_wheels_in(case: str, name: str) -> None:
    # only the faulty wheel is left out: the other three stay healthy on every row
    f = ft.inject(case, name)
    est = ft.estimate(case, name, f)
    others = [f"health_omega_{c}" for c in CORNERS if f"omega_{c}" != ft.WHEEL]
    assert np.all(est[others].to_numpy() == 1.0)


def test_step_matches_run_through_a_dropout() -> None:
    # the same health kernel runs in run() and step(): equal to rounding (1e-9)
    f = ft.inject("dropout", "sim:accel_brake")
    veh = ft.load("sim:accel_brake")[1]
    est = Pipeline(veh).run(f.log)
    pipe = Pipeline(veh)
    samples: list[dict[str, float]] = f.log.to_dict("records")  # type: ignore[assignment]
    rows = [pipe.step(s) for s in samples]
    for k in ("vx", f"health_{ft.WHEEL}", "reason_velocity"):
        np.testing.assert_allclose([r[k] for r in rows], est[k].to_numpy(), rtol=1e-9, atol=1e-9)


@pytest.mark.parametrize("name", [pytest.param(n, marks=_needs(n)) for n in ft.LOGS])
def test_a_long_nan_burst_through_step_is_a_clear_error(name: str) -> None:
    # longer than HOLD_S (0.5 s) no value is held: LogFormatError naming the channel, the
    # last finite sample (the row before 5 s) and the first sample more than HOLD_S after it
    # (within one 5 ms sample)
    msg = ft.nan_long_message(name)
    assert "channel 'ax'" in msg and f"at most {HOLD_S} s" in msg, msg
    t_err = float(msg.split("t = ")[1].split(" s")[0])
    t_good = float(msg.split("since t = ")[1].split(" s")[0])
    t = ft.load(name)[0]["t"].to_numpy()
    assert t_good == pytest.approx(t[t < ft.ON][-1], abs=5e-4), msg
    assert HOLD_S < t_err - t_good <= HOLD_S + 0.0051, msg


@pytest.mark.parametrize("name", [pytest.param(n, marks=_needs(n)) for n in ft.LOGS])
def test_run_refuses_a_nan_burst_naming_column_and_row(name: str) -> None:
    # run() checks the whole log first: the first NaN is the row at t = 5 s (200 Hz: row 1000)
    msg = ft.nan_run_message(name)
    row = int(np.searchsorted(ft.load(name)[0]["t"].to_numpy(), ft.ON))
    assert "column 'ax'" in msg and f"row {row} " in msg, msg


def _mistakes() -> list[object]:
    out: list[object] = []
    for i, (what, _, _, logs) in enumerate(ft.MISTAKES):
        for name in logs:
            marks = (_needs(name) if name != "rav4"
                     else [] if (ft.ict.RAV4 / "seg40.parquet").is_file()
                     else [pytest.mark.skip(reason="RAV4 log missing")])
            out.append(pytest.param(i, name, marks=marks, id=f"{what}-{name}"))
    return out


def _channels(how: str) -> list[str]:
    """The columns a mistake changes, from input_checks_table's description of it."""
    names = ["yaw_rate", "ax", "ay", "az", "roll_rate", "delta_fl", "omega_rl", "vehicle_speed",
             "gnss_speed", "torque_fl", "omega_fl"]
    return [n for n in names if n in how.replace("omega_*", "omega_fl omega_rl")
            .replace("torque_*", "torque_fl").replace("steering", "delta_fl")]


@pytest.mark.parametrize(("index", "name"), _mistakes())
def test_a_sign_or_unit_mistake_is_named_before_estimating(index: int, name: str) -> None:
    # a whole-log check before estimating: an error or warning whose message names one of the
    # columns the mistake changed (the clean logs give none: tests/io/test_sanity.py)
    what, how, _, _ = ft.MISTAKES[index]
    sev, msg = ft.mistake(index, name)
    if "(clean)" in what:  # input_checks_table's no-false-alarm rows
        assert sev == "none", msg
        return
    assert sev in ("error", "warning"), msg
    assert any(c in msg for c in _channels(how)), (how, msg)


def test_the_docs_table_lists_every_case() -> None:
    # docs/faults.md is generated from these cases: each case × log has its row
    text = (ROOT / "docs" / "faults.md").read_text(encoding="utf-8")
    for case in ft.CASES:
        for name in ft.LOGS:
            assert f"| {case} | {ft.WHAT[case]} | {name} |" in text
    assert json.dumps(ft.FLAG_S) in text
