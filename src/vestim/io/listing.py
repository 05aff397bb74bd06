"""What a recording holds (``vestim channels``): every signal with its unit, rate and time span,
and a starter channel map of the spec channels recognised by name and unit.

The signals are found per source kind (:func:`vestim.io.readers.source_kind`) and then read
with the same readers an import uses (:func:`vestim.io.readers.read_source`), so every
address listed is one a channel map can name:

- CSV/Parquet: every numeric column but the time column (``--time``, else ``t``, ``time``
  or ``timestamp``); no units (the file has none);
- numpy folder: every ``<name>/t`` + ``<name>/value`` pair, ``name[i]`` per column;
- MDF4: every plain channel (``GROUP/name`` where a name is in several groups) with its
  MDF unit, and, with the DBC(s), every ``Message.Signal`` whose frames the file holds,
  with the DBC unit; without a DBC, the raw CAN IDs seen (pass ``--dbc`` to decode them);
- ROS 2 bag: every numeric field of every topic (``/topic:field.path``; ``header`` and
  ``*_covariance`` left out), with the REP-103 unit of standard messages
  (:data:`vestim.io.readers.ros2.FIELD_UNITS`).

The rate is 1 / the median sample interval (Hz), the span the first and last sample time (s,
the source's clock).
"""

from __future__ import annotations

import dataclasses
import math
import re
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from vestim.errors import LogFormatError
from vestim.io import channels as ch
from vestim.io.readers import Stream, read_source, source_kind

__all__ = ["Listing", "SignalInfo", "list_signals", "starter_map"]

TIME_COLUMNS = ("t", "time", "timestamp", "time_s")
"""Time columns of a table tried in order when none is named."""
MAX_ARRAY_FIELDS = 16
"""A ROS 2 array field with more elements than this is not listed element by element."""


@dataclass(frozen=True)
class SignalInfo:
    """One signal of a recording: its address, unit (None: the source gives none), number of
    samples, rate (Hz, NaN below two samples) and first/last sample time (s, source clock)."""

    address: str
    unit: str | None
    samples: int
    rate_hz: float
    t_start: float
    t_end: float


def _info(address: str, s: Stream) -> SignalInfo:
    dt = np.diff(s.t)
    rate = 1.0 / float(np.median(dt)) if dt.size and float(np.median(dt)) > 0 else math.nan
    t0, t1 = (float(s.t[0]), float(s.t[-1])) if len(s.t) else (math.nan, math.nan)
    return SignalInfo(address, s.unit, len(s.t), rate, t0, t1)


@dataclass(frozen=True)
class Listing:
    """What :func:`list_signals` found: the signals in the source's order, lines worth telling
    the user (raw CAN IDs without a DBC, a table without a time column), the source kind
    and, for a table, the time column used (None: none found)."""

    signals: list[SignalInfo]
    notes: list[str]
    kind: str
    time: str | None = None


def list_signals(path: Path, *, dbc: Sequence[Path] = (), kind: str | None = None,
                 time: str | None = None) -> Listing:
    """Every signal of the recording at ``path`` (see the module docstring).

    Args:
        path: CSV/Parquet file, numpy folder, MDF4 file or ROS 2 bag; only read.
        dbc: MDF4 only: DBC files to decode raw CAN frames with.
        kind: force a reader (as ``[source] kind``); default by file kind.
        time: tabular only: the time column (default: the first of :data:`TIME_COLUMNS`).

    Returns:
        The :class:`Listing`.

    Raises:
        LogFormatError: an unreadable source, or a reader's error.
    """
    path = Path(path)
    kind = kind or source_kind(path)
    notes: list[str] = []
    if kind == "tabular":
        addresses, time = _tabular_columns(path, time, notes)
        if time is None:
            return Listing([SignalInfo(a, None, 0, math.nan, math.nan, math.nan) for a in addresses],
                           notes, kind)
        streams = read_source(path, addresses, kind=kind, time=time)
    elif kind == "numpy":
        streams = read_source(path, _numpy_addresses(path), kind=kind)
    elif kind == "mdf":
        addresses = _mdf_addresses(path, dbc, notes)
        streams = read_source(path, addresses, kind=kind, dbc=dbc) if addresses else {}
    elif kind == "ros2":
        streams = _ros2_streams(path)
    else:
        raise LogFormatError(f"kind {kind!r}: use one of tabular, numpy, mdf, ros2")
    return Listing([_info(a, s) for a, s in streams.items()], notes, kind,
                   time if kind == "tabular" else None)


def _tabular_columns(path: Path, time: str | None, notes: list[str]) -> tuple[list[str], str | None]:
    import pandas as pd
    import pyarrow.parquet as pq

    if path.suffix.lower() in (".parquet", ".pq"):
        schema = pq.read_schema(path)
        numeric = [f.name for f in schema if pa_numeric(f.type)]
    else:
        head = pd.read_csv(path, nrows=100)
        numeric = [c for c in head.columns if pd.api.types.is_numeric_dtype(head[c])]
    if time is None:
        time = next((c for c in TIME_COLUMNS if c in numeric), None)
        if time is None:
            notes.append(f"{path}: no time column ({', '.join(TIME_COLUMNS)}); pass --time NAME "
                         "for rates and spans")
    return [c for c in numeric if c != time], time


