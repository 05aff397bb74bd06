"""Write a drive log (docs/format.md) as the containers real cars record.

- :func:`write_mdf_can`: an MDF4 file whose measured channels are raw CAN frames (ASAM
  bus-logging ``CAN_DataFrame`` channel group), encoded with the DBC :data:`VEHICLE_DBC`
  (also written out as a ``.dbc`` file), one frame per message at every sample;
- :func:`write_ros2_bag`: a ROS 2 bag (sqlite3 ``.db3`` or ``.mcap``) with
  ``sensor_msgs/msg/Imu`` on ``/imu``, ``std_msgs/msg/Float64MultiArray`` wheel speeds on
  ``/wheel_speeds`` and message types of our own, ``vestim_msgs/msg/WheelTorques``,
  ``Steering`` and ``RoadWheelAngles`` (definitions stored in the bag), all in SI units.

A message (topic) is written when the log has all its columns, and a log that has some of
them but not all is an error naming the missing one; a log's ``delta`` (one angle for both
front wheels) is sent as both road-wheel angles.

They make test and example data for :mod:`vestim.io.readers` and the channel map, and let
a spec log be replayed into tools that read those formats (CANape, asammdf GUI, Foxglove,
``ros2 bag play``). The CAN encoding quantises each value to its DBC factor (rounded to the
nearest step by cantools, an error of at most factor/2; see :data:`CAN_SIGNALS`). The ROS 2 bag stores
float64 values exactly. Outputs are written atomically.

Needs the ``logs`` extra (``pip install 'vestim[logs]'``).
"""

from __future__ import annotations

import math
import os
import shutil
import uuid
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Literal

import numpy as np
import pandas as pd

from vestim.errors import LogFormatError
from vestim.io import channels as ch
from vestim.io.files import atomic_path, write_text_atomic
from vestim.io.readers.mdf import asammdf_module, cantools_module
from vestim.io.readers.ros2 import rosbags_modules

__all__ = ["CAN_SIGNALS", "ROS2_FIELDS", "VEHICLE_DBC", "can_database", "check_can_values", "encode_frames",
           "write_dbc", "write_mdf_can", "write_ros2_bag"]

VEHICLE_DBC = """\
VERSION "vestim example vehicle bus 1"

NS_ :

BS_:

BU_: ABS EPS IMU VCU GNSS VESTIM

BO_ 416 WHEEL_SPEEDS: 8 ABS
 SG_ WheelSpeed_FL : 0|16@1+ (0.05,0) [0|3276.75] "rpm" VESTIM
 SG_ WheelSpeed_FR : 16|16@1+ (0.05,0) [0|3276.75] "rpm" VESTIM
 SG_ WheelSpeed_RL : 32|16@1+ (0.05,0) [0|3276.75] "rpm" VESTIM
 SG_ WheelSpeed_RR : 48|16@1+ (0.05,0) [0|3276.75] "rpm" VESTIM

BO_ 432 WHEEL_TORQUES: 8 VCU
 SG_ WheelTorque_FL : 0|16@1- (0.5,0) [-16384|16383.5] "Nm" VESTIM
 SG_ WheelTorque_FR : 16|16@1- (0.5,0) [-16384|16383.5] "Nm" VESTIM
 SG_ WheelTorque_RL : 32|16@1- (0.5,0) [-16384|16383.5] "Nm" VESTIM
 SG_ WheelTorque_RR : 48|16@1- (0.5,0) [-16384|16383.5] "Nm" VESTIM

BO_ 194 STEERING: 2 EPS
 SG_ SteeringWheelAngle : 0|16@1- (0.1,0) [-3276.8|3276.7] "deg" VESTIM

BO_ 195 ROAD_WHEEL_ANGLES: 4 EPS
 SG_ RoadWheelAngle_FL : 0|16@1- (0.002,0) [-65.536|65.534] "deg" VESTIM
 SG_ RoadWheelAngle_FR : 16|16@1- (0.002,0) [-65.536|65.534] "deg" VESTIM

BO_ 304 IMU_ACCEL: 6 IMU
 SG_ LongAccel : 7|16@0+ (0.002,-65.536) [-65.536|65.534] "m/s^2" VESTIM
 SG_ LatAccel : 23|16@0+ (0.002,-65.536) [-65.536|65.534] "m/s^2" VESTIM
 SG_ VertAccel : 39|16@0+ (0.002,-65.536) [-65.536|65.534] "m/s^2" VESTIM

BO_ 305 IMU_RATES: 6 IMU
 SG_ YawRate : 7|16@0- (0.01,0) [-327.68|327.67] "deg/s" VESTIM
 SG_ RollRate : 23|16@0- (0.01,0) [-327.68|327.67] "deg/s" VESTIM
 SG_ PitchRate : 39|16@0- (0.01,0) [-327.68|327.67] "deg/s" VESTIM

BO_ 2566844832 GNSS_SPEED: 2 GNSS
 SG_ SpeedOverGround : 0|16@1+ (0.01,0) [0|655.35] "km/h" VESTIM

CM_ BO_ 416 "Wheel angular speeds, 100 Hz in a car; here one frame per log sample.";
CM_ BO_ 432 "Net wheel torques (drive minus brake), positive driving forward.";
CM_ BO_ 194 "Steering-wheel angle, positive steering left.";
CM_ BO_ 195 "Road-wheel angles of the front wheels, positive steering left.";
CM_ BO_ 304 "IMU specific force, ISO 8855 body axes (x forward, y left, z up); Motorola byte order.";
CM_ BO_ 305 "IMU body rates, ISO 8855, right-handed; Motorola byte order.";
CM_ BO_ 2566844832 "GNSS speed over ground, extended (29-bit) ID 0x18FEF1A0, sent at the fix rate.";
"""
"""The example vehicle's CAN database: realistic scaled-integer signals (Intel and Motorola
byte order, signed and offset-unsigned, one extended ID)."""

