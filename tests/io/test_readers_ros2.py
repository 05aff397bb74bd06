"""ROS 2 bag reader (vestim.io.readers.ros2) and the bag writer (vestim.io.writers).

Bags are written with rosbags in both storages (sqlite3 ``.db3`` and ``.mcap``): the
standard ``sensor_msgs/msg/Imu`` and ``std_msgs/msg/Float64MultiArray`` and two message
types of our own whose definitions travel in the bag. float64 fields are stored exactly, so
values come back bit for bit; times come back as float64 s on the bag clock (epoch 1.7e9 s,
where float64 resolves 2.4e-7 s, hence the 1e-6 s time tolerance).
"""

from __future__ import annotations

from pathlib import Path
from typing import Literal

import numpy as np
import pandas as pd
import pytest

from tests._paths import CROSSPLANT_DATA
from vestim.errors import LogFormatError
from vestim.io.readers import ros2
from vestim.io.writers import ROS2_FIELDS, ROS2_START_TIME_NS, ros2_typestore, write_ros2_bag

rosbags = pytest.importorskip("rosbags")

CROSSPLANT = CROSSPLANT_DATA
X05 = CROSSPLANT / "x05_sine_steer_dry_rwd.parquet"
EXAMPLE = Path(__file__).resolve().parents[2] / "examples" / "ros2_bag"
EPOCH = ROS2_START_TIME_NS * 1e-9
LATENCY = 0.002
"""s; the test bags record every message 2 ms after its sample time, so header and receive
times differ and the reader's choice between them shows."""
Storage = Literal["sqlite3", "mcap"]
STORAGES: tuple[Storage, ...] = ("sqlite3", "mcap")


@pytest.fixture(scope="module")
def log() -> pd.DataFrame:
    """The first 10 s of crossplant x05 (sine steer, 200 Hz, 2001 rows), measured channels."""
    if not X05.exists():
        pytest.skip("crossplant logs not available")
    df = pd.read_parquet(X05)
    return df.loc[df["t"] <= 10.0 + 1e-9, [c for c in df.columns if not c.startswith("ref_")]]


@pytest.fixture(scope="module")
def bags(log: pd.DataFrame, tmp_path_factory: pytest.TempPathFactory) -> dict[Storage, Path]:
    folder = tmp_path_factory.mktemp("bags")
    return {s: write_ros2_bag(log, folder / f"x05_{s}", storage=s, receive_latency=LATENCY) for s in STORAGES}


@pytest.mark.parametrize("storage", STORAGES)
def test_round_trip_values_and_times(log: pd.DataFrame, bags: dict[Storage, Path], storage: Storage) -> None:
    """Every field equals the log exactly (float64 stored as is). Topics with a header
    (/imu, /wheel_torques, /steering, /road_wheel_angles) are timed by header.stamp =
    epoch + t; /wheel_speeds (Float64MultiArray, no header) by its receive time, 2 ms later."""
    addresses = {c: a for c, a in ROS2_FIELDS.items() if c in log.columns}
    assert len(addresses) == 17
    streams = ros2.read_streams(bags[storage], list(addresses.values()))
    t = log["t"].to_numpy()
    for column, address in addresses.items():
        s = streams[address]
        np.testing.assert_array_equal(s.value, log[column].to_numpy(), err_msg=address)
        late = LATENCY if address.startswith("/wheel_speeds") else 0.0
        np.testing.assert_allclose(s.t - EPOCH, t + late, rtol=0, atol=1e-6, err_msg=address)


@pytest.mark.parametrize("storage", STORAGES)
def test_receive_time_and_storage_file(log: pd.DataFrame, bags: dict[Storage, Path],
                                       storage: Storage) -> None:
    """time="receive" times /imu by when it was recorded (t + 2 ms); the storage file itself
    (.db3 / .mcap inside the bag folder) reads like the folder; header.stamp reads as s."""
    file = next(bags[storage].glob("*.db3" if storage == "sqlite3" else "*.mcap"))
    s = ros2.read_streams(file, ["/imu:angular_velocity.z", "/imu:header.stamp"], time="receive")
    t = log["t"].to_numpy()
    np.testing.assert_allclose(s["/imu:angular_velocity.z"].t - EPOCH, t + LATENCY, rtol=0, atol=1e-6)
    np.testing.assert_allclose(s["/imu:header.stamp"].value - EPOCH, t, rtol=0, atol=1e-6)
    np.testing.assert_array_equal(s["/imu:angular_velocity.z"].value, log["yaw_rate"].to_numpy())


def test_address_parsing() -> None:
    assert ros2.parse_address("/imu:linear_acceleration.x") == ("/imu", ["linear_acceleration", "x"])
    assert ros2.parse_address("/a/b:wheels[1].speed") == ("/a/b", ["wheels", 1, "speed"])
    assert ros2.parse_address("/m:data[2][0]") == ("/m", ["data", 2, 0])
    for bad in ("imu:linear_acceleration.x", "/imu", "/imu:", "/imu:a..b", "/imu:a[x]"):
        with pytest.raises(LogFormatError, match="is not"):
            ros2.parse_address(bad)


