"""Drive logs: round trips, atomic writes, and every validation message (spec: log-format.md)."""

from __future__ import annotations

import hashlib
import math
import os
import re
from pathlib import Path

import numpy as np
import pandas as pd
import pyarrow.csv as pacsv
import pyarrow.parquet as pq
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from vestim.constants import CORNERS, G
from vestim.errors import LogFormatError
from vestim.io import channels as ch
from vestim.io import read_log, road_wheel_angles, validate_log, write_log

FS = 100.0  # Hz; row i has t = i / FS, so messages are checked against t = i * 0.01


def _log(n: int = 50) -> pd.DataFrame:
    """A plausible measured log at rest-to-cruise, in SI units, canonical column order."""
    t = np.arange(n) / FS
    cols: dict[str, np.ndarray] = {"t": t}
    for k, c in enumerate(CORNERS):
        cols[f"omega_{c}"] = 30.0 + 0.01 * k + 0.1 * np.sin(t)
    for c in CORNERS:
        cols[f"torque_{c}"] = 120.0 * np.cos(t)
    cols.update(ax=0.5 * np.sin(t), ay=0.2 * np.cos(t), az=np.full(n, G),
                yaw_rate=0.05 * np.sin(t), roll_rate=0.01 * np.sin(t),
                pitch_rate=0.01 * np.cos(t), delta_fl=0.02 * np.sin(t),
                delta_fr=0.019 * np.sin(t))
    return pd.DataFrame(cols)


def _sha(path: Path) -> str:
    return hashlib.sha256(path.read_bytes()).hexdigest()


def _assert_identical(a: pd.DataFrame, b: pd.DataFrame) -> None:
    """Same columns, dtypes and bit patterns (-0.0 is not 0.0 here)."""
    assert list(a.columns) == list(b.columns)
    for c in a.columns:
        assert a[c].dtype == b[c].dtype, c
        assert np.array_equal(a[c].to_numpy().view(np.uint64), b[c].to_numpy().view(np.uint64)), c


# --- channels ---------------------------------------------------------------------------------


def test_corner_columns_follow_corners_order() -> None:
    assert ch.corner_columns("omega") == ["omega_fl", "omega_fr", "omega_rl", "omega_rr"]


def test_channel_names_cover_the_spec() -> None:
    """Names typed from the spec's tables, independently of channels.py."""
    measured = ["t", "omega_fl", "omega_rr", "torque_fr", "ax", "ay", "az", "yaw_rate",
                "roll_rate", "pitch_rate", "delta_fl", "delta_fr", "delta",
                "steering_wheel_angle"]
    assert set(measured) <= set(ch.MEASURED)
    reference = ["ref_vx", "ref_vy", "ref_vx_fl", "ref_vy_rr", "ref_fx_fl", "ref_fy_rl",
                 "ref_fz_fr", "ref_slip_ratio_rr", "ref_slip_angle_fl", "ref_mu_rl", "ref_roll",
                 "ref_pitch", "ref_stiffness_cx_f", "ref_stiffness_cx_r", "ref_stiffness_cy_f",
                 "ref_stiffness_cy_r"]
    assert set(reference) <= set(ch.REFERENCE)
    assert all(c.startswith("ref_") for c in ch.REFERENCE)
    assert ch.MEASURED[0] == "t"
    assert len(set(ch.KNOWN)) == len(ch.KNOWN)


def test_every_known_column_has_a_unit() -> None:
    """Every spec column has a unit; the others UNITS holds are the pipeline's further
    outputs (tire-frame velocities, bias_ax, …), and the flag families have theirs by prefix."""
    assert set(ch.KNOWN) <= set(ch.UNITS)
    extras = set(ch.UNITS) - set(ch.KNOWN)
    assert extras == {*ch.corner_columns("vxt"), *ch.corner_columns("vyt"), "bias_ax",
                      "cornering_stiffness", "radius_scale", "gnss_latency",
                      *(f"mu_{c}_excited" for c in ("fl", "fr", "rl", "rr"))}
    assert ch.unit_of("reason_velocity") == ch.unit_of("health_omega_fl") == "-"
    assert ch.unit_of("sigma_vxt_fl") == "m/s" and ch.unit_of("not_a_column") is None
    assert ch.UNITS["omega_fl"] == "rad/s"
    assert ch.UNITS["ref_fz_rr"] == "N"
    assert ch.UNITS["ref_stiffness_cy_f"] == "N/rad"
    assert ch.unit_of("sigma_vx") == "m/s"
    assert ch.unit_of("gear") is None