_RPM = 60.0 / (2.0 * math.pi)
_DEG = 180.0 / math.pi


@dataclass(frozen=True)
class CanSignal:
    """Where a log column goes on the bus: ``Message.Signal`` and the factor SI → DBC unit."""

    address: str
    unit: str
    per_si: float  # DBC value = SI value * per_si


CAN_SIGNALS: dict[str, CanSignal] = {
    **{f"omega_{c}": CanSignal(f"WHEEL_SPEEDS.WheelSpeed_{c.upper()}", "rpm", _RPM)
       for c in ("fl", "fr", "rl", "rr")},
    **{f"torque_{c}": CanSignal(f"WHEEL_TORQUES.WheelTorque_{c.upper()}", "N*m", 1.0)
       for c in ("fl", "fr", "rl", "rr")},
    "steering_wheel_angle": CanSignal("STEERING.SteeringWheelAngle", "deg", _DEG),
    "delta_fl": CanSignal("ROAD_WHEEL_ANGLES.RoadWheelAngle_FL", "deg", _DEG),
    "delta_fr": CanSignal("ROAD_WHEEL_ANGLES.RoadWheelAngle_FR", "deg", _DEG),
    "ax": CanSignal("IMU_ACCEL.LongAccel", "m/s^2", 1.0),
    "ay": CanSignal("IMU_ACCEL.LatAccel", "m/s^2", 1.0),
    "az": CanSignal("IMU_ACCEL.VertAccel", "m/s^2", 1.0),
    "yaw_rate": CanSignal("IMU_RATES.YawRate", "deg/s", _DEG),
    "roll_rate": CanSignal("IMU_RATES.RollRate", "deg/s", _DEG),
    "pitch_rate": CanSignal("IMU_RATES.PitchRate", "deg/s", _DEG),
    "gnss_speed": CanSignal("GNSS_SPEED.SpeedOverGround", "km/h", 3.6),
}
"""Log column → CAN signal of :data:`VEHICLE_DBC`. The DBC factor in SI (factor / per_si) is
the quantisation step; a decoded value is within half of it of the log's value."""


def can_database() -> Any:
    """:data:`VEHICLE_DBC` as a cantools ``Database``."""
    cantools = cantools_module()
    return cantools.database.load_string(VEHICLE_DBC, database_format="dbc", strict=True)


def write_dbc(path: str | os.PathLike[str]) -> Path:
    """Write :data:`VEHICLE_DBC` to ``path`` (atomically); returns the path."""
    return write_text_atomic(path, VEHICLE_DBC)


