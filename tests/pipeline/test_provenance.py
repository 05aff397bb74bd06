"""Provenance: `vestim.estimate()` returns in `DataFrame.attrs` the metadata `vestim estimate`
writes (one builder, vestim.pipeline.provenance), and an estimate through a channel map
records the map (path and SHA-256), the IMU mounting and the source clock's time of t = 0."""

from __future__ import annotations

import hashlib
import json
from importlib import resources
from pathlib import Path

import pandas as pd
import pytest
from typer.testing import CliRunner

import vestim
from vestim.cli import app
from vestim.io import channels as ch
from vestim.io import read_log, write_log
from vestim.io.channel_map import import_log
from vestim.sim import simulate

runner = CliRunner()
T_SOURCE = 1000.0
"""s: the recording's clock at the log's first sample (a CAN logger's boot time)."""


@pytest.fixture(scope="module")
def short_log() -> pd.DataFrame:
    """1.5 s of a step steer at 200 Hz (301 rows), every measured and ref_ channel."""
    return simulate("step_steer", "hashemi_suv", seed=0).iloc[:301].reset_index(drop=True)


def _vehicle_file(tmp_path: Path) -> Path:
    path = tmp_path / "car.toml"
    path.write_bytes((resources.files("vestim") / "data" / "vehicles" / "hashemi_suv.toml")
                     .read_bytes())
    return path


def test_estimate_attrs_are_the_cli_metadata(tmp_path: Path, short_log: pd.DataFrame) -> None:
    """Same log, same vehicle file: every key and value of the Parquet metadata `vestim
    estimate` writes is in `vestim.estimate(...).attrs`, and nothing else."""
    src = write_log(short_log, tmp_path / "log.parquet")
    veh = _vehicle_file(tmp_path)
    out = tmp_path / "est.parquet"
    res = runner.invoke(app, ["estimate", str(src), "--vehicle", str(veh), "--out", str(out)])
    assert res.exit_code == 0, res.output
    cli = read_log(out).attrs
    api = vestim.estimate(src, veh).attrs
    assert api == cli
    assert api["vehicle_file"] == str(veh) and api["source"] == str(src)
    assert api["vehicle_sha256"] == hashlib.sha256(veh.read_bytes()).hexdigest()
    assert api["vestim_version"] == vestim.__version__
    assert json.loads(api["config"])["velocity"] == "reference"
    assert api["torque_source"] == "measured" and json.loads(api["gaps"]) == []
    # an in-memory log and a built-in vehicle
    mem = vestim.estimate(short_log, "hashemi_suv").attrs
    assert mem["source"] == "DataFrame" and mem["vehicle_file"] == "hashemi_suv"
    assert set(mem) == set(api)


def _raw_recording(tmp_path: Path, log: pd.DataFrame) -> tuple[Path, Path]:
    """A CSV on a logger's clock (time_s = T_SOURCE + t) and its channel map, with the IMU
    mounted pitched by 0.5° (the map states it)."""
    raw = log.drop(columns=[c for c in log.columns if c.startswith("ref_")]).copy()
    raw.insert(0, "time_s", raw.pop("t") + T_SOURCE)
    csv = tmp_path / "raw.csv"
    raw.to_csv(csv, index=False)
    lines = ['format = 1', '[source]', 'time = "time_s"', '[output]', 'rate = 200.0',
             '[imu]', 'mounting = { roll_deg = 0.0, pitch_deg = 0.5, yaw_deg = 0.0 }']
    for col in raw.columns[1:]:
        unit = str(ch.unit_of(col)).replace("·", "*").replace("²", "^2")  # pint's spelling
        lines += [f"[channels.{col}]", f'source = "{col}"', f'unit = "{unit}"']
    cmap = tmp_path / "map.toml"
    cmap.write_text("\n".join(lines) + "\n", encoding="utf-8")
    return csv, cmap


def test_estimate_map_records_map_mounting_and_time_offset(tmp_path: Path,
                                                           short_log: pd.DataFrame) -> None:
    """`estimate --map` writes the import's metadata: the map's path and SHA-256, the
    mounting it applied (pitch 0.5°, given) and the source time of t = 0 (1000 s), so the
    estimate aligns back to the recording's clock; `vestim.estimate` on the imported log
    gives the same keys but the hash (it cannot know the map is unchanged since)."""
    csv, cmap = _raw_recording(tmp_path, short_log)
    out = tmp_path / "est.parquet"
    res = runner.invoke(app, ["estimate", str(csv), "--map", str(cmap), "--vehicle",
                              "hashemi_suv", "--out", str(out)])
    assert res.exit_code == 0, res.output
    meta = read_log(out).attrs
    assert meta["import.map"] == str(cmap)
    assert meta["import.map_sha256"] == hashlib.sha256(cmap.read_bytes()).hexdigest()
    assert float(meta["import.t0_source_s"]) == pytest.approx(T_SOURCE, abs=1e-9)
    mounting = json.loads(meta["import.mounting"])
    assert mounting["pitch_deg"] == pytest.approx(0.5)
    assert meta["import.source"] == str(csv) and meta["source"] == str(csv)
    log, _ = import_log(csv, cmap)
    api = vestim.estimate(log, "hashemi_suv").attrs
    assert {k: v for k, v in api.items() if k.startswith("import.")} == \
        {k: v for k, v in meta.items() if k.startswith("import.") and k != "import.map_sha256"}


def test_parquet_schema_gives_every_column_its_unit(tmp_path: Path, short_log: pd.DataFrame) -> None:
    """Every column of a default estimate has a unit in the Parquet schema (field metadata
    `unit`, from the one table vestim.io.channels.unit_of): v_x m/s, F_x N, σ of F_z N,
    slip ratio and the flags "-", the roll gradient... none is missing; the file's own
    metadata is still read back."""
    import pyarrow.parquet as pq

    src = write_log(short_log, tmp_path / "log.parquet")
    out = tmp_path / "est.parquet"
    assert runner.invoke(app, ["estimate", str(src), "--vehicle", "hashemi_suv",
                               "--out", str(out)]).exit_code == 0
    schema = pq.read_schema(out)
    units = {f.name: (f.metadata or {}).get(b"unit", b"").decode() for f in schema}
    assert "" not in units.values(), [k for k, v in units.items() if not v]
    assert units["t"] == "s" and units["vx"] == "m/s" and units["fx_fl"] == "N"
    assert units["sigma_fz_rr"] == "N" and units["slip_angle_fl"] == "rad"
    assert units["valid_velocity"] == units["reason_force"] == units["health_ax"] == "-"
    assert units["vxt_fl"] == "m/s" and units["bias_ax"] == "m/s²"
    assert units["cornering_stiffness"] == "1/rad" and units["gnss_latency"] == "s"
    assert all(units[c] == ch.unit_of(c) for c in units)
    assert read_log(out).attrs["velocity"] == "reference"
