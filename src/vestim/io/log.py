"""Read, validate and write drive logs (docs/format.md, version 1).

A log is a table with one row per sample: a strictly increasing, finite time
column ``t`` in s and numeric channels in SI units named as in
:mod:`vestim.io.channels`. CSV (``.csv``) and Parquet (``.parquet``, ``.pq``)
are chosen by file extension.

Every problem raises :class:`~vestim.errors.LogFormatError` whose message
names the source, the column, the row (0-based data row, header excluded) and
its time ``t`` where one applies, and how to fix it.
"""

from __future__ import annotations

import base64
import csv
import io
import math
import os
import sys
from collections.abc import Iterable, Iterator, Mapping
from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd
import pyarrow as pa
import pyarrow.csv as pacsv
import pyarrow.parquet as pq

from vestim.constants import G
from vestim.errors import LogFormatError
from vestim.io import channels as ch
from vestim.io.files import atomic_path

__all__ = ["LogWriter", "iter_log", "parquet_rows", "read_log", "road_wheel_angles",
           "validate_log", "write_log"]

CSV_SUFFIXES: tuple[str, ...] = (".csv",)
PARQUET_SUFFIXES: tuple[str, ...] = (".parquet", ".pq")
METADATA_PREFIX = "vestim."
"""Prefix of vestim's keys in Parquet schema metadata."""

REQUIRE_GROUPS: dict[str, tuple[str, ...]] = {
    "measured": ch.MEASURED_REQUIRED,
    "wheel_speeds": ch.WHEEL_SPEEDS,
    "torques": ch.TORQUES,
    "imu": ch.IMU_REQUIRED,
    "steering": (),
}
"""Group names accepted by ``require``. "measured" is what the estimators cannot do
without: t, ay, yaw_rate, a steering channel (delta_fl and delta_fr, or delta, or
steering_wheel_angle; "steering" alone checks only that) and a speed: the four wheel
speeds, or, without any ``omega_*``, ``gnss_speed`` or ``vehicle_speed`` (the pipeline then
gives no per-wheel quantities, see docs/fewer-sensors.md). ``ax`` is optional under
"measured" (derived from the speed). The wheel torques and the wheel speeds are
all-or-none under "measured": a log without any ``torque_*`` is accepted (the force stage
then uses the chassis equation, most CAN logs have no wheel torques), one with some but not
all four is an error; "torques" requires all four. az, roll_rate and pitch_rate are
optional everywhere; "imu" is ax, ay, yaw_rate."""

_NEEDS_STEERING = frozenset({"measured", "steering"})
_TORQUES_ALL_OR_NONE = frozenset({"measured"})
_NEEDS_SPEED = frozenset({"measured"})

# Unit-plausibility limits (SI expected). Each is far beyond what a road car reaches in SI
# yet is exceeded by typical signals recorded in the wrong unit.
OMEGA_MAX = 400.0
"""rad/s; 400 rad/s is 475 km/h at R = 0.33 m, while 40 km/h already reads 320 rpm."""
ROAD_WHEEL_ANGLE_MAX = math.pi / 2
"""rad; road wheels never steer 90°, and any real manoeuvre in degrees exceeds it."""
STEERING_WHEEL_ANGLE_MAX = 4 * math.pi
"""rad; two full turns. A steering wheel legitimately turns beyond π/2 (lock is about
±1.5 turns), so it gets a looser limit than the road wheels."""
RATE_MAX = 5.0
"""rad/s; 286 deg/s of yaw, roll or pitch rate is beyond a road vehicle."""
ACCEL_MAX = 60.0
"""m/s²; about 6 g, beyond any tire-road acceleration."""
AZ_G_UNITS = (0.5, 1.5)
"""A median |az| in this range means az is in g, not m/s² (which reads about 9.81)."""

# Wheel-speed scale check (see _check_wheel_speed_scale).
SCALE_WINDOW_S = 1.0
"""s; length of the non-overlapping windows over which increments are compared."""
SCALE_MIN_STEP = 1.0
"""m/s; a window counts as excited when ∫ax dt over it is at least this large."""
SCALE_MIN_WINDOWS = 10
"""Minimum number of excited windows; below it the check is skipped."""
SCALE_MAX_REL_SE = 0.03
"""Maximum relative standard error of the fitted slope; above it the check is skipped."""
SCALE_TOL = 0.1
"""Log-ratio tolerance (about 10 %) of the fitted slope. Pitch (the accelerometer tilts by
about 2–4 % of ax per m/s²), longitudinal slip and a varying road grade move the slope of a
rad/s log by up to about 8 %. A slope within SCALE_TOL of a wrong-unit candidate c is
reported, and only candidates with |ln c| >= 2·SCALE_TOL are considered, so a rad/s log
within that bias can never be reported."""