def pa_numeric(t: Any) -> bool:
    """True for an Arrow integer or floating type."""
    import pyarrow as pa

    return bool(pa.types.is_integer(t) or pa.types.is_floating(t))


def _numpy_addresses(path: Path) -> list[str]:
    out: list[str] = []
    for t_file in sorted(path.rglob("t")):
        v_file = t_file.parent / "value"
        if not (t_file.is_file() and v_file.is_file()):
            continue
        name = t_file.parent.relative_to(path).as_posix()
        shape = np.load(v_file, mmap_mode="r", allow_pickle=False).shape
        cols = shape[1] if len(shape) == 2 and shape[1] > 1 else 0
        out.extend([f"{name}[{i}]" for i in range(cols)] if cols else [name])
    return out


def _mdf_addresses(path: Path, dbc: Sequence[Path], notes: list[str]) -> list[str]:
    from vestim.io.readers import mdf as mdf_reader

    asammdf = mdf_reader.asammdf_module()
    dbcs = mdf_reader.load_dbc(dbc)
    try:
        mdf = asammdf.MDF(str(path), process_bus_logging=False)
    except Exception as err:  # asammdf raises bare Exceptions on a bad file
        raise LogFormatError(f"{path} is not a readable MDF file: {err}") from err
    try:
        out: list[str] = []
        for name, entries in mdf.channels_db.items():
            if any(k in name for k in ("CAN_DataFrame", "CAN_ErrorFrame", "CAN_RemoteFrame")):
                continue  # the raw frames' fields: decoded with the DBC below
            # Numbers only (MDF4 data types 0-5: integers and floats), no master channels.
            plain = [(int(g), int(c)) for g, c in entries
                     if mdf.groups[int(g)].channels[int(c)].channel_type not in (2, 3)
                     and int(getattr(mdf.groups[int(g)].channels[int(c)], "data_type", 0)) <= 5]
            if len(plain) == 1:
                out.append(name)
            elif plain:
                out.extend(f"{g}/{name}" for g, _ in plain)
        keys = np.unique(mdf_reader._can_frames(mdf, path).key)
    finally:
        mdf.close()
    seen = {int(k) for k in keys}
    known: set[int] = set()
    for _, db in dbcs:
        for m in db.messages:
            key = mdf_reader._id_key(m.frame_id, m.is_extended_frame)
            if key in seen:
                known.add(key)
                out.extend(f"{m.name}.{s.name}" for s in m.signals)
    if unknown := sorted(seen - known):
        ids = ", ".join(f"0x{k & 0x1FFFFFFF:X}" for k in unknown[:20])
        notes.append(f"{len(unknown)} CAN ID(s) in the file "
                     + ("no DBC defines" if dbcs else "(pass the bus's DBC with --dbc to decode them)")
                     + f": {ids}")
    return list(dict.fromkeys(out))


def _leaves(obj: Any, prefix: str) -> list[str]:
    """Field paths of the numeric leaves of a deserialised ROS 2 message."""
    out: list[str] = []
    if dataclasses.is_dataclass(obj):
        for f in dataclasses.fields(obj):
            if f.name in ("header", "__msgtype__") or f.name.endswith("covariance"):
                continue
            out += _leaves(getattr(obj, f.name), f"{prefix}.{f.name}" if prefix else f.name)
    elif isinstance(obj, bool | int | float | np.integer | np.floating):
        out.append(prefix)
    elif isinstance(obj, np.ndarray | list | tuple) and 0 < len(obj) <= MAX_ARRAY_FIELDS:
        for i, item in enumerate(obj):
            out += _leaves(item, f"{prefix}[{i}]")
    return out


def _ros2_streams(path: Path) -> dict[str, Stream]:
    from vestim.io.readers.ros2 import rosbags_modules

    rosbags = rosbags_modules()
    typestore = rosbags.typesys.get_typestore(rosbags.typesys.Stores.LATEST)
    try:
        reader = rosbags.highlevel.AnyReader([path], default_typestore=typestore)
        reader.open()
    except Exception as err:  # rosbags raises ReaderError, sqlite3/mcap errors…
        raise LogFormatError(f"{path} is not a readable ROS 2 bag: {err}") from err
    addresses: list[str] = []
    try:
        for topic in sorted(reader.topics):
            conns = [c for c in reader.connections if c.topic == topic]
            first = next(iter(reader.messages(connections=conns)), None)
            if first is None:
                continue
            msg = reader.deserialize(first[2], first[0].msgtype)
            addresses += [f"{topic}:{leaf}" for leaf in _leaves(msg, "")]
    finally:
        reader.close()
    return read_source(path, addresses, kind="ros2") if addresses else {}


# --- starter map ---------------------------------------------------------------------------------

