"""``vestim channels`` (vestim.io.listing): the signals of a recording, and a starter map."""

from __future__ import annotations

import math
import tomllib
from pathlib import Path

import numpy as np
import pandas as pd
import pytest
from typer.testing import CliRunner

from vestim.cli import app
from vestim.io.channel_map import load_channel_map
from vestim.io.listing import list_signals, starter_map


def _csv(tmp_path: Path) -> Path:
    t = np.arange(0.0, 2.0, 0.01)  # 100 Hz, 200 rows
    df = pd.DataFrame({"time": t, "WheelSpeed_FL": 40.0 + t, "lat_accel": np.sin(t),
                       "label": ["x"] * t.size})
    path = tmp_path / "obd.csv"
    df.to_csv(path, index=False)
    return path


def test_csv_columns_with_rate_and_span(tmp_path: Path) -> None:
    """Every numeric column but the time column (found by name), 100 Hz over 0 … 1.99 s; text
    columns are left out; a CSV has no units."""
    listing = list_signals(_csv(tmp_path))
    assert listing.kind == "tabular" and listing.time == "time"
    assert [s.address for s in listing.signals] == ["WheelSpeed_FL", "lat_accel"]
    s = listing.signals[0]
    assert s.unit is None and s.samples == 200
    assert s.rate_hz == pytest.approx(100.0, rel=1e-9)
    assert (s.t_start, s.t_end) == (0.0, pytest.approx(1.99))


def test_table_without_time_column_says_so(tmp_path: Path) -> None:
    path = tmp_path / "nt.csv"
    pd.DataFrame({"a": [1.0, 2.0], "b": [3.0, 4.0]}).to_csv(path, index=False)
    listing = list_signals(path)
    assert [s.address for s in listing.signals] == ["a", "b"]
    assert math.isnan(listing.signals[0].rate_hz)
    assert "pass --time NAME" in listing.notes[0]
    assert list_signals(path, time="a").signals[0].samples == 2


def test_numpy_folder_columns(tmp_path: Path) -> None:
    """A (n, 3) array lists as name[0] … name[2]; a (n,) one by its name."""
    for name, value in (("IMU/accelerometer", np.ones((50, 3))), ("CAN/speed", np.arange(20.0))):
        d = tmp_path / "log" / name
        d.mkdir(parents=True)
        np.save(d / "t.npy", np.arange(len(value)) * 0.02)
        np.save(d / "value.npy", value)
        (d / "t.npy").rename(d / "t")
        (d / "value.npy").rename(d / "value")
    listing = list_signals(tmp_path / "log")
    assert [s.address for s in listing.signals] == ["CAN/speed", "IMU/accelerometer[0]",
                                                    "IMU/accelerometer[1]", "IMU/accelerometer[2]"]
    assert listing.signals[1].rate_hz == pytest.approx(50.0)


def test_starter_map_recognises_by_name_and_unit(tmp_path: Path) -> None:
    """The CSV's WheelSpeed_FL and lat_accel become omega_fl and ay; without a unit in the
    source the map gives the spec's SI unit and says to check it; the map loads."""
    path = _csv(tmp_path)
    listing = list_signals(path)
    text = starter_map(listing.signals, time=listing.time)
    data = tomllib.loads(text)
    assert data["source"] == {"time": "time"} and data["output"]["rate"] == pytest.approx(100.0)
    assert data["channels"] == {"omega_fl": {"source": "WheelSpeed_FL", "unit": "rad/s"},
                                "ay": {"source": "lat_accel", "unit": "m/s²"}}
    assert "check rad/s" in text
    out = tmp_path / "map.toml"
    out.write_text(text)
    assert set(load_channel_map(out).channels) == {"omega_fl", "ay"}


def test_mdf_without_dbc_lists_the_can_ids(tmp_path: Path) -> None:
    pytest.importorskip("asammdf")
    pytest.importorskip("cantools")
    from vestim.io.writers import write_mdf_can

    t = np.arange(5) * 0.01
    log = pd.DataFrame({"t": t, **{f"omega_{c}": np.full(5, 30.0) for c in ("fl", "fr", "rl", "rr")}})
    write_mdf_can(log, tmp_path / "w.mf4")
    listing = list_signals(tmp_path / "w.mf4")
    assert listing.signals == []
    assert listing.notes == ["1 CAN ID(s) in the file (pass the bus's DBC with --dbc to decode them): 0x1A0"]


def test_cli_channels_table_and_errors(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setenv("COLUMNS", "200")
    runner = CliRunner()
    r = runner.invoke(app, ["channels", str(_csv(tmp_path))])
    assert r.exit_code == 0, r.output
    line = next(ln for ln in r.output.splitlines() if "WheelSpeed_FL" in ln)
    assert "200" in line and "100" in line and "1.99" in line
    r = runner.invoke(app, ["channels", str(tmp_path / "missing.mf4")])
    assert r.exit_code == 2 and "does not exist" in r.output and "Traceback" not in r.output
