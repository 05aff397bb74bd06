"""Figures of an estimate against ground truth, the papers' figure types (``vestim plot``).

:func:`plot_estimate` writes up to six PNG files, each skipped (without error) when
the estimate lacks its channels:

=========================  ==================================================================
``speed_cg_wheels.png``    estimated and reference CG v_x with wheel-periphery speeds R·ω per
                           corner (000 Fig. 11)
``velocity_cg.png``        CG v_x and v_y, estimate against reference
``velocity_corners.png``   corner v_x, one panel per corner
``force_fx.png``           F_x per corner (2×2 grid, front on top, left on the left), ±σ band
``force_fy.png``           F_y per corner, as F_x
``force_fz.png``           F_z per corner, as F_x
=========================  ==================================================================

Where a ``sigma_<name>`` column exists the estimate is drawn with a ±1σ band. Long
logs are reduced to a min/max envelope of :data:`MAX_POINTS` points per line before
drawing, which keeps peaks visible, drawing fast and every PNG well under 300 kB.
"""

from __future__ import annotations

import os
from collections.abc import Callable, Sequence
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt
import numpy as np
import pandas as pd
from matplotlib.axes import Axes
from matplotlib.figure import Figure

from vestim.constants import CORNERS
from vestim.errors import LogFormatError
from vestim.io import channels as ch
from vestim.report.plots import save_figure

__all__ = ["ANTIALIAS_MAX_POINTS", "FIGURE_FILES", "MAX_POINTS", "plot_estimate"]

FIGURE_FILES: dict[str, str] = {
    "speed": "speed_cg_wheels.png",
    "velocity_cg": "velocity_cg.png",
    "velocity_corners": "velocity_corners.png",
    "force_fx": "force_fx.png",
    "force_fy": "force_fy.png",
    "force_fz": "force_fz.png",
}
"""File name of each figure :func:`plot_estimate` can write, in the order it writes them."""

MAX_POINTS = 2000
"""Most points drawn per line; a longer series is drawn as its min/max envelope (1000
buckets, about one per pixel column of a figure 1100 px wide)."""

ANTIALIAS_MAX_POINTS = 500
"""Lines of more points are drawn without antialiasing: at several points per pixel column
it adds nothing visible, but its blended pixels make a noisy trace's PNG several times larger."""

_GRID: dict[str, tuple[int, int]] = {"fl": (0, 0), "fr": (0, 1), "rl": (1, 0), "rr": (1, 1)}
"""Panel of each corner in a 2×2 grid: front row on top, left column on the left."""

_FIGSIZE = (10.0, 6.5)  # in; at save_figure's 110 dpi: 1100 × 715 px
_EST_COLOR = "tab:blue"
_WHEEL_COLORS = ("tab:orange", "tab:green", "tab:red", "tab:purple")  # never the estimate's blue


def _envelope(t: np.ndarray, y: np.ndarray, max_points: int = MAX_POINTS) -> tuple[np.ndarray, np.ndarray]:
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


