"""Read-only access to an estimate and its reference, shared by the PNG figures and the HTML
report: channel look-up, the reference on the estimate's time base, error traces, scores and
the min/max envelope that keeps long logs small to draw.
"""

from __future__ import annotations

import os
from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd

from vestim.constants import CORNERS
from vestim.errors import LogFormatError
from vestim.estimators.validity import reason_names
from vestim.io import channels as ch
from vestim.metrics import channel_family, coverage, score, significant

__all__ = ["MAX_POINTS", "MAX_SPANS", "Logs", "Span", "band", "check_pairing", "envelope",
           "invalid_spans", "peak_points"]

MAX_POINTS = 2000
"""Most points drawn per line; a longer series is drawn as its min/max envelope (1000
buckets, about one per pixel column of a figure 1100 px wide)."""

_DERIVED_REF = {"mu_x": "fx", "mu_y": "fy"}
"""μ_x = F_x/F_z and μ_y = F_y/F_z have no ``ref_`` column in the spec; their reference is
the ratio of the reference forces (as :func:`vestim.metrics.score` pairs them)."""


def check_pairing(estimate: pd.DataFrame, reference: pd.DataFrame, reference_path: str) -> None:
    """Refuse a reference that does not belong to the estimate (issue 30: a report that pairs
    an estimate with another drive's reference showed 92.6 % NRMS without a word).

    Two tests: the estimate's metadata ``source`` (written by ``vestim estimate`` and
    ``vestim batch``) must name the reference file (the same file, or one of the same name,
    so a moved folder still pairs); and the two logs must span the same time, first and last
    ``t`` within one sample interval of the reference (an estimate has one row per sample of
    its log).

    Args:
        estimate: the log of estimates (``attrs`` from its Parquet metadata).
        reference: the reference log.
        reference_path: the reference's path, as given.

    Raises:
        LogFormatError: naming the estimate's own log or the two time spans.
    """
    source = str(estimate.attrs.get("source", ""))
    if source:
        src, ref = Path(source), Path(reference_path)
        same = src.name == ref.name or (src.exists() and ref.exists() and os.path.samefile(src, ref))
        if not same:
            raise LogFormatError(
                f"the estimate was made from {source} (its metadata 'source'), but the reference "
                f"is {reference_path}: scores against another drive's reference are meaningless; "
                f"pass {source} as REFERENCE (or --unpaired to compare them anyway)")
    if ch.T not in estimate.columns or ch.T not in reference.columns:
        return  # Logs names the missing column
    te = estimate[ch.T].to_numpy(dtype=np.float64)
    tr = reference[ch.T].to_numpy(dtype=np.float64)
    if te.size == 0 or tr.size == 0:
        return
    tol = (float(np.median(np.diff(tr))) if tr.size > 1 else 0.0) + 1e-6
    if abs(te[0] - tr[0]) > tol or abs(te[-1] - tr[-1]) > tol:
        raise LogFormatError(
            f"the estimate spans t = {te[0]:.3f}–{te[-1]:.3f} s ({te.size} rows) but the "
            f"reference {reference_path} spans {tr[0]:.3f}–{tr[-1]:.3f} s ({tr.size} rows): it "
            "is not the log the estimate was made from; pass that log as REFERENCE (or "
            "--unpaired to compare the overlap anyway)")


def envelope(t: np.ndarray, y: np.ndarray, max_points: int = MAX_POINTS) -> tuple[np.ndarray, np.ndarray]:
    """``(t, y)`` reduced to at most ``max_points`` points: each bucket's min then max.

    NaN samples are ignored inside a bucket (an all-NaN bucket stays NaN, a gap). Returns
    the inputs unchanged when they are short enough.
    """
    n = t.size
    if n <= max_points:
        return t, y
    buckets = max_points // 2
    starts = np.linspace(0, n, buckets, endpoint=False).astype(np.intp)
    ends = np.append(starts[1:], n)
    lo = np.fmin.reduceat(y, starts)
    hi = np.fmax.reduceat(y, starts)
    mid = (starts + ends - 1) // 2
    tt = np.column_stack((t[starts], t[mid])).ravel()
    yy = np.column_stack((lo, hi)).ravel()
    return tt, yy


