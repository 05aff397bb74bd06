"""Many logs in parallel on Dask (``vestim batch``), and the task map the studies share.

:func:`run_batch` estimates every log of a list with :class:`~vestim.pipeline.Pipeline`,
one task per log, and writes one output per log, ``<out>/<stem>_estimate.parquet``
(:func:`~vestim.io.write_log`, atomic), then a summary table, ``summary.parquet`` and
``summary.md`` (columns in :data:`SUMMARY_COLUMNS`). The estimate of a log is exactly
``Pipeline(vehicle, config).run(read_log(log))``: every task is independent and runs the
same code on the same input, so the arrays are bit-identical to a single run whatever the
scheduler and the number of workers.

Schedulers (:func:`open_runner`): ``None`` / ``"local"`` starts a ``dask.distributed``
``LocalCluster`` of ``n_workers`` processes with one thread each (and one Numba thread);
``"tcp://host:port"`` (any address ``distributed.Client`` accepts) uses a running cluster,
whose workers must have vestim installed and see the log paths; ``"synchronous"`` runs
the tasks one after the other in this process, without Dask (tests, debugging, one core).
Dask is the optional extra ``vestim[batch]``; without it the Dask schedulers raise
:class:`~vestim.errors.MissingDependencyError`. As with any spawned worker processes, a
script that starts a local cluster must do so under ``if __name__ == "__main__":``.

Resuming: each output stores, in its Parquet metadata, ``vestim.batch_key``, a SHA-256
of the input file's bytes, the vehicle's parameters, the pipeline configuration (and the
gains file it names), the vestim version and vestim's own source files, plus its summary
row. A log whose output carries the key of this run is *skipped* (its stored summary row
is reused); any change of input, vehicle, configuration or vestim code recomputes it.
Outputs are written atomically, so an output that exists is complete. ``force=True``
(``--force``) recomputes everything (e.g. after upgrading NumPy or Numba).

Raw recordings (``--map``): MDF4 files, ROS 2 bags (and, with a tabular map, CSV/Parquet
sources) are imported through a channel map (:func:`vestim.io.channel_map.apply_channel_map`)
inside their task; several maps may be given, one per source kind (``[source] kind``, or a
map without one for every kind). The key then also covers the map and its DBC files. A raw
recording without a map is refused: "a raw recording needs a map (--map)". A folder scan
skips vestim's own outputs (estimates and summaries, recognised by their metadata or their
``_estimate`` suffix).

Interrupting (Ctrl-C) raises :class:`BatchInterrupted` naming the logs that finished; their
outputs are complete and are skipped when the same command runs again. A local cluster's
scratch space (Dask's ``dask-scratch-space``) lives in a temporary folder removed on exit.

Input checks: every log goes through :func:`vestim.io.sanity.gate`, the gate of ``vestim
estimate``: a log it refuses (a yaw rate with the wrong sign, ax in g, …) fails with the
gate's message, and an estimate's metadata holds the gate's ``warnings`` and
``checks_not_run``, as ``vestim estimate`` writes them.

Failures: a log that cannot be read, has bad columns, fails the input gate or whose vehicle
cannot be found does not stop the others; its row has ``status = "failed"`` and the error
message.

Vehicles: one vehicle (a TOML path, a built-in name or a :class:`~vestim.io.vehicle.Vehicle`)
for all logs; ``"auto"`` to find each log's own vehicle with :func:`vehicle_for_log`; or a
callable ``log path -> vehicle``.
"""

from __future__ import annotations

import dataclasses
import functools
import hashlib
import json
import logging
import math
import os
import tempfile
import time
from collections.abc import Callable, Iterable, Iterator, Sequence
from contextlib import contextmanager
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd
import pyarrow as pa
import pyarrow.parquet as pq

from vestim.constants import CORNERS
from vestim.errors import (
    LogFormatError,
    MissingDependencyError,
    VehicleFileError,
    VestimError,
    optional_import,
)
from vestim.io import load_vehicle, read_log, write_log
from vestim.io.files import atomic_path, write_text_atomic
from vestim.io.log import METADATA_PREFIX
from vestim.io.sanity import gate
from vestim.io.vehicle import BUILTIN_VEHICLES, Vehicle
from vestim.metrics import score
from vestim.pipeline import Pipeline, PipelineConfig
from vestim.pipeline.provenance import estimate_metadata

__all__ = [
    "AUTO",
    "SUMMARY_COLUMNS",
    "SYNCHRONOUS",
    "BatchError",
    "BatchInterrupted",
    "BatchSummary",
    "TaskRunner",
    "collect_logs",
    "is_raw",
    "is_vestim_output",
    "map_for",
    "map_tasks",
    "open_runner",
    "output_path",
    "run_batch",
    "summary_markdown",
    "vehicle_for_log",
]

