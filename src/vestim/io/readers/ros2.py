"""ROS 2 bag reader (sqlite3 ``.db3`` and ``.mcap``), through ``rosbags``.

``path`` is a bag folder (with ``metadata.yaml``) or one ``.db3`` / ``.mcap`` storage file.
An address is ``/topic:field.path``: the topic, a colon, then the message field, with
``.`` between nested fields and ``[i]`` indexing an array, e.g.
``/imu:linear_acceleration.x`` (``sensor_msgs/msg/Imu``), ``/wheels:data[2]``
(``std_msgs/msg/Float64MultiArray``) or ``/corners:wheels[1].speed`` for a message type
of one's own. Message definitions are taken from the bag (rosbag2 stores them); a bag
without them is read with the standard ROS 2 types. A field that is a
``builtin_interfaces/msg/Time`` or ``Duration`` reads as seconds.

Time, per topic (the ``time`` option):

- ``"header"`` (default): a message that has a ``std_msgs/Header`` is timed by its
  ``header.stamp`` (when the sample was taken); a message without a header by the bag's
  receive time (when it was recorded, some latency later);
- ``"receive"``: every message by its receive time.

Times are s on the bag's clock (ROS time, usually s since 1970) and each stream is sorted
by time; nothing is resampled and no unit is converted (:mod:`vestim.io.readers`).

Needs the ``logs`` extra (``pip install 'vestim[logs]'``). Every problem raises
:class:`~vestim.errors.LogFormatError` naming the bag, the address and the fix.
"""

from __future__ import annotations

import dataclasses
import difflib
import importlib
import re
from collections.abc import Sequence
from dataclasses import dataclass, field
from pathlib import Path
from types import SimpleNamespace
from typing import Any, Literal

import numpy as np

from vestim.errors import LogFormatError
from vestim.io.readers import Stream

__all__ = ["FIELD_UNITS", "TIME_MODES", "field_unit", "parse_address", "read_streams"]

TimeMode = Literal["header", "receive"]
TIME_MODES: tuple[str, ...] = ("header", "receive")

_ADDRESS = re.compile(r"^(/[^:\s]*):(.+)$")
_PART = re.compile(r"([A-Za-z_][A-Za-z0-9_]*)((?:\[\d+\])*)$")
_TIME_TYPES = ("builtin_interfaces/msg/Time", "builtin_interfaces/msg/Duration")

FIELD_UNITS: dict[str, dict[str, str]] = {
    "sensor_msgs/msg/Imu": {"linear_acceleration": "m/s^2", "angular_velocity": "rad/s"},
    "geometry_msgs/msg/Twist": {"linear": "m/s", "angular": "rad/s"},
    "geometry_msgs/msg/TwistStamped": {"twist.linear": "m/s", "twist.angular": "rad/s"},
    "geometry_msgs/msg/Accel": {"linear": "m/s^2", "angular": "rad/s^2"},
    "geometry_msgs/msg/AccelStamped": {"accel.linear": "m/s^2", "accel.angular": "rad/s^2"},
    "nav_msgs/msg/Odometry": {"twist.twist.linear": "m/s", "twist.twist.angular": "rad/s",
                              "pose.pose.position": "m"},
    "sensor_msgs/msg/NavSatFix": {"latitude": "deg", "longitude": "deg", "altitude": "m"},
}
"""The units standard ROS 2 message fields are defined in (REP-103: SI units), by message
type and field path prefix; a stream of one of these fields carries its unit."""


def rosbags_modules() -> SimpleNamespace:
    """``rosbags``' ``highlevel``, ``rosbag2`` and ``typesys``, or a LogFormatError to install them."""
    try:
        return SimpleNamespace(**{m: importlib.import_module(f"rosbags.{m}")
                                  for m in ("highlevel", "rosbag2", "typesys")})
    except ImportError as err:
        raise LogFormatError("reading or writing ROS 2 bags needs the Python package 'rosbags', which "
                             "is not installed; install the log readers with: pip install 'vestim[logs]'"
                             ) from err


def parse_address(address: str) -> tuple[str, list[str | int]]:
    """Split an address: ``"/imu:linear_acceleration.x"`` → ``("/imu", ["linear_acceleration", "x"])``.

    An index becomes an int: ``"/wheels:data[2]"`` → ``("/wheels", ["data", 2])``.
    """
    m = _ADDRESS.match(address.strip())
    if not m:
        raise LogFormatError(f"ROS 2 address {address!r} is not /topic:field.path "
                             "(e.g. /imu:linear_acceleration.x or /wheels:data[2])")
    topic, path = m.group(1), m.group(2)
    parts: list[str | int] = []
    for piece in path.split("."):
        pm = _PART.match(piece)
        if not pm:
            raise LogFormatError(f"ROS 2 address {address!r}: {piece!r} is not a field name with optional "
                                 "[index] (fields are joined by '.', e.g. linear_acceleration.x, data[2])")
        parts.append(pm.group(1))
        parts.extend(int(i) for i in re.findall(r"\[(\d+)\]", pm.group(2)))
    return topic, parts


