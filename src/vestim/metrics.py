"""Accuracy metrics of an estimate against ground truth (``vestim score``).

The headline metric is the papers' normalised root-mean-square error, 000 Sec. IV::

    NRMS = sqrt( (1/N) Σ (p̂_i − p_i)² ) / p_m,        p_m = max_i |p_i|

with p̂ the estimate and p the reference over the N paired samples. A channel whose
truth stays near zero (F_y on a straight line, v_y without steering) would make p_m
tiny and the NRMS meaningless, so the denominator is ``max(p_m, floor)`` with a
per-channel floor from :data:`FLOORS`; the score table says where the floor was used.

Every metric is NaN-aware: a sample where either the estimate or the reference is NaN
is left out, and :func:`error_stats` reports how many were used and how many left out.
"""

from __future__ import annotations

import json
import math
from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np
import numpy.typing as npt
import pandas as pd

from vestim.constants import CORNERS
from vestim.errors import LogFormatError
from vestim.io import channels as ch

__all__ = [
    "COVERAGE_COLUMNS",
    "FLOORS",
    "SCORE_COLUMNS",
    "ErrorStats",
    "channel_family",
    "coverage",
    "error_stats",
    "floor_for",
    "max_abs_error",
    "nrms",
    "rmse",
    "score",
    "significant",
    "to_json",
    "to_markdown",
    "with_coverage",
]

FLOORS: dict[str, float] = {
    "vx": 0.0,            # m/s; vx and vx_* never stay near zero while driving
    "vy": 1.0,            # m/s; vy and vy_* are near zero without steering
    "fx": 500.0,          # N; the force floor (cruise F_x is a few hundred N)
    "fy": 500.0,          # N
    "fz": 500.0,          # N; F_z only approaches zero on wheel lift
    "mu_x": 0.1,          # -; F_x/F_z: 500 N over a typical 5 kN corner load
    "mu_y": 0.1,          # -; F_y/F_z, as mu_x
    "mu": 0.0,            # -; road friction is at least ~0.1 on any surface
    "slip_ratio": 0.05,   # -
    "slip_angle": 0.02,   # rad (≈ 1.1°)
    "roll": 0.01,         # rad (≈ 0.6°)
    "pitch": 0.01,        # rad
    "stiffness": 0.0,     # N or N/rad; axle stiffness is always large
}
"""NRMS denominator floor per channel family, in the channel's unit: NRMS divides by
``max(max|ref|, floor)``. A family is a channel name without its corner suffix
(``fx_fl`` → ``fx``); every ``stiffness_*`` channel is family ``stiffness``
(:func:`channel_family`). A channel of any other family gets floor 0."""

SCORE_COLUMNS: tuple[str, ...] = (
    "channel", "unit", "nrms_pct", "rmse", "max_error", "ref_max", "floor", "floored",
    "samples", "skipped",
)
"""Columns of the :func:`score` table, in order (see :func:`score` for their meaning)."""


# ------------------------------------------------------------------------------ kernels

@dataclass(frozen=True)
class ErrorStats:
    """Error of one channel over its valid samples (both estimate and reference non-NaN).

    Attributes:
        nrms: RMSE / ``max(ref_max, floor)`` (a fraction, not %); NaN when no sample is valid.
        rmse: root-mean-square error, in the channel's unit.
        max_error: max |p̂ − p|, in the channel's unit.
        ref_max: p_m = max |p| over the valid samples, in the channel's unit.
        floor: the floor the NRMS denominator was held at or above.
        samples: number of valid sample pairs used.
        skipped: number of pairs left out because either value was NaN.
    """

    nrms: float
    rmse: float
    max_error: float
    ref_max: float
    floor: float
    samples: int
    skipped: int

    @property
    def floored(self) -> bool:
        """True when the floor, not max |ref|, was the NRMS denominator."""
        return self.samples > 0 and self.floor > self.ref_max


def _pairs(est: npt.ArrayLike, ref: npt.ArrayLike) -> tuple[np.ndarray, np.ndarray, int]:
    """Flattened float64 pairs with NaN in neither, and the count of pairs left out."""
    e = np.asarray(est, dtype=float)
    r = np.asarray(ref, dtype=float)
    if e.shape != r.shape:
        raise ValueError(f"estimate and reference shapes differ: {e.shape} vs {r.shape}")
    e = e.ravel()
    r = r.ravel()
    valid = ~(np.isnan(e) | np.isnan(r))
    return e[valid], r[valid], int(valid.size - np.count_nonzero(valid))