def check_can_values(values: np.ndarray, signal: Any, *, column: str = "") -> None:
    """Refuse values [DBC unit] that cantools ``signal`` cannot carry, naming ``column`` and
    the row: not finite, or outside the raw range once rounded to the signal's step."""
    name = column or signal.name
    v = np.asarray(values, dtype=np.float64)
    if (bad := np.flatnonzero(~np.isfinite(v))).size:
        raise LogFormatError(f"column {name!r} row {bad[0]}: {v[bad[0]]} cannot be sent on the CAN bus; "
                             "every sample of a CAN channel must be finite")
    length = int(signal.length)
    raw = np.rint((v - float(signal.offset)) / float(signal.scale))
    lo, hi = (-(2.0 ** (length - 1)), 2.0 ** (length - 1) - 1) if signal.is_signed else (0.0, 2.0**length - 1)
    if (bad := np.flatnonzero((raw < lo) | (raw > hi))).size:
        i = int(bad[0])
        raise LogFormatError(f"column {name!r} row {i}: {v[i]:g} {signal.unit or ''} is outside the range "
                             f"of CAN signal {signal.name!r} ({lo * signal.scale + signal.offset:g} to "
                             f"{hi * signal.scale + signal.offset:g}); check the column's unit")


def encode_frames(message: Any, values: dict[str, np.ndarray]) -> np.ndarray:
    """Payloads (n, 8) uint8 of cantools ``message`` carrying ``values`` (signal name →
    (n,) values in the DBC's units), each frame encoded by cantools (``Message.encode``,
    raw = round((value − offset) / scale), ties to even)."""
    names = list(values)
    columns = [np.asarray(values[k], dtype=np.float64).tolist() for k in names]
    n = len(columns[0]) if columns else 0
    out = np.zeros((n, 8), dtype=np.uint8)
    for i in range(n):
        data = message.encode({k: col[i] for k, col in zip(names, columns, strict=True)},
                              scaling=True, strict=True)
        out[i, : len(data)] = np.frombuffer(data, dtype=np.uint8)
    return out


def _messages_for(log: pd.DataFrame, db: Any) -> dict[str, list[tuple[str, Any]]]:
    """Message name → [(column, cantools signal), ...] for the log's columns."""
    by_message: dict[str, list[tuple[str, Any]]] = {}
    for column, target in CAN_SIGNALS.items():
        if column in log.columns:
            message, signal = target.address.split(".")
            by_message.setdefault(message, []).append((column, db.get_message_by_name(message)
                                                       .get_signal_by_name(signal)))
    if not by_message:
        raise LogFormatError("the log has none of the channels the CAN bus carries "
                             f"({', '.join(CAN_SIGNALS)})")
    for message, present in by_message.items():
        wanted = [c for c, s in CAN_SIGNALS.items() if s.address.startswith(message + ".")]
        if missing := [c for c in wanted if c not in log.columns]:
            raise LogFormatError(f"the log has {present[0][0]!r} but not {missing[0]!r}, which CAN message "
                                 f"{message} also carries; add the column or drop the message's others")
    return by_message


def _with_road_wheel_angles(log: pd.DataFrame) -> pd.DataFrame:
    """``log``, with ``delta`` (one angle for both front wheels) as delta_fl and delta_fr where
    the log has no per-wheel angles; a new frame, the log itself is not modified."""
    if ch.DELTA in log.columns and not any(c in log.columns for c in ch.ROAD_WHEEL_ANGLES):
        return log.assign(**dict.fromkeys(ch.ROAD_WHEEL_ANGLES, log[ch.DELTA]))
    return log


def _times(log: pd.DataFrame) -> np.ndarray:
    if ch.T not in log.columns:
        raise LogFormatError("the log has no time column 't'")
    t = log[ch.T].to_numpy(dtype=np.float64)
    if t.size == 0 or not np.all(np.isfinite(t)) or np.any(np.diff(t) <= 0):
        raise LogFormatError("column 't' must be finite and strictly increasing to be written")
    return t