def read_log(
    path: str | os.PathLike[str],
    *,
    require: Iterable[str] = (),
    wheel_radius: float | None = None,
) -> pd.DataFrame:
    """Read a CSV or Parquet log and validate it with :func:`validate_log`.

    Args:
        path: ``.csv``, ``.parquet`` or ``.pq`` file; it is only read, never modified.
        require: column names or group names (see :data:`REQUIRE_GROUPS`) that must be present.
        wheel_radius: effective rolling radius in m; enables the wheel-speed scale check.

    Returns:
        The log, one row per sample, columns as in the file. CSV columns are float64;
        Parquet columns keep their stored dtype, and vestim's schema metadata is in
        ``df.attrs`` (keys without the ``vestim.`` prefix).

    Raises:
        LogFormatError: unsupported extension, unreadable content or an invalid log.
    """
    p = Path(path)
    kind = _kind(p)
    try:
        if kind == "csv":
            df = _read_csv(p)
        else:
            table = pq.read_table(p, page_checksum_verification=True)
            df = table.to_pandas()
            df.attrs = _vestim_metadata(table.schema.metadata)
    except Exception as exc:
        raise _unreadable(p, kind, exc) from exc
    validate_log(df, require=require, wheel_radius=wheel_radius, source=str(p))
    return df


STREAM_ROWS = 131_072
"""Rows per piece of :func:`iter_log` (about 11 min at 200 Hz; ~25 MB of input channels)."""


def parquet_rows(path: str | os.PathLike[str]) -> int:
    """Number of rows of a Parquet log, from its footer (nothing else is read)."""
    p = Path(path)
    try:
        return int(pq.ParquetFile(p).metadata.num_rows)
    except Exception as exc:
        raise _unreadable(p, "parquet", exc) from exc


def iter_log(
    path: str | os.PathLike[str],
    *,
    require: Iterable[str] = (),
    wheel_radius: float | None = None,
    rows: int | None = None,
) -> Iterator[pd.DataFrame]:
    """Read a Parquet log piece by piece, in bounded memory (a 10 h log at 200 Hz is 1.5 GB).

    Each piece of at least ``rows`` rows (default :data:`STREAM_ROWS`; whole record batches;
    the last may be shorter) is checked as :func:`read_log` checks a whole log, with messages
    that name the file's row, and ``t`` must go on increasing from one piece to the next; the
    pieces concatenated are the log :func:`read_log` returns, each with its ``attrs``. The unit checks are per
    sample or skip what a piece does not excite, so a short last piece is checked as well.

    Raises:
        LogFormatError: as :func:`read_log`, for the first piece with a problem.
    """
    p = Path(path)
    if _kind(p) != "parquet":
        raise LogFormatError(f"{p}: only Parquet logs are read in pieces; convert it with "
                             "`vestim import` or read it whole with read_log")
    rows = STREAM_ROWS if rows is None else rows
    if rows < 1:
        raise ValueError(f"rows = {rows}: read at least 1 row per piece")
    try:
        f = pq.ParquetFile(p, page_checksum_verification=True)
        attrs = _vestim_metadata(f.schema_arrow.metadata)
        first, t_last = 0, -math.inf
        buf: list[pa.RecordBatch] = []
        pieces = f.iter_batches(batch_size=rows)
        while True:
            batch = next(pieces, None)
            if batch is not None:
                buf.append(batch)
                if sum(b.num_rows for b in buf) < rows:
                    continue
            elif not buf and first > 0:
                return
            piece = pa.Table.from_batches(buf, schema=f.schema_arrow).to_pandas()
            buf = []
            piece.attrs = dict(attrs)
            validate_log(piece, require=require, wheel_radius=wheel_radius, source=str(p),
                         first_row=first)
            t0 = float(piece["t"].iloc[0])
            if not t0 > t_last:
                raise LogFormatError(
                    f"{p}: column 't' is not strictly increasing at row {first} (t = {t0!r} s); "
                    f"the previous row has t = {t_last!r} s. Sort the log by t and drop repeated "
                    "samples")
            t_last = float(piece["t"].iloc[-1])
            first += piece.shape[0]
            yield piece
            if batch is None:
                return
    except LogFormatError:
        raise
    except Exception as exc:
        raise _unreadable(p, "parquet", exc) from exc


def _vestim_metadata(meta: Mapping[bytes, bytes] | None) -> dict[str, str]:
    """vestim's keys of Parquet schema metadata, without their prefix."""
    prefix = METADATA_PREFIX.encode()
    return {k[len(prefix):].decode(errors="replace"): v.decode(errors="replace")
            for k, v in (meta or {}).items() if k.startswith(prefix)}


def _unreadable(p: Path, kind: str, exc: Exception) -> LogFormatError:
    """The decoders report a damaged file in many ways (pyarrow: OSError, ArrowInvalid;
    pandas: ParserError, a JSON ValueError or a KeyError from corrupt schema metadata): each
    means "this file cannot be read", and the decoder's own words say where."""
    if isinstance(exc, UnicodeDecodeError):
        return LogFormatError(f"{p}: not a UTF-8 text file ({exc.reason} at byte {exc.start}); "
                              "a CSV log is UTF-8 text with a header row")
    if isinstance(exc, FileNotFoundError):
        return LogFormatError(f"{p}: file not found")
    return LogFormatError(f"{p}: cannot be read as {kind.upper()}: {exc}")


