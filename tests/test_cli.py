"""Command-line interface: listing, simulating to a file, clear errors."""

import threading

from typer.testing import CliRunner

from vestim.cli import _say, app
from vestim.io import read_log
from vestim.io.channels import REFERENCE
from vestim.sim import maneuver_names

runner = CliRunner()


def test_maneuvers_lists_one_per_line_name_first():
    result = runner.invoke(app, ["maneuvers"])
    assert result.exit_code == 0
    names = [line.split("\t")[0] for line in result.stdout.splitlines()]
    assert names == maneuver_names()


def test_simulate_writes_a_readable_log_with_every_ref_channel(tmp_path):
    out = tmp_path / "ss.parquet"
    result = runner.invoke(app, ["simulate", "step_steer", "--tire", "lugre", "--mu", "0.8",
                                 "--seed", "4", "--out", str(out)])
    assert result.exit_code == 0, result.output
    log = read_log(out, require=["measured"])
    assert set(REFERENCE) <= set(log.columns)
    assert (log["ref_mu_fl"] == 0.8).all()
    assert log.attrs["maneuver"] == "step_steer" and log.attrs["tire"] == "lugre"


def test_simulate_csv_and_vehicle_file(tmp_path):
    out = tmp_path / "c.csv"
    result = runner.invoke(app, ["simulate", "coast", "--vehicle", "compact_car",
                                 "--drivetrain", "rwd", "--out", str(out)])
    assert result.exit_code == 0, result.output
    assert len(read_log(out)) == 2001


def test_simulate_unknown_maneuver_is_a_clear_error(tmp_path):
    result = runner.invoke(app, ["simulate", "nope", "--out", str(tmp_path / "x.csv")])
    assert result.exit_code == 2
    assert "unknown maneuver 'nope'" in result.output
    assert "Traceback" not in result.output


def test_simulate_bad_vehicle_file_names_the_key(tmp_path):
    bad = tmp_path / "bad.toml"
    bad.write_text("[vehicle]\nmass = -1\n[tire]\n")
    result = runner.invoke(app, ["simulate", "coast", "--vehicle", str(bad),
                                 "--out", str(tmp_path / "x.csv")])
    assert result.exit_code == 2
    assert "mass" in result.output


def test_score_and_plot_commands(tmp_path):
    """simulate → estimate → score (table and JSON) → plot, end to end through the CLI."""
    import json
    from pathlib import Path

    sim = tmp_path / "sim.parquet"
    est = tmp_path / "est.parquet"
    assert runner.invoke(app, ["simulate", "lc_wet", "--out", str(sim)]).exit_code == 0
    assert runner.invoke(app, ["estimate", "--vehicle", "hashemi_suv",
                               str(sim), "--out", str(est)]).exit_code == 0
    table = runner.invoke(app, ["score", str(est), str(sim)])
    assert table.exit_code == 0 and "| vx |" in table.stdout
    as_json = runner.invoke(app, ["score", str(est), str(sim), "--json"])
    records = json.loads(as_json.stdout)
    vx = next(r for r in records if r["channel"] == "vx")
    assert vx["nrms_pct"] < 2.0  # lane change on wet: the reference filter measures ~0.1 %
    plots = runner.invoke(app, ["plot", "--vehicle", "hashemi_suv",
                                str(est), str(sim), "--out", str(tmp_path / "png")])
    assert plots.exit_code == 0
    files = plots.stdout.split()
    assert files and all(Path(f).read_bytes()[:8] == b"\x89PNG\r\n\x1a\n" for f in files)


