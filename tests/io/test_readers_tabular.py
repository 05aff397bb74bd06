"""Source readers: tabular (CSV/Parquet), numpy folders, and the dispatch by file kind."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pandas as pd
import pytest

from tests._paths import CROSSPLANT_DATA
from tests._paths import RAV4 as RAV4_DIR
from vestim.errors import LogFormatError
from vestim.io.readers import read_source, source_kind
from vestim.io.readers import tabular as tab
from vestim.io.readers.numpy_dir import parse_address
from vestim.io.readers.numpy_dir import read_streams as read_numpy

RAW = RAV4_DIR / "raw"
needs_rav4 = pytest.mark.skipif(not RAW.is_dir(), reason="comma2k19 raw copy not present")


def _save(path: Path, a: np.ndarray) -> None:
    """A .npy array under a name without extension, as comma2k19 stores them."""
    with open(path, "wb") as f:
        np.save(f, a)


def _table() -> pd.DataFrame:
    """Two CAN signals on one time column in microseconds; 'speed' missing on odd rows."""
    t_us = np.array([0, 10_000, 19_000, 31_000, 40_000], dtype=np.int64)  # jittered CAN
    speed = np.array([1.0, np.nan, 3.0, np.nan, 5.0])
    return pd.DataFrame({"stamp": t_us, "speed kph": speed, "Steer.Angle": [0.5, 1, 2, 3, 4]})


@pytest.mark.parametrize("suffix", [".csv", ".parquet"])
def test_tabular_reads_any_names_scales_time_and_drops_missing_rows(tmp_path, suffix):
    """Times in µs become s (×1e-6); a column's NaN rows are left out of its own stream."""
    path = tmp_path / f"can{suffix}"
    df = _table()
    df.to_csv(path, index=False) if suffix == ".csv" else df.to_parquet(path)
    got = tab.read_streams(path, ["speed kph", "Steer.Angle"], time="stamp", time_scale=1e-6)
    np.testing.assert_array_equal(got["speed kph"].t, [0.0, 0.019, 0.040])
    np.testing.assert_array_equal(got["speed kph"].value, [1.0, 3.0, 5.0])
    np.testing.assert_array_equal(got["Steer.Angle"].t, [0.0, 0.01, 0.019, 0.031, 0.040])
    # Dispatch by extension gives the same streams.
    again = read_source(path, ["speed kph"], time="stamp", time_scale=1e-6)
    np.testing.assert_array_equal(again["speed kph"].value, got["speed kph"].value)


def test_tabular_errors_name_the_column(tmp_path):
    path = tmp_path / "x.csv"
    pd.DataFrame({"t": [0.0, 1.0, 0.5], "a": [1.0, 2.0, 3.0], "b": ["1", "x", "3"]}).to_csv(
        path, index=False)
    with pytest.raises(LogFormatError, match=r"'nope' not found.*'t', 'a', 'b'"):
        tab.read_streams(path, ["nope"], time="t")
    with pytest.raises(LogFormatError, match=r"column 'b' is not numeric: data row 1 holds 'x'"):
        tab.read_streams(path, ["b"], time="t")
    with pytest.raises(LogFormatError, match=r"time column 't' decreases at data row 2"):
        tab.read_streams(path, ["a"], time="t")
    with pytest.raises(LogFormatError, match=r"needs \[source\] time"):
        read_source(path, ["a"])


def test_source_kind_by_file_kind(tmp_path):
    for name, kind in [("a.csv", "tabular"), ("a.PARQUET", "tabular"), ("a.mf4", "mdf"),
                       ("a.mdf", "mdf"), ("a.db3", "ros2"), ("a.mcap", "ros2")]:
        (tmp_path / name).write_bytes(b"")
        assert source_kind(tmp_path / name) == kind
    bag = tmp_path / "bag"
    bag.mkdir()
    (bag / "metadata.yaml").write_text("rosbag2_bagfile_information: {}\n")
    assert source_kind(bag) == "ros2"
    npdir = tmp_path / "np" / "CAN" / "speed"
    npdir.mkdir(parents=True)
    _save(npdir / "t", np.arange(3.0))
    _save(npdir / "value", np.arange(3.0))
    assert source_kind(tmp_path / "np") == "numpy"
    (tmp_path / "a.xyz").write_bytes(b"")
    with pytest.raises(LogFormatError, match=r"unknown file kind '.xyz'"):
        source_kind(tmp_path / "a.xyz")
    with pytest.raises(LogFormatError, match="does not exist"):
        source_kind(tmp_path / "missing.csv")
    with pytest.raises(LogFormatError, match="dbc applies to MDF4 sources only"):
        read_source(tmp_path / "a.csv", ["x"], time="t", dbc=[tmp_path / "x.dbc"])