def test_canonical_order() -> None:
    given_order = ["x", "ref_vx", "omega_rr", "t", "y", "omega_fl", "vx"]
    assert ch.canonical_order(given_order) == ["t", "omega_fl", "omega_rr", "ref_vx", "vx",
                                               "x", "y"]


# --- round trips ------------------------------------------------------------------------------


@pytest.mark.parametrize("suffix", [".csv", ".parquet", ".pq"])
def test_read_write_read_is_identity(tmp_path: Path, suffix: str) -> None:
    df = _log()
    df["ref_vx"] = 10.0 + np.arange(len(df)) / 3.0  # non-terminating binary fractions
    df["extra"] = -0.0
    first = tmp_path / f"a{suffix}"
    write_log(df, first)
    read1 = read_log(first)
    _assert_identical(read1, df)
    second = tmp_path / f"b{suffix}"
    write_log(read1, second)
    _assert_identical(read_log(second), read1)
    if suffix == ".csv":  # deterministic text
        assert first.read_bytes() == second.read_bytes()


finite = st.floats(allow_nan=False, allow_infinity=False, width=64)


@settings(max_examples=60, deadline=None)
@given(
    t=st.lists(finite, min_size=1, max_size=15, unique=True).map(sorted),
    data=st.data(),
    suffix=st.sampled_from([".csv", ".parquet"]),
)
def test_round_trip_property(
    tmp_path_factory: pytest.TempPathFactory, t: list[float], data: st.DataObject, suffix: str
) -> None:
    """read → write → read is identity for any finite float64 values (STYLE.md, property)."""
    # Columns without unit heuristics, so any finite value is a valid log.
    names = data.draw(st.lists(st.sampled_from(["torque_fl", "ref_fx_rr", "vx", "custom"]),
                               unique=True))
    cols = {"t": np.array(t, dtype=np.float64)}
    for name in names:
        cols[name] = np.array(data.draw(st.lists(finite, min_size=len(t), max_size=len(t))),
                              dtype=np.float64)
    df = pd.DataFrame(cols)[ch.canonical_order(cols)]
    path = tmp_path_factory.mktemp("prop") / f"log{suffix}"
    write_log(df, path)
    read1 = read_log(path)
    _assert_identical(read1, df)
    write_log(read1, path)
    _assert_identical(read_log(path), read1)


def test_write_puts_columns_in_canonical_order_without_touching_input(tmp_path: Path) -> None:
    df = _log()[["ax", "omega_rr", "t", "omega_fl"]]
    df.insert(0, "custom", 1.0)
    before = df.copy()
    out = write_log(df, tmp_path / "deep" / "dir" / "log.csv")
    assert out == tmp_path / "deep" / "dir" / "log.csv"
    assert list(read_log(out).columns) == ["t", "omega_fl", "omega_rr", "ax", "custom"]
    pd.testing.assert_frame_equal(df, before)


def test_csv_header_is_plain_and_reads_back_as_float64(tmp_path: Path) -> None:
    df = pd.DataFrame({"t": [0.0, 1.0], "gear": [1, 2]})
    path = write_log(df, tmp_path / "log.csv")
    assert path.read_text().splitlines() == ["t,gear", "0,1", "1,2"]
    assert (read_log(path).dtypes == np.float64).all()


def test_parquet_metadata_round_trips_through_attrs(tmp_path: Path) -> None:
    path = write_log(_log(), tmp_path / "log.parquet",
                     metadata={"vehicle": "hashemi_suv", "maneuver": "dlc"})
    schema_meta = pq.read_schema(path).metadata
    assert schema_meta[b"vestim.vehicle"] == b"hashemi_suv"
    assert read_log(path).attrs == {"vehicle": "hashemi_suv", "maneuver": "dlc"}


