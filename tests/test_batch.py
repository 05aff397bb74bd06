"""``vestim batch``: many logs, one task each; failures in the summary; resumable; identical results.

The logs are short simulator logs (``vestim.sim``), written like ``vestim simulate`` does, so
they carry ``vestim.vehicle`` metadata; plus a corrupt Parquet file and a CSV without ``t``.
Every check of an estimate is against ``Pipeline(vehicle, config).run(read_log(log))`` run
here, in this process: the batch must reproduce it bit for bit (same code, same input, one
task per log), whatever the scheduler.
"""

from __future__ import annotations

import json
import math
import re
import shutil
import sys
from importlib import resources
from pathlib import Path

import numpy as np
import pandas as pd
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from typer.testing import CliRunner

from vestim.batch import (
    SUMMARY_COLUMNS,
    BatchError,
    _job_key,
    _validity,
    collect_logs,
    map_tasks,
    open_runner,
    output_path,
    run_batch,
    vehicle_for_log,
)
from vestim.cli import app
from vestim.errors import MissingDependencyError, VehicleFileError
from vestim.io import load_vehicle, read_log, write_log
from vestim.metrics import score
from vestim.pipeline import Pipeline, PipelineConfig
from vestim.sim import get_maneuver, simulate

CROSSPLANT = Path(__file__).resolve().parents[1] / ".." / "shared" / "crossplant" / "data"
GOOD = {"step_steer.parquet": "hashemi_suv", "launch_ice.parquet": "compact_car",
        "coast.csv": "compact_car"}
"""The good logs and the vehicle each was simulated with."""
BAD = ("corrupt.parquet", "bad_columns.csv")


def _builtin_toml(name: str) -> str:
    return (resources.files("vestim") / "data" / "vehicles" / f"{name}.toml").read_text()