@needs_rav4
def test_numpy_folder_reads_comma2k19_columns_byte_for_byte():
    """Column index addresses pick one column of the (n, 3) accelerometer array, unchanged."""
    acc = np.load(RAW / "processed_log/IMU/accelerometer/value")
    t = np.load(RAW / "processed_log/IMU/accelerometer/t")
    got = read_numpy(RAW, ["processed_log/IMU/accelerometer[2]", "processed_log/CAN/speed",
                           "global_pose/frame_velocities[1]@global_pose/frame_times"])
    s = got["processed_log/IMU/accelerometer[2]"]
    np.testing.assert_array_equal(s.t, t)
    np.testing.assert_array_equal(s.value, acc[:, 2])
    # CAN/speed is stored as (n, 1): one column, no index needed.
    assert got["processed_log/CAN/speed"].value.shape == (4974,)
    pose = got["global_pose/frame_velocities[1]@global_pose/frame_times"]
    np.testing.assert_array_equal(pose.value, np.load(RAW / "global_pose/frame_velocities")[:, 1])
    np.testing.assert_array_equal(pose.t, np.load(RAW / "global_pose/frame_times"))


@needs_rav4
def test_numpy_folder_errors_name_the_address():
    with pytest.raises(LogFormatError, match=r"has 3 columns; pick one, e.g. "
                                             r"'processed_log/IMU/gyro\[0\]'"):
        read_numpy(RAW, ["processed_log/IMU/gyro"])
    with pytest.raises(LogFormatError, match=r"column 3 out of range \(the array has 3 columns"):
        read_numpy(RAW, ["processed_log/IMU/gyro[3]"])
    with pytest.raises(LogFormatError, match=r"no folder 'processed_log/IMU/nothing'"):
        read_numpy(RAW, ["processed_log/IMU/nothing"])
    with pytest.raises(LogFormatError, match=r"a bare array: add '@TIME_ARRAY'"):
        read_numpy(RAW, ["global_pose/frame_velocities[0]"])
    with pytest.raises(LogFormatError, match="leaves the folder"):
        parse_address("../etc/passwd")
    with pytest.raises(LogFormatError, match="malformed"):
        parse_address("IMU/gyro[x]")


def test_numpy_folder_length_mismatch(tmp_path):
    d = tmp_path / "S"
    d.mkdir()
    _save(d / "t", np.arange(3.0))
    _save(d / "value", np.arange(4.0))
    with pytest.raises(LogFormatError, match=r"'S': 3 times but 4 values"):
        read_numpy(tmp_path, ["S"])


CROSSPLANT_X05 = CROSSPLANT_DATA / "x05_sine_steer_dry_rwd.parquet"


@pytest.mark.skipif(not CROSSPLANT_X05.is_file(), reason="crossplant not present")
def test_channel_map_dispatches_mdf_and_ros2_by_file_kind(tmp_path):
    """One crossplant log written as MDF4 (raw CAN + DBC) and as a ROS 2 bag, read back through
    channel maps whose [source] names no kind: the reader is picked from the file. MDF values
    are within half a DBC step (the CAN quantisation, converted to SI); ROS 2 stores float64,
    but its stamps are ns since 1970 and float64 seconds at 1.7e9 s resolve 2.4e-7 s, so the
    values are within 2 × 2.4e-7 s × the channel's largest slope."""
    pytest.importorskip("asammdf")
    pytest.importorskip("rosbags")
    from vestim.io.channel_map import apply_channel_map, parse_channel_map
    from vestim.io.writers import (
        CAN_SIGNALS,
        ROS2_FIELDS,
        can_database,
        write_dbc,
        write_mdf_can,
        write_ros2_bag,
    )

    cols = ["omega_fl", "omega_fr", "omega_rl", "omega_rr", "ax", "ay", "az", "yaw_rate",
            "roll_rate", "pitch_rate", "steering_wheel_angle", "delta_fl", "delta_fr"]
    log = pd.read_parquet(CROSSPLANT_X05, columns=["t", *cols]).iloc[:600]
    write_mdf_can(log, tmp_path / "can.mf4")
    write_dbc(tmp_path / "car.dbc")
    db = can_database()
    mdf_map = {"source": {"dbc": [str(tmp_path / "car.dbc")]}, "output": {"rate": 200.0},
               "channels": {c: {"source": CAN_SIGNALS[c].address, "unit": CAN_SIGNALS[c].unit}
                            for c in cols}}
    got, _ = apply_channel_map(tmp_path / "can.mf4", parse_channel_map(mdf_map))
    assert len(got) == len(log)
    for c in cols:
        message, signal = CAN_SIGNALS[c].address.split(".")
        step = db.get_message_by_name(message).get_signal_by_name(signal).scale
        tol = 0.5 * step / CAN_SIGNALS[c].per_si + 1e-12
        np.testing.assert_allclose(got[c], log[c], rtol=0, atol=tol, err_msg=c)

    write_ros2_bag(log, tmp_path / "bag")
    si = {c: ("rad/s" if c.startswith("omega") or c.endswith("rate") else
              "m/s^2" if c in ("ax", "ay", "az") else "rad") for c in cols}
    ros_map = {"output": {"rate": 200.0},
               "channels": {c: {"source": ROS2_FIELDS[c], "unit": si[c]} for c in cols}}
    got, _ = apply_channel_map(tmp_path / "bag", parse_channel_map(ros_map))
    assert len(got) == len(log)
    for c in cols:
        slope = float(np.max(np.abs(np.diff(log[c]) / np.diff(log["t"]))))
        np.testing.assert_allclose(got[c], log[c], rtol=0, atol=2 * 2.4e-7 * slope + 1e-12,
                                   err_msg=c)
