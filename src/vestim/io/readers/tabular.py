"""CSV and Parquet source tables with any column names.

A tabular source shares one time column between all its columns: the map names it
(``[source] time``) and its unit (``time_unit``, any pint time unit: ``"s"``, ``"ms"``,
``"us"``, ``"ns"``). An address is a column name. Values come back in the file's own units;
rows with a missing value (empty cell, NaN) in the requested column are dropped from that
column's stream, so a CAN export with one row per frame gives each signal its own samples.
"""

from __future__ import annotations

from collections.abc import Iterable
from pathlib import Path

import numpy as np
import pandas as pd
import pyarrow as pa
import pyarrow.parquet as pq

from vestim.errors import LogFormatError
from vestim.io.readers import Stream

CSV_SUFFIXES: tuple[str, ...] = (".csv", ".txt")
PARQUET_SUFFIXES: tuple[str, ...] = (".parquet", ".pq")

__all__ = ["read_streams"]


def read_streams(
    path: Path,
    addresses: Iterable[str],
    *,
    time: str,
    time_scale: float = 1.0,
) -> dict[str, Stream]:
    """Read columns ``addresses`` of a CSV or Parquet file as streams on its time column.

    Args:
        path: ``.csv``/``.txt`` or ``.parquet``/``.pq`` file, only read.
        addresses: column names.
        time: name of the time column.
        time_scale: seconds per unit of the time column (1e-3 for ms), from the map's
            ``time_unit``.

    Returns:
        ``{address: Stream(t [s], value [file units])}``; rows where the value is missing
        are left out of that stream.

    Raises:
        LogFormatError: unreadable file, a missing or non-numeric column (named), or a
            time column that is not finite or decreases.
    """
    wanted = list(dict.fromkeys(addresses))
    columns = list(dict.fromkeys([time, *wanted]))
    suffix = path.suffix.lower()
    try:
        if suffix in PARQUET_SUFFIXES:
            present = pq.read_schema(path).names
            _check_present(path, columns, present)
            df = pq.read_table(path, columns=columns).to_pandas()
        elif suffix in CSV_SUFFIXES:
            present = list(pd.read_csv(path, nrows=0).columns)
            _check_present(path, columns, present)
            df = pd.read_csv(path, usecols=columns)
        else:
            raise LogFormatError(
                f"{path}: not a tabular source (extension {suffix or '(none)'!r}); use "
                f"{', '.join(CSV_SUFFIXES + PARQUET_SUFFIXES)}"
            )
    except (pd.errors.ParserError, pd.errors.EmptyDataError, pa.ArrowException,
            UnicodeDecodeError) as exc:
        raise LogFormatError(f"{path}: cannot be read as a table: {exc}") from exc
    t_all = _numeric(df[time], path, time) * time_scale
    out: dict[str, Stream] = {}
    for address in wanted:
        v = _numeric(df[address], path, address)
        keep = ~np.isnan(v) & ~np.isnan(t_all)
        t = t_all[keep]
        if not np.all(np.isfinite(t)):
            raise LogFormatError(f"{path}: time column {time!r} holds a non-finite value")
        if len(t) > 1 and np.any(np.diff(t) < 0):
            i = int(np.flatnonzero(np.diff(t) < 0)[0]) + 1
            raise LogFormatError(
                f"{path}: time column {time!r} decreases at data row {i} (where {address!r} "
                "is present); sort the file by time"
            )
        out[address] = Stream(t, v[keep])
    return out


def _check_present(path: Path, columns: list[str], present: list[str]) -> None:
    missing = [c for c in columns if c not in present]
    if missing:
        raise LogFormatError(
            f"{path}: column(s) {', '.join(map(repr, missing))} not found; the file has "
            f"{', '.join(map(repr, present[:40]))}{' …' if len(present) > 40 else ''}. "
            "Fix the address in the channel map"
        )


def _numeric(s: pd.Series, path: Path, name: str) -> np.ndarray:
    coerced = pd.to_numeric(s, errors="coerce")
    bad = np.flatnonzero(coerced.isna().to_numpy() & s.notna().to_numpy())
    if len(bad):
        raise LogFormatError(
            f"{path}: column {name!r} is not numeric: data row {int(bad[0])} holds "
            f"{s.iloc[int(bad[0])]!r}"
        )
    return coerced.to_numpy(dtype=np.float64, na_value=np.nan)