def test_design_commands(tmp_path):
    """design lpv writes a gains file that design check certifies; bad gains exit non-zero."""
    gains = tmp_path / "gains.toml"
    res = runner.invoke(app, ["design", "lpv", "--vehicle", "hashemi_suv", "--out", str(gains)])
    assert res.exit_code == 0, res.output
    check = runner.invoke(app, ["design", "check", "--vehicle", "hashemi_suv", "--gains", str(gains)])
    assert check.exit_code == 0, check.output
    assert "VERIFIED" in check.stdout
    sim = tmp_path / "sim.parquet"
    assert runner.invoke(app, ["simulate", "lc_wet", "--out", str(sim)]).exit_code == 0
    est = runner.invoke(app, ["estimate", "--vehicle", "hashemi_suv",
                              str(sim), "--velocity", "lpv", "--gains", str(gains),
                              "--out", str(tmp_path / "est.csv")])
    assert est.exit_code == 0, est.output
    bad = tmp_path / "bad.toml"
    bad.write_text("[longitudinal]\nomega = [0.0]\n")
    res = runner.invoke(app, ["design", "check", "--vehicle", "hashemi_suv", "--gains", str(bad)])
    assert res.exit_code == 2 and "Traceback" not in res.output


def test_estimate_stiffness_pf_writes_stiffness_channels(tmp_path):
    """--method stiffness-pf (002 Algorithm 1) writes axle stiffness with sigmas and states."""
    sim = tmp_path / "sim.parquet"
    assert runner.invoke(app, ["simulate", "stiffness_study", "--out", str(sim)]).exit_code == 0
    out = tmp_path / "k.parquet"
    res = runner.invoke(app, ["estimate", "--vehicle", "hashemi_suv",
                              str(sim), "--method", "stiffness-pf", "--particles",
                              "100", "--seed", "3", "--out", str(out)])
    assert res.exit_code == 0, res.output
    est = read_log(out)
    for col in ("stiffness_cx_f", "sigma_stiffness_cx_f", "stiffness_cy_f", "stiffness_cy_r",
                "vx", "vy", "yaw_rate"):
        assert col in est.columns
    assert est["stiffness_cy_f"].gt(0).all()



def test_estimate_stiffness_ekf_writes_stiffness_channels(tmp_path):
    """--method stiffness-ekf runs the augmented-state EKF (002 Sec. V, the method the verdict in
    docs/results_stiffness.md favours on the cross-plant steps) and records it in the metadata;
    an unknown method is refused with the list of choices."""
    sim = tmp_path / "sim.parquet"
    assert runner.invoke(app, ["simulate", "stiffness_study", "--out", str(sim)]).exit_code == 0
    out = tmp_path / "k.parquet"
    res = runner.invoke(app, ["estimate", "--vehicle", "hashemi_suv", str(sim),
                              "--method", "stiffness-ekf", "--out", str(out)])
    assert res.exit_code == 0, res.output
    est = read_log(out)
    for col in ("stiffness_cx_f", "stiffness_cy_f", "stiffness_cy_r", "vx", "vy", "yaw_rate"):
        assert col in est.columns
    assert est["stiffness_cy_f"].gt(0).all()
    import pyarrow.parquet as pq
    assert b"stiffness-ekf" in b"".join((pq.read_schema(out).metadata or {}).values())
    bad = runner.invoke(app, ["estimate", "--vehicle", "hashemi_suv", str(sim),
                              "--method", "stiffness-rls", "--out", str(tmp_path / "b.parquet")])
    assert bad.exit_code == 2 and "stiffness-ekf" in bad.output and "Traceback" not in bad.output

def _short_log(tmp_path, name="log.parquet"):
    from vestim.io import load_vehicle, write_log
    from vestim.sim import get_maneuver, simulate

    log = simulate(get_maneuver("step_steer"), load_vehicle("hashemi_suv"), seed=0).iloc[:300]
    return write_log(log, tmp_path / name)


def test_estimate_refuses_to_overwrite_its_input(tmp_path):
    """`--out` equal to the input (also spelled differently) is refused before any work, and
    the input is left byte-identical."""
    src = _short_log(tmp_path)
    before = src.read_bytes()
    for out in (src, tmp_path / "." / "log.parquet"):
        result = runner.invoke(app, ["estimate", "--vehicle", "hashemi_suv", str(src), "--out", str(out)])
        assert result.exit_code == 2
        assert "is the input" in result.output
    assert src.read_bytes() == before


