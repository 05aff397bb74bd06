"""``vestim calibrate``: identify the car's sensors, body and tires from its own logs (issue 13).

:func:`calibrate` runs the identifications in the order each needs the last one's result:

1. IMU biases, accelerometer scale and mounting (:func:`.sensors.identify_imu`);
2. wheel radii, relative from straight free rolling, absolute with ``gnss_speed``
   (:func:`.sensors.identify_wheels`), on logs with the IMU corrected;
3. steering ratio, offset and understeer gradient (:func:`.sensors.identify_steering`);
4. roll and pitch gradients (:func:`.body_tire.identify_body`);
5. axle cornering and slip stiffness and the lumped LuGre values
   (:func:`.body_tire.identify_tires`), on logs with every sensor correction applied.

Logs are read without their ``ref_`` channels: calibration uses only what a production car
measures. :func:`write_calibrated` writes ``CAR.toml`` (the base file with the excited LuGre
values of the tire itself in ``[tire]`` — not μ_s, μ_c, v_s, which belong to the road — and
the ``[calibration.*]`` tables, :mod:`vestim.io.calibration`), and
:func:`write_report` a Markdown report with one PNG.
"""

from __future__ import annotations

import math
import os
import time
import tomllib
from collections.abc import Callable, Sequence
from dataclasses import dataclass, replace
from pathlib import Path

import pandas as pd

from vestim.design.calibrate.select import Fold, couple, decide, nominal_values
from vestim.errors import LogFormatError
from vestim.io.calibration import (
    KEYS,
    LUGRE_KEYS,
    Calibration,
    Identified,
    calibration_toml,
    corrected_log,
    toml_value,
)
from vestim.io.files import atomic_path, write_text_atomic
from vestim.io.log import read_log
from vestim.io.sanity import GateReport, gate
from vestim.io.vehicle import Vehicle, load_vehicle

__all__ = ["CalibrationResult", "Identified", "calibrate", "write_calibrated", "write_report"]

GROUP_OF = {key: group for group, keys in KEYS.items() for key in keys}
TIRE_KEYS = tuple(k for k in LUGRE_KEYS if k not in ("mu_s", "mu_c", "v_s"))
"""The LuGre values written into ``[tire]``: the tire's own. μ_s, μ_c and v_s belong to the
road the logs were driven on; they are reported in ``[calibration.tire]`` only."""


MIN_LOG_S = 2.0
"""s; shortest log :func:`calibrate` takes: its wheel-slip mask and fits work on 1 s windows,
and a log of twice that holds one window clear of both ends."""


@dataclass(frozen=True)
class CalibrationResult:
    """What :func:`calibrate` found, how long each step took (s), and the input gate's
    report on each log (:func:`vestim.io.sanity.gate`: warnings, checks not run)."""

    calibration: Calibration
    vehicle: Vehicle
    timings: dict[str, float]
    checks: tuple[GateReport, ...] = ()

    @property
    def values(self) -> dict[str, Identified]:
        """Every identified value by key (see :data:`vestim.io.calibration.KEYS`)."""
        return {k: v for g in self.calibration.groups.values() for k, v in g.items()}


def _measured(log: pd.DataFrame | str | os.PathLike[str]) -> pd.DataFrame:
    df = log if isinstance(log, pd.DataFrame) else read_log(log, require=["measured"])
    return df[[c for c in df.columns if not c.startswith("ref_")]]