def _ratio(rms: float, norm: float) -> float:
    """rms / norm; a zero reference with no floor gives 0 for a zero error and inf otherwise."""
    if norm > 0.0:
        return rms / norm
    return 0.0 if rms == 0.0 else math.inf


def error_stats(est: npt.ArrayLike, ref: npt.ArrayLike, floor: float = 0.0) -> ErrorStats:
    """NRMS (000 Sec. IV), RMSE and max error of ``est`` against ``ref``, NaN-aware.

    Args:
        est: estimate p̂, any shape; unit of the channel.
        ref: reference p, same shape and unit.
        floor: lower bound of the NRMS denominator, same unit (>= 0).

    Returns:
        The statistics over the pairs where neither value is NaN. With no valid pair,
        nrms, rmse, max_error and ref_max are NaN. With a zero denominator (reference
        identically zero and floor 0) nrms is 0 for a zero error and inf otherwise.
    """
    if not floor >= 0.0:
        raise ValueError(f"floor must be >= 0, got {floor}")
    e, r, skipped = _pairs(est, ref)
    if e.size == 0:
        nan = math.nan
        return ErrorStats(nan, nan, nan, nan, float(floor), 0, skipped)
    err = e - r
    rms = float(np.sqrt(np.mean(err * err)))
    ref_max = float(np.max(np.abs(r)))
    norm = max(ref_max, float(floor))
    ratio = _ratio(rms, norm)
    return ErrorStats(
        nrms=ratio,
        rmse=rms,
        max_error=float(np.max(np.abs(err))),
        ref_max=ref_max,
        floor=float(floor),
        samples=int(e.size),
        skipped=skipped,
    )


def nrms(est: npt.ArrayLike, ref: npt.ArrayLike, floor: float = 0.0) -> float:
    """Normalised RMS error, 000 Sec. IV: sqrt(mean((p̂ − p)²)) / max(max|p|, floor).

    A dimensionless fraction (multiply by 100 for the papers' %). Pairs with a NaN in
    either array are ignored (:func:`error_stats` reports how many); NaN if none is left.
    """
    return error_stats(est, ref, floor).nrms


def rmse(est: npt.ArrayLike, ref: npt.ArrayLike) -> float:
    """Root-mean-square error sqrt(mean((p̂ − p)²)) in the channel's unit, NaN pairs ignored."""
    return error_stats(est, ref).rmse


def max_abs_error(est: npt.ArrayLike, ref: npt.ArrayLike) -> float:
    """Largest |p̂ − p| in the channel's unit, NaN pairs ignored (NaN if none is left)."""
    return error_stats(est, ref).max_error


# ------------------------------------------------------------------------------ channels

def channel_family(channel: str) -> str:
    """Family of a channel name for :data:`FLOORS`: the name without its corner suffix.

    ``fx_fl`` → ``fx``, ``mu_y_rr`` → ``mu_y``, ``vy`` → ``vy``, ``stiffness_cy_f`` → ``stiffness``.
    """
    if channel.startswith("stiffness_"):
        return "stiffness"
    for corner in CORNERS:
        if channel.endswith("_" + corner):
            return channel[: -len(corner) - 1]
    return channel


def floor_for(channel: str) -> float:
    """NRMS floor of ``channel`` from :data:`FLOORS` (0 for a family not listed)."""
    return FLOORS.get(channel_family(channel), 0.0)


_DERIVED_REF = {"mu_x": "fx", "mu_y": "fy"}
"""Normalised forces: the reference of ``mu_x_<c>`` is ref_fx_<c> / ref_fz_<c> when the
reference log has no ``ref_mu_x_<c>`` column (the spec lists none)."""


def _reference_column(reference: pd.DataFrame, channel: str) -> np.ndarray | None:
    """Reference values of an estimated channel, or ``None`` when the log cannot give them."""
    name = ch.REF_PREFIX + channel
    if name in reference.columns:
        return reference[name].to_numpy(dtype=float, copy=True)
    family = channel_family(channel)
    if family in _DERIVED_REF and channel != family:
        corner = channel[len(family) + 1:]
        num = f"{ch.REF_PREFIX}{_DERIVED_REF[family]}_{corner}"
        den = f"{ch.REF_PREFIX}fz_{corner}"
        if num in reference.columns and den in reference.columns:
            with np.errstate(divide="ignore", invalid="ignore"):
                ratio = reference[num].to_numpy(dtype=float) / reference[den].to_numpy(dtype=float)
            ratio[~np.isfinite(ratio)] = np.nan  # wheel lift: F_z = 0 has no μ
            return ratio
    return None