def test_output_extension_is_checked_before_the_work(tmp_path, monkeypatch):
    """A wrong --out extension fails at once: the pipeline is never built."""
    import vestim.pipeline

    def boom(*_a, **_k):
        raise AssertionError("the pipeline ran before the output path was checked")

    monkeypatch.setattr(vestim.pipeline, "Pipeline", boom)
    src = _short_log(tmp_path)
    result = runner.invoke(app, ["estimate", "--vehicle", "hashemi_suv",
                                 str(src), "--out", str(tmp_path / "est.xlsx")])
    assert result.exit_code == 2
    assert "unsupported extension '.xlsx'" in result.output


def _slow_compile(said: threading.Event) -> None:
    """A Numba compilation (its compile events) that lasts until the notice was given: the
    slow first call, made deterministic (no sleep; the 30 s is only a guard)."""
    from numba.core import event

    event.start_event("numba:compile")
    try:
        assert said.wait(30.0), "no compile notice"
    finally:
        event.end_event("numba:compile")


def test_compile_notice_says_so_once_while_compiling():
    """A compilation still running after `after_s` is announced once (a nested one and a
    second one are not announced again); one that ends first, or a block without any
    compilation (kernels loaded from the cache), says nothing."""
    from numba.core import event

    from vestim import _cache

    said = threading.Event()
    messages: list[str] = []

    def say(text: str) -> None:
        messages.append(text)
        said.set()

    with _cache.compile_notice(say, after_s=0.01):
        event.start_event("numba:compile")  # outer compile; the slow one nests inside it
        _slow_compile(said)
        event.end_event("numba:compile")
        _slow_compile(said)  # already said: returns at once
    assert messages == [_cache.notice_text()]
    assert "compiling vestim's kernels for this code path" in messages[0]
    assert str(_cache.cache_dir()) in messages[0]
    quiet: list[str] = []
    with _cache.compile_notice(quiet.append, after_s=3600.0):
        event.start_event("numba:compile")
        event.end_event("numba:compile")  # done long before the timer
    with _cache.compile_notice(quiet.append, after_s=0.0):
        pass  # nothing compiled
    assert quiet == []


def test_cli_announces_a_slow_compilation(monkeypatch):
    """Any command: a kernel call whose compilation takes more than 1 s the first time
    (here `vestim maneuvers` with an injected one) prints the notice on stderr, and the
    command's own output follows."""
    import vestim.sim

    said = threading.Event()
    real = vestim.sim.maneuver_names
    monkeypatch.setattr("vestim.cli._say", lambda text: (_say(text), said.set()))

    def names() -> list[str]:
        _slow_compile(said)
        return real()

    monkeypatch.setattr(vestim.sim, "maneuver_names", names)
    result = runner.invoke(app, ["maneuvers"])
    assert result.exit_code == 0, result.output
    assert "compiling vestim's kernels for this code path" in result.output
    assert "step_steer" in result.output


def test_estimate_metadata_says_how_it_was_made(tmp_path):
    """Version, full configuration and the vehicle file's hash go into the output (issue 15)."""
    import hashlib
    import json

    from vestim import __version__

    src = _short_log(tmp_path)
    veh = tmp_path / "car.toml"
    from importlib import resources
    veh.write_bytes((resources.files("vestim") / "data" / "vehicles" / "hashemi_suv.toml").read_bytes())
    out = tmp_path / "est.parquet"
    result = runner.invoke(app, ["estimate", str(src), "--vehicle", str(veh), "--out", str(out)])
    assert result.exit_code == 0, result.output
    meta = read_log(out).attrs
    assert meta["vestim_version"] == __version__
    assert meta["vehicle_sha256"] == hashlib.sha256(veh.read_bytes()).hexdigest()
    assert json.loads(meta["config"])["velocity"] == "reference"


def test_score_coverage_table(tmp_path):
    sim = tmp_path / "sim.parquet"
    est = tmp_path / "est.parquet"
    assert runner.invoke(app, ["simulate", "lc_wet", "--out", str(sim)]).exit_code == 0
    assert runner.invoke(app, ["estimate", "--vehicle", "hashemi_suv",
                               str(sim), "--out", str(est)]).exit_code == 0
    result = runner.invoke(app, ["score", str(est), str(sim), "--coverage"])
    assert result.exit_code == 0, result.output
    # the scores and, beside them, the σ coverage (issue 30): NRMS … samples, 1σ %, 2σ %
    assert "| NRMS [%] |" in result.output and "| within 1σ % | within 2σ % |" in result.output
    vx = next(line for line in result.output.splitlines() if line.startswith("| vx | m/s |"))
    cells = [c.strip() for c in vx.strip("|").split("|")]
    assert len(cells) == 10 and 0.0 <= float(cells[8]) <= float(cells[9]) <= 100.0


