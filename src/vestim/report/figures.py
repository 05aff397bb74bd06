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

Conventions (:mod:`vestim.report.style`, shared with the HTML report): one colour per
corner in every figure, the reference in black, CG estimates in orange; the four panels of
a per-corner quantity share one y range. Where a ``sigma_<name>`` column exists the
estimate is drawn with a ±1σ band. Where a reference exists each value panel has an error
strip (estimate − reference, same unit, below it; the four strips of a quantity share one
range too) and names its score, NRMS and RMSE of :func:`vestim.metrics.score` (``*``: the
NRMS floor was the denominator). Long logs are reduced to a min/max envelope of
:data:`MAX_POINTS` points per line before drawing, which keeps peaks visible, drawing fast
and every PNG well under 300 kB.
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
from vestim.io import channels as ch
from vestim.metrics import channel_family
from vestim.report.data import MAX_POINTS, Logs, band, envelope
from vestim.report.plots import save_figure
from vestim.report.style import (
    CG_COLOR,
    CORNER_COLORS,
    CORNER_NAMES,
    ERROR_ALPHA,
    GRID,
    REFERENCE_COLOR,
    SIGMA_ALPHA,
    axis_label,
    shared_range,
)

__all__ = ["ANTIALIAS_MAX_POINTS", "FIGURE_FILES", "MAX_POINTS", "estimate_figure", "plot_estimate"]

FIGURE_FILES: dict[str, str] = {
    "speed": "speed_cg_wheels.png",
    "velocity_cg": "velocity_cg.png",
    "velocity_corners": "velocity_corners.png",
    "force_fx": "force_fx.png",
    "force_fy": "force_fy.png",
    "force_fz": "force_fz.png",
}
"""File name of each figure :func:`plot_estimate` can write, in the order it writes them."""

ANTIALIAS_MAX_POINTS = 500
"""Lines of more points are drawn without antialiasing: at several points per pixel column
it adds nothing visible, but its blended pixels make a noisy trace's PNG several times larger."""

_FIGSIZE = (10.0, 6.5)  # in; at save_figure's 110 dpi: 1100 × 715 px
_FIGSIZE_ERR = (10.0, 8.0)  # with error strips: 1100 × 880 px
_MAIN, _ERR = 3, 1  # height ratio of a value panel and its error strip


def _smooth(t: np.ndarray) -> bool:
    """Whether a line of these points is drawn antialiased (see :data:`ANTIALIAS_MAX_POINTS`)."""
    return bool(t.size <= ANTIALIAS_MAX_POINTS)


def _extent(logs: Logs, name: str) -> list[np.ndarray | None]:
    """Every value the value panel of ``name`` draws (for the shared y range)."""
    arrays: list[np.ndarray | None] = [logs.reference(name)]
    if logs.has(name):
        y = logs.estimate(name)
        arrays.append(y)
        s = logs.sigma(name)
        if s is not None:
            arrays += [y - s, y + s]
    return arrays


def _draw(ax: Axes, err_ax: Axes | None, logs: Logs, name: str, ylabel: str, color: str, *,
          label: str = "estimate", lw: float = 1.0, legend: bool = True) -> None:
    """Reference, estimate and ±σ band of channel ``name`` on ``ax``; estimate − reference on
    ``err_ax``; the score (NRMS, RMSE) in the panel's corner."""
    ref = logs.reference(name)
    if ref is not None:
        tt, yy = envelope(logs.t_ref, ref)
        # truth on top (zorder 3) so a noisy estimate cannot hide it
        ax.plot(tt, yy, color=REFERENCE_COLOR, lw=lw + 0.2, antialiased=_smooth(tt),
                label="reference", zorder=3)
    if logs.has(name):
        y = logs.estimate(name)
        s = logs.sigma(name)
        if s is not None:
            tb, lo, hi = band(logs.t_est, y, s)
            ax.fill_between(tb, lo, hi, color=color, alpha=SIGMA_ALPHA, lw=0, label="±1σ")
        tt, yy = envelope(logs.t_est, y)
        ax.plot(tt, yy, color=color, lw=lw, antialiased=_smooth(tt), label=label)
    else:
        ax.text(0.5, 0.5, "no estimate", ha="center", va="center", transform=ax.transAxes,
                color="0.4")
    text = logs.score_text(name)
    if text:
        ax.text(0.01, 0.97, text, ha="left", va="top", transform=ax.transAxes, fontsize=7,
                bbox={"facecolor": "white", "alpha": 0.8, "lw": 0, "pad": 1.5}, zorder=5)
    ax.set_ylabel(ylabel)
    ax.grid(alpha=0.3)
    if err_ax is not None:
        err = logs.error(name)
        if err is not None:
            tt, ee = envelope(logs.t_est, err)
            err_ax.plot(tt, ee, color=color, lw=0.7, alpha=ERROR_ALPHA, antialiased=_smooth(tt))
        err_ax.axhline(0.0, color="0.5", lw=0.6)
        err_ax.set_ylabel("error", fontsize=8)
        err_ax.grid(alpha=0.3)
    if legend and ax.get_legend_handles_labels()[0]:
        ax.legend(fontsize=7, loc="best")