def write_log(
    df: pd.DataFrame,
    path: str | os.PathLike[str],
    *,
    metadata: Mapping[str, str] | None = None,
    float32: bool = False,
) -> Path:
    """Write a log atomically as CSV or Parquet (by extension), columns in canonical order.

    The log is first checked (``t`` present, numeric columns, finite values, strictly
    increasing ``t``); unit heuristics are not applied on writing. Parent directories are
    created. The file is written to a temporary file in the same directory and moved into
    place with :func:`os.replace`, so readers never see a partial file and a failed write
    leaves any previous file untouched. The index is not written.

    CSV floats are written in shortest round-trip form, so read → write → read returns
    identical float64 values; :func:`read_log` reads every CSV column as float64.
    ``metadata`` is stored in Parquet schema metadata under ``vestim.<key>``; CSV has no
    place for it and ignores it. ``float32``: as :class:`LogWriter`'s.

    Returns:
        The path written.
    """
    with LogWriter(path, float32=float32) as w:
        w.write(df)
        if metadata is not None:
            w.metadata.update(metadata)
    return w.path


_ARROW_SCHEMA = "ARROW:schema"
"""The Parquet key-value entry in which Arrow stores a file's schema, field metadata included
(Arrow's convention: base64 of the IPC-serialised schema)."""


def _unit_schema(schema: pa.Schema, metadata: Mapping[str, str]) -> str:
    """``schema`` with each column's unit (:func:`vestim.io.channels.unit_of`) as field
    metadata ``unit`` and ``metadata`` as schema metadata, serialised for the
    ``ARROW:schema`` entry: Parquet has no field metadata of its own, and writing the entry
    when the file is closed lets metadata be added until then."""
    fields = [f.with_metadata({"unit": unit}) if (unit := ch.unit_of(f.name)) else f
              for f in schema]
    full = pa.schema(fields, metadata=dict(metadata))
    return base64.b64encode(full.serialize().to_pybytes()).decode("ascii")


