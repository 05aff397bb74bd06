"""Folders of numpy arrays, as comma2k19's ``processed_log``.

A stream is a folder ``<dir>/<name>/`` holding two ``.npy`` arrays saved without an
extension: ``t`` (sample times, s) and ``value`` (shape ``(n,)`` or ``(n, k)``). Addresses:

- ``IMU/gyro`` — a one-column stream (``value`` of shape ``(n,)`` or ``(n, 1)``);
- ``IMU/accelerometer[0]`` — column 0 of a ``(n, k)`` stream;
- ``global_pose/frame_velocities[2]@global_pose/frame_times`` — a bare array file with its
  times in another file (``@`` then the time array's path).

Paths are relative to the folder and may not leave it. Arrays are loaded with
``allow_pickle=False``; values come back in the files' own units.
"""

from __future__ import annotations

import re
from collections.abc import Iterable
from pathlib import Path, PurePosixPath

import numpy as np

from vestim.errors import LogFormatError
from vestim.io.readers import Stream

__all__ = ["is_numpy_dir", "parse_address", "read_streams"]

_ADDRESS = re.compile(r"^(?P<path>[^\[\]@]+?)(?:\[(?P<col>\d+)\])?(?:@(?P<time>[^\[\]@]+))?$")


def parse_address(address: str) -> tuple[str, int | None, str | None]:
    """Split ``path[col]@time`` into its parts (``col`` and ``time`` may be ``None``).

    Raises:
        LogFormatError: malformed address, or a path that is absolute or contains ``..``.
    """
    m = _ADDRESS.match(address.strip())
    if m is None:
        raise LogFormatError(
            f"numpy-folder address {address!r} is malformed; write 'NAME', 'NAME[i]' or "
            "'ARRAY[i]@TIME_ARRAY' (paths relative to the folder)"
        )
    path, col, time = m.group("path"), m.group("col"), m.group("time")
    for p in (path, time):
        if p is not None and (PurePosixPath(p).is_absolute() or ".." in PurePosixPath(p).parts):
            raise LogFormatError(
                f"numpy-folder address {address!r} leaves the folder; use a path relative to it"
            )
    return path, (int(col) if col is not None else None), time


def is_numpy_dir(path: Path) -> bool:
    """True when ``path`` is a folder holding at least one ``<name>/t`` + ``<name>/value`` pair."""
    if not path.is_dir():
        return False
    return any(p.parent.joinpath("value").is_file() for p in path.rglob("t") if p.is_file())


def read_streams(path: Path, addresses: Iterable[str]) -> dict[str, Stream]:
    """Read ``addresses`` from the numpy folder ``path``.

    Returns:
        ``{address: Stream(t [s], value [file units])}``.

    Raises:
        LogFormatError: a missing array, a column index out of range or missing for a
            multi-column array, lengths of ``t`` and ``value`` that differ, or times that
            are not finite or decrease; each message names the address.
    """
    cache: dict[Path, np.ndarray] = {}
    out: dict[str, Stream] = {}
    for address in dict.fromkeys(addresses):
        name, col, time = parse_address(address)
        base = path / name
        if time is None:
            if not base.is_dir():
                hint = (" (a bare array: add '@TIME_ARRAY', the file holding its times)"
                        if base.is_file() else "")
                raise LogFormatError(
                    f"{path}: address {address!r}: no folder {name!r} with 't' and 'value'"
                    f"{hint}; fix the address in the channel map"
                )
            t_file, v_file = base / "t", base / "value"
        else:
            t_file, v_file = path / time, base
        t = np.asarray(_load(t_file, address, cache), dtype=np.float64).reshape(-1)
        v = np.asarray(_load(v_file, address, cache), dtype=np.float64)
        if v.ndim == 2 and col is None and v.shape[1] == 1:
            v = v[:, 0]
        elif v.ndim == 2:
            if col is None:
                raise LogFormatError(
                    f"{path}: address {address!r} has {v.shape[1]} columns; pick one, e.g. "
                    f"'{name}[0]'"
                )
            if col >= v.shape[1]:
                raise LogFormatError(
                    f"{path}: address {address!r}: column {col} out of range (the array has "
                    f"{v.shape[1]} columns, 0 … {v.shape[1] - 1})"
                )
            v = v[:, col]
        elif v.ndim == 1:
            if col not in (None, 0):
                raise LogFormatError(
                    f"{path}: address {address!r}: the array has one column; drop '[{col}]'"
                )
        else:
            raise LogFormatError(
                f"{path}: address {address!r}: value array has shape {v.shape}; expected "
                "(n,) or (n, k)"
            )
        if len(t) != len(v):
            raise LogFormatError(
                f"{path}: address {address!r}: {len(t)} times but {len(v)} values"
            )
        if not np.all(np.isfinite(t)) or (len(t) > 1 and np.any(np.diff(t) < 0)):
            raise LogFormatError(
                f"{path}: address {address!r}: times are not finite and non-decreasing"
            )
        out[address] = Stream(t, np.ascontiguousarray(v))
    return out


def _load(file: Path, address: str, cache: dict[Path, np.ndarray]) -> np.ndarray:
    if file not in cache:
        if not file.is_file():
            raise LogFormatError(f"address {address!r}: array file {file} not found")
        try:
            cache[file] = np.load(file, allow_pickle=False)
        except (ValueError, OSError) as exc:
            raise LogFormatError(
                f"address {address!r}: {file} is not a numpy array file: {exc}"
            ) from exc
    return cache[file]
