"""Source readers: raw, multi-rate streams out of real log containers.

Every reader returns the streams it was asked for as :class:`Stream` records in the
source's own units and time base; the channel map (:mod:`vestim.io.channel_map`) then
converts units, rotates frames, evaluates expressions and resamples them onto one time
base. A reader never resamples, never converts units, and never fills gaps.

Source addresses, per container:

- tabular (CSV, Parquet): a column name;
- numpy folder (comma2k19 ``processed_log``): a path relative to the folder, e.g.
  ``IMU/accelerometer``, optionally with a column index, ``IMU/accelerometer[0]``;
- MDF4: a channel name, or ``Message.Signal`` decoded from raw CAN frames with a DBC;
- ROS 2 bag: ``/topic:field.path``, e.g. ``/imu:linear_acceleration.x``.
"""

from __future__ import annotations

from collections.abc import Iterable, Sequence
from pathlib import Path
from typing import NamedTuple

import numpy as np


class Stream(NamedTuple):
    """One source signal: sample times [s, the source's clock] and values [source units].

    ``unit`` is the unit the source itself gives (a DBC signal's, an MDF4 channel's, the
    fixed SI unit of a standard ROS 2 message field), as written there; None where it
    gives none (CSV, Parquet, numpy folders, other message fields).
    """

    t: np.ndarray  # float64, shape (n,), non-decreasing
    value: np.ndarray  # float64, shape (n,)
    unit: str | None = None


SOURCE_KINDS: tuple[str, ...] = ("tabular", "numpy", "mdf", "ros2")
"""Source kinds :func:`read_source` dispatches to, see :func:`source_kind`."""

_SUFFIX_KINDS: dict[str, str] = {
    ".csv": "tabular", ".txt": "tabular", ".parquet": "tabular", ".pq": "tabular",
    ".mf4": "mdf", ".mdf": "mdf", ".db3": "ros2", ".mcap": "ros2",
}


def source_kind(path: Path) -> str:
    """The reader for ``path``, by file kind.

    ``.csv``/``.txt``/``.parquet``/``.pq`` → ``"tabular"``; ``.mf4``/``.mdf`` → ``"mdf"``;
    ``.db3``/``.mcap`` or a folder with a bag's ``metadata.yaml`` → ``"ros2"``; a folder of
    ``<name>/t`` + ``<name>/value`` arrays → ``"numpy"``.

    Raises:
        LogFormatError: the path is missing or of no known kind.
    """
    from vestim.errors import LogFormatError

    if not path.exists():
        raise LogFormatError(f"source {path} does not exist")
    if path.is_dir():
        if (path / "metadata.yaml").is_file() or any(
                p.suffix in (".db3", ".mcap") for p in path.iterdir()):
            return "ros2"
        from vestim.io.readers.numpy_dir import is_numpy_dir

        if is_numpy_dir(path):
            return "numpy"
        raise LogFormatError(
            f"source folder {path} is neither a ROS 2 bag (metadata.yaml, *.db3, *.mcap) nor a "
            "numpy folder (<name>/t and <name>/value arrays)"
        )
    kind = _SUFFIX_KINDS.get(path.suffix.lower())
    if kind is None:
        raise LogFormatError(
            f"source {path}: unknown file kind {path.suffix or '(no extension)'!r}; use one of "
            f"{', '.join(_SUFFIX_KINDS)}, a ROS 2 bag folder or a numpy folder, or set "
            f"[source] kind to one of {', '.join(SOURCE_KINDS)}"
        )
    return kind


def read_source(
    path: Path,
    addresses: Iterable[str],
    *,
    kind: str | None = None,
    time: str | None = None,
    time_scale: float = 1.0,
    dbc: Sequence[Path] = (),
) -> dict[str, Stream]:
    """Read ``addresses`` from ``path`` with the reader of its kind (see :func:`source_kind`).

    Args:
        path: the source file or folder, only read.
        addresses: source addresses in the conventions of this module's docstring.
        kind: force a reader (one of :data:`SOURCE_KINDS`); default by file kind.
        time: tabular: the time column's name (required there); ROS 2: "header" (default)
            or "receive" (see :mod:`vestim.io.readers.ros2`).
        time_scale: tabular only: seconds per unit of the time column.
        dbc: MDF only: DBC files to decode raw CAN frames with.

    Returns:
        ``{address: Stream}`` in the source's units and clock (s).

    Raises:
        LogFormatError: unknown kind, options that do not apply to it, or a reader's error.
    """
    from vestim.errors import LogFormatError

    kind = kind or source_kind(path)
    if kind not in SOURCE_KINDS:
        raise LogFormatError(f"[source] kind {kind!r}: use one of {', '.join(SOURCE_KINDS)}")
    if dbc and kind != "mdf":
        raise LogFormatError(f"[source] dbc applies to MDF4 sources only, not {kind}")
    if kind != "tabular" and time_scale != 1.0:
        raise LogFormatError(
            f"[source] time_unit applies to tabular sources only; a {kind} source carries "
            "its own sample times in s"
        )
    if kind in ("numpy", "mdf") and time is not None:
        raise LogFormatError(
            f"[source] time applies to tabular sources (the time column) and ROS 2 bags "
            f"(\"header\" or \"receive\") only; a {kind} source carries its own sample times"
        )
    if kind == "ros2" and time not in (None, "header", "receive"):
        raise LogFormatError(
            f"[source] time = {time!r}: a ROS 2 bag is timed by \"header\" stamps (default) "
            "or \"receive\" times"
        )
    if kind == "tabular":
        if time is None:
            raise LogFormatError(
                f"{path}: a tabular source needs [source] time = \"<time column name>\""
            )
        from vestim.io.readers.tabular import read_streams as read_tabular

        return read_tabular(path, addresses, time=time, time_scale=time_scale)
    if kind == "numpy":
        from vestim.io.readers.numpy_dir import read_streams as read_numpy

        return read_numpy(path, addresses)
    if kind == "mdf":
        from vestim.io.readers.mdf import read_streams as read_mdf

        return dict(read_mdf(path, list(addresses), dbc=list(dbc)))
    from vestim.io.readers.ros2 import read_streams as read_ros2

    if time == "receive":
        return dict(read_ros2(path, list(addresses), time="receive"))
    return dict(read_ros2(path, list(addresses)))