def field_unit(msgtype: str, parts: Sequence[str | int]) -> str | None:
    """The unit of field ``parts`` of a ``msgtype`` message from :data:`FIELD_UNITS`, or None."""
    path = ".".join(p for p in parts if isinstance(p, str))
    for prefix, unit in FIELD_UNITS.get(msgtype, {}).items():
        if path == prefix or path.startswith(prefix + "."):
            return unit
    return None


def _msgtype(obj: Any) -> str | None:
    return getattr(type(obj), "__msgtype__", None)


def _fields(obj: Any) -> list[str]:
    return [f.name for f in dataclasses.fields(obj)] if dataclasses.is_dataclass(obj) else []


def _path_text(parts: Sequence[str | int]) -> str:
    out = ""
    for p in parts:
        out += f"[{p}]" if isinstance(p, int) else (f".{p}" if out else p)
    return out


@dataclass
class _Field:
    """One address: where its value sits in a message, and what has been read."""

    address: str
    parts: list[str | int]
    t_ns: list[int] = field(default_factory=list)
    value: list[float] = field(default_factory=list)


def _fast_get(msg: Any, parts: Sequence[str | int]) -> float:
    """:func:`_get` without its checks, for messages of a type :func:`_get` has accepted once.

    Raises on anything unusual (a shorter array, a value that is no number, a Time); the
    caller then takes :func:`_get`, which gives the value or a named error.
    """
    obj = msg
    for p in parts:
        obj = obj[p] if isinstance(p, int) else getattr(obj, p)
    if isinstance(obj, float | int | np.floating | np.integer):
        return float(obj)
    raise TypeError(type(obj).__name__)


class _AddressError(Exception):
    """A field path that does not fit a message; turned into a LogFormatError with context."""


def _get(msg: Any, parts: Sequence[str | int]) -> float:
    obj = msg
    for k, p in enumerate(parts):
        if isinstance(p, int):
            if isinstance(obj, (str, bytes)) or not hasattr(obj, "__len__"):
                raise _AddressError(f"{_path_text(parts[:k]) or 'the message'} is not an array; drop [{p}]")
            if p >= len(obj):
                here = _path_text(parts[: k + 1])
                raise _AddressError(f"{here} is out of range: {_path_text(parts[:k])} has "
                                    f"{len(obj)} elements")
            obj = obj[p]
        else:
            names = _fields(obj)
            if p not in names:
                of = f"{_path_text(parts[:k]) or 'the message'} ({_msgtype(obj) or type(obj).__name__})"
                if not names:
                    raise _AddressError(f"{of} has no fields; {p!r} cannot be read from it")
                near = difflib.get_close_matches(p, names, n=3, cutoff=0.5)
                raise _AddressError(f"{of} has no field {p!r}"
                                    + (f"; close matches: {', '.join(near)}" if near else "")
                                    + f"; its fields: {', '.join(names)}")
            obj = getattr(obj, p)
    if _msgtype(obj) in _TIME_TYPES:
        return float(obj.sec) + float(obj.nanosec) * 1e-9
    if isinstance(obj, (bool, int, float, np.bool_, np.integer, np.floating)):
        return float(obj)
    here = _path_text(parts)
    if dataclasses.is_dataclass(obj):
        raise _AddressError(f"{here} is a message ({_msgtype(obj)}), not a number; address one of its "
                            f"fields: {', '.join(here + '.' + n for n in _fields(obj))}")
    if isinstance(obj, (str, bytes)):
        raise _AddressError(f"{here} is text, not a number")
    if hasattr(obj, "__len__"):
        raise _AddressError(f"{here} is an array of {len(obj)} elements; address one, e.g. {here}[0]")
    raise _AddressError(f"{here} is a {type(obj).__name__}, not a number")


def _stamp(msg: Any) -> int | None:
    """``header.stamp`` in ns, or None if the message has no std_msgs/Header."""
    header = getattr(msg, "header", None)
    stamp = getattr(header, "stamp", None)
    if stamp is None or _msgtype(stamp) != "builtin_interfaces/msg/Time":
        return None
    return int(stamp.sec) * 1_000_000_000 + int(stamp.nanosec)