SYNCHRONOUS = "synchronous"
"""Scheduler name: run every task in this process, in order, without Dask."""
AUTO = "auto"
"""Vehicle name: find each log's vehicle with :func:`vehicle_for_log`."""
LOG_SUFFIXES = (".parquet", ".pq", ".csv")
"""Files a directory argument contributes (not recursive)."""
RAW_SUFFIXES = (".mf4", ".mdf", ".db3", ".mcap")
"""Raw recordings a directory argument also contributes when a map is given (with ROS 2 bag
folders, those holding a ``metadata.yaml``)."""
OUTPUT_SUFFIX = "_estimate"
"""Stem suffix of the estimates :func:`run_batch` writes (:func:`output_path`)."""
BATCH_FORMAT = "1"
"""Version of the key and summary-row layout stored in the outputs (part of the key)."""

SCORED = ("vx", "vy", "fx", "fy", "fz")
"""Channel families scored when the log has ``ref_`` channels: NRMS of vx and vy and of the
worst corner of fx, fy, fz (:func:`vestim.metrics.score`)."""

_CG_SCORED = ("vx", "vy")
_CORNER_SCORED = ("fx", "fy", "fz")

SUMMARY_COLUMNS: tuple[str, ...] = (
    "log", "status", "error", "output", "vehicle", "samples", "wall_s",
    *(f"nrms_{c}_pct" for c in SCORED), "valid_fraction", "valid_columns",
)
"""Columns of the summary table, one row per log in input order:

- ``log``: input path; ``status``: ``ok`` (estimated now), ``skipped`` (output of this key
  already there) or ``failed``; ``error``: the message of a failed log ("" otherwise);
- ``output``: the estimate's path ("" if failed); ``vehicle``: the vehicle used (path or name);
- ``samples``: rows of the estimate (0 if failed); ``wall_s``: seconds this run spent on the
  log in its worker (read, estimate, score, write; for a skipped log the check);
- ``nrms_<c>_pct``: 100·NRMS (000 Sec. IV, floors of :data:`vestim.metrics.FLOORS`) of vx,
  vy and the worst corner of fx, fy, fz against the log's ``ref_`` channels; NaN without them;
- ``valid_fraction``: share of samples where every ``valid_*`` column of the estimate is
  non-zero, NaN when the estimate has none; ``valid_columns``: how many it has.
"""


class BatchError(VestimError, ValueError):
    """A batch that cannot start: no logs, clashing output names, an unknown scheduler."""


class BatchInterrupted(VestimError, KeyboardInterrupt):  # noqa: N818 - a KeyboardInterrupt
    """The batch was interrupted (Ctrl-C); ``finished`` lists the logs whose outputs this run
    wrote (complete, skipped when the same command runs again), ``total`` the logs asked for."""

    def __init__(self, finished: list[str], total: int, out_dir: Path) -> None:
        self.finished, self.total, self.out_dir = finished, total, out_dir
        names = ", ".join(Path(f).name for f in finished[:10]) + (" …" if len(finished) > 10 else "")
        super().__init__(
            f"interrupted: {len(finished)} of {total} logs finished"
            + (f" ({names})" if finished else "")
            + f"; their estimates in {out_dir} are complete. Run the same command again to "
            "resume: finished logs are skipped")


# ---------------------------------------------------------------------------- task map

def _star(fn: Callable[..., Any], args: Sequence[Any]) -> Any:
    return fn(*args)


class TaskRunner:
    """Maps a function over items on a Dask client, or in this process without one."""

    def __init__(self, client: Any | None = None) -> None:
        self.client = client

    @property
    def dashboard_link(self) -> str | None:
        """The Dask dashboard's address (None in-process)."""
        return None if self.client is None else str(self.client.dashboard_link)

    @property
    def n_workers(self) -> int:
        """Workers the tasks run on (1 in-process)."""
        if self.client is None:
            return 1
        return len(self.client.scheduler_info().get("workers", {}))

    def map(self, fn: Callable[..., Any], items: Iterable[Any], *, star: bool = False,
            progress: Callable[[int, int], None] | None = None) -> list[Any]:
        """``fn(item)`` (``fn(*item)`` with ``star``) for every item; results in item order.

        ``fn`` and the items must pickle (Dask ships them to the workers); a function of an
        importable module travels by name. ``progress(done, total)`` is called after each
        finished task, in completion order. An exception of a task propagates (the other
        tasks are cancelled).
        """
        jobs = list(items)
        call: Callable[..., Any] = (lambda item: fn(*item)) if star else fn
        total = len(jobs)
        if self.client is None:
            out = []
            for i, item in enumerate(jobs):
                out.append(call(item))
                if progress is not None:
                    progress(i + 1, total)
            return out
        distributed = optional_import("distributed", "batch", "Dask scheduling")
        if star:
            futures = self.client.map(_star, [fn] * total, jobs, pure=False)
        else:
            futures = self.client.map(fn, jobs, pure=False)
        try:
            for done, _ in enumerate(distributed.as_completed(futures), start=1):
                if progress is not None:
                    progress(done, total)
            return list(self.client.gather(futures))
        finally:
            self.client.cancel(futures)