def test_csv_ignores_metadata(tmp_path: Path) -> None:
    path = write_log(_log(), tmp_path / "log.csv", metadata={"vehicle": "x"})
    assert read_log(path).attrs == {}


def test_metadata_must_be_strings(tmp_path: Path) -> None:
    with pytest.raises(TypeError, match="metadata must map str to str"):
        write_log(_log(), tmp_path / "log.parquet", metadata={"mu": 0.3})


@pytest.mark.parametrize("suffix", [".csv", ".parquet"])
def test_read_does_not_modify_the_file(tmp_path: Path, suffix: str) -> None:
    path = write_log(_log(), tmp_path / f"log{suffix}")
    digest, mtime = _sha(path), path.stat().st_mtime_ns
    df = read_log(path, require=["measured"], wheel_radius=0.33)
    df["omega_fl"] = 0.0  # mutating the frame must not reach the file either
    assert _sha(path) == digest
    assert path.stat().st_mtime_ns == mtime


@pytest.mark.parametrize("name", ["log.txt", "log.csv.gz", "log"])
def test_unsupported_extension(tmp_path: Path, name: str) -> None:
    suffix = re.escape(Path(name).suffix or "(none)")
    with pytest.raises(LogFormatError, match=rf"extension '{suffix}'.*\.csv, \.parquet, \.pq"):
        read_log(tmp_path / name)
    with pytest.raises(LogFormatError, match=rf"extension '{suffix}'"):
        write_log(_log(), tmp_path / name)
    assert list(tmp_path.iterdir()) == []


# --- atomic writes ----------------------------------------------------------------------------


def _partial_then_fail(*args: object, **kwargs: object) -> None:
    sink = args[1]
    if hasattr(sink, "write"):  # the CSV writer's open file
        sink.write(b"0.0,1.0\n")  # type: ignore[attr-defined]
    # the Parquet writer (args: the writer, the table) has already opened the temporary file
    raise OSError("disk full")


@pytest.mark.parametrize(
    ("suffix", "module", "writer"),
    [(".csv", pacsv, "write_csv"), (".parquet", pq.ParquetWriter, "write_table")],
)
def test_failed_write_keeps_previous_file_and_leaves_no_temp(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch, suffix: str, module: object, writer: str
) -> None:
    path = write_log(_log(), tmp_path / f"log{suffix}")
    digest = _sha(path)
    monkeypatch.setattr(module, writer, _partial_then_fail)
    with pytest.raises(OSError, match="disk full"):
        write_log(_log(10), path)
    assert _sha(path) == digest
    assert [p.name for p in tmp_path.iterdir()] == [path.name]


def test_invalid_log_is_not_written(tmp_path: Path) -> None:
    df = _log()
    df.loc[3, "ax"] = np.nan
    with pytest.raises(LogFormatError, match=r"'ax' is missing \(NaN\) at row 3 \(t = 0\.03 s\)"):
        write_log(df, tmp_path / "log.csv")
    assert list(tmp_path.iterdir()) == []


def test_written_file_has_normal_permissions(tmp_path: Path) -> None:
    umask = os.umask(0)
    os.umask(umask)
    path = write_log(_log(), tmp_path / "log.csv")
    assert path.stat().st_mode & 0o777 == 0o666 & ~umask


# --- structural validation --------------------------------------------------------------------


def test_valid_log_passes() -> None:
    validate_log(_log(), require=["measured"], wheel_radius=0.33)


def test_missing_t() -> None:
    df = _log().rename(columns={"t": "time"})
    with pytest.raises(LogFormatError, match=r"column 't' .*missing \(rename 'time' to 't'\)"):
        validate_log(df)


def test_empty_log() -> None:
    with pytest.raises(LogFormatError, match="no rows"):
        validate_log(_log().iloc[:0])


def test_duplicate_column() -> None:
    df = _log()
    df = pd.concat([df, df[["ax"]]], axis=1)
    with pytest.raises(LogFormatError, match="column 'ax' appears more than once"):
        validate_log(df)