def _is_candidate(column: str) -> bool:
    return column != ch.T and not column.startswith((ch.REF_PREFIX, ch.SIGMA_PREFIX))


# ------------------------------------------------------------------------------ alignment

def _time(df: pd.DataFrame, name: str) -> np.ndarray:
    if ch.T not in df.columns:
        raise LogFormatError(f"{name}: no time column 't'; add one in s")
    t = df[ch.T].to_numpy(dtype=float)
    if t.size == 0:
        raise LogFormatError(f"{name}: the log has no rows")
    if not np.all(np.isfinite(t)):
        raise LogFormatError(f"{name}: column 't' has NaN or infinite values")
    if t.size > 1 and not np.all(np.diff(t) > 0):
        raise LogFormatError(f"{name}: column 't' is not strictly increasing; sort the log by time")
    return t


def _align(t_est: np.ndarray, t_ref: np.ndarray, estimate_name: str,
           reference_name: str) -> tuple[np.ndarray, bool]:
    """Mask of estimate rows to score and whether the reference must be interpolated."""
    if t_est.shape == t_ref.shape and np.array_equal(t_est, t_ref):
        return np.ones(t_est.size, dtype=bool), False
    inside = (t_est >= t_ref[0]) & (t_est <= t_ref[-1])
    if not inside.any():
        raise LogFormatError(
            f"{estimate_name} (t = {t_est[0]:g} … {t_est[-1]:g} s) and {reference_name} "
            f"(t = {t_ref[0]:g} … {t_ref[-1]:g} s) do not overlap in time; score an estimate "
            "against the log it was computed from"
        )
    return inside, True


# ------------------------------------------------------------------------------ score

def score(
    estimate: pd.DataFrame,
    reference: pd.DataFrame,
    *,
    channels: Sequence[str] | None = None,
    estimate_name: str = "estimate",
    reference_name: str = "reference",
) -> pd.DataFrame:
    """Score every estimated channel ``X`` of ``estimate`` against ``ref_X`` of ``reference``.

    Pairing: ``X`` is scored when ``estimate`` has it and ``reference`` has ``ref_X``;
    ``t``, ``ref_*`` and ``sigma_*`` columns are never scored. ``mu_x_<c>``/``mu_y_<c>``
    (normalised forces) are scored against ref_fx_<c>/ref_fz_<c> and ref_fy_<c>/ref_fz_<c>
    when the reference has no ``ref_mu_x_<c>``/``ref_mu_y_<c>``. ``reference`` may be the
    same frame as ``estimate`` (a simulator log that also carries estimates).

    Time alignment on ``t`` (s):

    - identical time columns: samples are paired row by row;
    - otherwise the reference is linearly interpolated onto the estimate's times
      (:func:`numpy.interp`); estimate samples outside the reference's time span are
      dropped (never extrapolated), and a reference NaN makes the interpolated values
      next to it NaN, which are then skipped. Logs that do not overlap at all raise
      :class:`~vestim.errors.LogFormatError` naming both time ranges.

    Args:
        estimate: log with ``t`` and estimated channels (spec names, no prefix).
        reference: log with ``t`` and ``ref_`` channels.
        channels: estimated channels to score, in this order; default every pairable one
            in the spec's column order. A named channel that cannot be paired is an error.
        estimate_name, reference_name: how messages name the two logs (e.g. file paths).

    Returns:
        One row per channel with the columns of :data:`SCORE_COLUMNS`: ``channel``;
        ``unit`` (SI, "-" dimensionless, "" unknown); ``nrms_pct`` = 100·NRMS (000 Sec. IV
        with the floors of :data:`FLOORS`); ``rmse`` and ``max_error`` (max |p̂ − p|) in the
        channel's unit; ``ref_max`` = max |p|; ``floor``; ``floored`` (the floor exceeded
        ``ref_max`` and was the denominator); ``samples`` used and ``skipped`` for NaN.
        Neither input is modified.

    Raises:
        LogFormatError: missing or invalid ``t``, logs that do not overlap in time, a named
            channel without its estimate or reference, or nothing to score.
    """
    t_est = _time(estimate, estimate_name)
    t_ref = _time(reference, reference_name)
    if channels is None:
        names = ch.canonical_order(
            c for c in estimate.columns
            if isinstance(c, str) and _is_candidate(c) and _reference_column(reference, c) is not None
        )
        if not names:
            raise LogFormatError(
                f"{estimate_name}: no estimated channel has a reference in {reference_name}; an "
                "estimate named X (vx, fx_fl, …) is scored against ref_X"
            )
    else:
        names = list(channels)
        if not names:
            raise ValueError("channels is empty; give at least one channel or None for all")
        for name in names:
            if not _is_candidate(name):
                raise LogFormatError(f"{name!r} is not an estimated channel (no t, ref_ or sigma_)")
            if name not in estimate.columns:
                raise LogFormatError(f"{estimate_name}: no column {name!r} to score")
            if _reference_column(reference, name) is None:
                raise LogFormatError(
                    f"{reference_name}: no column {ch.REF_PREFIX + name!r} to score {name!r} against"
                )
    rows_used, interpolate = _align(t_est, t_ref, estimate_name, reference_name)
    t_used = t_est[rows_used]
    rows: list[dict[str, Any]] = []
    for name in names:
        ref = _reference_column(reference, name)
        assert ref is not None  # checked above
        if interpolate:
            ref = np.interp(t_used, t_ref, ref)
        est = estimate[name].to_numpy(dtype=float)[rows_used]
        stats = error_stats(est, ref, floor_for(name))
        rows.append({
            "channel": name,
            "unit": ch.unit_of(name) or "",
            "nrms_pct": 100.0 * stats.nrms,
            "rmse": stats.rmse,
            "max_error": stats.max_error,
            "ref_max": stats.ref_max,
            "floor": stats.floor,
            "floored": stats.floored,
            "samples": stats.samples,
            "skipped": stats.skipped,
        })
    return pd.DataFrame(rows, columns=list(SCORE_COLUMNS))