def can_frames(log: pd.DataFrame, *, db: Any = None) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The log's CAN frames ``(t [s], frame ID, payload (n, 8) uint8)`` sorted by time.

    One frame per message of :data:`VEHICLE_DBC` at every row (``gnss_speed``: at its
    finite rows only); frames of one row keep the DBC's message order.
    """
    db = can_database() if db is None else db
    log = _with_road_wheel_angles(log)
    t = _times(log)
    ts, ids, payloads, order = [], [], [], []
    for k, (message_name, signals) in enumerate(_messages_for(log, db).items()):
        message = db.get_message_by_name(message_name)
        rows = np.arange(t.size)
        if any(c in ch.SPARSE for c, _ in signals):
            finite = np.all([np.isfinite(log[c].to_numpy(dtype=np.float64)) for c, _ in signals], axis=0)
            rows = np.flatnonzero(finite)
        values: dict[str, np.ndarray] = {}
        for column, signal in signals:
            values[signal.name] = log[column].to_numpy(dtype=np.float64)[rows] * CAN_SIGNALS[column].per_si
            check_can_values(values[signal.name], signal, column=column)
        payload = encode_frames(message, values)
        key = message.frame_id | (1 << 31 if message.is_extended_frame else 0)
        ts.append(t[rows])
        ids.append(np.full(rows.size, key, dtype=np.uint32))
        payloads.append(payload)
        order.append(np.full(rows.size, k))
    t_all = np.concatenate(ts)
    sort = np.lexsort((np.concatenate(order), t_all))
    return t_all[sort], np.concatenate(ids)[sort], np.concatenate(payloads)[sort]


def write_mdf_can(log: pd.DataFrame, path: str | os.PathLike[str],
                  dbc_path: str | os.PathLike[str] | None = None, *, bus_channel: int = 1) -> Path:
    """Write ``log``'s measured channels as raw CAN frames in an MDF4 file; returns its path.

    The frames (see :func:`can_frames`; values converted from SI to the DBC units of
    :data:`CAN_SIGNALS`) go into one ASAM bus-logging channel group ``CAN_DataFrame``
    (``BusChannel``, ``ID`` with bit 31 set for extended IDs, ``IDE``, ``DLC``,
    ``DataLength``, ``DataBytes``) with the log's ``t`` [s] as master time. Where
    ``dbc_path`` is given, the DBC is written there too. The log is not modified.
    """
    asammdf = asammdf_module()
    from asammdf.blocks import v4_constants as v4c
    from asammdf.blocks.source_utils import Source

    t, ids, payload = can_frames(log)
    db = can_database()
    lengths = {m.frame_id | (1 << 31 if m.is_extended_frame else 0): m.length for m in db.messages}
    dtype = np.dtype([("CAN_DataFrame.BusChannel", "u1"), ("CAN_DataFrame.ID", "<u4"),
                      ("CAN_DataFrame.IDE", "u1"), ("CAN_DataFrame.DLC", "u1"),
                      ("CAN_DataFrame.DataLength", "u1"), ("CAN_DataFrame.DataBytes", "u1", (8,))])
    record = np.zeros(t.size, dtype=dtype)
    record["CAN_DataFrame.BusChannel"] = bus_channel
    record["CAN_DataFrame.ID"] = ids
    record["CAN_DataFrame.IDE"] = (ids >> 31) & 1
    n_bytes = np.vectorize(lengths.__getitem__, otypes=[np.uint8])(ids) if ids.size else ids
    record["CAN_DataFrame.DLC"] = n_bytes
    record["CAN_DataFrame.DataLength"] = n_bytes
    record["CAN_DataFrame.DataBytes"] = payload
    source = Source(name=f"CAN{bus_channel}", path=f"CAN{bus_channel}", comment="vestim.io.writers",
                    source_type=v4c.SOURCE_BUS, bus_type=v4c.BUS_TYPE_CAN)
    mdf = asammdf.MDF(version="4.10")
    try:
        mdf.append([asammdf.Signal(record, t, name="CAN_DataFrame", source=source)],
                   acq_name=f"CAN{bus_channel}", comment="CAN bus logging")
        with atomic_path(path) as tmp, open(tmp, "wb+") as f:
            mdf.save(f, overwrite=True)
    finally:
        mdf.close()
    if dbc_path is not None:
        write_dbc(dbc_path)
    return Path(path)


# --- ROS 2 ----------------------------------------------------------------------------------

WHEEL_TORQUES_MSG = """\
# Net wheel torques (drive minus brake) [N*m], positive driving forward.
std_msgs/Header header
float64 fl
float64 fr
float64 rl
float64 rr
"""
STEERING_MSG = """\
# Steering-wheel angle [rad], positive steering left (ISO 8855 / REP-103).
std_msgs/Header header
float64 steering_wheel_angle
"""
ROAD_WHEEL_ANGLES_MSG = """\
# Road-wheel angles of the front wheels [rad], positive steering left.
std_msgs/Header header
float64 fl
float64 fr
"""

ROS2_FIELDS: dict[str, str] = {
    "ax": "/imu:linear_acceleration.x",
    "ay": "/imu:linear_acceleration.y",
    "az": "/imu:linear_acceleration.z",
    "roll_rate": "/imu:angular_velocity.x",
    "pitch_rate": "/imu:angular_velocity.y",
    "yaw_rate": "/imu:angular_velocity.z",
    "omega_fl": "/wheel_speeds:data[0]",
    "omega_fr": "/wheel_speeds:data[1]",
    "omega_rl": "/wheel_speeds:data[2]",
    "omega_rr": "/wheel_speeds:data[3]",
    "torque_fl": "/wheel_torques:fl",
    "torque_fr": "/wheel_torques:fr",
    "torque_rl": "/wheel_torques:rl",
    "torque_rr": "/wheel_torques:rr",
    "steering_wheel_angle": "/steering:steering_wheel_angle",
    "delta_fl": "/road_wheel_angles:fl",
    "delta_fr": "/road_wheel_angles:fr",
    "gnss_speed": "/gnss_speed:data",
}
"""Log column → ROS 2 address written by :func:`write_ros2_bag` (SI, REP-103 = ISO 8855 axes)."""

_TOPIC_TYPES = {
    "/imu": "sensor_msgs/msg/Imu",
    "/wheel_speeds": "std_msgs/msg/Float64MultiArray",
    "/wheel_torques": "vestim_msgs/msg/WheelTorques",
    "/steering": "vestim_msgs/msg/Steering",
    "/road_wheel_angles": "vestim_msgs/msg/RoadWheelAngles",
    "/gnss_speed": "std_msgs/msg/Float64",
}
ROS2_START_TIME_NS = 1_700_000_000_000_000_000
"""Default epoch of the log's t = 0 in a written bag (2023-11-14 22:13:20 UTC), ns."""