@contextmanager
def open_runner(scheduler: str | None = None, n_workers: int = 2, *,
                connect_timeout: float = 10.0, dashboard: bool = False) -> Iterator[TaskRunner]:
    """A :class:`TaskRunner` for the scheduler, closed (cluster stopped) on exit.

    Args:
        scheduler: ``None`` or ``"local"``: a new ``LocalCluster`` of ``n_workers`` worker
            processes, one thread each, ``NUMBA_NUM_THREADS=1``, its scratch space in a
            temporary folder removed on exit; ``"synchronous"``: this process, no Dask;
            anything else: the address of a running Dask scheduler (``tcp://host:8786``).
        n_workers: worker processes of the local cluster (>= 1).
        connect_timeout: seconds to wait for a scheduler given by address.
        dashboard: serve the local cluster's dashboard (on a free port; needs bokeh).

    Raises:
        MissingDependencyError: dask.distributed is not installed (``vestim[batch]``); the
            message says that ``scheduler="synchronous"`` works without it.
        BatchError: ``n_workers`` < 1, or the scheduler cannot be reached.
    """
    if scheduler == SYNCHRONOUS:
        yield TaskRunner(None)
        return
    try:
        distributed = optional_import("distributed", "batch", "Parallel batches (vestim[batch])")
    except MissingDependencyError as exc:
        raise MissingDependencyError(f"{exc}; or run the logs one after the other in this process "
                                     "with --scheduler synchronous (scheduler=\"synchronous\"), "
                                     "which needs no Dask") from None
    if scheduler in (None, "local"):
        if n_workers < 1:
            raise BatchError(f"n_workers = {n_workers}: use at least 1 worker process")
        import dask

        scratch = tempfile.TemporaryDirectory(prefix="vestim-dask-")
        # Dask puts its dask-scratch-space in its temporary-directory (the system's temp folder
        # by default) and leaves it behind: point it, and the workers, into ours.
        config = dask.config.set({"temporary-directory": scratch.name})
        try:
            try:
                cluster = distributed.LocalCluster(
                    n_workers=n_workers, threads_per_worker=1, processes=True,
                    dashboard_address=":0" if dashboard else None, local_directory=scratch.name,
                    silence_logs=logging.ERROR,
                    env={"NUMBA_NUM_THREADS": "1", "OMP_NUM_THREADS": "1", "MKL_NUM_THREADS": "1",
                         "OPENBLAS_NUM_THREADS": "1"})
            except RuntimeError as exc:
                raise BatchError(
                    f"the local Dask cluster did not start ({exc}); a script that starts one must "
                    "do so under `if __name__ == \"__main__\":` (worker processes are spawned and "
                    "import the script), or use scheduler=\"synchronous\"") from None
            try:
                with distributed.Client(cluster) as client:
                    yield TaskRunner(client)
            finally:
                cluster.close()
        finally:
            config.__exit__(None, None, None)
            scratch.cleanup()
        return
    try:
        client = distributed.Client(scheduler, timeout=f"{connect_timeout}s")
    except (OSError, TimeoutError, ValueError) as exc:
        raise BatchError(f"cannot connect to the Dask scheduler {scheduler!r}: {exc}; start one "
                         "(`dask scheduler` and `dask worker ADDRESS`), or leave --scheduler out "
                         "for a local cluster") from None
    with client:
        yield TaskRunner(client)


def map_tasks(fn: Callable[..., Any], items: Iterable[Any], *, scheduler: str | None = None,
              n_workers: int = 2, star: bool = False,
              progress: Callable[[int, int], None] | None = None) -> list[Any]:
    """``fn(item)`` for every item on the scheduler of :func:`open_runner`; results in item
    order. Opens and closes a cluster; for several maps use one :func:`open_runner`."""
    with open_runner(scheduler, n_workers) as runner:
        return runner.map(fn, items, star=star, progress=progress)


# ---------------------------------------------------------------------------- inputs

def is_raw(path: Path) -> bool:
    """True for a raw recording (MDF4 file, ROS 2 bag file or folder, numpy folder): a source
    that only a channel map turns into a log."""
    return path.is_dir() or path.suffix.lower() in RAW_SUFFIXES


def is_vestim_output(path: Path) -> bool:
    """True for a file vestim wrote as an output: an estimate (``vestim estimate``, ``vestim
    batch``: its Parquet metadata names the pipeline's stages, or its stem ends in
    ``_estimate``) or a batch summary."""
    if path.stem.endswith(OUTPUT_SUFFIX) or path.name in ("summary.parquet", "summary.md"):
        return True
    if path.suffix.lower() not in (".parquet", ".pq"):
        return False
    try:
        meta = pq.read_schema(path).metadata or {}
    except (pa.ArrowException, OSError):
        return False
    keys = {(METADATA_PREFIX + k).encode() for k in ("velocity", "fusion", "batch_wall_s")}
    return bool(keys & set(meta))