def _error_unit(ylabel: str) -> str:
    """``"error [N]"`` from ``"F_x [N]"``: an error strip has its value panel's unit."""
    return "error " + ylabel[ylabel.rfind("["):] if "[" in ylabel else "error"


def _share(axes: Sequence[Axes], rng: tuple[float, float] | None) -> None:
    if rng is not None:
        for ax in axes:
            ax.set_ylim(*rng)


def _has_errors(logs: Logs, names: Sequence[str]) -> bool:
    return any(logs.error(n) is not None for n in names)


def _speed_figure(logs: Logs, wheel_radius: float | None) -> Figure | None:
    if not logs.has("vx"):
        return None
    errors = _has_errors(logs, ["vx"])
    if errors:
        fig, (ax, err_ax) = plt.subplots(2, 1, figsize=_FIGSIZE_ERR, sharex=True,
                                         gridspec_kw={"height_ratios": [_MAIN, _ERR]},
                                         constrained_layout=True)
    else:
        fig, ax = plt.subplots(figsize=_FIGSIZE, constrained_layout=True)
        err_ax = None
    wheels = logs.wheel_speeds()
    if wheels is not None and wheel_radius is not None:
        t, omega = wheels
        for i, corner in enumerate(CORNERS):
            tt, yy = envelope(t, wheel_radius * omega[:, i])
            ax.plot(tt, yy, lw=0.6, color=CORNER_COLORS[corner], antialiased=_smooth(tt),
                    label=f"R·ω {corner}", zorder=1)
    _draw(ax, err_ax, logs, "vx", "speed [m/s]", CG_COLOR, label="estimate v_x (CG)", lw=1.6,
          legend=False)
    if err_ax is not None:
        err_ax.set_ylabel("error v_x [m/s]", fontsize=8)
    (err_ax or ax).set_xlabel("t [s]")
    ax.set_title("CG longitudinal speed and wheel-periphery speeds R·ω (cf. 000 Fig. 11)")
    ax.legend(fontsize=7, ncol=2, loc="best")
    return fig


def _rows_figure(logs: Logs, names: Sequence[str], title: str) -> Figure | None:
    present = [n for n in names if logs.has(n)]
    if not present:
        return None
    errors = _has_errors(logs, present)
    ratios = [_MAIN, _ERR] * len(present) if errors else [1] * len(present)
    fig, axes = plt.subplots(len(ratios), 1, figsize=_FIGSIZE_ERR if errors else _FIGSIZE,
                             sharex=True, squeeze=False, constrained_layout=True,
                             gridspec_kw={"height_ratios": ratios})
    step = 2 if errors else 1
    for k, name in enumerate(present):
        ylabel = axis_label(channel_family(name), ch.unit_of(name))
        err_ax = axes[step * k + 1, 0] if errors else None
        _draw(axes[step * k, 0], err_ax, logs, name, ylabel, CG_COLOR)
        if err_ax is not None:
            err_ax.set_ylabel(_error_unit(ylabel), fontsize=8)
    axes[-1, 0].set_xlabel("t [s]")
    fig.suptitle(title)
    return fig