def calibrate(
    logs: Sequence[pd.DataFrame | str | os.PathLike[str]],
    vehicle: Vehicle | str | os.PathLike[str],
    *,
    names: Sequence[str] | None = None,
    progress: Callable[[str, float], None] | None = None,
    select: bool = True,
) -> CalibrationResult:
    """Identify sensors, body and tires of one car from its logs.

    Args:
        logs: drive logs (frames or paths) of one car; their ``ref_`` channels are dropped.
        vehicle: the base vehicle file (its values are kept for what the logs do not excite).
        names: a name per log for the evidence (default: the paths, or ``log<i>``).
        progress: called with (step name, fraction of the steps done).
        select: decide which identified values the estimators use
            (:mod:`vestim.design.calibrate.select`: more than ``K_SIGMA``·σ from the nominal
            value and better than it on the held-out logs); False: every excited value is
            used (the behaviour before issue 31, for comparison).

    Returns:
        The calibration and the base vehicle with it attached.

    Raises:
        LogFormatError: a log shorter than :data:`MIN_LOG_S`, or one the input gate
            (:func:`vestim.io.sanity.gate`, as ``vestim estimate`` runs it) refuses: the
            message names the log, the channel and the fix.
    """
    from vestim.design.calibrate import body_tire, sensors

    base = vehicle if isinstance(vehicle, Vehicle) else load_vehicle(os.fspath(vehicle))
    if names is None:
        names = [Path(x).name if not isinstance(x, pd.DataFrame) else f"log{i}"
                 for i, x in enumerate(logs)]
    raw = [_measured(x) for x in logs]
    for df, name in zip(raw, names, strict=True):
        t = df["t"].to_numpy(dtype=float)
        span = float(t[-1] - t[0]) if len(t) else 0.0
        if span < MIN_LOG_S:
            raise LogFormatError(
                f"{name}: the log spans {span:.3g} s ({len(t)} samples); calibration needs at "
                f"least {MIN_LOG_S:g} s per log (its fits use 1 s windows), and minutes of "
                "driving to excite most values: give a longer log or leave this one out")
    checks = tuple(gate(df, base, source=name) for df, name in zip(raw, names, strict=True))
    steps: list[tuple[str, Callable[[Sequence[pd.DataFrame], Vehicle], dict[str, Identified]]]] = [
        ("imu", sensors.identify_imu), ("wheels", sensors.identify_wheels),
        ("steering", sensors.identify_steering), ("body", body_tire.identify_body),
        ("tire", body_tire.identify_tires)]
    # The data sets identified side by side: all logs, then each leave-one-out fold's
    # training logs and held-out log (select.py); each step sees every set corrected by the
    # values used so far.
    held = _held_out(raw) if select else []
    sets: list[list[pd.DataFrame]] = [raw]
    index: dict[tuple[int, ...], int] = {tuple(map(id, raw)): 0}
    folds: list[tuple[int, int]] = []  # the sets of each fold: (training, held out)
    for pair in held:
        for data in pair:  # with two logs, one fold's training set is the other's held out
            index.setdefault(tuple(map(id, data)), len(sets))
            if index[tuple(map(id, data))] == len(sets):
                sets.append(data)
        folds.append((index[tuple(map(id, pair[0]))], index[tuple(map(id, pair[1]))]))
    found: list[dict[str, Identified]] = [{} for _ in sets]
    nominal = nominal_values(base)
    timings: dict[str, float] = {}
    b = base.body
    for i, (step, fn) in enumerate(steps):
        if progress is not None:
            progress(step, i / len(steps))
        t0 = time.perf_counter()
        for j, data in enumerate(sets):
            cal = _calibration(found[j], base, names)
            corrected = [corrected_log(df, cal, wheel_radius=b.wheel_radius,
                                       steering_ratio=b.steering_ratio) for df in data]
            veh = replace(base, calibration=None if step == "imu" else cal)
            found[j].update(fn(corrected, veh))
        if select:  # the decisions on all logs, applied to every set before the next step
            for k in list(found[0]):
                if found[0][k].decision or not found[0][k].excited:
                    continue
                found[0][k] = decide(k, found[0][k], nominal.get(k),
                                     [Fold(found[a].get(k), found[h].get(k)) for a, h in folds])
            found[0] = couple(found[0])
            for j in range(1, len(sets)):
                for k, v in found[j].items():
                    if k in found[0] and not found[0][k].used:
                        found[j][k] = replace(v, used=False)
        timings[step] = time.perf_counter() - t0
    if progress is not None:
        progress("done", 1.0)
    cal = _calibration(found[0], base, names)
    return CalibrationResult(cal, replace(base, calibration=cal), timings, checks)


def _held_out(raw: Sequence[pd.DataFrame]) -> list[tuple[list[pd.DataFrame], list[pd.DataFrame]]]:
    """The leave-one-out folds over the logs, (training logs, held-out log); one log is split
    into its two halves in time (none where a half is shorter than :data:`MIN_LOG_S`)."""
    if len(raw) == 1:
        df = raw[0]
        t = df["t"].to_numpy(dtype=float)
        mid = 0.5 * (t[0] + t[-1])
        halves = [df[t < mid].reset_index(drop=True), df[t >= mid].reset_index(drop=True)]
        if any(float(h["t"].iloc[-1] - h["t"].iloc[0]) < MIN_LOG_S for h in halves):
            return []
        return [([halves[1]], [halves[0]]), ([halves[0]], [halves[1]])]
    return [([d for j, d in enumerate(raw) if j != i], [raw[i]]) for i in range(len(raw))]


def _calibration(found: dict[str, Identified], base: Vehicle, names: Sequence[str]) -> Calibration:
    from vestim import __version__

    groups: dict[str, dict[str, Identified]] = {}
    for key, value in found.items():
        group = GROUP_OF.get(key)
        if group is None:
            raise ValueError(f"calibration step returned unknown key {key!r}")
        groups.setdefault(group, {})[key] = value
    return Calibration(groups, base=base.name, sources=tuple(names), vestim_version=__version__)