def test_non_numeric_column_names_row_time_and_value(tmp_path: Path) -> None:
    path = tmp_path / "log.csv"
    path.write_text("t,omega_fl,ax\n0.0,1,0\n0.01,2,0\n0.02,abc,0\n")
    with pytest.raises(LogFormatError, match=r"column 'omega_fl' is not numeric .*row 2 "
                                             r"\(t = 0\.02 s\) holds 'abc'"):
        read_log(path)


def test_boolean_column() -> None:
    df = _log()
    df["flag"] = True
    with pytest.raises(LogFormatError, match="column 'flag' is boolean"):
        validate_log(df)


def test_t_not_strictly_increasing() -> None:
    df = _log()
    df.loc[5, "t"] = df.loc[4, "t"]
    with pytest.raises(LogFormatError, match=r"'t' is not strictly increasing at row 5 "
                                             r"\(t = 0\.04 s\); the previous row has t = 0\.04"):
        validate_log(df, source="drive.csv")


@pytest.mark.parametrize(
    ("column", "row", "value", "shown"),
    [("omega_rl", 7, np.nan, r"missing \(NaN\)"), ("ax", 3, np.inf, "inf"),
     ("ref_fz_fl", 12, -np.inf, "-inf")],
)
def test_non_finite_value(column: str, row: int, value: float, shown: str) -> None:
    df = _log()
    if column not in df:
        df[column] = 1000.0
    df.loc[row, column] = value
    with pytest.raises(LogFormatError,
                       match=rf"'{column}' is {shown} at row {row} \(t = {row / FS!r} s\)"):
        validate_log(df)


def test_first_non_finite_row_is_reported() -> None:
    df = _log()
    df.loc[20, "omega_fl"] = np.nan
    df.loc[9, "delta_fr"] = np.nan
    with pytest.raises(LogFormatError, match=r"'delta_fr' is missing \(NaN\) at row 9 "):
        validate_log(df)


def test_nan_time() -> None:
    df = _log()
    df.loc[4, "t"] = np.nan
    with pytest.raises(LogFormatError, match=r"'t' is missing \(NaN\) at row 4 \(t = nan s\)"):
        validate_log(df)


def test_source_prefixes_messages(tmp_path: Path) -> None:
    path = tmp_path / "drive.csv"
    path.write_text("t,ax\n0,1\n0,1\n")
    with pytest.raises(LogFormatError, match=r"drive\.csv: column 't' is not strictly"):
        read_log(path)


def test_unreadable_files(tmp_path: Path) -> None:
    bad_pq = tmp_path / "log.parquet"
    bad_pq.write_bytes(b"not parquet")
    with pytest.raises(LogFormatError, match=r"log\.parquet: cannot be read as PARQUET"):
        read_log(bad_pq)
    ragged = tmp_path / "log.csv"
    ragged.write_text("t,ax\n0,1\n1,2,3,4\n")
    with pytest.raises(LogFormatError, match=r"log\.csv: cannot be read as CSV"):
        read_log(ragged)


# --- required channels ------------------------------------------------------------------------


@pytest.mark.parametrize(
    ("require", "drop", "match"),
    [
        (["measured"], ["torque_rr"], r"missing: torque_rr \[N·m\]"),
        (["wheel_speeds"], ["omega_fl", "omega_rl"], r"missing: omega_fl \[rad/s\], omega_rl"),
        (["torques"], ["torque_fr"], r"torque_fr"),
        (["imu"], ["yaw_rate"], r"yaw_rate \[rad/s\]"),
        (["az"], ["az"], r"missing: az \[m/s²\]"),
        ("roll_rate", ["roll_rate"], r"missing: roll_rate"),
    ],
)
def test_required_channels(require: list[str] | str, drop: list[str], match: str) -> None:
    df = _log().drop(columns=drop)
    with pytest.raises(LogFormatError, match=match):
        validate_log(df, require=require)


def test_optional_imu_channels_are_not_required_by_measured() -> None:
    validate_log(_log().drop(columns=["az", "roll_rate", "pitch_rate"]), require=["measured"])