def test_non_finite_or_mistyped_options_are_clear_errors(tmp_path):
    """Issue 15: `simulate --v0 inf` was a FloatingPointError traceback and `[pipeline]
    gains = 5` was silently accepted."""
    res = runner.invoke(app, ["simulate", "coast", "--v0", "inf", "--out", str(tmp_path / "a.csv")])
    assert res.exit_code == 2 and "v0 = inf m/s must be in [0, 100]" in res.output
    src = _short_log(tmp_path)
    cfg = tmp_path / "cfg.toml"
    cfg.write_text("[pipeline]\ngains = 5\n", encoding="utf-8")
    res = runner.invoke(app, ["estimate", "--vehicle", "hashemi_suv",
                              str(src), "--out", str(tmp_path / "e.parquet"),
                              "--config", str(cfg)])
    assert res.exit_code == 2 and "gains = 5: the path of a gains file" in res.output


def test_estimate_metadata_states_the_roll_gradient_and_warns_of_unverified_vy(tmp_path):
    """Issue 29: the crossplant ramp steer without roll rate (its file states no
    [suspension]): the metadata says the roll gradient was identified and how large (6.7°/g
    measured, where the file's default suspension said 11.3°/g); our simulator's AWD slide on
    ice warns that v_y was unverified on 31 % of the rows (the a_y integral alone; 26 % before
    issue 31's wheel evidence moved v_x in the slide)."""
    import json
    from pathlib import Path

    import pandas as pd
    import pytest

    data = Path(__file__).resolve().parents[1].parent / "shared" / "crossplant" / "data"
    if not data.exists():
        pytest.skip(f"crossplant data not found at {data}")
    log = pd.read_parquet(data / "x06_ramp_steer_wet_fwd.parquet")
    src = tmp_path / "x06.parquet"
    log[[c for c in log.columns if not c.startswith("ref_") and c != "roll_rate"]].to_parquet(src)
    out = tmp_path / "est.parquet"
    res = runner.invoke(app, ["estimate", str(src), "--vehicle", str(data / "vehicle1.toml"),
                              "--out", str(out)])
    assert res.exit_code == 0, res.output
    meta = read_log(out).attrs
    assert meta["roll_gradient_source"] == "identified"
    assert 3.0 <= float(meta["roll_gradient_deg_per_g"]) <= 9.0

    sim, est = tmp_path / "sim.parquet", tmp_path / "slide.parquet"
    assert runner.invoke(app, ["simulate", "ait_slippery", "--tire", "lugre", "--drivetrain",
                               "awd", "--out", str(sim)]).exit_code == 0
    res = runner.invoke(app, ["estimate", str(sim), "--vehicle", "hashemi_suv",
                              "--out", str(est)])
    assert res.exit_code == 0, res.output
    warned = [w for w in json.loads(read_log(est).attrs["warnings"])
              if w["check"] == "lateral_consistency"]
    assert len(warned) == 1 and warned[0]["evidence"] == pytest.approx(0.31, abs=0.03)


def test_simulate_realistic_sensors_and_a_softer_plant(tmp_path):
    """`simulate --sensors realistic --roll-scale 1.6` (issue 29: the default sensors and a
    plant that rolls as the file says hid the lateral filter's drift); a wrong mode is named."""
    out = tmp_path / "r.parquet"
    res = runner.invoke(app, ["simulate", "lc_wet", "--sensors", "realistic", "--roll-scale",
                              "1.6", "--out", str(out)])
    assert res.exit_code == 0, res.output
    assert read_log(out).attrs["roll_scale"] == "1.6"
    bad = runner.invoke(app, ["simulate", "lc_wet", "--sensors", "noisy", "--out", str(out)])
    assert bad.exit_code == 2 and "--sensors 'noisy': use default or realistic" in bad.output