COVERAGE_COLUMNS: tuple[str, ...] = ("channel", "unit", "within_1sigma", "within_2sigma",
                                     "median_sigma", "rmse", "samples")
"""Columns of :func:`coverage`."""


def coverage(estimate: pd.DataFrame, reference: pd.DataFrame, *,
             channels: Sequence[str] | None = None,
             estimate_name: str = "estimate", reference_name: str = "reference") -> pd.DataFrame:
    """How honest the estimate's σ is: for every channel ``X`` with ``sigma_X`` and ``ref_X``,
    the share of samples whose error lies within 1σ and within 2σ (|X − ref_X| ≤ σ, ≤ 2σ).

    A Gaussian error with that σ gives 68.3 % and 95.4 %; the issue's band for a calibrated
    σ is 60–80 % and 90–98 %. Time alignment and NaN handling are those of :func:`score`
    (a sample whose σ is NaN is left out too).

    Args:
        channels: the channels to cover, in this order; default every channel with both a
            ``sigma_`` column and a reference, in the spec's column order. Each named one
            must have both.

    Returns:
        One row per channel, columns :data:`COVERAGE_COLUMNS` (shares as fractions 0–1;
        ``median_sigma`` and ``rmse`` in the channel's unit).

    Raises:
        LogFormatError: as :func:`score`; also when no channel has both a σ and a reference.
    """
    covered = [c for c in ch.canonical_order(estimate.columns)
               if _is_candidate(c) and f"{ch.SIGMA_PREFIX}{c}" in estimate.columns
               and _reference_column(reference, c) is not None]
    names = covered if channels is None else list(channels)
    for name in names:
        if name not in covered:
            raise LogFormatError(f"{estimate_name}: {name!r} needs a {ch.SIGMA_PREFIX}{name} column "
                                 f"and a reference ({ch.REF_PREFIX}{name}) in {reference_name} "
                                 "for its σ coverage")
    if not names:
        raise LogFormatError(f"{estimate_name}: no channel has both a sigma_ column and a "
                             f"reference in {reference_name}")
    t_est, t_ref = _time(estimate, estimate_name), _time(reference, reference_name)
    rows_used, interpolate = _align(t_est, t_ref, estimate_name, reference_name)
    rows: list[dict[str, Any]] = []
    for name in names:
        ref = _reference_column(reference, name)
        assert ref is not None
        if interpolate:
            ref = np.interp(t_est[rows_used], t_ref, ref)
        est = estimate[name].to_numpy(dtype=float)[rows_used]
        sig = estimate[f"{ch.SIGMA_PREFIX}{name}"].to_numpy(dtype=float)[rows_used]
        ok = np.isfinite(est) & np.isfinite(ref) & np.isfinite(sig)
        err = np.abs(est[ok] - ref[ok])
        n = int(ok.sum())
        rows.append({
            "channel": name, "unit": ch.unit_of(name) or "",
            "within_1sigma": float(np.mean(err <= sig[ok])) if n else math.nan,
            "within_2sigma": float(np.mean(err <= 2 * sig[ok])) if n else math.nan,
            "median_sigma": float(np.median(sig[ok])) if n else math.nan,
            "rmse": float(np.sqrt(np.mean(err**2))) if n else math.nan,
            "samples": n,
        })
    return pd.DataFrame(rows, columns=list(COVERAGE_COLUMNS))


