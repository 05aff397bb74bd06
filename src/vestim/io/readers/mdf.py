"""MDF4 reader: plain channels and CAN signals decoded from raw bus-logging frames.

An address is one of

- an MDF channel name, e.g. ``VehSpd``; where several channel groups hold a channel of
  that name, ``GROUP/name`` picks one, GROUP being the 0-based channel-group index, the
  group's acquisition name or the channel's source name (``2/VehSpd``, ``ESP/VehSpd``);
- ``Message.Signal``, decoded with the DBC file(s) given as ``dbc`` from the raw CAN frames
  of the file's ASAM bus-logging channel groups (``CAN_DataFrame`` with ``.ID``,
  ``.DataBytes``, ``.BusChannel``, …), e.g. ``WHEEL_SPEEDS.WheelSpeed_FL``;
  ``CAN2.Message.Signal`` takes the frames of bus channel 2 only, which is needed where
  the message's ID is seen on more than one bus.

A plain channel's values are its physical values (the MDF conversion applied); samples
its invalidation bits flag are dropped, not filled. A CAN signal's values are
``raw * factor + offset`` of the DBC, at the frames' timestamps, decoded with NumPy for all
frames of one message at once (Intel and Motorola byte order, signed, IEEE float and
multiplexed signals). Times are the file's master time in s; nothing is resampled and
no unit is converted (:mod:`vestim.io.readers`).

Needs the ``logs`` extra (``pip install 'vestim[logs]'``: asammdf for the file, cantools
for the DBC). Every problem raises :class:`~vestim.errors.LogFormatError` naming the
file, the address and the fix.
"""

from __future__ import annotations

import difflib
import re
from collections.abc import Iterable, Sequence
from dataclasses import dataclass
from pathlib import Path
from types import ModuleType
from typing import Any

import numpy as np

from vestim.errors import LogFormatError
from vestim.io.readers import Stream

__all__ = ["decode_signal", "read_streams"]

_INSTALL_HINT = "install the log readers with: pip install 'vestim[logs]'"
_FD_LENGTHS = np.array([0, 1, 2, 3, 4, 5, 6, 7, 8, 12, 16, 20, 24, 32, 48, 64], dtype=np.int64)
"""Payload bytes of each CAN (FD) DLC code 0…15."""
_BUS_PREFIX = re.compile(r"^CAN(\d+)\.(.+)$")


def _optional(name: str, what: str) -> ModuleType:
    """Import an optional dependency of the ``logs`` extra, or say how to install it."""
    try:
        return __import__(name)
    except ImportError as err:
        raise LogFormatError(f"{what} needs the Python package {name!r}, which is not installed; "
                             f"{_INSTALL_HINT}") from err


def asammdf_module() -> ModuleType:
    """The ``asammdf`` package, or a LogFormatError saying how to install it."""
    return _optional("asammdf", "reading or writing MDF4 files")


def cantools_module() -> ModuleType:
    """The ``cantools`` package, or a LogFormatError saying how to install it."""
    _optional("cantools", "decoding CAN frames with a DBC file")
    import cantools.database

    return cantools


# --- DBC ------------------------------------------------------------------------------------


def load_dbc(paths: Sequence[Path]) -> list[tuple[Path, Any]]:
    """Load DBC files with cantools: ``[(path, cantools Database), ...]``."""
    cantools = cantools_module()
    out: list[tuple[Path, Any]] = []
    for p in paths:
        path = Path(p)
        if not path.is_file():
            raise LogFormatError(f"DBC file {path} does not exist; pass the path of the bus's DBC file")
        try:
            db = cantools.database.load_file(str(path), database_format="dbc", strict=True)
        except Exception as err:  # cantools raises its own parse errors, OSError, UnicodeError…
            raise LogFormatError(f"DBC file {path} is not a readable DBC: {err}") from err
        out.append((path, db))
    return out


