"""Fuzzing the two readers a user feeds by hand: whatever the bytes, only vestim's own error
class comes out (a clear message), never a traceback from pandas, pyarrow, tomllib or numpy."""

from __future__ import annotations

import string
from pathlib import Path

import numpy as np
import pandas as pd
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from vestim.errors import VestimError
from vestim.io import load_vehicle, read_log, write_log

VEHICLE = Path(__file__).resolve().parents[2] / "src" / "vestim" / "data" / "vehicles" / "hashemi_suv.toml"
COLUMNS = ["t", "omega_fl", "omega_fr", "omega_rl", "omega_rr", "ax", "ay", "az", "yaw_rate",
           "delta", "gnss_speed", "torque_fl", "x"]
SETTINGS = settings(max_examples=400, deadline=None,
                    suppress_health_check=[HealthCheck.function_scoped_fixture])


def _valid_log(n: int = 50) -> pd.DataFrame:
    t = np.arange(n) * 0.01
    df = pd.DataFrame({"t": t})
    for c in ("omega_fl", "omega_fr", "omega_rl", "omega_rr"):
        df[c] = 30.0
    for c in ("ax", "ay", "yaw_rate", "delta"):
        df[c] = 0.0
    df["az"] = 9.81
    return df


def _accepts_or_refuses_clearly(path: Path) -> None:
    try:
        read_log(path, require=["measured"], wheel_radius=0.33)
    except VestimError as exc:
        assert str(exc)  # a message, not an empty error


@SETTINGS
@given(data=st.binary(max_size=600), suffix=st.sampled_from([".csv", ".parquet"]))
def test_random_bytes(tmp_path: Path, data: bytes, suffix: str):
    p = tmp_path / f"log{suffix}"
    p.write_bytes(data)
    _accepts_or_refuses_clearly(p)


@SETTINGS
@given(header=st.lists(st.sampled_from(COLUMNS), min_size=1, max_size=8),
       rows=st.lists(st.lists(st.one_of(
           st.floats(allow_nan=True, allow_infinity=True),
           st.integers(-10**20, 10**20),
           st.text(string.printable, max_size=5)), min_size=0, max_size=9), max_size=6))
def test_random_csv_tables(tmp_path: Path, header: list[str], rows: list[list[object]]):
    p = tmp_path / "log.csv"
    lines = [",".join(header)] + [",".join(str(v) for v in r) for r in rows]
    p.write_text("\n".join(lines) + "\n", encoding="utf-8")
    _accepts_or_refuses_clearly(p)


@SETTINGS
@given(pos=st.integers(0, 10**6), flips=st.binary(min_size=1, max_size=16))
def test_corrupted_parquet(tmp_path: Path, pos: int, flips: bytes):
    """A valid Parquet file with bytes overwritten anywhere, pages included: the page
    checksums vestim writes make a damaged data page an error, not silently wrong values."""
    good = tmp_path / "good.parquet"
    write_log(_valid_log(), good)
    raw = bytearray(good.read_bytes())
    i = pos % len(raw)
    raw[i:i + len(flips)] = flips
    bad = tmp_path / "bad.parquet"
    bad.write_bytes(bytes(raw[:len(good.read_bytes())]))
    try:
        df = read_log(bad, require=["measured"], wheel_radius=0.33)
    except VestimError:
        return
    # Accepted: then it must be the original data (the damage hit metadata or padding).
    want = _valid_log()
    pd.testing.assert_frame_equal(df[list(want.columns)].reset_index(drop=True), want,
                                  check_dtype=False)


@SETTINGS
@given(data=st.binary(max_size=400))
def test_vehicle_random_bytes(tmp_path: Path, data: bytes):
    p = tmp_path / "car.toml"
    p.write_bytes(data)
    try:
        load_vehicle(p)
    except VestimError as exc:
        assert str(exc)


@SETTINGS
@given(line=st.integers(0, 40), value=st.one_of(
    st.floats(allow_nan=True, allow_infinity=True).map(repr), st.integers(-10**30, 10**30).map(str),
    st.text(string.printable, max_size=8).map(lambda s: '"' + s.replace('"', "") + '"'),
    st.just("[1, 2]"), st.just("{a = 1}"), st.just("true")))
def test_vehicle_with_one_value_replaced(tmp_path: Path, line: int, value: str):
    """The real vehicle file with one `key = value` line's value replaced by anything."""
    lines = VEHICLE.read_text(encoding="utf-8").splitlines()
    keyed = [i for i, s in enumerate(lines) if "=" in s and not s.lstrip().startswith("#")]
    i = keyed[line % len(keyed)]
    key = lines[i].split("=", 1)[0]
    lines[i] = f"{key}= {value}"
    p = tmp_path / "car.toml"
    p.write_text("\n".join(lines) + "\n", encoding="utf-8")
    try:
        load_vehicle(p)
    except VestimError as exc:
        assert str(exc)


def test_vehicle_file_with_a_utf8_bom_is_read(tmp_path: Path):
    """Windows editors write a byte-order mark; it is not part of the TOML."""
    p = tmp_path / "car.toml"
    p.write_bytes(b"\xef\xbb\xbf" + VEHICLE.read_bytes())
    assert load_vehicle(p).body.mass == load_vehicle(VEHICLE).body.mass


@pytest.mark.parametrize("scale", [1e3, 1e9])
def test_time_in_ms_or_ns_is_refused_clearly(tmp_path: Path, scale: float):
    """t in ms or ns (a 200 Hz log with t steps of 5 or 5e6) must be refused by name, not
    crash with a MemoryError in the resampling of the checks."""
    df = _valid_log()
    df["t"] = df["t"] * scale
    p = write_log(df, tmp_path / "log.parquet")
    with pytest.raises(VestimError, match="'t'"):
        read_log(p, require=["measured"], wheel_radius=0.33)