def test_field_errors_name_the_fields(bags: dict[Storage, Path]) -> None:
    bag = bags["mcap"]
    with pytest.raises(LogFormatError, match=r"no topic '/imu0'.*close matches: /imu; topics in the bag: "
                                             r"/imu, /road_wheel_angles, /steering, /wheel_speeds, "
                                             r"/wheel_torques"):
        ros2.read_streams(bag, ["/imu0:linear_acceleration.x"])
    with pytest.raises(LogFormatError, match=r"sensor_msgs/msg/Imu\) has no field 'linear_accel'; "
                                             r"close matches: linear_acceleration"):
        ros2.read_streams(bag, ["/imu:linear_accel.x"])
    with pytest.raises(LogFormatError, match=r"linear_acceleration is a message "
                                             r"\(geometry_msgs/msg/Vector3\).*"
                                             r"linear_acceleration.x, linear_acceleration.y"):
        ros2.read_streams(bag, ["/imu:linear_acceleration"])
    with pytest.raises(LogFormatError, match=r"data\[4\] is out of range: data has 4 elements"):
        ros2.read_streams(bag, ["/wheel_speeds:data[4]"])
    with pytest.raises(LogFormatError, match=r"data is an array of 4 elements; address one, e.g. data\[0\]"):
        ros2.read_streams(bag, ["/wheel_speeds:data"])
    with pytest.raises(LogFormatError, match=r"header.frame_id is text"):
        ros2.read_streams(bag, ["/imu:header.frame_id"])
    with pytest.raises(LogFormatError, match="time='sensor' is not a ROS 2 time choice"):
        ros2.read_streams(bag, ["/imu:linear_acceleration.x"], time="sensor")  # type: ignore[arg-type]


def test_bad_bags(tmp_path: Path) -> None:
    with pytest.raises(LogFormatError, match="does not exist"):
        ros2.read_streams(tmp_path / "nothing", ["/imu:linear_acceleration.x"])
    junk = tmp_path / "junk.db3"
    junk.write_bytes(b"this is not sqlite" * 20)
    with pytest.raises(LogFormatError, match="is not a readable ROS 2 bag"):
        ros2.read_streams(junk, ["/imu:linear_acceleration.x"])
    folder = tmp_path / "not_a_bag"
    folder.mkdir()
    with pytest.raises(LogFormatError, match="is not a readable ROS 2 bag"):
        ros2.read_streams(folder, ["/imu:linear_acceleration.x"])


def test_unset_header_stamps_say_use_receive_time(tmp_path: Path) -> None:
    """An Imu publisher that leaves header.stamp at 0 gives no sample times: the error says
    to read receive times instead, which then work (0.01 s apart, as recorded)."""
    ts = ros2_typestore()
    Imu, Header, Time = (ts.types[n] for n in ("sensor_msgs/msg/Imu", "std_msgs/msg/Header",
                                                "builtin_interfaces/msg/Time"))
    V3, Q = ts.types["geometry_msgs/msg/Vector3"], ts.types["geometry_msgs/msg/Quaternion"]
    path = tmp_path / "unstamped"
    with rosbags.rosbag2.Writer(path, version=9) as w:
        conn = w.add_connection("/imu", "sensor_msgs/msg/Imu", typestore=ts)
        for i in range(5):
            msg = Imu(header=Header(stamp=Time(sec=0, nanosec=0), frame_id=""),
                      orientation=Q(x=0.0, y=0.0, z=0.0, w=1.0), orientation_covariance=np.zeros(9),
                      angular_velocity=V3(x=0.0, y=0.0, z=0.1 * i), angular_velocity_covariance=np.zeros(9),
                      linear_acceleration=V3(x=0.0, y=0.0, z=9.81),
                      linear_acceleration_covariance=np.zeros(9))
            w.write(conn, 10**18 + i * 10_000_000, ts.serialize_cdr(msg, "sensor_msgs/msg/Imu"))
    with pytest.raises(LogFormatError, match=r"5 messages on /imu have header.stamp = 0.*time='receive'"):
        ros2.read_streams(path, ["/imu:angular_velocity.z"])
    s = ros2.read_streams(path, ["/imu:angular_velocity.z"], time="receive")["/imu:angular_velocity.z"]
    np.testing.assert_allclose(np.diff(s.t), 0.01, rtol=0, atol=1e-6)
    np.testing.assert_allclose(s.value, 0.1 * np.arange(5))


def test_writer_refuses_existing_folder_and_partial_topics(log: pd.DataFrame, tmp_path: Path) -> None:
    """The bag folder is never overwritten; a log with ax but no az cannot fill /imu, and a
    NaN in a dense channel is refused. Nothing is left behind."""
    (tmp_path / "exists").mkdir()
    with pytest.raises(LogFormatError, match="exists already"):
        write_ros2_bag(log, tmp_path / "exists")
    with pytest.raises(LogFormatError, match="has 'ax' but not 'az'"):
        write_ros2_bag(log.drop(columns=["az"]), tmp_path / "b")
    with pytest.raises(LogFormatError, match="none of the channels the bag carries"):
        write_ros2_bag(log[["t"]], tmp_path / "b")
    bad = log.copy()
    bad.loc[bad.index[4], "torque_rl"] = np.nan
    with pytest.raises(LogFormatError, match="column 'torque_rl' row 4: nan is not finite"):
        write_ros2_bag(bad, tmp_path / "c")
    assert sorted(p.name for p in tmp_path.iterdir()) == ["exists"]