def test_wheel_torques_are_optional_for_measured() -> None:
    """Most CAN logs have no wheel torques; the force stage then uses the chassis equation."""
    validate_log(_log().drop(columns=list(ch.TORQUES)), require=["measured"])


def test_partial_wheel_torques_name_the_missing_ones_and_the_fix() -> None:
    df = _log().drop(columns=["torque_rl", "torque_rr"])
    with pytest.raises(LogFormatError, match=r"missing: torque_rl \[N·m\], torque_rr \[N·m\].*"
                                             r"all four or none.*drop every torque_\* column"):
        validate_log(df, require=["measured"])


def test_required_column_with_wrong_case_gets_a_rename_hint() -> None:
    df = _log().rename(columns={"omega_fl": "Omega_FL"})
    with pytest.raises(LogFormatError, match=r"rename 'Omega_FL' → 'omega_fl'"):
        validate_log(df, require=["wheel_speeds"])


@pytest.mark.parametrize(
    "keep", [["delta_fl", "delta_fr"], ["delta"], ["steering_wheel_angle"]]
)
def test_steering_alternatives(keep: list[str]) -> None:
    df = _log().drop(columns=["delta_fl", "delta_fr"])
    for c in keep:
        df[c] = _log()["delta_fl"]
    validate_log(df, require=["measured"])


@pytest.mark.parametrize("require", [["measured"], ["steering"]])
def test_missing_steering(require: list[str]) -> None:
    df = _log().drop(columns=["delta_fr"])
    with pytest.raises(LogFormatError, match=r"no steering channel: needs delta_fl and "
                                             r"delta_fr, or delta, or steering_wheel_angle"):
        validate_log(df, require=require)


# --- unit plausibility ------------------------------------------------------------------------


def _with(column: str, values: np.ndarray) -> pd.DataFrame:
    df = _log()
    df[column] = values
    return df


def _peak(value: float, row: int = 10) -> np.ndarray:
    v = np.full(50, value / 2)
    v[row] = value
    return v


def test_rpm_wheel_speed() -> None:
    df = _with("omega_fr", _peak(30.0 * 60 / (2 * math.pi) * 3))  # 90 rad/s in rpm
    with pytest.raises(LogFormatError, match=r"'omega_fr' reaches 859\.4.* at row 10 "
                                             r"\(t = 0\.1 s\).*looks like rpm \(convert with "
                                             r"×2π/60\)"):
        validate_log(df)


@pytest.mark.parametrize("column", ["delta_fl", "delta_fr", "delta"])
def test_road_wheel_angle_in_degrees(column: str) -> None:
    with pytest.raises(LogFormatError, match=rf"'{column}' reaches -12 rad at row 10 \(t = 0\.1 "
                                             r"s\).*looks like degrees \(convert with ×π/180\)"):
        validate_log(_with(column, _peak(-12.0)))


def test_steering_wheel_angle_limits() -> None:
    validate_log(_with("steering_wheel_angle", _peak(3.0)))  # 172° of steering wheel: fine
    with pytest.raises(LogFormatError, match=r"'steering_wheel_angle' reaches 90 rad at row 10"
                                             r".*degrees"):
        validate_log(_with("steering_wheel_angle", _peak(90.0)))


@pytest.mark.parametrize("column", ["yaw_rate", "roll_rate", "pitch_rate"])
def test_rates_in_deg_per_s(column: str) -> None:
    with pytest.raises(LogFormatError, match=rf"'{column}' reaches 20 rad/s at row 10 \(t = 0\.1 "
                                             r"s\).*looks like deg/s"):
        validate_log(_with(column, _peak(20.0)))


@pytest.mark.parametrize("az", [1.0, -1.0, 0.98])
def test_az_in_g(az: float) -> None:
    with pytest.raises(LogFormatError, match=r"'az' has median \|az\| = .*g units, multiply by "
                                             r"9\.81"):
        validate_log(_with("az", np.full(50, az)))


def test_az_in_si_passes() -> None:
    validate_log(_with("az", np.full(50, -G)))
    validate_log(_with("az", np.full(50, 0.0)))  # free fall / missing sensor: not g units