def ros2_typestore() -> Any:
    """A ROS 2 Humble typestore with the three ``vestim_msgs`` message types registered."""
    rosbags = rosbags_modules()
    ts = rosbags.typesys.get_typestore(rosbags.typesys.Stores.ROS2_HUMBLE)
    types: dict[str, Any] = {}
    types.update(rosbags.typesys.get_types_from_msg(WHEEL_TORQUES_MSG, "vestim_msgs/msg/WheelTorques"))
    types.update(rosbags.typesys.get_types_from_msg(STEERING_MSG, "vestim_msgs/msg/Steering"))
    types.update(rosbags.typesys.get_types_from_msg(ROAD_WHEEL_ANGLES_MSG, "vestim_msgs/msg/RoadWheelAngles"))
    ts.register(types)
    return ts


def _topic_columns(log: pd.DataFrame) -> dict[str, list[str]]:
    topics: dict[str, list[str]] = {}
    for column, address in ROS2_FIELDS.items():
        topics.setdefault(address.split(":")[0], []).append(column)
    out: dict[str, list[str]] = {}
    for topic, columns in topics.items():
        have = [c for c in columns if c in log.columns]
        if not have:
            continue
        if missing := [c for c in columns if c not in log.columns]:
            raise LogFormatError(f"the log has {have[0]!r} but not {missing[0]!r}, which ROS 2 topic {topic} "
                                 "also carries; add the column or drop the topic's others")
        out[topic] = columns
    if not out:
        raise LogFormatError(f"the log has none of the channels the bag carries ({', '.join(ROS2_FIELDS)})")
    return out