def _corner_figure(logs: Logs, prefix: str, title: str) -> Figure | None:
    names = ch.corner_columns(prefix)
    if not any(logs.has(n) for n in names):
        return None
    errors = _has_errors(logs, names)
    ratios = [_MAIN, _ERR, _MAIN, _ERR] if errors else [1, 1]
    fig, axes = plt.subplots(len(ratios), 2, figsize=_FIGSIZE_ERR if errors else _FIGSIZE,
                             sharex=True, constrained_layout=True,
                             gridspec_kw={"height_ratios": ratios})
    step = 2 if errors else 1
    ylabel = axis_label(prefix, ch.unit_of(names[0]))
    value_axes: list[Axes] = []
    error_axes: list[Axes] = []
    for corner, name in zip(CORNERS, names, strict=True):
        row, col = GRID[corner]
        ax = axes[step * row, col]
        err_ax = axes[step * row + 1, col] if errors else None
        _draw(ax, err_ax, logs, name, ylabel, CORNER_COLORS[corner], legend=corner == CORNERS[0])
        ax.set_title(f"{CORNER_NAMES[corner]} ({corner})", fontsize=9, color=CORNER_COLORS[corner])
        value_axes.append(ax)
        if err_ax is not None:
            err_ax.set_ylabel(_error_unit(ylabel), fontsize=8)
            error_axes.append(err_ax)
    # one y range across the four corners, so the panels compare at a glance
    _share(value_axes, shared_range(a for n in names for a in _extent(logs, n)))
    _share(error_axes, shared_range(logs.error(n) for n in names))
    for ax in axes[-1, :]:
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
        LogFormatError: a log has no ``t`` column, or (with reference channels to score)
            an invalid ``t`` or logs that do not overlap in time (:func:`vestim.metrics.score`).
        ValueError: ``wheel_radius`` is not a positive finite number.
    """
    logs = _logs(estimate, reference, wheel_radius)
    out = Path(out_dir)
    written: list[Path] = []
    for key, build in _builders(logs, wheel_radius).items():
        fig = build()
        if fig is not None:  # save_figure closes the figure, also when writing fails
            written.append(save_figure(fig, out / FIGURE_FILES[key]))
    return written


def estimate_figure(
    estimate: pd.DataFrame,
    reference: pd.DataFrame | None,
    key: str,
    *,
    wheel_radius: float | None = None,
) -> Figure | None:
    """The one figure ``key`` of :data:`FIGURE_FILES` that :func:`plot_estimate` would save,
    unsaved (the caller closes it), or ``None`` when the estimate lacks its channels.

    Arguments and errors as :func:`plot_estimate`; an unknown ``key`` is a ValueError.
    """
    if key not in FIGURE_FILES:
        raise ValueError(f"unknown figure {key!r}; use one of {', '.join(FIGURE_FILES)}")
    logs = _logs(estimate, reference, wheel_radius)
    return _builders(logs, wheel_radius)[key]()


def _logs(estimate: pd.DataFrame, reference: pd.DataFrame | None, wheel_radius: float | None) -> Logs:
    if wheel_radius is not None and not (np.isfinite(wheel_radius) and wheel_radius > 0):
        raise ValueError(f"wheel_radius must be a positive length in m, got {wheel_radius}")
    return Logs(estimate, reference)


def _builders(logs: Logs, wheel_radius: float | None) -> dict[str, Callable[[], Figure | None]]:
    return {
        "speed": lambda: _speed_figure(logs, wheel_radius),
        "velocity_cg": lambda: _rows_figure(logs, ("vx", "vy"), "CG velocity, body frame"),
        "velocity_corners": lambda: _corner_figure(logs, "vx", "Wheel-centre longitudinal velocity"),
        "force_fx": lambda: _corner_figure(logs, "fx", "Longitudinal tire force (tire frame)"),
        "force_fy": lambda: _corner_figure(logs, "fy", "Lateral tire force (tire frame)"),
        "force_fz": lambda: _corner_figure(logs, "fz", "Normal load"),
    }