def collect_logs(paths: Iterable[str | os.PathLike[str]],
                 exclude: str | os.PathLike[str] | None = None, *, raw: bool = False) -> list[Path]:
    """The logs named by files and directories, in the given order (directories sorted).

    A file is taken as it is (a wrong extension fails later, as that log's error); a
    directory contributes its ``*.parquet``, ``*.pq`` and ``*.csv`` files (not recursive)
    but not vestim's own outputs (:func:`is_vestim_output`); with ``raw`` (a map is given)
    also its ``*.mf4``, ``*.mdf``, ``*.db3``, ``*.mcap`` files and ROS 2 bag folders. The
    directory ``exclude`` (the output folder) is never scanned.

    Raises:
        BatchError: a path that does not exist, a raw recording without ``raw`` ("a raw
            recording needs a map"), or no log at all.
    """
    out: list[Path] = []
    skip = Path(exclude).resolve() if exclude is not None else None
    suffixes = LOG_SUFFIXES + (RAW_SUFFIXES if raw else ())
    for arg in paths:
        p = Path(arg)
        if p.is_dir() and not (p / "metadata.yaml").is_file():
            if skip is not None and p.resolve() == skip:
                continue
            for f in sorted(p.iterdir()):
                log_file = f.is_file() and f.suffix.lower() in suffixes and not is_vestim_output(f)
                if log_file or (raw and f.is_dir() and (f / "metadata.yaml").is_file()):
                    out.append(f)
        elif p.exists():
            if is_raw(p) and not raw:
                raise BatchError(f"{p}: a raw recording needs a map (--map MAP.toml, "
                                 "docs/channel-map.md) to be read as a drive log")
            out.append(p)
        else:
            raise BatchError(f"{p}: no such file or directory; give log files (.parquet, .csv) "
                             "or folders holding them")
    if not out:
        raise BatchError("no logs found: the folders hold no "
                         + (".parquet, .pq, .csv, .mf4, .mdf, .db3, .mcap files or bag folders"
                            if raw else ".parquet, .pq or .csv files"))
    return out


def output_path(log: str | os.PathLike[str], out_dir: str | os.PathLike[str]) -> Path:
    """Where :func:`run_batch` writes the estimate of ``log``: ``<out_dir>/<stem>_estimate.parquet``."""
    return Path(out_dir) / f"{Path(log).stem}{OUTPUT_SUFFIX}.parquet"


def _parquet_metadata(path: Path) -> dict[bytes, bytes]:
    try:
        return dict(pq.read_schema(path).metadata or {})
    except (pa.ArrowException, OSError) as exc:
        raise LogFormatError(f"{path}: cannot be read as PARQUET: {exc}") from exc


def vehicle_for_log(log: str | os.PathLike[str]) -> str:
    """The vehicle of a log, by the first rule that applies (``--vehicle auto``):

    1. a TOML with the log's stem next to it (``run7.parquet`` → ``run7.toml``);
    2. the crossplant convention: the Parquet schema metadata ``drive_log`` (JSON) names a
       ``vehicle_file`` in the log's folder;
    3. the crossplant ``manifest.json`` in the log's folder: ``maneuvers.<stem>.vehicle_file``
       (also for CSV copies of those logs);
    4. vestim's simulator logs: the Parquet metadata ``vestim.vehicle`` names a built-in
       vehicle (``vestim simulate`` writes it).

    Returns:
        A TOML path or a built-in vehicle name, for :func:`~vestim.io.load_vehicle`.

    Raises:
        VehicleFileError: no rule applies, or a named vehicle file does not exist.
        LogFormatError: a Parquet log whose metadata cannot be read.
    """
    p = Path(log)
    own = p.with_suffix(".toml")
    if own.is_file():
        return str(own)
    meta = _parquet_metadata(p) if p.suffix.lower() in (".parquet", ".pq") else {}
    named: list[tuple[str, str]] = []
    if b"drive_log" in meta:
        try:
            info = json.loads(meta[b"drive_log"])
        except ValueError:
            info = {}
        if isinstance(info, dict) and isinstance(info.get("vehicle_file"), str):
            named.append(("its drive_log metadata", info["vehicle_file"]))
    manifest = p.parent / "manifest.json"
    if not named and manifest.is_file():
        try:
            entry = json.loads(manifest.read_text(encoding="utf-8"))["maneuvers"][p.stem]
            named.append((str(manifest), str(entry["vehicle_file"])))
        except (ValueError, KeyError, TypeError):
            pass
    for where, name in named:
        f = p.parent / name
        if not f.is_file():
            raise VehicleFileError(f"{p}: {where} names the vehicle file {name!r}, but {f} does "
                                   "not exist; put it there or pass --vehicle FILE")
        return str(f)
    sim = meta.get((METADATA_PREFIX + "vehicle").encode(), b"").decode(errors="replace")
    if sim in BUILTIN_VEHICLES:
        return sim
    raise VehicleFileError(
        f"{p}: cannot tell which vehicle this log is from: no {own.name} next to it, no "
        "vehicle_file in its drive_log metadata or in a manifest.json beside it, no built-in "
        "vestim.vehicle metadata; pass --vehicle FILE (or a built-in name) for all logs")