def with_coverage(scores: pd.DataFrame, cover: pd.DataFrame) -> pd.DataFrame:
    """:func:`score`'s table with :func:`coverage`'s ``within_1sigma`` and ``within_2sigma``
    beside each channel's scores (NaN for a channel without a σ); what ``vestim score
    --coverage`` prints."""
    shares = cover.set_index("channel")[["within_1sigma", "within_2sigma"]]
    return scores.join(shares, on="channel")


# ------------------------------------------------------------------------------ output

def significant(value: Any, digits: int = 3) -> str:
    """``value`` to ``digits`` significant figures, never in exponent form and never rounded
    to zero: 0.01234 → "0.0123", 5 → "5.00", 1234.6 → "1235"; "0" for 0, "–" for NaN,
    "inf"/"-inf" for infinities. The NRMS of every table and title is written with it."""
    x = float(value)
    if math.isnan(x):
        return "–"
    if math.isinf(x) or x == 0.0:
        return "0" if x == 0.0 else ("inf" if x > 0 else "-inf")
    decimals = max(digits - 1 - math.floor(math.log10(abs(x))), 0)
    return f"{x:.{decimals}f}"


def _sig(value: Any, digits: int = 4, *, fixed: int | None = None) -> str:
    """``value`` to ``digits`` significant figures (or ``fixed`` decimals); "–" for NaN."""
    x = float(value)
    if math.isnan(x):
        return "–"
    return f"{x:.{fixed}f}" if fixed is not None else f"{x:.{digits}g}"


def to_markdown(table: pd.DataFrame) -> str:
    """A :func:`score` table as a GitHub Markdown table (like 001 Table III), with a footnote.

    NRMS is shown in % to 3 significant figures (:func:`significant`: a 0.004 % error reads
    0.00400, not 0.00); an NRMS normalised by the floor is marked ``*``.
    RMSE, max error and max |ref| are given to 4 significant figures in the channel's unit;
    a table from :func:`with_coverage` adds the σ coverage in % ("–": no σ).
    """
    missing = [c for c in SCORE_COLUMNS if c not in table.columns]
    if missing:
        raise ValueError(f"not a score table: missing column(s) {', '.join(missing)}")
    cover = "within_1sigma" in table.columns
    lines = [
        "| channel | unit | NRMS [%] | RMSE | max error | max abs ref | floor | samples |"
        + (" within 1σ % | within 2σ % |" if cover else ""),
        "|---|---|---:|---:|---:|---:|---:|---:|" + ("---:|---:|" if cover else ""),
    ]
    for row in table.to_dict(orient="records"):
        pct = significant(row["nrms_pct"])
        if bool(row["floored"]):
            pct += "*"
        skipped = int(row["skipped"])
        samples = f"{int(row['samples'])}" + (f" ({skipped} NaN skipped)" if skipped else "")
        lines.append(
            f"| {row['channel']} | {row['unit']} | {pct} | {_sig(row['rmse'])} | "
            f"{_sig(row['max_error'])} | {_sig(row['ref_max'])} | {_sig(row['floor'])} | {samples} |"
            + (f" {_sig(100 * float(row['within_1sigma']), fixed=1)} | "
               f"{_sig(100 * float(row['within_2sigma']), fixed=1)} |" if cover else "")
        )
    note = "NRMS = RMS error / max(max|ref|, floor) (000 Sec. IV)."
    if table["floored"].astype(bool).any():
        note += " * The truth stayed below the floor, so the floor was the denominator."
    lines += ["", note]
    return "\n".join(lines) + "\n"


def _json_value(value: Any) -> Any:
    if isinstance(value, bool | np.bool_):
        return bool(value)
    if isinstance(value, int | np.integer):
        return int(value)
    if isinstance(value, float | np.floating):
        x = float(value)
        if not math.isfinite(x):
            return None
        return float(f"{x:.6g}")
    return value


def to_json(table: pd.DataFrame, *, indent: int | None = 2) -> str:
    """A :func:`score` table as a JSON list of records (one object per channel).

    Floats are rounded to 6 significant figures; NaN and infinite values become ``null``.
    """
    records = [
        {str(k): _json_value(v) for k, v in rec.items()}
        for rec in table.to_dict(orient="records")
    ]
    return json.dumps(records, indent=indent, ensure_ascii=False)