_CORNER_WORDS = {"fl": "(fl|frontleft|vl)", "fr": "(fr|frontright|vr)",
                 "rl": "(rl|rearleft|hl)", "rr": "(rr|rearright|hr)"}
_PATTERNS: dict[str, str] = {
    **{f"omega_{c}": rf"(wheelspeed|wheelrate|omega|whlspd).*{w}$" for c, w in _CORNER_WORDS.items()},
    **{f"torque_{c}": rf"(torque|trq).*{w}$" for c, w in _CORNER_WORDS.items()},
    **{f"delta_{c}": rf"(roadwheelangle|wheelangle|delta).*{w}$" for c, w in _CORNER_WORDS.items()
       if c in ("fl", "fr")},
    "steering_wheel_angle": r"(steeringwheelangle|steerwhlangle|steeringangle|swa$)",
    "ax": r"(longacc|lonacc|accelx$|accx$|linearaccelerationx$|^ax$)",
    "ay": r"(latacc|accely$|accy$|linearaccelerationy$|^ay$)",
    "az": r"(vertacc|accelz$|accz$|linearaccelerationz$|^az$)",
    "yaw_rate": r"(yawrate|angularvelocityz$|gyroz$)",
    "roll_rate": r"(rollrate|angularvelocityx$|gyrox$)",
    "pitch_rate": r"(pitchrate|angularvelocityy$|gyroy$)",
    "gnss_speed": r"(speedoverground|gnssspeed|gpsspeed)",
}
"""Spec channel → regular expression on a signal's address, lower-cased with everything but
letters and digits removed (``IMU_RATES.YawRate`` → ``imuratesyawrate``)."""


def _recognise(info: SignalInfo) -> tuple[str, str | None] | None:
    """(spec channel, comment) the signal looks like, or None; its unit must fit the channel."""
    from vestim.io.channel_map import ChannelMapError, ambiguous_rate, unit_factor

    flat = re.sub(r"[^a-z0-9]", "", info.address.lower())
    bare = info.address.rsplit(".", 1)[-1].rsplit(":", 1)[-1]
    for name, pattern in _PATTERNS.items():
        if not (bare == name or re.search(pattern, flat)):
            continue
        if info.unit is None:
            return name, f"the source gives no unit: check {ch.unit_of(name)}"
        try:
            if ambiguous_rate(info.unit, name):
                return name, f"the source says {info.unit!r}: revolutions (rpm) or radians?"
            unit_factor(info.unit, name)
        except ChannelMapError:
            continue  # a name that fits but a unit of another quantity
        return name, None
    return None


def _toml_string(text: str) -> str:
    return '"' + text.replace("\\", "\\\\").replace('"', '\\"') + '"'


def starter_map(signals: Sequence[SignalInfo], *, dbc: Sequence[Path] = (),
                time: str | None = None, kind: str | None = None) -> str:
    """A channel map (TOML, ``docs/channel-map.md``) of the spec channels recognised among
    ``signals``: by address (:data:`_PATTERNS`) and unit (one that converts to the spec's).

    An entry whose source carries its unit has no ``unit`` (the source's is taken); one
    whose source gives none, or an ambiguous one (``1/min``), has the spec's SI unit or
    ``rpm`` and a comment to check it. ``[output] rate`` is the highest rate among them.
    The IMU frame, mounting and signs are not guessed: check them (``[imu] frame``).
    """
    chosen: dict[str, tuple[SignalInfo, str | None]] = {}
    for info in signals:
        found = _recognise(info)
        if found is not None and found[0] not in chosen:
            chosen[found[0]] = (info, found[1])
    rates = [i.rate_hz for i, _ in chosen.values() if math.isfinite(i.rate_hz)]
    rate = round(max(rates), 3) if rates else 100.0
    lines = ["# Starter channel map written by `vestim channels --starter-map` (docs/channel-map.md).",
             "# Check every entry: the channels were recognised by name and unit only; signs, the",
             "# IMU's axes ([imu] frame) and its mounting are not guessed.", "format = 1", ""]
    source: list[str] = []
    if kind is not None:
        source.append(f"kind = {_toml_string(kind)}")
    if dbc:
        source.append("dbc = [" + ", ".join(_toml_string(str(p)) for p in dbc) + "]")
    if time is not None:
        source.append(f"time = {_toml_string(time)}")
    if source:
        lines += ["[source]", *source, ""]
    lines += ["[output]", f"rate = {rate!r}          # Hz: the fastest recognised signal's rate", ""]
    for name in ch.canonical_order(chosen):
        info, comment = chosen[name]
        lines += [f"[channels.{name}]", f"source = {_toml_string(info.address)}"]
        if comment is not None:
            unit = "rpm" if "revolutions" in comment else str(ch.unit_of(name))
            lines.append(f"unit = {_toml_string(unit)}    # {comment}")
        lines.append("")
    if not chosen:
        lines.append("# No spec channel was recognised; add [channels.<name>] tables by hand.")
    return "\n".join(lines).rstrip() + "\n"