def write_ros2_bag(log: pd.DataFrame, path: str | os.PathLike[str], *,
                   storage: Literal["sqlite3", "mcap"] = "sqlite3",
                   start_time_ns: int = ROS2_START_TIME_NS, receive_latency: float = 0.0) -> Path:
    """Write ``log``'s measured channels as a ROS 2 bag folder at ``path``; returns the path.

    Topics (SI units, see :data:`ROS2_FIELDS`): ``/imu`` sensor_msgs/msg/Imu (orientation
    unknown: covariance[0] = −1), ``/wheel_speeds`` std_msgs/msg/Float64MultiArray
    [fl, fr, rl, rr] rad/s, ``/wheel_torques`` vestim_msgs/msg/WheelTorques,
    ``/steering`` vestim_msgs/msg/Steering, ``/road_wheel_angles``
    vestim_msgs/msg/RoadWheelAngles and, where the log has it, ``/gnss_speed``
    std_msgs/msg/Float64 at its finite rows. A message with a header is stamped
    ``start_time_ns + t``; every message is recorded (receive time) ``receive_latency`` s
    after its sample time. ``storage`` picks the file format (``.db3`` or ``.mcap``).
    ``path`` must not exist; the folder appears complete or not at all.
    """
    rosbags = rosbags_modules()
    target = Path(path)
    if target.exists():
        raise LogFormatError(f"{target} exists already; a ROS 2 bag is written to a new folder")
    if storage not in ("sqlite3", "mcap"):
        raise LogFormatError(f"storage {storage!r} is not a ROS 2 storage; use 'sqlite3' or 'mcap'")
    log = _with_road_wheel_angles(log)
    t = _times(log)
    topics = _topic_columns(log)
    ts = ros2_typestore()
    types = ts.types
    stamp_ns = start_time_ns + np.rint(t * 1e9).astype(np.int64)
    receive_ns = stamp_ns + round(receive_latency * 1e9)
    values = {c: log[c].to_numpy(dtype=np.float64) for cols in topics.values() for c in cols}
    for c, v in values.items():
        if c not in ch.SPARSE and (bad := np.flatnonzero(~np.isfinite(v))).size:
            raise LogFormatError(f"column {c!r} row {bad[0]}: {v[bad[0]]} is not finite; "
                                 "a measured channel is finite on every row")

    Header, Time = types["std_msgs/msg/Header"], types["builtin_interfaces/msg/Time"]

    def header(i: int) -> Any:
        sec, nsec = divmod(int(stamp_ns[i]), 1_000_000_000)
        return Header(stamp=Time(sec=sec, nanosec=nsec), frame_id="base_link")

    def make(topic: str, i: int) -> Any:
        v = {c: float(values[c][i]) for c in topics[topic]}
        if topic == "/imu":
            Vector3, Quaternion = types["geometry_msgs/msg/Vector3"], types["geometry_msgs/msg/Quaternion"]
            unknown = np.zeros(9)
            unknown[0] = -1.0
            return types["sensor_msgs/msg/Imu"](
                header=header(i), orientation=Quaternion(x=0.0, y=0.0, z=0.0, w=1.0),
                orientation_covariance=unknown,
                angular_velocity=Vector3(x=v["roll_rate"], y=v["pitch_rate"], z=v["yaw_rate"]),
                angular_velocity_covariance=np.zeros(9),
                linear_acceleration=Vector3(x=v["ax"], y=v["ay"], z=v["az"]),
                linear_acceleration_covariance=np.zeros(9))
        if topic == "/wheel_speeds":
            Layout, Dim = types["std_msgs/msg/MultiArrayLayout"], types["std_msgs/msg/MultiArrayDimension"]
            return types["std_msgs/msg/Float64MultiArray"](
                layout=Layout(dim=[Dim(label="fl,fr,rl,rr", size=4, stride=4)], data_offset=0),
                data=np.array([v[f"omega_{c}"] for c in ("fl", "fr", "rl", "rr")]))
        if topic == "/wheel_torques":
            return types["vestim_msgs/msg/WheelTorques"](
                header=header(i), **{c: v[f"torque_{c}"] for c in ("fl", "fr", "rl", "rr")})
        if topic == "/steering":
            return types["vestim_msgs/msg/Steering"](header=header(i), **v)
        if topic == "/road_wheel_angles":
            return types["vestim_msgs/msg/RoadWheelAngles"](header=header(i), fl=v["delta_fl"],
                                                             fr=v["delta_fr"])
        return types["std_msgs/msg/Float64"](data=v["gnss_speed"])

    plugins = rosbags.rosbag2.StoragePlugin
    plugin = plugins.MCAP if storage == "mcap" else plugins.SQLITE3
    tmp_dir = target.parent / f".{target.name}.{uuid.uuid4().hex}.tmp"
    tmp_dir.mkdir(parents=True)
    try:
        with rosbags.rosbag2.Writer(tmp_dir / target.name, version=9, storage_plugin=plugin) as writer:
            conns = {topic: writer.add_connection(topic, _TOPIC_TYPES[topic], typestore=ts)
                     for topic in topics}
            rows = {topic: np.arange(t.size) for topic in topics}
            if "/gnss_speed" in topics:
                rows["/gnss_speed"] = np.flatnonzero(np.isfinite(values["gnss_speed"]))
            events = sorted((int(receive_ns[i]), k, topic, int(i))
                            for k, topic in enumerate(topics) for i in rows[topic])
            for when, _, topic, i in events:
                msg = make(topic, i)
                writer.write(conns[topic], when, ts.serialize_cdr(msg, _TOPIC_TYPES[topic]))
        os.replace(tmp_dir / target.name, target)
    finally:
        shutil.rmtree(tmp_dir, ignore_errors=True)
    return target