# ---------------------------------------------------------------------------- keys

def _canonical(obj: Any) -> Any:
    """JSON-able form of parameters, the same in every process (sets sorted, floats exact)."""
    if dataclasses.is_dataclass(obj) and not isinstance(obj, type):
        return {"__type__": type(obj).__name__,
                **{f.name: _canonical(getattr(obj, f.name)) for f in dataclasses.fields(obj)}}
    if isinstance(obj, dict):
        return {str(k): _canonical(v) for k, v in sorted(obj.items(), key=lambda kv: str(kv[0]))}
    if isinstance(obj, set | frozenset):
        return sorted((_canonical(v) for v in obj), key=repr)
    if isinstance(obj, list | tuple):
        return [_canonical(v) for v in obj]
    if isinstance(obj, np.ndarray):
        return [_canonical(v) for v in obj.tolist()]
    if isinstance(obj, float | np.floating):
        return float(obj).hex()
    if isinstance(obj, bool | int | str) or obj is None:
        return obj
    if isinstance(obj, np.integer):
        return int(obj)
    return repr(obj)


def _file_digest(path: Path) -> str:
    h = hashlib.sha256()
    with open(path, "rb") as f:
        for block in iter(lambda: f.read(1 << 20), b""):
            h.update(block)
    return h.hexdigest()


@functools.cache
def _code_digest() -> str:
    """SHA-256 of vestim's own source files (this process's copy), read once per process."""
    root = Path(__file__).resolve().parent
    h = hashlib.sha256()
    for f in sorted(root.rglob("*.py")):
        h.update(f.relative_to(root).as_posix().encode())
        h.update(f.read_bytes())
    return h.hexdigest()


def _input_digest(path: Path) -> str:
    """SHA-256 of a file, or of a folder's files (a ROS 2 bag) by relative name and content."""
    if not path.is_dir():
        return _file_digest(path)
    h = hashlib.sha256()
    for f in sorted(q for q in path.rglob("*") if q.is_file()):
        h.update(f.relative_to(path).as_posix().encode())
        h.update(_file_digest(f).encode())
    return h.hexdigest()


def _job_key(log: Path, vehicle: Vehicle, config: PipelineConfig, channel_map: str | None = None
             ) -> str:
    from vestim import __version__

    parts: dict[str, Any] = {
             "format": BATCH_FORMAT, "vestim": __version__, "code": _code_digest(),
             "input": _input_digest(log),
             "vehicle": _canonical(vehicle), "config": _canonical(config)}
    if config.gains:
        gains = Path(config.gains)
        parts["gains"] = _file_digest(gains) if gains.is_file() else "missing"
    if channel_map is not None:  # the map and the DBC files it names decide the imported log
        from vestim.io.channel_map import load_channel_map

        cmap = load_channel_map(channel_map)
        parts["map"] = [_file_digest(Path(channel_map)),
                        *(_file_digest(d) if d.is_file() else "missing" for d in cmap.dbc)]
    text = json.dumps(parts, sort_keys=True, separators=(",", ":"))
    return hashlib.sha256(text.encode()).hexdigest()


_KEY = METADATA_PREFIX + "batch_key"
_ROW = METADATA_PREFIX + "batch_row"


def _stored_row(out: Path, key: str) -> dict[str, Any] | None:
    """The summary row stored in ``out`` when it was made with ``key``; else None."""
    if not out.is_file():
        return None
    try:
        meta = pq.read_schema(out).metadata or {}
        if meta.get(_KEY.encode(), b"").decode() != key:
            return None
        row = json.loads(meta[_ROW.encode()])
        if pq.read_metadata(out).num_rows != row["samples"]:
            return None
    except (pa.ArrowException, OSError, KeyError, ValueError, TypeError):
        return None  # unreadable or foreign: recompute (the new output replaces it atomically)
    return row if isinstance(row, dict) else None


# ---------------------------------------------------------------------------- one log

def _import(path: Path, channel_map: str, wheel_radius: float) -> tuple[pd.DataFrame, dict[str, str]]:
    """A raw recording through its channel map, checked as a log to estimate; the log and the
    import's metadata (``import.*``: map, clock offset, gaps, mounting)."""
    from vestim.io.channel_map import apply_channel_map, load_channel_map
    from vestim.io.log import validate_log

    log, report = apply_channel_map(path, load_channel_map(channel_map))
    validate_log(log, require=["measured"], wheel_radius=wheel_radius,
                 source=f"{path} (through {channel_map})")
    return log, report.metadata()