@pytest.mark.parametrize("column", ["ax", "ay"])
def test_implausible_acceleration(column: str) -> None:
    with pytest.raises(LogFormatError, match=rf"'{column}' reaches 98\.1 m/s² at row 10 \(t = "
                                             r"0\.1 s\).*expected m/s²"):
        validate_log(_with(column, _peak(98.1)))


# --- wheel-speed scale from the dynamics ------------------------------------------------------


def _drive(R: float, seed: int, v0: float = 20.0, amp: float = 1.0, duration: float = 60.0,
           ) -> pd.DataFrame:
    """Accelerating and braking drive with the errors a real log has.

    Speed v = v0 + amp·(6 sin(2πt/9) + sin(2πt/3)) (|a| up to about 6.3 m/s² at amp=1).
    ax carries a 4 % pitch error, 0.2 m/s² bias, a ±2 % grade and noise; wheel speeds carry
    slip κ = a/150 and noise. These bias the rad/s slope by several percent, which the check
    must tolerate.
    """
    rng = np.random.default_rng(seed)
    t = np.arange(0.0, duration, 1.0 / FS)
    w1, w2 = 2 * np.pi / 9.0, 2 * np.pi / 3.0
    v = v0 + amp * (6.0 * np.sin(w1 * t) + 1.0 * np.sin(w2 * t))
    a = amp * (6.0 * w1 * np.cos(w1 * t) + 1.0 * w2 * np.cos(w2 * t))
    grade = 0.02 * np.sin(2 * np.pi * t / 30.0)
    ax = 1.04 * a + G * grade + 0.2 + rng.normal(0.0, 0.05, t.size)
    cols = {"t": t}
    for c in CORNERS:
        cols[f"omega_{c}"] = v * (1 + a / 150.0) / R + rng.normal(0.0, 0.02, t.size)
    cols["ax"] = ax
    return pd.DataFrame(cols)


def _scaled(df: pd.DataFrame, factor: float, corners: tuple[str, ...] = CORNERS) -> pd.DataFrame:
    out = df.copy()
    for c in corners:
        out[f"omega_{c}"] *= factor
    return out


@pytest.mark.parametrize("R", [0.22, 0.28, 0.31, 0.33, 0.36, 0.5])
@pytest.mark.parametrize("seed", [0, 1])
def test_rad_per_s_wheel_speeds_pass(R: float, seed: int) -> None:
    validate_log(_drive(R, seed), wheel_radius=R)


@pytest.mark.parametrize("R", [0.36, 0.5, 0.2])
def test_kmh_wheel_speeds_detected_when_distinguishable(R: float) -> None:
    """km/h reads 3.6·R times rad/s; told apart only when 3.6·R is >= 22 % away from 1."""
    df = _scaled(_drive(R, seed=3), 3.6 * R, corners=("rl",))
    with pytest.raises(LogFormatError, match=r"column 'omega_rl' looks like km/h, not rad/s: "
                                             r"between t = 0\.0 s and t = 59\.0 s"):
        validate_log(df, wheel_radius=R)


def test_kmh_not_distinguishable_near_unit_scale_passes() -> None:
    """R = 0.31 m: 3.6·R = 1.116 is within the slope's bias band, so no verdict."""
    validate_log(_scaled(_drive(0.31, seed=3), 3.6 * 0.31), wheel_radius=0.31)


def test_low_speed_rpm_detected_by_dynamics() -> None:
    """3–13 m/s at R = 0.33 m stays below 400 in rpm, so only the slope can catch it."""
    df = _scaled(_drive(0.33, seed=4, v0=8.0, amp=0.6), 60 / (2 * math.pi))
    assert df["omega_fl"].abs().max() < 400
    with pytest.raises(LogFormatError, match=r"'omega_fl' looks like rpm.*×2π/60"):
        validate_log(df, wheel_radius=0.33)


def test_wheel_centre_speed_in_m_per_s_detected() -> None:
    df = _scaled(_drive(0.33, seed=5), 0.33)
    with pytest.raises(LogFormatError, match=r"'omega_fl' looks like m/s.*×1/R = ×3\.03"):
        validate_log(df, wheel_radius=0.33)