class LogWriter:
    """Write a log piece by piece (bounded memory), atomically: the file appears, whole, when
    the ``with`` block ends without an exception, and not at all otherwise.

    The first piece fixes the columns (canonical order) and, for Parquet, the types; every
    later piece must have the same columns, and ``t`` must go on increasing. Each piece is
    checked as :func:`write_log` checks a log. With ``float32``, every float column but ``t``
    is stored in single precision (a relative 6e-8, far below any estimate's σ; ``t`` stays
    float64, which a 10 h log at 200 Hz needs), which halves the file. Parquet columns are
    zstd-compressed without dictionaries (measured variables rarely repeat a value), floats
    byte-stream split (the encoding every Parquet reader since 2020 knows), and the
    Parquet schema gives each column its unit (field metadata ``unit``,
    :func:`vestim.io.channels.unit_of`: "m/s", "N", "-" for dimensionless; a column vestim
    does not know has none).
    ``metadata`` (str → str) may be filled until the block ends: Parquet stores it in the
    file's key-value metadata under ``vestim.<key>`` (:func:`read_log` returns it in
    ``attrs``); CSV ignores it. Parquet pages carry checksums, which :func:`read_log` verifies.

    Example::

        with LogWriter("est.parquet") as w:
            for piece in pieces:
                w.write(piece)
            w.metadata["source"] = "drive.parquet"
    """

    def __init__(self, path: str | os.PathLike[str], *, float32: bool = False) -> None:
        self.path = Path(path)
        self._float32 = float32
        self._kind = _kind(self.path)
        self.metadata: dict[str, str] = {}
        self._columns: list[str] | None = None
        self._rows = 0
        self._t_last = -math.inf
        self._atomic: Any = None
        self._tmp: Path | None = None
        self._parquet: pq.ParquetWriter | None = None
        self._csv: Any = None

    @property
    def rows(self) -> int:
        """Rows written so far."""
        return self._rows

    @property
    def columns(self) -> list[str]:
        """The columns, in the order written (empty before the first piece)."""
        return list(self._columns or [])

    def __enter__(self) -> LogWriter:
        self._atomic = atomic_path(self.path)
        self._tmp = self._atomic.__enter__()
        return self

    def write(self, df: pd.DataFrame) -> None:
        """Append the rows of ``df`` (a log piece: ``t`` and numeric channels)."""
        if self._tmp is None:
            raise RuntimeError("LogWriter.write outside its `with` block")
        source = "log to write" if self._rows == 0 else f"log to write (rows from {self._rows})"
        t = check_structure(df, source=source, first_row=self._rows)
        if self._columns is None:
            self._columns = ch.canonical_order(df.columns)
        elif set(df.columns) != set(self._columns):
            extra = sorted(set(df.columns) - set(self._columns))
            lack = sorted(set(self._columns) - set(df.columns))
            raise LogFormatError(f"{source}: the piece's columns differ from the first piece's "
                                 f"(extra: {', '.join(extra) or 'none'}; missing: "
                                 f"{', '.join(lack) or 'none'}); every piece needs the same "
                                 "columns")
        if not t[0] > self._t_last:
            raise LogFormatError(f"{source}: column 't' is not strictly increasing at row "
                                 f"{self._rows} (t = {float(t[0])!r} s after {self._t_last!r} s)")
        table = pa.Table.from_arrays([self._array(df[name], name) for name in self._columns],
                                     names=self._columns)
        if self._kind == "csv":
            if self._csv is None:
                self._csv = open(self._tmp, "wb")  # noqa: SIM115 (closed in __exit__)
                buf = io.StringIO()
                csv.writer(buf, lineterminator="\n").writerow(table.column_names)
                self._csv.write(buf.getvalue().encode("utf-8"))
            pacsv.write_csv(table, self._csv, pacsv.WriteOptions(include_header=False))
        else:
            if self._parquet is None:
                # Without the stored Arrow schema, readers take the schema metadata from
                # the file's key-value metadata, which can still be added at the end.
                # Byte-stream split puts each float's exponent bytes together, which zstd
                # then packs: an hour of estimates 148 → 91 MB, no slower to write.
                self._parquet = pq.ParquetWriter(self._tmp, table.schema.remove_metadata(),
                                                 write_page_checksum=True, store_schema=False,
                                                 use_dictionary=False, compression="zstd",
                                                 use_byte_stream_split=[
                                                     f.name for f in table.schema
                                                     if pa.types.is_floating(f.type)])
            self._parquet.write_table(table.cast(self._parquet.schema))
        self._rows += df.shape[0]
        self._t_last = float(t[-1])

    def _array(self, column: pd.Series, name: str) -> pa.Array:
        """One column as Arrow (NaN as null, as ``pa.Table.from_pandas`` has it), float32
        with ``float32`` but ``t``: taken from the column's own values, never through a
        reordered copy of the frame."""
        if column.dtype == np.float64:
            values = column.to_numpy()
            if self._float32 and name != ch.T:
                values = values.astype(np.float32)
            return pa.array(values, from_pandas=True)
        return pa.Array.from_pandas(column)

    def __exit__(self, kind: Any, exc: Any, tb: Any) -> None:
        try:
            if kind is None:
                if self._rows == 0:
                    raise LogFormatError("log to write: no rows were written; a log needs at "
                                         "least one sample")
                for key, value in self.metadata.items():
                    if not isinstance(key, str) or not isinstance(value, str):
                        raise TypeError(f"metadata must map str to str; got {key!r}: {value!r} "
                                        f"({type(key).__name__}: {type(value).__name__})")
                if self._parquet is not None:
                    meta = {METADATA_PREFIX + k: v for k, v in self.metadata.items()}
                    self._parquet.add_key_value_metadata(
                        {**meta, _ARROW_SCHEMA: _unit_schema(self._parquet.schema, meta)})
        except BaseException:
            self._close()
            self._atomic.__exit__(*sys.exc_info())
            raise
        self._close()
        self._atomic.__exit__(kind, exc, tb)

    def _close(self) -> None:
        if self._parquet is not None:
            self._parquet.close()
            self._parquet = None
        if self._csv is not None:
            self._csv.close()
            self._csv = None


def validate_log(
    df: pd.DataFrame,
    *,
    require: Iterable[str] = (),
    wheel_radius: float | None = None,
    source: str = "log",
    first_row: int = 0,
) -> None:
    """Check a log against the spec; return ``None`` or raise :class:`LogFormatError`.

    Checks, in order: ``t`` present, unique string column names, at least one row, numeric
    columns only, finite values, strictly increasing ``t``; the channels in ``require``
    (column names or the groups of :data:`REQUIRE_GROUPS`); with ``require`` ``"measured"``,
    a median sample interval of at most :data:`MAX_SAMPLE_INTERVAL` (t in ms, µs or ns is
    named); then unit plausibility:

    - ``omega_*``: max |ω| > 400 rad/s looks like rpm;
    - steering angles: max |δ| > π/2 rad (steering_wheel_angle: > 4π rad) looks like degrees;
    - ``yaw_rate``, ``roll_rate``, ``pitch_rate``: max > 5 rad/s looks like deg/s;
    - ``az``: median |az| in [0.5, 1.5] looks like g;
    - ``ax``, ``ay``: max > 60 m/s² is implausible;
    - with ``wheel_radius`` (m): wheel-speed increments R·Δω over 1 s windows regressed on
      ∫ax dt have slope 1 in rad/s, 3.6·R for km/h, 60/(2π) for rpm and R for m/s; a column
      whose slope lies within 10 % of a wrong unit's is reported. Skipped, silently, when
      ``ax`` is missing, the log has fewer than 10 windows with |∫ax dt| ≥ 1 m/s (i.e. mean
      |ax| ≥ 1 m/s² over a second), or the slope's relative standard error exceeds 3 %.
      Pitch, slip and grade bias the slope by up to about 8 %, so km/h is only checked
      when 3.6·R differs from 1 by 22 % or more (R ≥ 0.34 m or R ≤ 0.227 m); for the
      usual 0.23–0.34 m radii a km/h column cannot be told from rad/s and passes.

    Args:
        df: the log.
        require: column or group names that must be present.
        wheel_radius: effective rolling radius in m, or ``None`` to skip the scale check.
        source: prefix of every message (the file name when called by :func:`read_log`).
        first_row: the file row of ``df``'s first row (a piece read by :func:`iter_log`).
    """
    t = check_structure(df, source=source, first_row=first_row)
    if isinstance(require, str):
        require = (require,)
    _check_required(df, tuple(require), source)
    if "measured" in require:  # a log to estimate from, not any table of results
        _check_time_base(t, source)
    _check_units(df, t, wheel_radius, source, first_row)