def map_for(path: Path, maps: Sequence[tuple[str, str | None]]) -> str | None:
    """The map of ``(map path, [source] kind)`` pairs that applies to ``path``: the one of its
    source kind, else the one without a kind; None for a spec log (CSV/Parquet) no map claims.

    Raises:
        BatchError: a raw recording no map applies to, or several that do.
    """
    from vestim.io.readers import source_kind

    kind = source_kind(path)
    fits = [m for m, k in maps if k == kind] or [m for m, k in maps if k is None]
    if kind == "tabular" and not [m for m, k in maps if k == kind]:
        return None  # a CSV/Parquet beside raw files is a spec log unless a map says kind = tabular
    if not fits:
        raise BatchError(f"{path}: a raw recording needs a map (--map) for {kind} sources; the "
                         "maps given are for " + ", ".join(sorted({k or "any" for _, k in maps})))
    if len(fits) > 1:
        raise BatchError(f"{path}: {len(fits)} maps apply to its kind ({kind}): "
                         f"{', '.join(fits)}; give each map's [source] kind")
    return fits[0]


@dataclass(frozen=True)
class _Job:
    log: str
    vehicle: str | Vehicle
    config: PipelineConfig
    out: str
    force: bool
    channel_map: str | None = None


def _scores(est: pd.DataFrame, log: pd.DataFrame) -> dict[str, float]:
    """100·NRMS of vx, vy and of the worst corner of fx, fy, fz; NaN where no reference."""
    res = {f"nrms_{c}_pct": math.nan for c in SCORED}
    family = {**{c: c for c in _CG_SCORED},
              **{f"{f}_{c}": f for f in _CORNER_SCORED for c in CORNERS}}
    names = [c for c in est.columns if c in family and f"ref_{c}" in log.columns]
    if not names:
        return res
    table = score(est, log, channels=names)
    for name, value in zip(table["channel"], table["nrms_pct"], strict=True):
        key = f"nrms_{family[name]}_pct"
        res[key] = float(value) if math.isnan(res[key]) else max(res[key], float(value))
    return res


def _validity(est: pd.DataFrame) -> dict[str, float | int]:
    cols = [c for c in est.columns if c.startswith("valid_")]
    if not cols:
        return {"valid_fraction": math.nan, "valid_columns": 0}
    ok = np.all(est[cols].to_numpy(dtype=float) != 0.0, axis=1)
    return {"valid_fraction": float(ok.mean()), "valid_columns": len(cols)}


def _empty_row(log: str, vehicle: str) -> dict[str, Any]:
    return {"log": log, "status": "failed", "error": "", "output": "", "vehicle": vehicle,
            "samples": 0, "wall_s": 0.0, **{f"nrms_{c}_pct": math.nan for c in SCORED},
            "valid_fraction": math.nan, "valid_columns": 0}


def _vehicle_label(vehicle: str | Vehicle) -> str:
    return vehicle.name if isinstance(vehicle, Vehicle) else str(vehicle)


def _run_one(job: _Job) -> dict[str, Any]:
    """Estimate one log (a Dask task): its summary row; errors become a failed row."""
    t0 = time.perf_counter()
    row = _empty_row(job.log, _vehicle_label(job.vehicle))
    path, out = Path(job.log), Path(job.out)
    try:
        veh = job.vehicle if isinstance(job.vehicle, Vehicle) else load_vehicle(job.vehicle)
        key = _job_key(path, veh, job.config, job.channel_map)
        stored = None if job.force else _stored_row(out, key)
        if stored is not None:
            row.update({k: stored[k] for k in row if k in stored})
            row.update(status="skipped", error="", log=job.log, output=job.out,
                       vehicle=_vehicle_label(job.vehicle), wall_s=time.perf_counter() - t0)
            return row
        imported: dict[str, str] = {}
        if job.channel_map is None:
            log = read_log(path, require=["measured"], wheel_radius=veh.body.wheel_radius)
        else:
            log, imported = _import(path, job.channel_map, veh.body.wheel_radius)
        checked = gate(log, veh, source=job.log)  # the input gate of `vestim estimate`
        pipe = Pipeline(veh, job.config)
        est = pipe.run(log)
        row.update(status="ok", output=job.out, samples=len(est), **_scores(est, log),
                   **_validity(est))
        row["wall_s"] = time.perf_counter() - t0
        meta = {**estimate_metadata(pipe, job.vehicle, source=job.log, checked=checked,
                                    log_attrs={**log.attrs, **imported},
                                    map_path=job.channel_map),
                "batch_key": key,
                "batch_row": json.dumps({k: v for k, v in row.items()
                                         if k not in ("log", "output", "status", "error")})}
        write_log(est, out, metadata=meta, float32=True)  # as `vestim estimate` writes
    except Exception as exc:  # one bad log must not stop the batch: its row says why
        msg = str(exc) if isinstance(exc, VestimError) else f"{type(exc).__name__}: {exc}"
        row = _empty_row(job.log, _vehicle_label(job.vehicle))
        row.update(error=msg, wall_s=time.perf_counter() - t0)
    row["wall_s"] = time.perf_counter() - t0
    return row