def test_sparse_gnss_topic(log: pd.DataFrame, tmp_path: Path) -> None:
    """gnss_speed (NaN between fixes) goes on /gnss_speed at its finite rows only: 10 Hz → 101
    messages in 10 s, at receive time (Float64 has no header)."""
    with_gnss = log.copy()
    gnss = np.full(len(log), np.nan)
    gnss[::20] = 18.0 + 0.01 * np.arange(len(gnss[::20]))
    with_gnss["gnss_speed"] = gnss
    bag = write_ros2_bag(with_gnss, tmp_path / "gnss", storage="mcap")
    s = ros2.read_streams(bag, ["/gnss_speed:data"])["/gnss_speed:data"]
    assert len(s.t) == 101
    np.testing.assert_array_equal(s.value, gnss[::20])
    np.testing.assert_allclose(s.t - EPOCH, log["t"].to_numpy()[::20], rtol=0, atol=1e-6)


# --- the estimate through the channel map (issue 14) ------------------------------------------


@pytest.mark.parametrize("storage", STORAGES)
def test_bag_import_gives_the_parquet_estimate(log: pd.DataFrame, tmp_path: Path, storage: Storage) -> None:
    """x05 as a ROS 2 bag through examples/ros2_bag/map.toml gives the Parquet estimate.

    The bag holds the values exactly; the only loss is time: s since 1970 in float64 resolve
    2.4e-7 s, so the imported log's channels are the Parquet's interpolated up to ~1e-7 s off
    (measured: largest input change 0.005 N·m on a torque). The estimate moves by < 0.001 of
    its own one-sigma (median sigma_vx, sigma_vy, sigma_fx_*, sigma_fy_*); measured 1.3e-4 σ
    on F_y, 4e-5 σ on v_x. The bag written here has no receive latency, as the map's
    /wheel_speeds (no header) is timed by receive time.
    """
    from vestim.io import load_vehicle
    from vestim.io.channel_map import import_log
    from vestim.pipeline import Pipeline, PipelineConfig

    bag = write_ros2_bag(log, tmp_path / "x05", storage=storage)
    imported, report = import_log(bag, EXAMPLE / "map.toml")
    assert len(imported) == len(log)
    assert report.t0_source == pytest.approx(EPOCH, abs=1e-6)
    vehicle = load_vehicle(CROSSPLANT / "vehicle2.toml")
    parquet = Pipeline(vehicle, PipelineConfig()).run(log.reset_index(drop=True))
    from_bag = Pipeline(vehicle, PipelineConfig()).run(imported)
    for c in [c for c in from_bag.columns if f"sigma_{c}" in from_bag.columns]:
        if c.startswith("mu_"):  # friction potential: NaN where not excited
            a, b = from_bag[c].to_numpy(), parquet[c].to_numpy()
            both = np.isfinite(a) & np.isfinite(b)
            assert np.mean(np.isfinite(a) != np.isfinite(b)) < 0.01, c  # flag flips at 1e-6
            if both.any():
                assert np.max(np.abs(a[both] - b[both])) < 1e-3, c
            continue
        sigma = float(parquet[f"sigma_{c}"].median())
        worst = float(np.max(np.abs(from_bag[c] - parquet[c])))
        assert worst < 1e-3 * sigma, f"{c}: {worst:.3g} vs sigma {sigma:.3g}"


def test_a_later_shorter_array_names_the_message(tmp_path: Path) -> None:
    """Float64MultiArray lengths may change between messages: data[3] of a later message
    with 2 elements is an error naming that message (index 3) and its time."""
    ts = ros2_typestore()
    Arr, Layout = ts.types["std_msgs/msg/Float64MultiArray"], ts.types["std_msgs/msg/MultiArrayLayout"]
    path = tmp_path / "ragged"
    with rosbags.rosbag2.Writer(path, version=9, storage_plugin=rosbags.rosbag2.StoragePlugin.MCAP) as w:
        conn = w.add_connection("/wheels", "std_msgs/msg/Float64MultiArray", typestore=ts)
        for i, n in enumerate((4, 4, 4, 2, 4)):
            msg = Arr(layout=Layout(dim=[], data_offset=0), data=np.arange(n, dtype=np.float64) + i)
            w.write(conn, 10**18 + i * 10_000_000, ts.serialize_cdr(msg, "std_msgs/msg/Float64MultiArray"))
    ok = ros2.read_streams(path, ["/wheels:data[1]"])["/wheels:data[1]"]
    np.testing.assert_array_equal(ok.value, [1.0, 2.0, 3.0, 4.0, 5.0])
    with pytest.raises(LogFormatError, match=r"data\[3\] is out of range: data has 2 elements "
                                             r"\(message 3 on that topic, t = 1000000000.030000000 s\)"):
        ros2.read_streams(path, ["/wheels:data[3]"])