MIN_RATE_HZ = 80.0
"""Lowest sample rate (Hz) of a log to estimate from. The force stage integrates the tire's
LuGre bristle dynamics once per sample, and that integration goes unstable when the step
is too long: on vestim's simulator (both built-in cars, the five maneuvers of DEFAULT_SET)
50 Hz left 68–84 % of the rows NaN, 58.8 Hz up to 24 %, 62.5 Hz none; the crossplant logs
decimated to 66.7 Hz none. 80 Hz keeps a margin of a third over the first rate that failed;
the real logs are 100 Hz, the simulator's 200 Hz."""

MAX_SAMPLE_INTERVAL = 1.0 / MIN_RATE_HZ
"""Largest median sample interval (s) of a log to estimate from (:data:`MIN_RATE_HZ`)."""

_PLAUSIBLE_DT = (1.0 / 2000.0, MAX_SAMPLE_INTERVAL)
"""s; median steps of a log recorded at 80 Hz to 2 kHz: a step that lands here once divided
by 1e3, 1e6 or 1e9 means ``t`` is in ms, µs or ns."""


def _check_time_base(t: np.ndarray, source: str) -> None:
    if t.shape[0] < 2:
        return
    dt = float(np.median(np.diff(t)))
    if dt <= MAX_SAMPLE_INTERVAL * (1 + 1e-9):  # 80 Hz written as decimals is 0.0125000…01
        return
    lo, hi = _PLAUSIBLE_DT
    unit = next(((u, f) for u, f in (("milliseconds", 1e3), ("microseconds", 1e6),
                                     ("nanoseconds", 1e9)) if lo <= dt / f <= hi), None)
    if unit is not None:
        name, f = unit
        raise LogFormatError(
            f"{source}: column 't' steps by {dt:g} (median): t looks like {name} (a "
            f"{f / dt:.0f} Hz log in s would step by {dt / f:g}); divide t by {f:g} to get "
            "seconds")
    raise LogFormatError(
        f"{source}: the log is sampled at {1 / dt:.3g} Hz (column 't' steps by {dt:g} s, "
        f"median), below the {MIN_RATE_HZ:g} Hz the estimators need (the tire model is "
        f"integrated once per sample and goes unstable on longer steps: NaN estimates); "
        f"record or export the channels at {MIN_RATE_HZ:g} Hz or more (100–200 Hz is usual)")


def road_wheel_angles(df: pd.DataFrame, steering_ratio: float | None) -> np.ndarray:
    """Front road-wheel steering angles in rad, shape (n, 2): columns [delta_fl, delta_fr].

    Taken from ``delta_fl`` and ``delta_fr`` when both exist, else ``delta`` for both
    wheels, else ``steering_wheel_angle / steering_ratio`` (steering-wheel angle over
    road-wheel angle, ``[vehicle] steering_ratio``). Positive steers left.
    """
    cols = set(df.columns)
    if set(ch.ROAD_WHEEL_ANGLES) <= cols:
        return np.column_stack([_floats(df[c]) for c in ch.ROAD_WHEEL_ANGLES])
    if ch.DELTA in cols:
        d = _floats(df[ch.DELTA])
        return np.column_stack([d, d])
    if ch.STEERING_WHEEL_ANGLE in cols:
        if steering_ratio is None:
            raise LogFormatError(
                f"log has only '{ch.STEERING_WHEEL_ANGLE}' for steering, which needs a steering "
                "ratio: pass steering_ratio (the vehicle file's [vehicle] steering_ratio) or add "
                "road-wheel angle columns delta_fl and delta_fr (or delta) in rad"
            )
        if not (math.isfinite(steering_ratio) and steering_ratio > 0):
            raise ValueError(f"steering_ratio = {steering_ratio!r} must be finite and > 0")
        d = _floats(df[ch.STEERING_WHEEL_ANGLE]) / steering_ratio
        return np.column_stack([d, d])
    present = [c for c in ch.ROAD_WHEEL_ANGLES if c in cols]
    partial = f" ('{present[0]}' is present without its pair)" if present else ""
    raise LogFormatError(
        "log has no steering channel: missing delta_fl and delta_fr, delta, and "
        f"steering_wheel_angle{partial}; add delta_fl and delta_fr (or delta) in rad, or "
        "steering_wheel_angle in rad with the vehicle's steering_ratio"
    )