def test_scale_check_skipped_without_excitation_or_ax() -> None:
    R = 0.5  # km/h would be detectable if the log were excited enough
    steady = _scaled(_drive(R, seed=6, amp=0.1), 3.6 * R)  # |a| <= 0.8 m/s²
    validate_log(steady, wheel_radius=R)
    short = _scaled(_drive(R, seed=6, duration=8.0), 3.6 * R)  # 8 windows < 10
    validate_log(short, wheel_radius=R)
    validate_log(_scaled(_drive(R, seed=6), 3.6 * R).drop(columns=["ax"]), wheel_radius=R)
    with pytest.raises(LogFormatError, match="looks like km/h"):
        validate_log(_scaled(_drive(R, seed=6), 3.6 * R), wheel_radius=R)


@pytest.mark.parametrize("R", [0.0, -0.3, math.nan])
def test_bad_wheel_radius(R: float) -> None:
    with pytest.raises(ValueError, match="wheel_radius"):
        validate_log(_log(), wheel_radius=R)


# --- road-wheel angles ------------------------------------------------------------------------


def test_road_wheel_angles_from_each_source() -> None:
    df = _log()
    both = road_wheel_angles(df, steering_ratio=None)
    assert both.shape == (50, 2) and both.dtype == np.float64
    np.testing.assert_array_equal(both, df[["delta_fl", "delta_fr"]].to_numpy())

    only_delta = df.drop(columns=["delta_fl", "delta_fr"]).assign(delta=df["delta_fl"])
    np.testing.assert_array_equal(road_wheel_angles(only_delta, None),
                                  np.column_stack([df["delta_fl"], df["delta_fl"]]))

    swa = df.drop(columns=["delta_fl", "delta_fr"]).assign(steering_wheel_angle=16.7 * 0.1)
    np.testing.assert_allclose(road_wheel_angles(swa, 16.7), 0.1, rtol=1e-15)


def test_road_wheel_angles_prefer_per_wheel_columns() -> None:
    df = _log().assign(delta=9.0, steering_wheel_angle=9.0)
    np.testing.assert_array_equal(road_wheel_angles(df, 16.7)[:, 1], df["delta_fr"])


def test_road_wheel_angles_errors() -> None:
    df = _log().drop(columns=["delta_fl", "delta_fr"])
    with pytest.raises(LogFormatError, match=r"only 'steering_wheel_angle'.*steering_ratio"):
        road_wheel_angles(df.assign(steering_wheel_angle=0.0), None)
    with pytest.raises(ValueError, match="steering_ratio = 0"):
        road_wheel_angles(df.assign(steering_wheel_angle=0.0), 0)
    with pytest.raises(LogFormatError, match=r"no steering channel: missing delta_fl and "
                                             r"delta_fr, delta, and steering_wheel_angle;"):
        road_wheel_angles(df, 16.7)
    with pytest.raises(LogFormatError, match=r"'delta_fl' is present without its pair"):
        road_wheel_angles(df.assign(delta_fl=0.0), 16.7)


def test_temp_file_of_a_killed_writer_is_removed_by_the_next_write(tmp_path: Path) -> None:
    """kill -9 leaves `.log.parquet.<pid>.<uuid>.tmp` behind; the next write to the same file
    removes it when that process is gone, and leaves a live writer's temp file alone."""
    import subprocess
    import sys

    dead = subprocess.run([sys.executable, "-c", "import os; print(os.getpid())"],
                          capture_output=True, text=True, check=True)
    pid = int(dead.stdout)
    stale = tmp_path / f".log.parquet.{pid}.{'0' * 32}.tmp"
    stale.write_bytes(b"PAR1 partial")
    live = tmp_path / f".log.parquet.{os.getpid()}.{'1' * 32}.tmp"
    live.write_bytes(b"PAR1 in progress")
    other = tmp_path / f".other.parquet.{pid}.{'2' * 32}.tmp"
    other.write_bytes(b"x")
    write_log(_log(), tmp_path / "log.parquet")
    assert not stale.exists()
    assert live.exists() and other.exists()