def read_streams(path: Path, addresses: Sequence[str], *, time: TimeMode = "header") -> dict[str, Stream]:
    """Read ``addresses`` (``/topic:field.path``) from the ROS 2 bag at ``path``.

    Returns ``{address: Stream(t [s, bag clock], value [the field's unit], unit)}``, each
    sorted by time (``unit`` from :data:`FIELD_UNITS`, else None); ``time`` chooses header
    stamps or receive times (module docstring).
    """
    path = Path(path)
    if time not in TIME_MODES:
        raise LogFormatError(f"time={time!r} is not a ROS 2 time choice; use 'header' (header.stamp where "
                             "the message has one, else receive time) or 'receive'")
    parsed = {a: parse_address(a) for a in dict.fromkeys(addresses)}
    if not path.exists():
        raise LogFormatError(f"ROS 2 bag {path} does not exist; pass the bag folder or its .db3/.mcap file")
    rosbags = rosbags_modules()
    typestore = rosbags.typesys.get_typestore(rosbags.typesys.Stores.LATEST)
    try:
        reader = rosbags.highlevel.AnyReader([path], default_typestore=typestore)
        reader.open()
    except Exception as err:  # rosbags raises ReaderError, FileNotFoundError, sqlite3/mcap errors…
        raise LogFormatError(f"{path} is not a readable ROS 2 bag: {err}") from err
    try:
        topics = reader.topics
        by_topic: dict[str, list[_Field]] = {}
        for address, (topic, parts) in parsed.items():
            if topic not in topics:
                near = difflib.get_close_matches(topic, list(topics), n=3, cutoff=0.5)
                raise LogFormatError(f"{path}: no topic {topic!r} (address {address!r})"
                                     + (f"; close matches: {', '.join(near)}" if near else "")
                                     + f"; topics in the bag: {', '.join(sorted(topics)) or 'none'}")
            by_topic.setdefault(topic, []).append(_Field(address, parts))
        connections = [c for c in reader.connections if c.topic in by_topic]
        use_header = time == "header"
        zero_stamps: dict[str, int] = {}
        checked: set[int] = set()
        for conn, receive_ns, raw in reader.messages(connections=connections):
            try:
                msg = reader.deserialize(raw, conn.msgtype)
            except Exception as err:
                raise LogFormatError(f"{path}: a message on {conn.topic} ({conn.msgtype}) cannot be decoded "
                                     f"with its definition: {err}") from err
            stamp = _stamp(msg) if use_header else None
            if stamp == 0:
                zero_stamps[conn.topic] = zero_stamps.get(conn.topic, 0) + 1
            t_ns = receive_ns if stamp is None else stamp
            fields = by_topic[conn.topic]
            seen = id(conn) in checked
            for f in fields:
                try:
                    try:  # the checked walk on a connection's first message, the fast one after
                        value = _fast_get(msg, f.parts) if seen else _get(msg, f.parts)
                    except (AttributeError, IndexError, KeyError, TypeError):
                        value = _get(msg, f.parts)
                    f.value.append(value)
                except _AddressError as err:
                    sec, nsec = divmod(t_ns, 10**9)
                    which = ("" if not seen else
                             f" (message {len(f.value)} on that topic, t = {sec}.{nsec:09d} s)")
                    raise LogFormatError(f"{path}: address {f.address!r}: {err}{which}") from None
                f.t_ns.append(t_ns)
            checked.add(id(conn))
        if zero_stamps:
            topic, n = next(iter(zero_stamps.items()))
            raise LogFormatError(f"{path}: {n} messages on {topic} have header.stamp = 0 (the publisher did "
                                 "not set it); read the bag with time='receive'")
    except LogFormatError:
        raise
    except Exception as err:  # storage errors while iterating (truncated file, bad sqlite)
        raise LogFormatError(f"{path}: could not read the bag's messages: {err}") from err
    finally:
        reader.close()
    out: dict[str, Stream] = {}
    for topic, fields_ in by_topic.items():
        msgtype = next((c.msgtype for c in connections if c.topic == topic), "")
        for f in fields_:
            ns = np.asarray(f.t_ns, dtype=np.int64)
            t = (ns // 10**9).astype(np.float64) + (ns % 10**9) * 1e-9  # one rounding, ≤ 1.2e-7 s
            v = np.asarray(f.value, dtype=np.float64)
            order = np.argsort(t, kind="stable")
            out[f.address] = Stream(t[order], v[order], field_unit(msgtype, f.parts))
    return {a: out[a] for a in addresses}