@pytest.fixture(scope="module")
def logs(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """Three good logs (vehicle found by --vehicle auto: metadata, or coast.toml beside the CSV),
    a corrupt Parquet file and a CSV whose time column is called 'time'."""
    d = tmp_path_factory.mktemp("logs")
    for name, veh in GOOD.items():
        stem = Path(name).stem
        log = simulate(get_maneuver(stem), load_vehicle(veh), seed=3)
        if stem == "launch_ice":
            log = log.iloc[:800]  # 4 s: keeps the test short
        write_log(log, d / name, metadata=log.attrs)
    (d / "coast.toml").write_text(_builtin_toml("compact_car"))
    (d / "corrupt.parquet").write_bytes(b"PAR1 this is not a parquet file")
    bad = read_log(d / "coast.csv").rename(columns={"t": "time"})
    bad.to_csv(d / "bad_columns.csv", index=False)
    (d / "bad_columns.toml").write_text(_builtin_toml("compact_car"))
    return d


def _single_run(log: Path, vehicle: str, config: PipelineConfig | None = None) -> pd.DataFrame:
    veh = load_vehicle(vehicle)
    return Pipeline(veh, config).run(read_log(log, require=["measured"],
                                              wheel_radius=veh.body.wheel_radius))


def _assert_bit_identical(got: pd.DataFrame, want: pd.DataFrame) -> None:
    """The batch's file holds the single run's estimates, in float32 but t (as `vestim
    estimate` writes them), bit for bit."""
    assert sorted(got.columns) == sorted(want.columns)
    for c in want.columns:
        a = got[c].to_numpy()
        b = want[c].to_numpy() if c == "t" else want[c].to_numpy().astype(np.float32)
        assert a.dtype == b.dtype and a.shape == b.shape, c
        assert a.tobytes() == b.tobytes(), f"column {c} differs from the single run"


def _inputs(d: Path) -> list[Path]:
    return [d / n for n in (*GOOD, *BAD)]


def test_batch_failures_identical_results_resume_and_config_change(logs: Path, tmp_path: Path):
    out = tmp_path / "out"
    seen: list[tuple[int, int]] = []
    summary = run_batch(_inputs(logs), "auto", out, scheduler="synchronous",
                        progress=lambda done, total: seen.append((done, total)))
    table = summary.table
    assert list(table.columns) == list(SUMMARY_COLUMNS)
    assert table["log"].tolist() == [str(p) for p in _inputs(logs)]  # input order
    # 3 good logs estimated, the 2 bad ones failed with their reason, and the batch went on.
    assert table["status"].tolist() == ["ok"] * 3 + ["failed"] * 2
    assert summary.failed and summary.count("ok") == 3
    err = dict(zip(table["log"], table["error"], strict=True))
    assert "corrupt.parquet" in err[str(logs / "corrupt.parquet")]
    assert "cannot be read as PARQUET" in err[str(logs / "corrupt.parquet")]
    assert "rename 'time' to 't'" in err[str(logs / "bad_columns.csv")]
    assert seen[-1] == (5, 5) and [d for d, _ in seen] == sorted(d for d, _ in seen)

    # Each estimate is bit-identical to a single Pipeline.run on the same log and vehicle, and its
    # summary scores are vestim.metrics.score's (vx, vy; worst corner of fx, fy, fz).
    for name, veh in GOOD.items():
        want = _single_run(logs / name, veh)
        got = read_log(output_path(logs / name, out))
        _assert_bit_identical(got, want)
        row = table[table["log"] == str(logs / name)].iloc[0]
        # --vehicle auto: the simulator's metadata names the built-in; coast.csv has coast.toml.
        label = str(logs / "coast.toml") if name == "coast.csv" else veh
        assert row["samples"] == len(want) and row["vehicle"] == label
        ref = score(want, read_log(logs / name)).set_index("channel")["nrms_pct"]
        assert row["nrms_vx_pct"] == ref["vx"] and row["nrms_vy_pct"] == ref["vy"]
        for fam in ("fx", "fy", "fz"):
            assert row[f"nrms_{fam}_pct"] == max(ref[f"{fam}_{c}"] for c in ("fl", "fr", "rl", "rr"))
        # The pipeline writes valid_velocity, valid_force, valid_slip: the share of rows
        # with all three set is the summary's valid fraction.
        valid = want[["valid_velocity", "valid_force", "valid_slip"]].to_numpy().all(axis=1)
        assert row["valid_columns"] == 3 and row["valid_fraction"] == float(valid.mean())
    # Failed rows have no output; summary.parquet holds the same table; summary.md names the errors.
    assert not output_path(logs / "corrupt.parquet", out).exists()
    stored = pd.read_parquet(out / "summary.parquet")
    pd.testing.assert_frame_equal(stored, table)
    md = (out / "summary.md").read_text()
    assert "3 ok, 0 skipped (up to date), 2 failed" in md and "rename 'time' to 't'" in md

    # Second run: the up-to-date outputs are skipped (files untouched, same stored scores).
    mtimes = {n: output_path(logs / n, out).stat().st_mtime_ns for n in GOOD}
    again = run_batch(_inputs(logs), "auto", out, scheduler="synchronous")
    assert again.table["status"].tolist() == ["skipped"] * 3 + ["failed"] * 2
    assert {n: output_path(logs / n, out).stat().st_mtime_ns for n in GOOD} == mtimes
    cols = ["samples", *(f"nrms_{c}_pct" for c in ("vx", "vy", "fx", "fy", "fz"))]
    pd.testing.assert_frame_equal(again.table[cols].iloc[:3], table[cols].iloc[:3])

    # A changed configuration recomputes every log, bit-identical to single runs with it.
    cfg = PipelineConfig(force="naive", velocity="reference")
    changed = run_batch(_inputs(logs)[:3], "auto", out, config=cfg, scheduler="synchronous")
    assert changed.table["status"].tolist() == ["ok"] * 3 and not changed.failed
    for name, veh in GOOD.items():
        _assert_bit_identical(read_log(output_path(logs / name, out)),
                              _single_run(logs / name, veh, cfg))


def test_local_cluster_of_two_workers_is_identical_and_resumable_in_another_process(
        logs: Path, tmp_path: Path):
    """Two Dask worker processes: the same bits as single runs. The resume key is computed in the
    workers and again here (other processes, other str hash seeds), so it must not depend on
    set order: the synchronous rerun skips all three."""
    out = tmp_path / "out"
    summary = run_batch(_inputs(logs)[:3], "auto", out, n_workers=2)
    assert summary.workers == 2
    assert summary.table["status"].tolist() == ["ok"] * 3
    for name, veh in GOOD.items():
        _assert_bit_identical(read_log(output_path(logs / name, out)), _single_run(logs / name, veh))
    again = run_batch(_inputs(logs)[:3], "auto", out, scheduler="synchronous")
    assert again.table["status"].tolist() == ["skipped"] * 3


def test_changed_input_or_vehicle_recomputes_and_force_always_does(logs: Path, tmp_path: Path):
    d = tmp_path / "in"
    d.mkdir()
    src = d / "coast.csv"
    shutil.copy(logs / "coast.csv", src)
    out = tmp_path / "out"
    assert run_batch([src], "compact_car", out, scheduler="synchronous").table.status[0] == "ok"
    assert run_batch([src], "compact_car", out, scheduler="synchronous").table.status[0] == "skipped"
    assert run_batch([src], "compact_car", out, scheduler="synchronous",
                     force=True).table.status[0] == "ok"
    # Another vehicle: a different estimate, recomputed.
    assert run_batch([src], "hashemi_suv", out, scheduler="synchronous").table.status[0] == "ok"
    _assert_bit_identical(read_log(output_path(src, out)), _single_run(src, "hashemi_suv"))
    # A changed input file (one sample dropped): recomputed, 1 sample fewer than the 2001.
    read_log(src).iloc[:-1].to_csv(src, index=False)
    row = run_batch([src], "hashemi_suv", out, scheduler="synchronous").table.iloc[0]
    assert row["status"] == "ok" and row["samples"] == 2000


@settings(max_examples=25, deadline=None)
@given(a=st.tuples(st.sampled_from(["ukf", "pid", "naive"]), st.sampled_from(["static", "dynamic"]),
                   st.sampled_from(["fused", "reference", "kinematic"])),
       b=st.tuples(st.sampled_from(["ukf", "pid", "naive"]), st.sampled_from(["static", "dynamic"]),
                   st.sampled_from(["fused", "reference", "kinematic"])))
def test_resume_key_changes_exactly_when_the_configuration_does(a, b):
    """Two configurations give the same key if and only if they are equal."""
    log = Path(__file__)  # any file: the key hashes its bytes
    veh = load_vehicle("hashemi_suv")
    ca = PipelineConfig(force=a[0], normal=a[1], velocity=a[2])
    cb = PipelineConfig(force=b[0], normal=b[1], velocity=b[2])
    assert (_job_key(log, veh, ca) == _job_key(log, veh, cb)) == (ca == cb)


def test_validity_is_the_share_of_samples_with_every_valid_column_set():
    """valid_a fails at row 2, valid_b at row 1: rows 0 and 3 of 4 are valid, 0.5."""
    est = pd.DataFrame({"t": [0.0, 1.0, 2.0, 3.0], "valid_a": [1, 1, 0, 1],
                        "valid_b": [True, False, True, True]})
    assert _validity(est) == {"valid_fraction": 0.5, "valid_columns": 2}
    assert math.isnan(_validity(est[["t"]])["valid_fraction"])


def test_vehicle_for_log_rules(logs: Path, tmp_path: Path):
    # 1. <stem>.toml beside the log; 4. a simulator log's built-in vehicle metadata.
    assert vehicle_for_log(logs / "coast.csv") == str(logs / "coast.toml")
    assert vehicle_for_log(logs / "step_steer.parquet") == "hashemi_suv"
    # 3. the crossplant manifest.json beside the log names its vehicle file.
    d = tmp_path / "m"
    d.mkdir()
    shutil.copy(logs / "coast.csv", d / "x99_run.csv")
    (d / "manifest.json").write_text(json.dumps({"maneuvers": {"x99_run": {
        "vehicle_file": "car.toml"}}}))
    with pytest.raises(VehicleFileError, match=r"car\.toml"):  # named but absent
        vehicle_for_log(d / "x99_run.csv")
    (d / "car.toml").write_text(_builtin_toml("compact_car"))
    assert vehicle_for_log(d / "x99_run.csv") == str(d / "car.toml")
    # No rule applies: a clear error naming the log and the fix.
    shutil.copy(logs / "coast.csv", tmp_path / "lonely.csv")
    with pytest.raises(VehicleFileError, match=r"lonely\.csv.*--vehicle"):
        vehicle_for_log(tmp_path / "lonely.csv")
    # A log whose vehicle is unknown fails alone in a batch.
    row = run_batch([tmp_path / "lonely.csv"], "auto", tmp_path / "out",
                    scheduler="synchronous").table.iloc[0]
    assert row["status"] == "failed" and "--vehicle" in row["error"]


@pytest.mark.skipif(not (CROSSPLANT / "x05_sine_steer_dry_rwd.parquet").is_file(),
                    reason="cross-plant data not found")
def test_vehicle_for_log_crossplant_parquet_metadata(tmp_path: Path):
    """2. The crossplant logs name their vehicle in the Parquet metadata drive_log: x05 is vehicle2."""
    assert vehicle_for_log(CROSSPLANT / "x05_sine_steer_dry_rwd.parquet") == str(
        CROSSPLANT / "vehicle2.toml")
    shutil.copy(CROSSPLANT / "x05_sine_steer_dry_rwd.parquet", tmp_path / "x05.parquet")
    with pytest.raises(VehicleFileError, match=r"vehicle2\.toml"):  # the named file is not beside it
        vehicle_for_log(tmp_path / "x05.parquet")


def test_collect_logs_and_clashing_outputs(logs: Path, tmp_path: Path):
    found = collect_logs([logs])
    assert [p.name for p in found] == sorted(["bad_columns.csv", "coast.csv", "corrupt.parquet",
                                              "launch_ice.parquet", "step_steer.parquet"])
    assert collect_logs([logs, logs / "coast.csv"], exclude=logs) == [logs / "coast.csv"]
    with pytest.raises(BatchError, match="no such file"):
        collect_logs([tmp_path / "missing"])
    with pytest.raises(BatchError, match="no logs found"):
        collect_logs([tmp_path])
    (tmp_path / "coast.parquet").write_bytes(b"")
    with pytest.raises(BatchError, match="same file stem"):
        run_batch([logs / "coast.csv", tmp_path / "coast.parquet"], "auto", tmp_path / "o",
                  scheduler="synchronous")


def test_map_tasks_keeps_item_order_and_propagates_errors():
    assert map_tasks(divmod, [(7, 2), (9, 4)], scheduler="synchronous", star=True) == [(3, 1), (2, 1)]
    with pytest.raises(ZeroDivisionError):
        map_tasks(divmod, [(1, 0)], scheduler="synchronous", star=True)


def test_missing_dask_is_a_clear_error(monkeypatch: pytest.MonkeyPatch):
    monkeypatch.setitem(sys.modules, "distributed", None)  # as if vestim[batch] were not installed
    with pytest.raises(MissingDependencyError, match=r"vestim\[batch\].*--scheduler synchronous"), \
            open_runner(None):
        pass
    with open_runner("synchronous") as runner:  # needs no Dask
        assert runner.map(abs, [-2]) == [2]


def _flat(text: str) -> str:
    return " ".join(text.split())  # Rich wraps long lines at the terminal width


def test_cli_batch_exit_status_and_errors(logs: Path, tmp_path: Path):
    runner = CliRunner()
    out = tmp_path / "out"
    ok = runner.invoke(app, ["batch", str(logs / "coast.csv"), str(logs / "step_steer.parquet"),
                             "--out", str(out), "--scheduler", "synchronous"])
    assert ok.exit_code == 0, ok.output
    assert "2 logs: 2 ok, 0 skipped, 0 failed" in _flat(ok.output)
    bad = runner.invoke(app, ["batch", str(logs), "--out", str(out), "--scheduler", "synchronous"])
    assert bad.exit_code == 1  # two logs failed; the summary is still written
    assert "corrupt.parquet" in _flat(bad.output) and "2 skipped, 2 failed" in _flat(bad.output)
    assert (out / "summary.md").is_file() and "Traceback" not in bad.output
    missing = runner.invoke(app, ["batch", str(tmp_path / "nope"), "--out", str(out)])
    assert missing.exit_code == 2 and "no such file" in _flat(missing.output)
    cfg = tmp_path / "bad.toml"
    cfg.write_text("[pipeline]\nforce = 'magic'\n")
    wrong = runner.invoke(app, ["batch", str(logs), "--out", str(out), "--config", str(cfg)])
    assert wrong.exit_code == 2 and "force method 'magic'" in _flat(wrong.output)
    assert "Traceback" not in wrong.output + missing.output


def test_unreachable_scheduler_is_a_clear_error():
    address = "tcp://127.0.0.1:9"  # the discard port: nothing listens there
    with pytest.raises(BatchError, match=re.escape(f"cannot connect to the Dask scheduler {address!r}")), \
            open_runner(address, connect_timeout=1.0):
        pass


def test_outputs_are_never_written_into_the_inputs(logs: Path, tmp_path: Path):
    before = {p.name: p.read_bytes() for p in logs.iterdir()}
    run_batch(_inputs(logs), "auto", tmp_path / "o", scheduler="synchronous")
    assert {p.name: p.read_bytes() for p in logs.iterdir()} == before
    assert np.all([not p.name.startswith(".") for p in (tmp_path / "o").iterdir()])  # no temp files


# --- raw recordings, own outputs, Ctrl-C, Dask clusters (issue 28) ------------------------------


def test_a_raw_recording_needs_a_map(tmp_path: Path):
    """`vestim batch x.mf4` without --map says so (exit 2), not "cannot tell which vehicle"."""
    (tmp_path / "x.mf4").write_bytes(b"")
    r = CliRunner().invoke(app, ["batch", str(tmp_path / "x.mf4"), "--out", str(tmp_path / "o"),
                                 "--scheduler", "synchronous"])
    assert r.exit_code == 2 and "a raw recording needs a map (--map" in _flat(r.output)
    with pytest.raises(BatchError, match="needs a map"):
        collect_logs([tmp_path / "x.mf4"])
    assert collect_logs([tmp_path], raw=True) == [tmp_path / "x.mf4"]


def test_folder_scan_skips_vestims_own_outputs(logs: Path, tmp_path: Path):
    """A folder holding logs and the estimates of an earlier run (written next to them, and one
    renamed so only its metadata tells) yields only the logs: 3, not 3 + 2 + summary."""
    d = tmp_path / "mixed"
    shutil.copytree(logs, d)
    for p in d.glob("*.parquet"):
        if p.name.startswith(("corrupt", "launch")):
            p.unlink()
    run_batch([d / "step_steer.parquet", d / "coast.csv"], "auto", d, scheduler="synchronous")
    (d / "step_steer_estimate.parquet").rename(d / "renamed.parquet")  # only metadata tells
    found = [p.name for p in collect_logs([d])]
    assert found == ["bad_columns.csv", "coast.csv", "step_steer.parquet"], found


def test_ctrl_c_names_what_finished_and_how_to_resume(logs: Path, tmp_path: Path,
                                                      monkeypatch: pytest.MonkeyPatch):
    """Ctrl-C after the first log: BatchInterrupted lists it (its output is complete); the CLI
    prints that and exits 130; the same command then skips it."""
    from vestim.batch import BatchInterrupted

    def stop(done: int, _total: int) -> None:
        if done == 1:
            raise KeyboardInterrupt

    out = tmp_path / "o"
    two = [logs / "coast.csv", logs / "step_steer.parquet"]
    with pytest.raises(BatchInterrupted, match=r"interrupted: 1 of 2 logs finished \(coast.csv"
                                               r".*Run the same command again to resume") as info:
        run_batch(two, "auto", out, scheduler="synchronous", progress=stop)
    assert info.value.finished == [str(logs / "coast.csv")]  # the larger file runs first
    again = run_batch(two, "auto", out, scheduler="synchronous")
    assert list(again.table["status"]) == ["skipped", "ok"]

    def interrupted(*_a: object, **_k: object) -> None:
        raise BatchInterrupted([str(two[0])], 2, out)

    monkeypatch.setattr("vestim.batch.run_batch", interrupted)
    r = CliRunner().invoke(app, ["batch", *map(str, two), "--out", str(out)])
    assert r.exit_code == 130 and "1 of 2 logs finished" in _flat(r.output)
    assert "Traceback" not in r.output


class _Deadline:
    """Fail, rather than hang, if the block runs longer than ``seconds`` (SIGALRM, Unix)."""

    def __init__(self, seconds: int) -> None:
        self.seconds = seconds

    def __enter__(self) -> None:
        import signal

        def fail(*_a: object) -> None:
            raise TimeoutError(f"Dask test ran over {self.seconds} s")

        self._old = signal.signal(signal.SIGALRM, fail)
        signal.alarm(self.seconds)

    def __exit__(self, *_exc: object) -> None:
        import signal

        signal.alarm(0)
        signal.signal(signal.SIGALRM, self._old)


def test_existing_cluster_by_address_and_local_scratch_cleanup(logs: Path, tmp_path: Path,
                                                               monkeypatch: pytest.MonkeyPatch):
    """`--scheduler tcp://…` runs on a running cluster (a LocalCluster of 1 process, always
    closed): the estimate is the in-process one bit for bit. A local cluster started by
    vestim with a dashboard gives its link and leaves no dask-scratch-space in the temp
    folder. Each part has 120 s before it fails (never hangs)."""
    distributed = pytest.importorskip("distributed")
    import tempfile

    with _Deadline(120):
        cluster = distributed.LocalCluster(processes=True, n_workers=1, threads_per_worker=1,
                                           dashboard_address=None, local_directory=str(tmp_path / "w"))
        try:
            summary = run_batch([logs / "coast.csv"], "auto", tmp_path / "o",
                                scheduler=cluster.scheduler_address)
        finally:
            cluster.close()
    assert summary.workers == 1 and summary.count("ok") == 1
    _assert_bit_identical(read_log(tmp_path / "o" / "coast_estimate.parquet"),
                          _single_run(logs / "coast.csv", "compact_car"))
    scratch_root = tmp_path / "tmp"
    scratch_root.mkdir()
    monkeypatch.setattr(tempfile, "tempdir", str(scratch_root))
    links: list[str] = []
    with _Deadline(120):
        run_batch([logs / "coast.csv"], "auto", tmp_path / "o2", n_workers=1, dashboard=links.append)
    assert len(links) == 1 and links[0].startswith("http")
    assert list(scratch_root.rglob("dask-scratch-space")) == []


def test_a_map_per_source_kind(tmp_path: Path):
    """A recording takes the map of its kind, else the one without a kind; a spec log (CSV)
    takes none unless a map says kind = "tabular"; none or two that fit are named errors."""
    from vestim.batch import map_for

    (tmp_path / "a.mf4").write_bytes(b"")
    bag = tmp_path / "b_bag"
    bag.mkdir()
    (bag / "metadata.yaml").write_text("rosbag2_bagfile_information: {}\n")
    (tmp_path / "c.csv").write_text("t\n0\n")
    maps = [("can.toml", "mdf"), ("any.toml", None)]
    assert map_for(tmp_path / "a.mf4", maps) == "can.toml"
    assert map_for(bag, maps) == "any.toml"
    assert map_for(tmp_path / "c.csv", maps) is None
    assert map_for(tmp_path / "c.csv", [("csv.toml", "tabular")]) == "csv.toml"
    with pytest.raises(BatchError, match=r"b_bag: a raw recording needs a map \(--map\) for ros2 "
                                         r"sources; the maps given are for mdf"):
        map_for(bag, [("can.toml", "mdf")])
    with pytest.raises(BatchError, match=r"2 maps apply to its kind \(mdf\).*give each map's "
                                         r"\[source\] kind"):
        map_for(tmp_path / "a.mf4", [("x.toml", "mdf"), ("y.toml", "mdf")])
    bad = tmp_path / "bad.toml"
    bad.write_text("[output]\nrate = 100\n")
    r = CliRunner().invoke(app, ["batch", str(tmp_path), "--map", str(bad), "--out",
                                 str(tmp_path / "o"), "--scheduler", "synchronous"])
    assert r.exit_code == 2 and "[channels] is missing" in _flat(r.output)