def band(t: np.ndarray, y: np.ndarray, s: np.ndarray,
         max_points: int = MAX_POINTS) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Lower and upper edge y ∓ s of a ±σ band, reduced to at most ``max_points`` points
    (each bucket's lowest lower edge and highest upper edge, so the band only widens)."""
    lower, upper = y - s, y + s
    n = t.size
    if n <= max_points:
        return t, lower, upper
    starts = np.linspace(0, n, max_points, endpoint=False).astype(np.intp)
    return t[starts], np.fmin.reduceat(lower, starts), np.fmax.reduceat(upper, starts)


def peak_points(x: np.ndarray, y: np.ndarray, max_points: int = MAX_POINTS) -> np.ndarray:
    """Indices of at most ``max_points`` samples of the scatter (x, y) to draw, in time order.

    A short series keeps every finite sample. A longer one is cut into ``max_points`` time
    buckets and keeps, per bucket, the sample farthest from the origin, so the outline of a
    friction circle or GG diagram (its peaks) survives the reduction.
    """
    finite = np.isfinite(x) & np.isfinite(y)
    n = x.size
    if n <= max_points:
        return np.flatnonzero(finite)
    r = np.where(finite, np.hypot(np.where(finite, x, 0.0), np.where(finite, y, 0.0)), -1.0)
    starts = np.linspace(0, n, max_points, endpoint=False).astype(np.intp)
    ends = np.append(starts[1:], n)
    best = np.maximum.reduceat(r, starts)
    idx = np.empty(starts.size, dtype=np.intp)
    for k, (a, b) in enumerate(zip(starts, ends, strict=True)):
        idx[k] = a + int(np.argmax(r[a:b] == best[k]))
    return idx[best >= 0.0]


Span = tuple[float, float, int]
"""(start, end, reason mask) of a stretch of rows whose ``valid_<group>`` is 0: ``t`` of its
first row, ``t`` of the first valid row after it (the last ``t`` at the log's end), in s."""


MAX_SPANS = 100
"""Most "not valid" spans drawn per validity group: a flag that flickers more often is drawn
at a coarser time resolution (every span a shape in each plot; 1000 of them in seven plots
would add several MB to a report)."""


def invalid_spans(t: np.ndarray, valid: np.ndarray, reason: np.ndarray,
                  max_points: int = MAX_POINTS, max_spans: int = MAX_SPANS) -> list[Span]:
    """The stretches where ``valid`` is 0, split where the ``reason`` mask changes.

    A log longer than ``max_points`` is first cut into ``max_points // 2`` time buckets (as
    :func:`envelope` cuts lines): a bucket is invalid when any of its rows is, with the
    bitwise OR of their masks, so no invalid row is lost and a flickering flag gives at most
    one span per bucket. When that still gives more than ``max_spans`` spans, the buckets
    are ``max_spans`` instead.
    """
    bad = np.asarray(valid, dtype=float) == 0.0
    mask = np.where(bad, np.nan_to_num(np.asarray(reason, dtype=float)), 0.0).astype(np.int64)
    if t.size == 0 or not bad.any():
        return []
    spans = _spans(t, bad, mask, None if t.size <= max_points else max_points // 2)
    return spans if len(spans) <= max_spans else _spans(t, bad, mask, max_spans)


def _spans(t: np.ndarray, bad: np.ndarray, mask: np.ndarray, buckets: int | None) -> list[Span]:
    """:func:`invalid_spans` at the resolution of the samples (``buckets`` None) or of
    ``buckets`` equal time buckets."""
    if buckets is not None and buckets < t.size:
        starts = np.linspace(0, t.size, buckets, endpoint=False).astype(np.intp)
        bad = np.logical_or.reduceat(bad, starts)
        mask = np.bitwise_or.reduceat(mask, starts)
        t_start, t_end = t[starts], np.append(t[starts[1:]], t[-1])
    else:
        t_start, t_end = t, np.append(t[1:], t[-1])
    key = np.where(bad, mask, -1)
    edges = np.flatnonzero(np.diff(key)) + 1
    first = np.concatenate(([0], edges))
    last = np.concatenate((edges, [key.size])) - 1
    return [(float(t_start[a]), float(t_end[b]), int(key[a]))
            for a, b in zip(first, last, strict=True) if key[a] >= 0]


class Logs:
    """Read-only view of an estimate and its reference (``ref_`` channels) as float arrays.

    ``reference=None`` uses the estimate's own ``ref_`` columns (a simulator log that also
    carries estimates). Measured channels (``omega_*``, ``ax``, ``ay``) are taken from the
    estimate when it has them, else from the reference log.
    """

    def __init__(self, estimate: pd.DataFrame, reference: pd.DataFrame | None) -> None:
        self.est = estimate
        self.ref = reference if reference is not None else estimate
        self.t_est = self._time(self.est, "estimate")
        self.t_ref = self._time(self.ref, "reference")
        self._same_t = self.t_est.shape == self.t_ref.shape and np.array_equal(self.t_est, self.t_ref)
        self._scores: dict[str, dict[str, Any]] | None = None
        self._coverage: dict[str, dict[str, Any]] | None = None

    @staticmethod
    def _time(df: pd.DataFrame, name: str) -> np.ndarray:
        if ch.T not in df.columns:
            raise LogFormatError(f"{name}: no time column 't'; add one in s")
        return df[ch.T].to_numpy(dtype=float)

    def has(self, name: str) -> bool:
        """Whether the estimate has column ``name``."""
        return name in self.est.columns

    def estimate(self, name: str) -> np.ndarray:
        """Estimated channel ``name`` on :attr:`t_est`."""
        return self.est[name].to_numpy(dtype=float)

    def sigma(self, name: str) -> np.ndarray | None:
        """``sigma_<name>`` (same unit as ``name``) on :attr:`t_est`, or ``None``."""
        col = ch.SIGMA_PREFIX + name
        return self.est[col].to_numpy(dtype=float) if col in self.est.columns else None

    def reference(self, name: str) -> np.ndarray | None:
        """Reference of estimated channel ``name`` on :attr:`t_ref` (``ref_<name>``, or for
        ``mu_x_<c>``/``mu_y_<c>`` the ratio ref_fx_<c>/ref_fz_<c>, ref_fy_<c>/ref_fz_<c>)."""
        col = ch.REF_PREFIX + name
        if col in self.ref.columns:
            return self.ref[col].to_numpy(dtype=float)
        family = channel_family(name)
        if family in _DERIVED_REF and family != name:
            corner = name[len(family) + 1:]
            num = f"{ch.REF_PREFIX}{_DERIVED_REF[family]}_{corner}"
            den = f"{ch.REF_PREFIX}fz_{corner}"
            if num in self.ref.columns and den in self.ref.columns:
                with np.errstate(divide="ignore", invalid="ignore"):
                    ratio = self.ref[num].to_numpy(dtype=float) / self.ref[den].to_numpy(dtype=float)
                ratio[~np.isfinite(ratio)] = np.nan  # wheel lift: F_z = 0 has no μ
                return ratio
        return None

    def reference_at_estimate(self, name: str) -> np.ndarray | None:
        """Reference of ``name`` on :attr:`t_est`: row by row when both logs share ``t``,
        else linearly interpolated and NaN outside the reference's time span (never
        extrapolated), the pairing of :func:`vestim.metrics.score`."""
        ref = self.reference(name)
        if ref is None:
            return None
        if self._same_t:
            return ref
        out = np.interp(self.t_est, self.t_ref, ref)
        out[(self.t_est < self.t_ref[0]) | (self.t_est > self.t_ref[-1])] = np.nan
        return out

    def error(self, name: str) -> np.ndarray | None:
        """Error trace estimate − reference of ``name`` on :attr:`t_est` (its unit), or ``None``
        without an estimate or a reference."""
        if not self.has(name):
            return None
        ref = self.reference_at_estimate(name)
        return None if ref is None else self.estimate(name) - ref

    def measured(self, name: str) -> tuple[np.ndarray, np.ndarray] | None:
        """(t, values) of a measured channel from the estimate, else the reference, else ``None``."""
        for df, t in ((self.est, self.t_est), (self.ref, self.t_ref)):
            if name in df.columns:
                return t, df[name].to_numpy(dtype=float)
        return None

    def wheel_speeds(self) -> tuple[np.ndarray, np.ndarray] | None:
        """(t, ω of shape (N, 4) in rad/s) from the estimate, else the reference, else ``None``."""
        cols = list(ch.WHEEL_SPEEDS)
        for df, t in ((self.est, self.t_est), (self.ref, self.t_ref)):
            if all(c in df.columns for c in cols):
                return t, df[cols].to_numpy(dtype=float)
        return None

    def scorable(self) -> list[str]:
        """Estimated channels that have a reference, in the spec's column order."""
        names = [c for c in self.est.columns
                 if isinstance(c, str) and c != ch.T
                 and not c.startswith((ch.REF_PREFIX, ch.SIGMA_PREFIX))
                 and self.reference(c) is not None]
        return ch.canonical_order(names)

    def scores(self) -> dict[str, dict[str, Any]]:
        """The :func:`vestim.metrics.score` row of every scorable channel, by channel name
        (empty without a reference). Computed once."""
        if self._scores is None:
            names = self.scorable()
            table = score(self.est, self.ref, channels=names) if names else None
            self._scores = ({} if table is None else
                            {str(r["channel"]): {str(k): v for k, v in r.items()}
                             for r in table.to_dict(orient="records")})
        return self._scores

    def coverage(self) -> dict[str, dict[str, Any]]:
        """The :func:`vestim.metrics.coverage` row (share of samples with |error| ≤ 1σ and
        ≤ 2σ) of every scorable channel that has a ``sigma_`` column, by channel name (empty
        when none has). Computed once."""
        if self._coverage is None:
            names = [n for n in self.scorable() if self.sigma(n) is not None]
            table = coverage(self.est, self.ref, channels=names) if names else None
            self._coverage = ({} if table is None else
                              {str(r["channel"]): {str(k): v for k, v in r.items()}
                               for r in table.to_dict(orient="records")})
        return self._coverage

    def coverage_text(self, name: str) -> str:
        """``"within 1σ 68 %, 2σ 95 %"`` for a channel with a σ and a reference, else ``""``."""
        row = self.coverage().get(name)
        if row is None or not row["samples"]:
            return ""
        return (f"within 1σ {100 * row['within_1sigma']:.0f} %, "
                f"2σ {100 * row['within_2sigma']:.0f} %")

    def score_text(self, name: str) -> str:
        """``"NRMS 3.21 %, RMSE 0.12 m/s"`` for a scored channel (NRMS to 3 significant
        figures, :func:`vestim.metrics.significant`; ``*``: floor used), followed by its σ
        coverage (:meth:`coverage_text`) where it has a σ; else ``""``."""
        row = self.scores().get(name)
        if row is None or not np.isfinite(row["nrms_pct"]):
            return ""
        star = "*" if bool(row["floored"]) else ""
        unit = f" {row['unit']}" if row["unit"] not in ("", "-") else ""
        cover = self.coverage_text(name)
        return (f"NRMS {significant(row['nrms_pct'])} %{star}, RMSE {row['rmse']:.3g}{unit}"
                + (f", {cover}" if cover else ""))

    def invalid_spans(self, group: str) -> list[Span]:
        """:func:`invalid_spans` of ``valid_<group>`` and ``reason_<group>`` on :attr:`t_est`
        (empty when the estimate lacks either)."""
        valid, reason = f"valid_{group}", f"reason_{group}"
        if not (self.has(valid) and self.has(reason)):
            return []
        return invalid_spans(self.t_est, self.estimate(valid), self.estimate(reason))

    @staticmethod
    def reasons(mask: int) -> list[str]:
        """The reasons of a ``reason_*`` mask, decoded by
        :func:`vestim.estimators.validity.reason_names` (``[]`` for 0)."""
        return reason_names(mask)

    def corners_with(self, prefix: str) -> list[str]:
        """Corners whose ``<prefix>_<corner>`` the estimate has."""
        return [c for c in CORNERS if self.has(f"{prefix}_{c}")]