# ---------------------------------------------------------------------------- batch

@dataclass(frozen=True)
class BatchSummary:
    """What :func:`run_batch` did.

    Attributes:
        table: one row per log, in input order, columns :data:`SUMMARY_COLUMNS`.
        summary_parquet, summary_md: the files the table was written to.
        wall_s: wall-clock seconds of the whole batch (cluster start included).
        workers: worker processes the tasks ran on (1 for ``"synchronous"``).
    """

    table: pd.DataFrame
    summary_parquet: Path
    summary_md: Path
    wall_s: float
    workers: int

    def count(self, status: str) -> int:
        """Number of logs with this status (ok, skipped, failed)."""
        return int((self.table["status"] == status).sum())

    @property
    def failed(self) -> bool:
        """True when any log failed (``vestim batch`` then exits with status 1)."""
        return self.count("failed") > 0


VehicleArg = str | os.PathLike[str] | Vehicle | Callable[[Path], "str | os.PathLike[str] | Vehicle"]


def run_batch(
    logs: Sequence[str | os.PathLike[str]],
    vehicle: VehicleArg,
    out_dir: str | os.PathLike[str],
    *,
    config: PipelineConfig | None = None,
    scheduler: str | None = None,
    n_workers: int = 2,
    force: bool = False,
    progress: Callable[[int, int], None] | None = None,
    maps: Sequence[str | os.PathLike[str]] = (),
    dashboard: Callable[[str], None] | None = None,
) -> BatchSummary:
    """Estimate every log (one Dask task each); write the estimates and the summary.

    Args:
        logs: log files (``.parquet``, ``.pq``, ``.csv``; see :func:`collect_logs` for
            folders); only read.
        vehicle: a vehicle TOML path or built-in name, or a :class:`Vehicle`, for every log;
            ``"auto"`` for :func:`vehicle_for_log`; or a callable giving a log's vehicle.
        out_dir: output folder (created): ``<stem>_estimate.parquet`` per log,
            ``summary.parquet`` and ``summary.md``.
        config: the pipeline configuration of every log (default :class:`PipelineConfig`).
        scheduler: see :func:`open_runner` (default: a local cluster).
        n_workers: worker processes of a local cluster.
        force: recompute logs whose output is up to date.
        progress: ``progress(done, total)`` after each finished log.
        maps: channel maps (TOML) through which raw recordings are imported, one per source
            kind (:func:`map_for`); their DBC paths are taken from the map's folder.
        dashboard: called with the Dask dashboard's address once the cluster is up (a
            local cluster then serves one); None: no dashboard.

    Returns:
        The summary; failed logs are rows with ``status = "failed"``, never exceptions.

    Raises:
        BatchError: no logs, two logs with the same stem (same output), an output that would
            overwrite an input, or a scheduler that cannot be used. ChannelMapError: an invalid
            map. MissingDependencyError: Dask missing for a Dask scheduler. BatchInterrupted:
            Ctrl-C (what finished is named).
    """
    t0 = time.perf_counter()
    cfg = config or PipelineConfig()
    out = Path(out_dir)
    paths = [Path(p) for p in logs]
    if not paths:
        raise BatchError("no logs to run; give log files or folders holding them")
    seen: dict[Path, Path] = {}
    for p in paths:
        o = output_path(p, out)
        if o in seen:
            raise BatchError(f"{seen[o]} and {p} would both write {o} (same file stem); rename "
                             "one or run them into different --out folders")
        seen[o] = p
    _refuse_overwriting_inputs(paths, [*seen, out / "summary.parquet", out / "summary.md"])
    from vestim.io.channel_map import load_channel_map

    map_kinds = [(str(m), load_channel_map(m).kind) for m in maps]
    rows: dict[int, dict[str, Any]] = {}
    jobs: list[tuple[int, _Job]] = []
    for i, p in enumerate(paths):
        try:
            cmap = map_for(p, map_kinds) if map_kinds else None
            if cmap is None and is_raw(p):
                raise BatchError(f"{p}: a raw recording needs a map (--map MAP.toml, "
                                 "docs/channel-map.md) to be read as a drive log")
            if callable(vehicle) and not isinstance(vehicle, Vehicle):
                veh: str | Vehicle = _as_vehicle_arg(vehicle(p))
            elif isinstance(vehicle, Vehicle):
                veh = vehicle
            elif str(vehicle) == AUTO:
                veh = vehicle_for_log(p)
            else:
                veh = str(vehicle)
        except Exception as exc:  # the vehicle of one log is unknown: that log fails
            row = _empty_row(str(p), "")
            row["error"] = str(exc) if isinstance(exc, VestimError) else f"{type(exc).__name__}: {exc}"
            rows[i] = row
            continue
        jobs.append((i, _Job(str(p), veh, cfg, str(output_path(p, out)), force, cmap)))
    # Largest inputs first: the last task to start is a short one (better balance).
    jobs.sort(key=lambda ij: -_size(Path(ij[1].log)))
    total = len(paths)
    done0 = len(rows)
    if progress is not None and done0:
        progress(done0, total)
    step = None if progress is None else (lambda d, _n: progress(done0 + d, total))
    workers = 1
    if jobs:
        started = time.time()
        try:
            with open_runner(scheduler, n_workers, dashboard=dashboard is not None) as runner:
                workers = runner.n_workers
                if dashboard is not None and runner.dashboard_link:
                    dashboard(runner.dashboard_link)
                results = runner.map(_run_one, [j for _, j in jobs], progress=step)
        except KeyboardInterrupt:
            finished = [j.log for _, j in jobs if _written_since(Path(j.out), started)]
            raise BatchInterrupted(finished, total, out) from None
        rows.update({i: r for (i, _), r in zip(jobs, results, strict=True)})
    table = pd.DataFrame([rows[i] for i in range(total)], columns=list(SUMMARY_COLUMNS))
    table["samples"] = table["samples"].astype("int64")
    table["valid_columns"] = table["valid_columns"].astype("int64")
    wall = time.perf_counter() - t0
    pq_path, md_path = _write_summary(table, out, wall, workers, scheduler)
    return BatchSummary(table, pq_path, md_path, wall, workers)


