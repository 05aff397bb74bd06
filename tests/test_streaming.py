"""A long log in bounded memory (issue 15): read in pieces, estimated piece by piece with the
state carried over, written piece by piece. Every step must give what the whole-log path
gives, bit for bit, so that streaming is only a memory layout."""

from __future__ import annotations

import itertools
import json
from pathlib import Path

import numpy as np
import pandas as pd
import pyarrow as pa
import pyarrow.parquet as pq
import pytest
from typer.testing import CliRunner

from vestim.cli import app
from vestim.errors import LogFormatError
from vestim.io import LogWriter, iter_log, load_vehicle, parquet_rows, read_log
from vestim.pipeline import Pipeline, PipelineConfig
from vestim.sim import get_maneuver, simulate

SUV = load_vehicle("hashemi_suv")


@pytest.fixture(scope="module")
def gap_log() -> pd.DataFrame:
    """accel_brake with 2 s cut out at 4–6 s (a recording gap), truth dropped."""
    full = simulate(get_maneuver("accel_brake"), SUV, seed=0)
    t = full["t"].to_numpy()
    meas = full[[c for c in full.columns if not c.startswith("ref_")]]
    return meas[(t < 4.0) | (t >= 6.0)].reset_index(drop=True)


def _write_row_groups(df: pd.DataFrame, path: Path, group: int) -> None:
    pq.write_table(pa.Table.from_pandas(df, preserve_index=False), path, row_group_size=group)


@pytest.mark.parametrize("velocity", ["fused", "kf"])
def test_pieces_equal_the_whole_log_bit_for_bit(gap_log: pd.DataFrame, velocity: str) -> None:
    """Pieces of 333 rows, one boundary exactly at the gap (row of t = 6 s): the concatenated
    estimates equal run() of the whole log exactly (every stage's state carries over, and a gap
    between pieces restarts the filters as one inside a piece does)."""
    cfg = PipelineConfig(velocity=velocity)
    whole_pipe = Pipeline(SUV, cfg)
    whole = whole_pipe.run(gap_log)
    at_gap = int(np.flatnonzero(gap_log["t"].to_numpy() >= 6.0)[0])
    bounds = sorted({*range(0, len(gap_log), 333), at_gap, len(gap_log)})
    pieces = [gap_log.iloc[a:b] for a, b in itertools.pairwise(bounds)]
    pipe = Pipeline(SUV, cfg)
    streamed = pd.concat(list(pipe.run_pieces(pieces)), ignore_index=True)
    pd.testing.assert_frame_equal(streamed, whole, check_exact=True)
    assert pipe.gaps == whole_pipe.gaps and len(pipe.gaps) == 1


def test_pieces_out_of_order_are_refused(gap_log: pd.DataFrame) -> None:
    pieces = [gap_log.iloc[100:200], gap_log.iloc[0:100]]
    with pytest.raises(LogFormatError, match=r"'t' is not strictly increasing at row 100"):
        list(Pipeline(SUV).run_pieces(pieces))


def test_iter_log_reads_the_file_in_pieces_that_concatenate_to_read_log(
        tmp_path: Path, gap_log: pd.DataFrame) -> None:
    """Row groups of 700 rows read in pieces of at least 1000: every piece but the last has
    1000–1399 rows (whole record batches), and together they are read_log's frame."""
    path = tmp_path / "log.parquet"
    _write_row_groups(gap_log, path, 700)
    pieces = list(iter_log(path, require=["measured"], rows=1000))
    assert all(1000 <= len(p) < 1400 for p in pieces[:-1])
    assert parquet_rows(path) == len(gap_log) == sum(map(len, pieces))
    pd.testing.assert_frame_equal(pd.concat(pieces, ignore_index=True), read_log(path))


def test_iter_log_names_the_file_row_of_a_bad_value(tmp_path: Path,
                                                   gap_log: pd.DataFrame) -> None:
    """A NaN in row 2500 is reported as row 2500 of the file, not of its piece."""
    bad = gap_log.copy()
    bad.loc[2500, "ax"] = np.nan
    path = tmp_path / "bad.parquet"
    _write_row_groups(bad, path, 1000)
    with pytest.raises(LogFormatError, match=r"'ax' is missing \(NaN\) at row 2500 "):
        list(iter_log(path, rows=1000))


def test_log_writer_writes_pieces_atomically_with_late_metadata(tmp_path: Path,
                                                                gap_log: pd.DataFrame) -> None:
    """Pieces written one by one read back as the whole log, with metadata added at the end;
    an exception inside the block leaves no file and no temporary."""
    path = tmp_path / "out.parquet"
    with LogWriter(path) as w:
        for a in range(0, len(gap_log), 1000):
            w.write(gap_log.iloc[a:a + 1000])
        assert not path.exists()  # nothing appears before the block ends
        w.metadata["source"] = "gap"
    back = read_log(path)
    assert back.attrs == {"source": "gap"}
    pd.testing.assert_frame_equal(back[list(gap_log.columns)], gap_log)
    failed = tmp_path / "failed.csv"
    with pytest.raises(RuntimeError, match="boom"), LogWriter(failed) as w:
        w.write(gap_log.iloc[:10])
        raise RuntimeError("boom")
    assert sorted(p.name for p in tmp_path.iterdir()) == ["out.parquet"]


def test_log_writer_refuses_a_piece_with_other_columns(tmp_path: Path,
                                                       gap_log: pd.DataFrame) -> None:
    with pytest.raises(LogFormatError, match="extra: none; missing: ax"), \
            LogWriter(tmp_path / "o.parquet") as w:
        w.write(gap_log.iloc[:10])
        w.write(gap_log.iloc[10:20].drop(columns=["ax"]))
    assert list(tmp_path.iterdir()) == []


def test_cli_streams_a_parquet_log_to_the_same_result(tmp_path: Path, gap_log: pd.DataFrame,
                                                      monkeypatch: pytest.MonkeyPatch) -> None:
    """`vestim estimate` on a Parquet log reads, estimates and writes it in pieces (here of
    1500 rows, with the input checks on the first 3000): the file equals run() of the whole
    log rounded to float32 (t in float64), and the gap is in its metadata."""
    import vestim.io.log as io_log
    import vestim.io.sanity as sanity

    monkeypatch.setattr(io_log, "STREAM_ROWS", 1500)
    monkeypatch.setattr(sanity, "GATE_ROWS", 3000)
    src = tmp_path / "in.parquet"
    _write_row_groups(gap_log, src, 500)
    out = tmp_path / "est.parquet"
    res = CliRunner().invoke(app, ["estimate", "--vehicle", "hashemi_suv", str(src), "--out", str(out)])
    assert res.exit_code == 0, res.output
    est, whole = read_log(out), Pipeline(SUV).run(gap_log)
    assert est["t"].dtype == np.float64 and (est.drop(columns="t").dtypes == np.float32).all()
    single = whole.astype({c: np.float32 for c in whole.columns if c != "t"})
    pd.testing.assert_frame_equal(est[list(whole.columns)], single, check_exact=True)
    assert json.loads(est.attrs["gaps"]) == [[pytest.approx(3.995), 6.0]]  # last t before: 4 − 1/200