def _bit_shifts(signal: Any) -> list[tuple[int, int]]:
    """``[(byte index, shift), ...]``: byte j contributes ``byte << shift`` (>> if negative)."""
    start, length = int(signal.start), int(signal.length)
    if signal.byte_order == "little_endian":
        first, last = start // 8, (start + length - 1) // 8
        return [(j, 8 * j - start) for j in range(first, last + 1)]
    # Motorola: ``start`` is the DBC start bit, the MSB; bits run down through bit 0 of a
    # byte and on from bit 7 of the next byte.
    first = start // 8
    last = first + max(0, (length - (start % 8) - 1 + 7) // 8)
    return [(j, 8 * (first - j) - (start % 8) + length - 1) for j in range(first, last + 1)]


def _raw_bits(payload: np.ndarray | _Words, signal: Any) -> np.ndarray:
    """The signal's raw bit field of every frame, uint64.

    ``payload`` is the frames' bytes (n, bytes) uint8, or their :class:`_Words` (frames of
    up to 8 bytes read as one 64-bit word each way, one shift per signal).
    """
    length = int(signal.length)
    mask = np.uint64((1 << length) - 1)
    if isinstance(payload, _Words):
        start = int(signal.start)
        if signal.byte_order == "little_endian":
            out = payload.little >> np.uint64(start)
        else:
            out = payload.big >> np.uint64((7 - start // 8) * 8 + start % 8 - length + 1)
        out &= mask
        return out
    acc = np.zeros(payload.shape[0], dtype=np.uint64)
    for j, shift in _bit_shifts(signal):
        byte = payload[:, j].astype(np.uint64)
        acc |= (byte << np.uint64(shift)) if shift >= 0 else (byte >> np.uint64(-shift))
    return acc & mask


class _Words:
    """Frames of at most 8 bytes as 64-bit words, bytes little-endian (byte 0 least
    significant) and, computed when a Motorola signal asks, big-endian."""

    def __init__(self, little: np.ndarray) -> None:
        self.little = little  # uint64
        self._big: np.ndarray | None = None

    @property
    def big(self) -> np.ndarray:
        """uint64 words with byte 0 most significant."""
        if self._big is None:
            self._big = self.little.byteswap()
        return self._big

    @classmethod
    def of(cls, payload: np.ndarray) -> _Words | None:
        """The words of ``payload`` (n, bytes) uint8, None where a frame has over 8 bytes."""
        if payload.shape[1] > 8:
            return None
        padded = np.zeros((payload.shape[0], 8), dtype=np.uint8)
        padded[:, : payload.shape[1]] = payload
        return cls(padded.view("<u8").reshape(-1).astype(np.uint64, copy=False))


def decode_signal(payload: np.ndarray | _Words, signal: Any) -> np.ndarray:
    """Physical values of a cantools ``signal`` in frames ``payload`` (n, bytes) uint8.

    ``raw * scale + offset`` in the DBC's unit, float64; raw is the bit field read in the
    signal's byte order, two's complement where signed, IEEE 754 where the DBC says float.
    Choices (value tables) are not applied: the numeric value is returned.
    """
    raw = _raw_bits(payload, signal)
    length = int(signal.length)
    conversion = signal.conversion
    if conversion.is_float:
        if length == 32:
            value = raw.astype(np.uint32).view(np.float32).astype(np.float64)
        elif length == 64:
            value = raw.view(np.float64).copy()
        else:
            raise LogFormatError(f"DBC signal {signal.name!r} is a float of {length} bits; "
                                 "only 32- and 64-bit floats exist")
    elif signal.is_signed:
        raw <<= np.uint64(64 - length)  # sign-extend: move the sign bit to bit 63, shift back
        signed = raw.view(np.int64)
        signed >>= np.int64(64 - length)
        value = signed.astype(np.float64)
    else:
        value = raw.astype(np.float64)
    scale, offset = float(conversion.scale), float(conversion.offset)
    if scale != 1.0:
        value *= scale
    if offset != 0.0:
        value += offset
    return value


def _mux_mask(payload: np.ndarray | _Words, message: Any, signal: Any) -> np.ndarray | None:
    """Frames in which a multiplexed ``signal`` is present, or None if it is not multiplexed."""
    if signal.multiplexer_ids is None or signal.multiplexer_signal is None:
        return None
    mux = message.get_signal_by_name(signal.multiplexer_signal)
    raw = _raw_bits(payload, mux)
    mask = np.isin(raw, np.asarray(signal.multiplexer_ids, dtype=np.uint64))
    outer = _mux_mask(payload, message, mux)
    return mask if outer is None else mask & outer


# --- CAN frames in the file -----------------------------------------------------------------


@dataclass
class _Frames:
    """Every CAN data frame of the file's bus-logging groups, in file order."""

    t: np.ndarray  # float64 s
    bus: np.ndarray  # integer bus channel
    key: np.ndarray  # int64: 29/11-bit ID, | 1 << 32 for extended IDs
    length: np.ndarray  # integer payload bytes
    data: np.ndarray  # uint8 (n, max bytes)

    def words(self) -> _Words | None:
        """All frames as 64-bit words (no copy for 8-byte payloads), None beyond 8 bytes."""
        if self.data.shape[1] == 8 and self.data.flags.c_contiguous:
            return _Words(self.data.view("<u8").reshape(-1).astype(np.uint64, copy=False))
        return _Words.of(self.data)

    def in_time_order(self) -> bool:
        return bool(np.all(self.t[1:] >= self.t[:-1]))


def _id_key(frame_id: int, extended: bool) -> int:
    return int(frame_id) | (1 << 32 if extended else 0)


def _can_groups(mdf: Any) -> list[int]:
    """Indices of the channel groups that hold raw CAN data frames."""
    return [i for i, group in enumerate(mdf.groups)
            if any(c.name == "CAN_DataFrame" for c in group.channels)]


def _can_frames(mdf: Any, path: Path) -> _Frames:
    parts: list[_Frames] = []
    for gi in _can_groups(mdf):
        names = {c.name for c in mdf.groups[gi].channels}
        needed = ("CAN_DataFrame.ID", "CAN_DataFrame.DataBytes")
        if missing := [n for n in needed if n not in names]:
            raise LogFormatError(f"{path}: CAN bus-logging group {gi} has no channel {missing[0]!r}; "
                                 "the file does not follow the ASAM MDF bus-logging layout")
        id_sig = mdf.get("CAN_DataFrame.ID", group=gi)
        ids = np.asarray(id_sig.samples).astype(np.int64)
        t = np.asarray(id_sig.timestamps, dtype=np.float64)

        def samples(name: str, gi: int = gi) -> np.ndarray:
            """One field's samples (the time is the ID's; samples_only skips reading it again)."""
            return np.asarray(mdf.get(name, group=gi, samples_only=True)[0])

        data = samples("CAN_DataFrame.DataBytes")
        if data.ndim == 1:  # variable-length payloads come as an object array of byte strings
            width = max((len(bytes(d)) for d in data), default=0)
            fixed = np.zeros((data.shape[0], width), dtype=np.uint8)
            for i, d in enumerate(data):
                b = np.frombuffer(bytes(d), dtype=np.uint8)
                fixed[i, : b.size] = b
            data = fixed
        data = np.ascontiguousarray(data, dtype=np.uint8)
        has_ide = "CAN_DataFrame.IDE" in names  # else bit 31 of the ID flags an extended ID
        ide = samples("CAN_DataFrame.IDE").astype(np.int64) if has_ide else (ids >> 31) & 1
        key = (ids & 0x1FFFFFFF) | (ide << 32)
        if "CAN_DataFrame.BusChannel" in names:
            bus = samples("CAN_DataFrame.BusChannel")
        else:
            bus = np.ones(t.size, dtype=np.uint8)
        if "CAN_DataFrame.DataLength" in names:
            length = samples("CAN_DataFrame.DataLength")
        elif "CAN_DataFrame.DLC" in names:
            dlc = samples("CAN_DataFrame.DLC").astype(np.int64)
            length = _FD_LENGTHS[np.clip(dlc, 0, 15)]
        else:
            length = np.full(t.size, data.shape[1], dtype=np.int64)
        parts.append(_Frames(t, bus, key, np.minimum(length, data.shape[1]), data))
    if not parts:
        return _Frames(np.zeros(0), np.zeros(0, np.int64), np.zeros(0, np.int64),
                       np.zeros(0, np.int64), np.zeros((0, 8), np.uint8))
    if len(parts) == 1:
        return parts[0]
    width = max(p.data.shape[1] for p in parts)
    data = np.concatenate([np.pad(p.data, ((0, 0), (0, width - p.data.shape[1]))) for p in parts])
    t, bus, key, length = (np.concatenate([getattr(p, f) for p in parts])
                           for f in ("t", "bus", "key", "length"))
    return _Frames(t, bus, key, length, data)


# --- addresses ------------------------------------------------------------------------------


@dataclass(frozen=True)
class _CanAddress:
    address: str
    bus: int | None
    message: Any
    signal: Any
    dbc: Path


def _dbc_names(dbcs: Iterable[tuple[Path, Any]]) -> list[str]:
    return [f"{m.name}.{s.name}" for _, db in dbcs for m in db.messages for s in m.signals]


def _plain_channel_names(mdf: Any) -> list[str]:
    return sorted(name for name in mdf.channels_db if name not in ("t", "time"))


def _close(word: str, candidates: Iterable[str]) -> str:
    near = difflib.get_close_matches(word, list(candidates), n=5, cutoff=0.5)
    return f"; close matches: {', '.join(near)}" if near else ""


def _resolve_can(address: str, dbcs: list[tuple[Path, Any]], path: Path) -> _CanAddress | None:
    """The DBC message and signal of ``address``, None if it names no DBC message."""
    bus: int | None = None
    rest = address
    if (m := _BUS_PREFIX.match(address)) and "." in m.group(2):
        bus, rest = int(m.group(1)), m.group(2)
    message_name, _, signal_name = rest.partition(".")
    if not signal_name:
        return None
    found = [(p, db.get_message_by_name(message_name)) for p, db in dbcs
             if message_name in {msg.name for msg in db.messages}]
    if not found:
        return None
    if len(found) > 1:
        raise LogFormatError(f"{path}: CAN message {message_name!r} of address {address!r} is defined in "
                             f"more than one DBC file ({', '.join(str(p) for p, _ in found)}); pass only "
                             "the DBC of the bus that carries it")
    dbc_path, message = found[0]
    names = [s.name for s in message.signals]
    if signal_name not in names:
        raise LogFormatError(f"{path}: CAN message {message_name!r} in {dbc_path} has no signal "
                             f"{signal_name!r} (address {address!r}){_close(signal_name, names)}; "
                             f"its signals: {', '.join(names)}")
    return _CanAddress(address, bus, message, message.get_signal_by_name(signal_name), dbc_path)


def _group_label(mdf: Any, gi: int, ci: int) -> list[str]:
    """The names ``GROUP/`` may use for channel ``ci`` of group ``gi``."""
    group = mdf.groups[gi]
    labels = [str(gi)]
    acq = getattr(group.channel_group, "acq_name", None)
    if acq:
        labels.append(str(acq))
    source = getattr(group.channels[ci], "source", None)
    if source is not None and getattr(source, "name", None):
        labels.append(str(source.name))
    return labels


def _resolve_plain(address: str, mdf: Any, path: Path) -> tuple[int, int] | None:
    """(group, channel index) of a plain channel address, None if the file has no such name."""
    db = mdf.channels_db
    name, qualifier = address, None
    if address not in db and "/" in address:
        qualifier, name = address.split("/", 1)
    entries = [(int(g), int(c)) for g, c in db.get(name, ())
               if mdf.groups[int(g)].channels[int(c)].channel_type not in (2, 3)]  # not a master
    if not entries:
        return None
    if qualifier is not None:
        entries = [e for e in entries if qualifier in _group_label(mdf, *e)]
        if not entries:
            options = ", ".join(f"{_group_label(mdf, g, c)[-1]}/{name}" for g, c in db[name])
            raise LogFormatError(f"{path}: no channel group {qualifier!r} holds channel {name!r} "
                                 f"(address {address!r}); it is in: {options}")
    if len(entries) > 1:
        options = ", ".join(f"{'/'.join(_group_label(mdf, g, c)[:1])}/{name}"
                            + (f" ({_group_label(mdf, g, c)[1]})" if len(_group_label(mdf, g, c)) > 1 else "")
                            for g, c in entries)
        raise LogFormatError(f"{path}: channel {name!r} is in {len(entries)} channel groups; "
                             f"address one as GROUP/{name}: {options}")
    return entries[0]


# --- reading --------------------------------------------------------------------------------


def _read_plain(mdf: Any, gi: int, ci: int, address: str, path: Path) -> Stream:
    sig = mdf.get(group=gi, index=ci)
    samples = np.asarray(sig.samples)
    if samples.ndim != 1 or samples.dtype.kind not in "biuf":
        kind = "text" if samples.dtype.kind in "SUO" else f"{samples.dtype} with shape {samples.shape[1:]}"
        raise LogFormatError(f"{path}: channel {address!r} holds {kind} values, not one number per "
                             "sample; address a numeric channel")
    t = np.asarray(sig.timestamps, dtype=np.float64)
    value = samples.astype(np.float64)
    if sig.invalidation_bits is not None:
        valid = ~np.asarray(sig.invalidation_bits, dtype=bool)
        t, value = t[valid], value[valid]
    order = np.argsort(t, kind="stable")
    return Stream(t[order], value[order], str(sig.unit).strip() or None)


def _read_can(frames: _Frames, can: list[_CanAddress], path: Path) -> dict[str, Stream]:
    out: dict[str, Stream] = {}
    all_words = frames.words()
    ordered = frames.in_time_order()
    by_message: dict[tuple[int, int | None], list[_CanAddress]] = {}
    for a in can:
        by_message.setdefault((_id_key(a.message.frame_id, a.message.is_extended_frame), a.bus), []).append(a)
    for (key, bus), addresses in by_message.items():
        message = addresses[0].message
        sel = frames.key == key
        if bus is not None:
            sel &= frames.bus == bus
        idx = np.flatnonzero(sel)
        where = f"bus {bus}" if bus is not None else "any bus"
        if idx.size == 0:
            seen = np.unique(frames.key[frames.bus == bus] if bus is not None else frames.key)
            ids = ", ".join(f"0x{k & 0x1FFFFFFF:X}" for k in seen[:20])
            raise LogFormatError(f"{path}: no CAN frame with ID 0x{message.frame_id:X} (message "
                                 f"{message.name!r}, address {addresses[0].address!r}) on {where}; "
                                 f"IDs in the file: {ids or 'none, it has no CAN_DataFrame group'}")
        bus_of = frames.bus[idx]
        buses = np.unique(bus_of) if bus_of.min() != bus_of.max() else bus_of[:1]
        if bus is None and buses.size > 1:
            raise LogFormatError(f"{path}: message {message.name!r} (ID 0x{message.frame_id:X}) is on "
                                 f"buses {', '.join(map(str, buses))}; address one bus as "
                                 f"CAN{buses[0]}.{addresses[0].address}")
        short = frames.length[idx] < message.length
        if short.any():
            raise LogFormatError(f"{path}: {int(short.sum())} of {idx.size} frames with ID "
                                 f"0x{message.frame_id:X} carry fewer than the {message.length} bytes "
                                 f"message {message.name!r} has in {addresses[0].dbc}; the DBC does not "
                                 "match this bus")
        t = frames.t[idx]
        if not ordered:
            order = np.argsort(t, kind="stable")
            idx, t = idx[order], t[order]
        payload: np.ndarray | _Words
        if all_words is not None:
            payload = _Words(all_words.little[idx])
        else:
            data = frames.data[idx, : max(message.length, 1)]
            words = _Words.of(data)
            payload = data if words is None else words
        for a in addresses:
            value = decode_signal(payload, a.signal)
            mask = _mux_mask(payload, message, a.signal)
            unit = str(a.signal.unit or "").strip() or None
            out[a.address] = (Stream(t, value, unit) if mask is None
                              else Stream(t[mask], value[mask], unit))
    return out


def read_streams(path: Path, addresses: Sequence[str], *, dbc: Sequence[Path] = ()) -> dict[str, Stream]:
    """Read ``addresses`` from the MDF file at ``path`` (see the module docstring).

    Returns ``{address: Stream(t [s, the file's master time], value [source unit], unit)}``,
    each sorted by time; ``unit`` is the channel's MDF unit or the DBC signal's unit (None
    where empty). A name that is both a channel of the file and a DBC ``Message.Signal``
    is read as the channel.
    """
    path = Path(path)
    if not path.is_file():
        raise LogFormatError(f"MDF file {path} does not exist")
    asammdf = asammdf_module()
    dbcs = load_dbc(dbc)
    try:
        mdf = asammdf.MDF(str(path), process_bus_logging=False)
    except Exception as err:  # asammdf raises bare Exceptions and MdfException on a bad file
        raise LogFormatError(f"{path} is not a readable MDF file: {err}") from err
    try:
        plain: dict[str, tuple[int, int]] = {}
        can: list[_CanAddress] = []
        for address in dict.fromkeys(addresses):
            where = _resolve_plain(address, mdf, path)
            if where is not None:
                plain[address] = where
                continue
            resolved = _resolve_can(address, dbcs, path) if dbcs else None
            if resolved is not None:
                can.append(resolved)
                continue
            known = _plain_channel_names(mdf) + _dbc_names(dbcs)
            hint = ("" if dbcs or not _can_groups(mdf) else
                    "; the file has raw CAN frames: pass the bus's DBC file to decode Message.Signal")
            raise LogFormatError(f"{path}: no channel {address!r} in the file"
                                 + (" nor message.signal in the DBC" if dbcs else "")
                                 + f"{_close(address, known)}{hint}")
        out = {a: _read_plain(mdf, gi, ci, a, path) for a, (gi, ci) in plain.items()}
        if can:
            out.update(_read_can(_can_frames(mdf, path), can, path))
    except LogFormatError:
        raise
    except Exception as err:  # a file that opens yet fails while its data are read
        raise LogFormatError(f"{path}: could not read the MDF data: {err}") from err
    finally:
        mdf.close()
    return {a: out[a] for a in addresses}