# --- helpers ----------------------------------------------------------------------------------

# pandas >= 3 reads floats in round-trip precision by default and deprecates the option.
_CSV_READ_OPTIONS: dict[str, Any] = (
    {"float_precision": "round_trip"} if int(pd.__version__.split(".")[0]) < 3 else {}
)


def _read_csv(p: Path) -> pd.DataFrame:
    """Every CSV column as float64: an integral float such as ``-0`` or ``3`` is written
    without a decimal point and must not come back as an integer."""
    try:
        return pd.read_csv(p, dtype=np.float64, **_CSV_READ_OPTIONS)
    except (ValueError, TypeError):
        # A non-numeric column; read it as is so validate_log can name column, row and value.
        return pd.read_csv(p, **_CSV_READ_OPTIONS)


def _kind(p: Path) -> str:
    suffix = p.suffix.lower()
    if suffix in CSV_SUFFIXES:
        return "csv"
    if suffix in PARQUET_SUFFIXES:
        return "parquet"
    supported = ", ".join(CSV_SUFFIXES + PARQUET_SUFFIXES)
    raise LogFormatError(
        f"{p}: unsupported log file extension {suffix or '(none)'!r}; use one of {supported}"
    )


def _floats(s: pd.Series) -> np.ndarray:
    return s.to_numpy(dtype=np.float64, na_value=np.nan)


def _is_number_dtype(dtype: Any) -> bool:
    return (pd.api.types.is_integer_dtype(dtype) or pd.api.types.is_float_dtype(dtype)) and not (
        pd.api.types.is_bool_dtype(dtype)
    )


def _where(i: int, t: np.ndarray | None, first_row: int = 0) -> str:
    if t is None:
        return f"row {first_row + i}"
    return f"row {first_row + i} (t = {float(t[i])!r} s)"


def check_structure(df: pd.DataFrame, *, source: str, first_row: int = 0) -> np.ndarray:
    """Structural checks shared by reading and writing; returns ``t`` as float64.

    ``first_row`` is the row number of ``df``'s first row in its file (a piece of a log read
    in chunks), so that messages name the row of the file.
    """
    if not isinstance(df, pd.DataFrame):
        raise TypeError(f"{source}: expected a pandas DataFrame, got {type(df).__name__}")
    names = list(df.columns)
    bad_names = [c for c in names if not isinstance(c, str)]
    if bad_names:
        raise LogFormatError(
            f"{source}: column name {bad_names[0]!r} is not a string; name every column as in "
            "the log format spec"
        )
    dup = df.columns[df.columns.duplicated()]
    if len(dup):
        raise LogFormatError(
            f"{source}: column {dup[0]!r} appears more than once; keep one of them"
        )
    if ch.T not in df.columns:
        hint = next((f" (rename {c!r} to 't')" for c in names
                     if c.strip().lower() in ("t", "time", "time_s", "timestamp")), "")
        raise LogFormatError(
            f"{source}: column 't' (sample time in s) is missing{hint}; every log needs it. "
            f"Columns present: {', '.join(names) or '(none)'}"
        )
    if len(df) == 0:
        raise LogFormatError(f"{source}: the log has no rows; record at least one sample")

    t: np.ndarray | None = None
    for name in [ch.T, *(c for c in names if c != ch.T)]:
        s = df[name]
        if _is_number_dtype(s.dtype):
            if t is None:
                t = _floats(s)
            continue
        if pd.api.types.is_bool_dtype(s.dtype):
            raise LogFormatError(
                f"{source}: column {name!r} is boolean; store it as 0/1 numbers or drop it"
            )
        coerced = pd.to_numeric(s, errors="coerce")
        bad = np.flatnonzero(coerced.isna().to_numpy() & s.notna().to_numpy())
        where = f": {_where(int(bad[0]), t, first_row)} holds {s.iloc[bad[0]]!r}" if len(bad) else ""
        raise LogFormatError(
            f"{source}: column {name!r} is not numeric (dtype {s.dtype}){where}; every column "
            "must hold numbers in SI units, so convert or drop it"
        )
    assert t is not None  # the loop reads t first, and it is numeric if we got here

    first_bad: tuple[int, str, float] | None = None
    for name in [ch.T, *(c for c in names if c != ch.T)]:
        s = df[name]
        if pd.api.types.is_integer_dtype(s.dtype) and not s.hasnans:
            continue
        v = t if name == ch.T else _floats(s)
        # A sparse channel is NaN between its own samples; inf or a negative speed is not.
        bad = ((np.isinf(v) | (v < 0)) if name in ch.SPARSE
               else np.isinf(v) if name in ch.MAY_BE_UNKNOWN else ~np.isfinite(v))
        if bad.any():
            i = int(bad.argmax())
            if first_bad is None or i < first_bad[0]:
                first_bad = (i, name, float(v[i]))
    if first_bad is not None:
        i, name, value = first_bad
        what = "missing (NaN)" if math.isnan(value) else f"{value}"
        if name in ch.SPARSE:
            raise LogFormatError(
                f"{source}: sparse column {name!r} is {what} at {_where(i, t, first_row)}; it holds a "
                "finite speed ≥ 0 m/s on the rows nearest its own samples and NaN between"
            )
        raise LogFormatError(
            f"{source}: column {name!r} is {what} at {_where(i, t, first_row)}; every value must be "
            "finite: fill the gap (e.g. interpolate) or drop that row"
        )

    dt = np.diff(t)
    bad_dt = np.flatnonzero(dt <= 0)
    if len(bad_dt):
        i = int(bad_dt[0]) + 1
        raise LogFormatError(
            f"{source}: column 't' is not strictly increasing at {_where(i, t, first_row)}; the previous "
            f"row has t = {float(t[i - 1])!r} s. Sort the log by t and drop repeated samples"
        )
    return t