def _band(t: np.ndarray, y: np.ndarray, s: np.ndarray,
          max_points: int = MAX_POINTS) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Lower and upper edge y ∓ s of a ±σ band, reduced to at most ``max_points`` points."""
    lower, upper = y - s, y + s
    n = t.size
    if n <= max_points:
        return t, lower, upper
    starts = np.linspace(0, n, max_points, endpoint=False).astype(np.intp)
    return t[starts], np.fmin.reduceat(lower, starts), np.fmax.reduceat(upper, starts)


def _smooth(t: np.ndarray) -> bool:
    """Whether a line of these points is drawn antialiased (see :data:`ANTIALIAS_MAX_POINTS`)."""
    return bool(t.size <= ANTIALIAS_MAX_POINTS)


class _Logs:
    """Read-only view of the estimate and the reference (``ref_`` channels) as float arrays."""

    def __init__(self, estimate: pd.DataFrame, reference: pd.DataFrame | None) -> None:
        self.est = estimate
        self.ref = reference if reference is not None else estimate
        self.t_est = self._time(self.est, "estimate")
        self.t_ref = self._time(self.ref, "reference")

    @staticmethod
    def _time(df: pd.DataFrame, name: str) -> np.ndarray:
        if ch.T not in df.columns:
            raise LogFormatError(f"{name}: no time column 't'; add one in s")
        return df[ch.T].to_numpy(dtype=float)

    def has(self, name: str) -> bool:
        return name in self.est.columns

    def estimate(self, name: str) -> np.ndarray:
        return self.est[name].to_numpy(dtype=float)

    def sigma(self, name: str) -> np.ndarray | None:
        col = ch.SIGMA_PREFIX + name
        return self.est[col].to_numpy(dtype=float) if col in self.est.columns else None

    def reference(self, name: str) -> np.ndarray | None:
        col = ch.REF_PREFIX + name
        return self.ref[col].to_numpy(dtype=float) if col in self.ref.columns else None

    def wheel_speeds(self) -> tuple[np.ndarray, np.ndarray] | None:
        """(t, ω of shape (N, 4)) from the estimate, else the reference, else ``None``."""
        cols = list(ch.WHEEL_SPEEDS)
        for df, t in ((self.est, self.t_est), (self.ref, self.t_ref)):
            if all(c in df.columns for c in cols):
                return t, df[cols].to_numpy(dtype=float)
        return None


def _draw(ax: Axes, logs: _Logs, name: str, unit: str, *, label: str = "estimate",
          lw: float = 1.0, legend: bool = True) -> None:
    """Reference, estimate and ±σ band of channel ``name`` on ``ax``."""
    ref = logs.reference(name)
    if ref is not None:
        tt, yy = _envelope(logs.t_ref, ref)
        # truth on top (zorder 3) so a noisy estimate cannot hide it
        ax.plot(tt, yy, color="k", lw=lw + 0.2, antialiased=_smooth(tt), label="reference", zorder=3)
    if logs.has(name):
        y = logs.estimate(name)
        s = logs.sigma(name)
        if s is not None:
            tb, lo, hi = _band(logs.t_est, y, s)
            ax.fill_between(tb, lo, hi, color=_EST_COLOR, alpha=0.25, lw=0, label="±1σ")
        tt, yy = _envelope(logs.t_est, y)
        ax.plot(tt, yy, color=_EST_COLOR, lw=lw, antialiased=_smooth(tt), label=label)
    else:
        ax.text(0.5, 0.5, "no estimate", ha="center", va="center", transform=ax.transAxes,
                color="0.4")
    ax.set_ylabel(f"{name} [{unit}]")
    ax.grid(alpha=0.3)
    if legend and ax.get_legend_handles_labels()[0]:
        ax.legend(fontsize=7, loc="best")


def _speed_figure(logs: _Logs, wheel_radius: float | None) -> Figure | None:
    if not logs.has("vx"):
        return None
    fig, ax = plt.subplots(figsize=_FIGSIZE, constrained_layout=True)
    wheels = logs.wheel_speeds()
    if wheels is not None and wheel_radius is not None:
        t, omega = wheels
        for i, corner in enumerate(CORNERS):
            tt, yy = _envelope(t, wheel_radius * omega[:, i])
            ax.plot(tt, yy, lw=0.6, color=_WHEEL_COLORS[i], antialiased=_smooth(tt),
                    label=f"R·ω {corner}", zorder=1)
    _draw(ax, logs, "vx", "m/s", label="estimate vx (CG)", lw=1.6, legend=False)
    ax.set_xlabel("t [s]")
    ax.set_title("CG longitudinal speed and wheel-periphery speeds (cf. 000 Fig. 11)")
    ax.legend(fontsize=7, ncol=2, loc="best")
    return fig


def _rows_figure(logs: _Logs, names: Sequence[str], title: str) -> Figure | None:
    present = [n for n in names if logs.has(n)]
    if not present:
        return None
    fig, axes = plt.subplots(len(present), 1, figsize=_FIGSIZE, sharex=True, squeeze=False,
                             constrained_layout=True)
    for ax, name in zip(axes[:, 0], present, strict=True):
        _draw(ax, logs, name, ch.unit_of(name) or "")
    axes[-1, 0].set_xlabel("t [s]")
    fig.suptitle(title)
    return fig


def _corner_figure(logs: _Logs, prefix: str, title: str) -> Figure | None:
    names = ch.corner_columns(prefix)
    if not any(logs.has(n) for n in names):
        return None
    fig, axes = plt.subplots(2, 2, figsize=_FIGSIZE, sharex=True, constrained_layout=True)
    for corner, name in zip(CORNERS, names, strict=True):
        ax = axes[_GRID[corner]]
        _draw(ax, logs, name, ch.unit_of(name) or "", legend=corner == CORNERS[0])
        ax.set_title(corner, fontsize=9)
    for ax in axes[1, :]:
        ax.set_xlabel("t [s]")
    fig.suptitle(title)
    return fig


def plot_estimate(
    estimate: pd.DataFrame,
    reference: pd.DataFrame | None = None,
    *,
    wheel_radius: float | None = None,
    out_dir: str | os.PathLike[str],
) -> list[Path]:
    """Draw an estimate against its reference as PNG files in ``out_dir`` (see module doc).

    Each log is drawn against its own ``t`` (s); no interpolation is needed to plot.

    Args:
        estimate: log with ``t`` and estimated channels (``vx``, ``fx_fl``, …) and optional
            ``sigma_<name>``; ``omega_*`` (rad/s) are taken from it when present.
        reference: log with ``t`` and ``ref_`` channels (and ``omega_*``); ``None`` uses the
            estimate's own ``ref_`` columns (a simulator log that also carries estimates).
            Without a reference channel the estimate is drawn alone.
        wheel_radius: effective rolling radius R in m for the R·ω curves of
            ``speed_cg_wheels.png``; ``None`` leaves them out.
        out_dir: directory for the PNG files (created; existing files of the same names
            are replaced atomically).

    Returns:
        The paths written, in :data:`FIGURE_FILES` order; a figure whose estimated channels
        are all missing is skipped. Neither input is modified.

    Raises:
        LogFormatError: a log has no ``t`` column.
        ValueError: ``wheel_radius`` is not a positive finite number.
    """
    if wheel_radius is not None and not (np.isfinite(wheel_radius) and wheel_radius > 0):
        raise ValueError(f"wheel_radius must be a positive length in m, got {wheel_radius}")
    logs = _Logs(estimate, reference)
    out = Path(out_dir)
    builders: dict[str, Callable[[], Figure | None]] = {
        "speed": lambda: _speed_figure(logs, wheel_radius),
        "velocity_cg": lambda: _rows_figure(logs, ("vx", "vy"), "CG velocity, body frame"),
        "velocity_corners": lambda: _corner_figure(logs, "vx", "Wheel-centre longitudinal velocity"),
        "force_fx": lambda: _corner_figure(logs, "fx", "Longitudinal tire force (tire frame)"),
        "force_fy": lambda: _corner_figure(logs, "fy", "Lateral tire force (tire frame)"),
        "force_fz": lambda: _corner_figure(logs, "fz", "Normal load"),
    }
    written: list[Path] = []
    for key, build in builders.items():
        fig = build()
        if fig is not None:  # save_figure closes the figure, also when writing fails
            written.append(save_figure(fig, out / FIGURE_FILES[key]))
    return written