def _written_since(path: Path, since: float) -> bool:
    try:
        return path.stat().st_mtime >= since - 1.0
    except OSError:
        return False


def _refuse_overwriting_inputs(inputs: Sequence[Path], outputs: Sequence[Path]) -> None:
    """Raise BatchError when an output would replace an input (also through a link)."""
    resolved = {p.resolve(): p for p in inputs}
    for o in outputs:
        src = resolved.get(o.resolve())
        if src is not None:
            raise BatchError(f"the output {o} would overwrite the input {src}; vestim never "
                             "overwrites its inputs: give another --out folder (or rename the "
                             "input)")


def _as_vehicle_arg(v: Any) -> str | Vehicle:
    return v if isinstance(v, Vehicle) else str(v)


def _size(p: Path) -> int:
    try:
        return p.stat().st_size
    except OSError:
        return 0


def _write_summary(table: pd.DataFrame, out: Path, wall: float, workers: int,
                   scheduler: str | None) -> tuple[Path, Path]:
    pq_path = out / "summary.parquet"
    md_path = out / "summary.md"
    arrow = pa.Table.from_pandas(table, preserve_index=False)
    arrow = arrow.replace_schema_metadata({
        **(arrow.schema.metadata or {}),
        (METADATA_PREFIX + "batch_wall_s").encode(): f"{wall:.3f}".encode(),
        (METADATA_PREFIX + "batch_workers").encode(): str(workers).encode(),
    })
    with atomic_path(pq_path) as tmp:
        pq.write_table(arrow, tmp)
    write_text_atomic(md_path, summary_markdown(table, wall=wall, workers=workers,
                                                scheduler=scheduler))
    return pq_path, md_path


def _cell(v: Any, digits: int = 2) -> str:
    if isinstance(v, float):
        return "–" if math.isnan(v) else f"{v:.{digits}f}"
    return str(v).replace("|", "\\|").replace("\n", " ")


def summary_markdown(table: pd.DataFrame, *, wall: float, workers: int,
                     scheduler: str | None) -> str:
    """The summary table as Markdown: counts, one row per log, then the errors in full."""
    counts = {s: int((table["status"] == s).sum()) for s in ("ok", "skipped", "failed")}
    if scheduler in (None, "local"):
        where = f"a local cluster of {workers} worker process(es)"
    elif scheduler == SYNCHRONOUS:
        where = "this process (synchronous)"
    else:
        where = f"the Dask cluster at {scheduler} ({workers} workers)"
    lines = ["# vestim batch summary", "",
             f"{len(table)} logs: {counts['ok']} ok, {counts['skipped']} skipped (up to date), "
             f"{counts['failed']} failed; {wall:.1f} s wall time on {where}.", "",
             "NRMS in % (000 Sec. IV) against the log's `ref_` channels: vx, vy, and the worst "
             "corner of fx, fy, fz; – where the log has no reference. valid: share of samples "
             "with every `valid_*` column set (– when the estimate has none).", "",
             "| log | status | samples | wall s | vx | vy | fx | fy | fz | valid |",
             "|---|---|---|---|---|---|---|---|---|---|"]
    for d in table.to_dict("records"):
        lines.append("| " + " | ".join([
            _cell(Path(d["log"]).name), d["status"], str(d["samples"]), _cell(d["wall_s"]),
            *(_cell(d[f"nrms_{c}_pct"]) for c in SCORED), _cell(d["valid_fraction"], 3)]) + " |")
    failed = table[table["status"] == "failed"]
    if len(failed):
        lines += ["", "## Failed", ""]
        lines += [f"- `{r.log}`: {_cell(r.error)}" for r in failed.itertuples(index=False)]
    return "\n".join([*lines, ""])