def _check_required(df: pd.DataFrame, require: tuple[str, ...], source: str) -> None:
    cols = set(df.columns)
    needed: list[str] = []
    needs_steering = False
    for item in require:
        if item in REQUIRE_GROUPS:
            needed.extend(REQUIRE_GROUPS[item])
            needs_steering |= item in _NEEDS_STEERING
            if item in _TORQUES_ALL_OR_NONE and any(c in cols for c in ch.TORQUES):
                needed.extend(ch.TORQUES)  # some torques given: the rest are missing
            lower = {c.strip().lower() for c in cols}
            if item in _NEEDS_SPEED and (any(c in lower for c in ch.WHEEL_SPEEDS)
                                         or not any(c in cols for c in ch.SPEED_SOURCES)):
                needed.extend(ch.WHEEL_SPEEDS)  # some wheel speeds given, or no other speed
        else:
            needed.append(item)
    missing = list(dict.fromkeys(c for c in needed if c not in cols))
    if (_NEEDS_SPEED.intersection(require) and set(ch.WHEEL_SPEEDS) <= set(missing)
            and not any(c.strip().lower() in ch.WHEEL_SPEEDS for c in cols)):
        raise LogFormatError(
            f"{source}: no speed channel: needs the four wheel speeds omega_fl, omega_fr, "
            "omega_rl, omega_rr [rad/s], or, without them, gnss_speed [m/s] (sparse) or "
            "vehicle_speed [m/s] (CAN vehicle speed, dense); add one of them"
        )
    if missing:
        lookup = {c.strip().lower(): c for c in df.columns}
        hints = [f"{lookup[m.lower()]!r} → {m!r}" for m in missing
                 if m.lower() in lookup and lookup[m.lower()] != m]
        hint = f" (rename {', '.join(hints)})" if hints else ""
        units = ", ".join(f"{m} [{ch.unit_of(m)}]" if ch.unit_of(m) else m for m in missing)
        torque_fix = (" — wheel torques are all four or none: add the missing ones or drop "
                      "every torque_* column (F_x then comes from the chassis equation)"
                      if any(m in ch.TORQUES for m in missing)
                      and _TORQUES_ALL_OR_NONE.intersection(require) else "")
        raise LogFormatError(
            f"{source}: required column(s) missing: {units}{hint}; add them in the spec's "
            f"names and SI units (required: {', '.join(require)}){torque_fix}"
        )
    if needs_steering and not (
        set(ch.ROAD_WHEEL_ANGLES) <= cols or ch.DELTA in cols or ch.STEERING_WHEEL_ANGLE in cols
    ):
        raise LogFormatError(
            f"{source}: no steering channel: needs delta_fl and delta_fr, or delta, or "
            "steering_wheel_angle (all in rad); add one of them"
        )


def _argmax_abs(v: np.ndarray) -> tuple[int, float]:
    i = int(np.abs(v).argmax())
    return i, float(v[i])


def _check_units(
    df: pd.DataFrame, t: np.ndarray, wheel_radius: float | None, source: str,
    first_row: int = 0,
) -> None:
    cols = set(df.columns)

    def over(name: str, limit: float, unit: str, fix: str) -> None:
        if name not in cols:
            return
        i, v = _argmax_abs(_floats(df[name]))
        if abs(v) > limit:
            raise LogFormatError(
                f"{source}: column {name!r} reaches {v:.6g} {unit} at {_where(i, t, first_row)}, beyond "
                f"±{limit:.4g} {unit}; {fix}"
            )

    for name in ch.WHEEL_SPEEDS:
        over(name, OMEGA_MAX, "rad/s", "this looks like rpm (convert with ×2π/60)")
    for name in (*ch.ROAD_WHEEL_ANGLES, ch.DELTA):
        over(name, ROAD_WHEEL_ANGLE_MAX, "rad", "this looks like degrees (convert with ×π/180)")
    over(ch.STEERING_WHEEL_ANGLE, STEERING_WHEEL_ANGLE_MAX, "rad",
         "this looks like degrees (convert with ×π/180)")
    for name in ("yaw_rate", "roll_rate", "pitch_rate"):
        over(name, RATE_MAX, "rad/s", "this looks like deg/s (convert with ×π/180)")
    for name in ("ax", "ay"):
        over(name, ACCEL_MAX, "m/s²", "expected m/s² (specific force); check the unit and "
             "scaling of this channel")
    if "az" in cols:
        median = float(np.median(np.abs(_floats(df["az"]))))
        lo, hi = AZ_G_UNITS
        if lo <= median <= hi:
            raise LogFormatError(
                f"{source}: column 'az' has median |az| = {median:.4g}; this looks like g "
                f"units, multiply by {G} to get m/s² (at rest az reads +{G})"
            )
    if wheel_radius is not None:
        if not (math.isfinite(wheel_radius) and wheel_radius > 0):
            raise ValueError(f"wheel_radius = {wheel_radius!r} m must be finite and > 0")
        _check_wheel_speed_scale(df, t, wheel_radius, source)