def write_calibrated(result: CalibrationResult, base_path: str | os.PathLike[str] | None,
                     out: str | os.PathLike[str]) -> Path:
    """Write ``CAR.toml``: the base file's tables (excited LuGre values put into ``[tire]``),
    then the ``[calibration.*]`` tables. Written atomically; the base file is only read.

    Args:
        result: :func:`calibrate`'s result.
        base_path: the base vehicle file (None: a built-in, written from its parsed values).
        out: the file to write.
    """
    from importlib import resources

    if base_path is not None and Path(base_path).is_file():
        text = Path(base_path).read_text(encoding="utf-8-sig")
    else:
        text = (resources.files("vestim") / "data" / "vehicles"
                / f"{result.vehicle.name}.toml").read_text(encoding="utf-8")
    data = tomllib.loads(text)
    data.pop("calibration", None)  # a recalibration replaces the old tables
    for key in TIRE_KEYS:
        v = result.calibration.excited("tire", key)
        if v is not None:
            data["tire"][key] = v
    lines = [f"# vestim calibrate: {result.calibration.base} calibrated from "
             f"{', '.join(result.calibration.sources)} (vestim {result.calibration.vestim_version})"]
    for table, values in data.items():
        lines += ["", f"[{table}]"]
        lines += [f"{k} = {toml_value(v)}" for k, v in values.items()]
    text_out = "\n".join(lines) + "\n\n" + calibration_toml(result.calibration)
    load_check = tomllib.loads(text_out)  # the file must load back as a vehicle
    from vestim.io.vehicle import vehicle_from_dict

    vehicle_from_dict(load_check, name=result.vehicle.name)
    return write_text_atomic(out, text_out)


def write_report(result: CalibrationResult, out_dir: str | os.PathLike[str]) -> Path:
    """Markdown report (``calibration.md``) and a figure (``calibration.png``): every value
    with its σ and evidence, what the logs did not excite, and the timings."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    from vestim.report.plots import save_figure

    d = Path(out_dir)
    values = result.values
    base = nominal_values(result.vehicle)
    rows = ["| group | key | value | σ | base | unit | evidence | used: why |",
            "|---|---|---|---|---|---|---|---|"]
    idle = ["| group | key | base kept | why |", "|---|---|---|---|"]
    for group, keys in KEYS.items():
        for key in keys:
            v = values.get(key)
            if v is None:
                continue
            b = base.get(key, math.nan)
            if v.excited:
                rows.append(f"| {group} | `{key}` | {v.value:.6g} | {v.sigma:.2g} | {b:.6g} | "
                            f"{v.unit} | {v.evidence} | {'yes' if v.used else 'no'}: "
                            f"{v.decision or 'no selection'} |")
            else:
                idle.append(f"| {group} | `{key}` | {v.value:.6g} | {v.evidence} |")
    excited = [(k, v) for k, v in values.items() if v.excited and math.isfinite(base.get(k, math.nan))
               and base.get(k) != 0.0]
    fig, ax = plt.subplots(figsize=(8, 0.3 * max(len(excited), 4) + 1.2))
    for i, (k, v) in enumerate(excited):
        b = base[k]
        ax.errorbar([v.value / b], [i], xerr=[[2 * v.sigma / abs(b)]], fmt="o", color="#0072B2",
                    capsize=3)
    ax.axvline(1.0, color="k", lw=0.8)
    ax.set_yticks(range(len(excited)), [k for k, _ in excited])
    ax.set_xlabel("identified / base value  (bars: ±2σ)")
    ax.set_title("vestim calibrate: identified values relative to the base file")
    fig.tight_layout()
    png = save_figure(fig, d / "calibration.png")
    timing = ", ".join(f"{k} {t:.2f} s" for k, t in result.timings.items())
    md = "\n".join([
        f"# Calibration of {result.calibration.base}",
        "",
        f"From {len(result.calibration.sources)} log(s): {', '.join(result.calibration.sources)}."
        f" vestim {result.calibration.vestim_version}. Time: {timing}.",
        "",
        f"![identified values]({png.name})",
        "",
        "## Identified",
        "",
        *rows,
        "",
        "## Not excited (base value kept)",
        "",
        *(idle if len(idle) > 2 else ["Every value was excited."]),
        "",
    ])
    path = d / "calibration.md"
    with atomic_path(path) as tmp:
        tmp.write_text(md, encoding="utf-8")
    return path