def _fit_slope(x: np.ndarray, y: np.ndarray) -> tuple[float, float]:
    """Least-squares y = s·x + c; returns (s, standard error of s)."""
    xm = x - x.mean()
    sxx = float(xm @ xm)
    if sxx <= 0.0:  # every window saw the same speed change: slope not identifiable
        return math.nan, math.inf
    s = float(xm @ (y - y.mean())) / sxx
    resid = y - y.mean() - s * xm
    dof = max(len(x) - 2, 1)
    return s, math.sqrt(float(resid @ resid) / dof / sxx)


def _check_wheel_speed_scale(
    df: pd.DataFrame, t: np.ndarray, wheel_radius: float, source: str
) -> None:
    """Detect wheel speeds recorded in km/h, rpm or m/s from their dynamics.

    Over non-overlapping windows of SCALE_WINDOW_S, the change of R·ω must match the change
    of forward speed, ∫ax dt, so the slope of R·Δω on ∫ax dt is 1 for rad/s. A column in
    km/h gives 3.6·R, rpm 60/(2π) ≈ 9.55, m/s R. The fit has an intercept, which absorbs a
    constant accelerometer bias or road grade; one refit without windows whose residual
    exceeds 4 robust sigmas removes spinning or locked wheels. See SCALE_TOL for why km/h is
    only distinguishable from rad/s when 3.6·R is at least 22 % away from 1 (R >= 0.34 m or
    R <= 0.227 m); for other radii only rpm and m/s are detected.
    """
    omegas = [c for c in ch.WHEEL_SPEEDS if c in df.columns]
    if "ax" not in df.columns or not omegas or len(t) < 3:
        return
    n_win = int((t[-1] - t[0]) // SCALE_WINDOW_S)
    if n_win < SCALE_MIN_WINDOWS:
        return
    edges = t[0] + SCALE_WINDOW_S * np.arange(n_win + 1)
    ax = _floats(df["ax"])
    speed_from_ax = np.concatenate(([0.0], np.cumsum(0.5 * (ax[1:] + ax[:-1]) * np.diff(t))))
    dv = np.diff(np.interp(edges, t, speed_from_ax))
    if int(np.count_nonzero(np.abs(dv) >= SCALE_MIN_STEP)) < SCALE_MIN_WINDOWS:
        return

    candidates = {
        "km/h": (3.6 * wheel_radius, f"convert with ×1/(3.6·R) = ×{1 / (3.6 * wheel_radius):.4g}"),
        "rpm": (60.0 / (2.0 * math.pi), "convert with ×2π/60"),
        "m/s (wheel-centre speed)": (wheel_radius, f"convert with ×1/R = ×{1 / wheel_radius:.4g}"),
    }
    for name in omegas:
        dw = wheel_radius * np.diff(np.interp(edges, t, _floats(df[name])))
        slope, se = _fit_slope(dv, dw)
        resid = dw - slope * dv
        resid -= np.median(resid)
        mad = 1.4826 * float(np.median(np.abs(resid)))
        keep = np.abs(resid) <= max(4.0 * mad, 1e-3)
        if int(np.count_nonzero(np.abs(dv[keep]) >= SCALE_MIN_STEP)) < SCALE_MIN_WINDOWS:
            continue
        slope, se = _fit_slope(dv[keep], dw[keep])
        if not (slope > 0 and se <= SCALE_MAX_REL_SE * slope):  # False for NaN too
            continue
        for unit, (expected, fix) in candidates.items():
            if (abs(math.log(expected)) < 2 * SCALE_TOL
                    or abs(math.log(slope / expected)) > SCALE_TOL):
                continue
            raise LogFormatError(
                f"{source}: column {name!r} looks like {unit}, not rad/s: between t = "
                f"{float(t[0])!r} s and t = {float(edges[-1])!r} s its increments R·Δω are "
                f"{slope:.3f} × ∫ax dt (rad/s gives 1, {unit} gives {expected:.3f} at "
                f"R = {wheel_radius} m); {fix}, or check wheel_radius (leave it out to skip "
                "this check)"
            )
