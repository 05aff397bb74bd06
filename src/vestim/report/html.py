"""Self-contained interactive HTML report of one estimate (``vestim report``).

:func:`write_html_report` writes one HTML file per log. plotly.js is embedded once in the
page (no CDN, no network: the file works offline and can be mailed or archived); every
figure is a plotly div. Sections, each left out (and listed under "not in this estimate")
when the estimate lacks its channels:

1. summary, score table against the reference (:func:`vestim.metrics.score`) and the
   configuration/metadata (the estimate's ``df.attrs``, i.e. its Parquet metadata, plus
   the caller's ``metadata``);
2. speeds: CG v_x with the wheel-periphery speeds R·ω per corner (000 Fig. 11);
3. velocities: CG v_x, v_y and the corner v_x, v_y (body frame);
4. tire forces F_x, F_y (tire frame) and F_z per corner, with ±1σ bands from ``sigma_*``;
5. slip ratio and slip angle per corner;
6. friction use: μ_x = F_x/F_z against μ_y = F_y/F_z per corner (with the road μ circle
   when known) and the a_x–a_y (GG) diagram of the measured specific force;
7. validity and health timelines of any ``valid_*`` and ``health_*`` columns.

Every time plot of a validity group is shaded where its ``valid_<group>`` is 0, by reason
(``reason_<group>`` decoded by :func:`vestim.estimators.validity.reason_names`); the score
table and the panel titles give each channel's σ coverage (:func:`vestim.metrics.coverage`).

Conventions are those of the PNG figures (:mod:`vestim.report.style`): one colour per
corner everywhere, reference in black, one y range shared by (and zoom-linked across) the
four corner panels of a quantity, an error strip (estimate − reference, same unit) under
every value panel that has a reference, and the channel's NRMS (3 significant figures),
RMSE and σ coverage in its panel title.
Long logs are drawn as a min/max envelope of :data:`~vestim.report.data.MAX_POINTS` points
per line (scatter plots keep the sample of largest magnitude per time bucket), stored as
float32, so a 1 h log at 200 Hz gives a file of about 9 MB, of which 4.8 MB is plotly.js.
"""

from __future__ import annotations

import datetime as _dt
import html
import json
import math
import os
from collections.abc import Mapping, Sequence
from pathlib import Path
from types import ModuleType
from typing import Any

import numpy as np
import pandas as pd

from vestim.constants import CORNERS, G
from vestim.errors import optional_import
from vestim.io import channels as ch
from vestim.io.files import write_text_atomic
from vestim.metrics import channel_family, significant
from vestim.report.data import Logs, band, envelope, peak_points
from vestim.report.style import (
    CG_COLOR,
    CORNER_COLORS,
    CORNER_NAMES,
    GRID,
    INVALID_ALPHA,
    REASON_COLORS,
    REFERENCE_COLOR,
    SIGMA_ALPHA,
    axis_label,
    rgba,
    shared_range,
)

__all__ = ["FIGURES", "SECTIONS", "report_figures", "write_html_report"]

FIGURES: dict[str, str] = {
    "speed": "CG longitudinal speed and wheel-periphery speeds R·ω",
    "velocity_cg": "CG velocity (body frame)",
    "velocity_vx": "Wheel-centre longitudinal velocity v_x (body frame)",
    "velocity_vy": "Wheel-centre lateral velocity v_y (body frame)",
    "force_fx": "Longitudinal tire force F_x (tire frame)",
    "force_fy": "Lateral tire force F_y (tire frame)",
    "force_fz": "Normal load F_z",
    "slip_ratio": "Slip ratio (R·ω − v_xt)/max(R·ω, v_xt)",
    "slip_angle": "Slip angle atan(v_yt/v_xt) (tire frame)",
    "friction_corners": "Friction use per corner: μ_x = F_x/F_z against μ_y = F_y/F_z",
    "friction_gg": "GG diagram: measured specific force a_x against a_y",
    "validity": "Validity and health flags",
}
"""Key and title of every figure the report can hold; the div of figure ``k`` has id
``plot-k``."""

SECTIONS: tuple[tuple[str, str, tuple[str, ...]], ...] = (
    ("speeds", "Speeds and wheel speeds", ("speed",)),
    ("velocities", "CG and corner velocities", ("velocity_cg", "velocity_vx", "velocity_vy")),
    ("forces", "Tire forces per corner", ("force_fx", "force_fy", "force_fz")),
    ("slip", "Slip ratio and slip angle", ("slip_ratio", "slip_angle")),
    ("friction", "Friction use", ("friction_corners", "friction_gg")),
    ("validity", "Validity and health", ("validity",)),
)
"""(id, heading, figure keys) of the plot sections, in page order."""

_CORNER_PREFIX = {"velocity_vx": "vx", "velocity_vy": "vy", "force_fx": "fx", "force_fy": "fy",
                  "force_fz": "fz", "slip_ratio": "slip_ratio", "slip_angle": "slip_angle"}
_FLAG_PREFIXES = ("valid_", "health_")
_BAND_GROUP = {"speed": "velocity", "velocity_cg": "velocity", "velocity_vx": "velocity",
               "velocity_vy": "velocity", "force_fx": "force", "force_fy": "force",
               "force_fz": "force", "slip_ratio": "slip", "slip_angle": "slip"}
"""The validity group (``valid_<group>``, ``reason_<group>``) whose "not valid" spans are
shaded behind each time plot."""
_PLOT_PX = 1150
"""Width in px of a one-column figure's plot area (a 2×2 grid: half of it each), the
page's maximum width less the margins."""
_CHAR_PX = 6.5
"""Width in px of one character of a band label (10 px sans-serif)."""
_CONFIG = {"responsive": True, "displaylogo": False}
_TEMPLATE = "plotly_white"


def _plotly() -> tuple[ModuleType, Any, ModuleType]:
    """plotly's graph_objects, make_subplots and io, or a MissingDependencyError naming
    ``vestim[report]``."""
    go = optional_import("plotly.graph_objects", "report", "vestim report (HTML)")
    subplots = optional_import("plotly.subplots", "report", "vestim report (HTML)")
    pio = optional_import("plotly.io", "report", "vestim report (HTML)")
    return go, subplots.make_subplots, pio


def _f32(a: np.ndarray) -> np.ndarray:
    """float32 copy for plotly: half the bytes in the page, 7 significant digits."""
    return np.asarray(a, dtype=np.float32)


class _Builder:
    """Builds the report's plotly figures from a :class:`~vestim.report.data.Logs`."""

    def __init__(self, logs: Logs, wheel_radius: float) -> None:
        self.go, self.make_subplots, _ = _plotly()
        self.logs = logs
        self.R = wheel_radius

    # ---------------------------------------------------------------- primitives

    def _line(self, x: np.ndarray, y: np.ndarray, *, name: str, color: str, width: float = 1.2,
              group: str | None = None, legend: bool = True, dash: str | None = None) -> Any:
        return self.go.Scatter(x=_f32(x), y=_f32(y), mode="lines", name=name,
                               line={"color": color, "width": width, "dash": dash},
                               legendgroup=group or name, showlegend=legend)

    def _series(self, fig: Any, logs: Logs, name: str, color: str, row: int, col: int,
                err_row: int | None, *, label: str, legend: bool) -> None:
        """±σ band, estimate and reference of ``name`` at (row, col); error at (err_row, col)."""
        ref = logs.reference(name)
        if logs.has(name):
            y = logs.estimate(name)
            s = logs.sigma(name)
            if s is not None:
                tb, lo, hi = band(logs.t_est, y, s)
                fig.add_trace(self.go.Scatter(x=_f32(tb), y=_f32(hi), mode="lines", line={"width": 0},
                                              hoverinfo="skip", showlegend=False,
                                              legendgroup=f"σ {label}"), row=row, col=col)
                fig.add_trace(self.go.Scatter(x=_f32(tb), y=_f32(lo), mode="lines", line={"width": 0},
                                              fill="tonexty", fillcolor=rgba(color, SIGMA_ALPHA),
                                              name=f"±1σ {label}", legendgroup=f"σ {label}",
                                              showlegend=legend, hoverinfo="skip"),
                              row=row, col=col)
            tt, yy = envelope(logs.t_est, y)
            fig.add_trace(self._line(tt, yy, name=f"estimate {label}", color=color, group=label,
                                     legend=legend), row=row, col=col)
        if ref is not None:
            tt, yy = envelope(logs.t_ref, ref)
            fig.add_trace(self._line(tt, yy, name="reference", color=REFERENCE_COLOR, width=1.4,
                                     group="reference", legend=legend and row == 1 and col == 1),
                          row=row, col=col)
        if err_row is not None:
            err = logs.error(name)
            if err is not None:
                tt, ee = envelope(logs.t_est, err)
                fig.add_trace(self._line(tt, ee, name=f"error {label}", color=color, width=0.9,
                                         group=label, legend=False), row=err_row, col=col)

    @staticmethod
    def _axis_name(fig: Any, row: int, col: int) -> str:
        """plotly's short y-axis name ('y', 'y3', …) of subplot (row, col)."""
        return str(fig.get_subplot(row, col).xaxis.anchor)

    def _share_y(self, fig: Any, cells: Sequence[tuple[int, int]], rng: tuple[float, float] | None) -> None:
        """One y range on ``cells``, zoom-linked (plotly ``matches``)."""
        if not cells:
            return
        first = self._axis_name(fig, *cells[0])
        for k, (r, c) in enumerate(cells):
            kw: dict[str, Any] = {"range": list(rng)} if rng is not None else {}
            if k:
                kw["matches"] = first
            fig.update_yaxes(row=r, col=c, **kw)

    def _bands(self, fig: Any, group: str, cells: Sequence[tuple[str, str]], *,
               legend: bool = True) -> None:
        """Shade every span where ``valid_<group>`` is 0 on the subplots ``cells`` ((x axis,
        y reference) pairs), coloured by its first reason (:data:`REASON_COLORS`), named in
        the legend as "<group> not valid: <reasons>" and labelled in place where its width
        on the page holds the label."""
        logs = self.logs
        spans = logs.invalid_spans(group)
        if not spans:
            return
        duration = float(logs.t_est[-1] - logs.t_est[0]) or 1.0
        px_per_s = _PLOT_PX / len({x for x, _ in cells}) / duration
        shown: set[str] = set()
        shapes: list[dict[str, Any]] = []
        for x0, x1, mask in spans:
            names = logs.reasons(mask)
            text = ", ".join(names) or "no reason given"
            name = f"{group} not valid: {text}"
            color = REASON_COLORS[names[0]] if names else REASON_COLORS["not converged"]
            for k, (xref, yref) in enumerate(cells):
                first = legend and k == 0 and name not in shown
                shape: dict[str, Any] = {
                    "type": "rect", "xref": xref, "yref": yref, "x0": x0, "x1": x1, "y0": 0,
                    "y1": 1, "fillcolor": color, "opacity": INVALID_ALPHA, "line": {"width": 0},
                    "layer": "below", "name": name, "legendgroup": name, "showlegend": first}
                if k == 0 and (x1 - x0) * px_per_s >= _CHAR_PX * (len(text) + 2):
                    shape["label"] = {"text": text, "textposition": "top left",
                                      "font": {"size": 10, "color": "#444444"}}
                shapes.append(shape)
                if first:
                    shown.add(name)
        # one assignment: plotly re-validates every shape on each add_shape (quadratic)
        fig.layout.shapes = (*fig.layout.shapes, *shapes)

    def _columns(self, fig: Any, cols: int) -> list[tuple[str, str]]:
        """(x axis, "paper") of each column of ``fig``: a band spans every row of a column."""
        return [(str(fig.get_subplot(1, c).yaxis.anchor), "paper") for c in range(1, cols + 1)]

    def _layout(self, fig: Any, key: str, height: int) -> Any:
        fig.update_layout(title={"text": FIGURES[key], "x": 0.01}, template=_TEMPLATE, height=height,
                          margin={"l": 70, "r": 20, "t": 70, "b": 95},
                          legend={"orientation": "h", "yref": "container", "y": 0.005,
                                  "yanchor": "bottom", "font": {"size": 11}})
        return fig

    # ---------------------------------------------------------------- figures

    def speed(self) -> Any | None:
        logs = self.logs
        if not logs.has("vx"):
            return None
        errors = logs.error("vx") is not None
        fig = self.make_subplots(rows=2 if errors else 1, cols=1, shared_xaxes=True,
                                 row_heights=[0.75, 0.25] if errors else None, vertical_spacing=0.05,
                                 subplot_titles=[logs.score_text("vx")])
        wheels = logs.wheel_speeds()
        if wheels is not None:
            t, omega = wheels
            for i, c in enumerate(CORNERS):
                tt, yy = envelope(t, self.R * omega[:, i])
                fig.add_trace(self._line(tt, yy, name=f"R·ω {c}", color=CORNER_COLORS[c], width=0.8),
                              row=1, col=1)
        self._series(fig, logs, "vx", CG_COLOR, 1, 1, 2 if errors else None,
                     label="v_x (CG)", legend=True)
        fig.update_yaxes(title_text="speed [m/s]", row=1, col=1)
        if errors:
            fig.update_yaxes(title_text="error v_x [m/s]", row=2, col=1)
        fig.update_xaxes(title_text="t [s]", row=2 if errors else 1, col=1)
        return self._layout(fig, "speed", 560)

    def velocity_cg(self) -> Any | None:
        logs = self.logs
        present = [n for n in ("vx", "vy") if logs.has(n)]
        if not present:
            return None
        errors = any(logs.error(n) is not None for n in present)
        step = 2 if errors else 1
        heights = [0.36, 0.14] * len(present) if errors else None
        titles: list[str] = []
        for n in present:
            titles += [logs.score_text(n)] + ([""] if errors else [])
        fig = self.make_subplots(rows=step * len(present), cols=1, shared_xaxes=True,
                                 row_heights=heights, vertical_spacing=0.04, subplot_titles=titles)
        for k, n in enumerate(present):
            label = axis_label(n, ch.unit_of(n))
            self._series(fig, logs, n, CG_COLOR, step * k + 1, 1, step * k + 2 if errors else None,
                         label=f"{n} (CG)", legend=True)
            fig.update_yaxes(title_text=label, row=step * k + 1, col=1)
            if errors:
                fig.update_yaxes(title_text=f"error [{ch.unit_of(n)}]", row=step * k + 2, col=1)
        fig.update_xaxes(title_text="t [s]", row=step * len(present), col=1)
        return self._layout(fig, "velocity_cg", 300 * len(present) + 120)

    def corners(self, key: str) -> Any | None:
        logs = self.logs
        prefix = _CORNER_PREFIX[key]
        names = ch.corner_columns(prefix)
        if not any(logs.has(n) for n in names):
            return None
        errors = any(logs.error(n) is not None for n in names)
        step = 2 if errors else 1
        titles = [""] * (4 * step)
        for c, n in zip(CORNERS, names, strict=True):
            r, col = GRID[c]
            score = logs.score_text(n)
            text = f"{CORNER_NAMES[c]} ({c})" + (f" · {score}" if score else "")
            if not logs.has(n):
                text += " · no estimate"
            titles[step * r * 2 + col] = f"<span style='color:{CORNER_COLORS[c]}'>{text}</span>"
        fig = self.make_subplots(rows=2 * step, cols=2, shared_xaxes=True,
                                 row_heights=[0.36, 0.14, 0.36, 0.14] if errors else None,
                                 vertical_spacing=0.05, horizontal_spacing=0.07, subplot_titles=titles)
        unit = ch.unit_of(names[0])
        label = axis_label(prefix, unit)
        value_cells, error_cells = [], []
        for c, n in zip(CORNERS, names, strict=True):
            r, col = GRID[c]
            row = step * r + 1
            self._series(fig, logs, n, CORNER_COLORS[c], row, col + 1, row + 1 if errors else None,
                         label=c, legend=True)
            fig.update_yaxes(title_text=label, row=row, col=col + 1)
            value_cells.append((row, col + 1))
            if errors:
                fig.update_yaxes(title_text=f"error [{unit or '-'}]", row=row + 1, col=col + 1)
                error_cells.append((row + 1, col + 1))
        values: list[np.ndarray | None] = []
        for n in names:
            values.append(logs.reference(n))
            if logs.has(n):
                y = logs.estimate(n)
                s = logs.sigma(n)
                values += [y] if s is None else [y - s, y + s]
        self._share_y(fig, value_cells, shared_range(values))
        self._share_y(fig, error_cells, shared_range(logs.error(n) for n in names))
        for col in (1, 2):
            fig.update_xaxes(title_text="t [s]", row=2 * step, col=col)
        return self._layout(fig, key, 760 if errors else 600)

    def _mu(self, axis: str, c: str) -> tuple[np.ndarray | None, np.ndarray | None]:
        """(estimate, reference) of μ_axis = F_axis/F_z at corner c on t_est; estimate from
        ``mu_<axis>_<c>`` or the ratio of the estimated forces."""
        logs = self.logs
        name = f"mu_{axis}_{c}"
        est: np.ndarray | None = None
        if logs.has(name):
            est = logs.estimate(name)
        elif logs.has(f"f{axis}_{c}") and logs.has(f"fz_{c}"):
            with np.errstate(divide="ignore", invalid="ignore"):
                est = logs.estimate(f"f{axis}_{c}") / logs.estimate(f"fz_{c}")
        return est, logs.reference_at_estimate(name)

    def friction_corners(self) -> Any | None:
        data = {c: (self._mu("x", c), self._mu("y", c)) for c in CORNERS}
        if all(mx[0] is None or my[0] is None for mx, my in data.values()):
            return None
        titles = [""] * 4
        for c in CORNERS:
            r, col = GRID[c]
            titles[2 * r + col] = f"<span style='color:{CORNER_COLORS[c]}'>{CORNER_NAMES[c]} ({c})</span>"
        fig = self.make_subplots(rows=2, cols=2, subplot_titles=titles, vertical_spacing=0.1,
                                 horizontal_spacing=0.08)
        extent: list[np.ndarray | None] = []
        for k, c in enumerate(CORNERS):
            (ex, rx), (ey, ry) = data[c]
            r, col = GRID[c]
            if rx is not None and ry is not None:
                idx = peak_points(rx, ry)
                fig.add_trace(self.go.Scatter(x=_f32(ry[idx]), y=_f32(rx[idx]), mode="markers",
                                              name="reference", legendgroup="reference",
                                              showlegend=k == 0,
                                              marker={"color": REFERENCE_COLOR, "size": 3, "opacity": 0.6}),
                              row=r + 1, col=col + 1)
                extent += [np.abs(rx[idx]), np.abs(ry[idx])]
            if ex is not None and ey is not None:
                idx = peak_points(ex, ey)
                fig.add_trace(self.go.Scatter(x=_f32(ey[idx]), y=_f32(ex[idx]), mode="markers",
                                              name=f"estimate {c}", legendgroup=c,
                                              marker={"color": CORNER_COLORS[c], "size": 4, "opacity": 0.6}),
                              row=r + 1, col=col + 1)
                extent += [np.abs(ex[idx]), np.abs(ey[idx])]
            mu = self._road_mu(c)
            if mu is not None:
                phi = np.linspace(0.0, 2.0 * np.pi, 181)
                fig.add_trace(self._line(mu * np.cos(phi), mu * np.sin(phi), name="road μ circle",
                                         color="#777777", width=1.0, dash="dash", group="road μ",
                                         legend=k == 0), row=r + 1, col=col + 1)
                extent.append(np.array([mu]))
        rng = shared_range(extent)
        lim = 1.0 if rng is None else rng[1]
        for c in CORNERS:
            r, col = GRID[c]
            fig.update_xaxes(range=[-lim, lim], title_text="μ_y = F_y/F_z [-]", row=r + 1, col=col + 1)
            fig.update_yaxes(range=[-lim, lim], title_text="μ_x = F_x/F_z [-]", row=r + 1, col=col + 1,
                             scaleanchor=str(fig.get_subplot(r + 1, col + 1).yaxis.anchor), scaleratio=1)
        return self._layout(fig, "friction_corners", 900)

    def _road_mu(self, c: str) -> float | None:
        """Largest road friction μ at corner c (reference, else estimate) for the circle."""
        logs = self.logs
        for values in (logs.reference(f"mu_{c}"), logs.estimate(f"mu_{c}") if logs.has(f"mu_{c}") else None):
            if values is not None and np.isfinite(values).any():
                return float(np.nanmax(values))
        return None

    def friction_gg(self) -> Any | None:
        logs = self.logs
        ax, ay = logs.measured("ax"), logs.measured("ay")
        if ax is None or ay is None or ax[0] is not ay[0]:
            return None
        idx = peak_points(ax[1], ay[1])
        fig = self.go.Figure()
        fig.add_trace(self.go.Scatter(x=_f32(ay[1][idx]), y=_f32(ax[1][idx]), mode="markers",
                                      name="measured a_x, a_y",
                                      marker={"color": CG_COLOR, "size": 4, "opacity": 0.6}))
        phi = np.linspace(0.0, 2.0 * np.pi, 181)
        fig.add_trace(self._line(G * np.cos(phi), G * np.sin(phi), name="1 g = 9.81 m/s²",
                                 color="#777777", width=1.0, dash="dash"))
        rng = shared_range([np.abs(ax[1][idx]), np.abs(ay[1][idx]), np.array([G])])
        lim = G if rng is None else rng[1]
        fig.update_xaxes(range=[-lim, lim], title_text="a_y (specific force, left +) [m/s²]")
        fig.update_yaxes(range=[-lim, lim], title_text="a_x (specific force, forward +) [m/s²]",
                         scaleanchor="x", scaleratio=1)
        self._layout(fig, "friction_gg", 560)
        fig.update_layout(width=620)
        return fig

    def validity(self) -> Any | None:
        logs = self.logs
        cols = [c for c in logs.est.columns if isinstance(c, str) and c.startswith(_FLAG_PREFIXES)]
        if not cols:
            return None
        fig = self.make_subplots(rows=len(cols), cols=1, shared_xaxes=True, vertical_spacing=0.02)
        for k, name in enumerate(cols):
            if name.startswith("valid_"):
                sub = fig.get_subplot(k + 1, 1)
                self._bands(fig, name[len("valid_"):],
                            [(str(sub.yaxis.anchor), f"{sub.xaxis.anchor} domain")])
            corner = next((c for c in CORNERS if name.endswith("_" + c)), None)
            color = CORNER_COLORS[corner] if corner else CG_COLOR
            tt, yy = envelope(logs.t_est, logs.estimate(name))
            tr = self._line(tt, yy, name=name, color=color, legend=False)
            tr.update(line_shape="hv", fill="tozeroy", fillcolor=rgba(color, 0.15))
            fig.add_trace(tr, row=k + 1, col=1)
            unit = ch.unit_of(name)
            fig.update_yaxes(title_text=f"{name} [{unit or '-'}]", title_font={"size": 10},
                             row=k + 1, col=1)
        fig.update_xaxes(title_text="t [s]", row=len(cols), col=1)
        return self._layout(fig, "validity", 90 * len(cols) + 140)

    def build(self) -> dict[str, Any]:
        out: dict[str, Any] = {}
        for key in FIGURES:
            fig = self.corners(key) if key in _CORNER_PREFIX else getattr(self, key)()
            if fig is not None:
                if key in _BAND_GROUP:
                    self._bands(fig, _BAND_GROUP[key],
                                self._columns(fig, 2 if key in _CORNER_PREFIX else 1))
                out[key] = fig
        return out


def report_figures(estimate: pd.DataFrame, reference: pd.DataFrame | None, *,
                   wheel_radius: float) -> dict[str, Any]:
    """The report's plotly figures by key of :data:`FIGURES`, those without channels left out.

    Args and raises as :func:`write_html_report` (``wheel_radius`` in m).
    """
    _check_radius(wheel_radius)
    return _Builder(Logs(estimate, reference), wheel_radius).build()


def _check_radius(wheel_radius: float) -> None:
    if not (isinstance(wheel_radius, int | float) and math.isfinite(wheel_radius) and wheel_radius > 0):
        raise ValueError(f"wheel_radius must be a positive length in m, got {wheel_radius}")


# ------------------------------------------------------------------------------ page

_CSS = """
body{font-family:system-ui,-apple-system,'Segoe UI',Roboto,sans-serif;margin:0 auto;max-width:1400px;
padding:0 24px 48px;color:#222}
h1{font-size:1.6em;margin:24px 0 4px}h2{margin-top:36px;border-bottom:1px solid #ddd;padding-bottom:4px}
table{border-collapse:collapse;font-size:0.9em;margin:8px 0}
td,th{border:1px solid #ddd;padding:3px 8px;text-align:right}th{background:#f4f4f4}
td:first-child,th:first-child{text-align:left}
table.kv td,table.kv th{text-align:left}.note{color:#555;font-size:0.9em}
.legend span{display:inline-block;margin-right:14px}
.swatch{display:inline-block;width:14px;height:4px;vertical-align:middle;margin-right:4px}
nav a{margin-right:12px}
"""


def _fmt(x: Any, digits: int = 4) -> str:
    v = float(x)
    return "–" if math.isnan(v) else f"{v:.{digits}g}"


def _samples_cell(r: Mapping[str, Any]) -> str:
    """Samples used, and why others were not: a road friction μ is NaN where the tire used
    too little of it to tell (``mu_*_excited`` = 0), so its left-out rows are "not excited"."""
    used, skipped = int(r["samples"]), int(r["skipped"])
    if channel_family(str(r["channel"])) == "mu" and skipped:
        return "not excited" if used == 0 else f"{used} ({skipped} not excited)"
    return f"{used}" + (f" ({skipped} NaN skipped)" if skipped else "")


def _score_table(logs: Logs) -> str:
    rows = logs.scores()
    if not rows:
        return ("<p class='note'>No reference channels: give a reference log (REF) with "
                "<code>ref_</code> columns to score the estimate.</p>")
    cover = logs.coverage()
    lines = ["<table class='scores' id='score-table'><tr><th>channel</th><th>unit</th>"
             "<th>NRMS [%]</th><th>RMSE</th><th>max error</th><th>max |ref|</th><th>floor</th>"
             "<th>within 1σ [%]</th><th>within 2σ [%]</th><th>samples</th></tr>"]
    floored = False
    for r in rows.values():
        pct = significant(r["nrms_pct"])
        if bool(r["floored"]):
            pct += "*"
            floored = True
        c = cover.get(str(r["channel"]))
        within = (["–", "–"] if c is None or not c["samples"] else
                  [f"{100 * c['within_1sigma']:.1f}", f"{100 * c['within_2sigma']:.1f}"])
        lines.append(f"<tr><td>{html.escape(r['channel'])}</td><td>{html.escape(r['unit'])}</td>"
                     f"<td>{pct}</td><td>{_fmt(r['rmse'])}</td><td>{_fmt(r['max_error'])}</td>"
                     f"<td>{_fmt(r['ref_max'])}</td><td>{_fmt(r['floor'])}</td>"
                     f"<td class='cover'>{within[0]}</td><td class='cover'>{within[1]}</td>"
                     f"<td>{html.escape(_samples_cell(r))}</td></tr>")
    lines.append("</table>")
    note = ("NRMS = RMS error / max(max|ref|, floor) (000 Sec. IV), to 3 significant figures; "
            "RMSE, max error, max |ref| and floor in the channel's unit. Within 1σ / 2σ: the "
            "share of samples whose |error| is at most the estimate's own σ (sigma_*) or 2σ; "
            "an honest Gaussian σ gives 68.3 % and 95.4 % (– where the estimate has no σ).")
    if floored:
        note += " * The truth stayed below the floor, so the floor was the denominator."
    lines.append(f"<p class='note'>{note}</p>")
    return "\n".join(lines)


def _kv_table(items: Mapping[str, Any], table_id: str) -> str:
    """Two-column table of ``items``; a value of several lines (a JSON list) keeps its lines."""
    if not items:
        return "<p class='note'>none</p>"
    rows = "".join(f"<tr><td>{html.escape(str(k))}</td>"
                   f"<td>{'<br>'.join(html.escape(x) for x in str(v).splitlines()) or '–'}</td></tr>"
                   for k, v in items.items())
    return f"<table class='kv' id='{table_id}'><tr><th>key</th><th>value</th></tr>{rows}</table>"


def _json(value: Any) -> Any:
    """``value`` parsed when it is a JSON object or array (Parquet metadata holds them as
    text), else ``value`` itself."""
    if isinstance(value, str) and value[:1] in "[{":
        try:
            return json.loads(value)
        except ValueError:
            return value
    return value


def _flatten(obj: Any, path: tuple[str, ...] = ()) -> list[tuple[str, str, str]]:
    """(table, parameter, value) rows of a nested configuration: ``{"force_params": {"ukf":
    {"r_omega": 0.18}}}`` → ``("force_params.ukf", "r_omega", "0.18")``."""
    if isinstance(obj, Mapping) and obj:
        return [row for k, v in obj.items() for row in _flatten(v, (*path, str(k)))]
    text = json.dumps(obj, ensure_ascii=False) if isinstance(obj, list | Mapping) else str(obj)
    return [(".".join(path[:-1]) or "pipeline", path[-1] if path else "", text)]


def _readable(value: Any) -> str:
    """A metadata value as text: a JSON list one item per line ("none" when empty), an item
    that is an object as ``key: value; …``."""
    value = _json(value)
    if isinstance(value, list):
        if not value:
            return "none"
        return "\n".join("; ".join(f"{k}: {v}" for k, v in item.items())
                         if isinstance(item, Mapping) else
                         (" … ".join(map(str, item)) if isinstance(item, list) else str(item))
                         for item in value)
    if isinstance(value, Mapping):
        return "\n".join(f"{k}: {v}" for k, v in value.items())
    return str(value)


def _config_table(config: Any) -> str:
    """The estimate's configuration (its ``config`` metadata, JSON) as a table of one row per
    parameter, grouped by the table it belongs to."""
    rows = _flatten(_json(config))
    body = "".join(f"<tr><td>{html.escape(t)}</td><td>{html.escape(k)}</td>"
                   f"<td>{html.escape(v)}</td></tr>" for t, k, v in rows)
    return ("<table class='kv' id='config-table'><tr><th>table</th><th>parameter</th>"
            f"<th>value</th></tr>{body}</table>")


def _legend() -> str:
    spans = "".join(f"<span><i class='swatch' style='background:{CORNER_COLORS[c]}'></i>"
                    f"{CORNER_NAMES[c]} ({c})</span>" for c in CORNERS)
    spans += (f"<span><i class='swatch' style='background:{CG_COLOR}'></i>CG estimate</span>"
              f"<span><i class='swatch' style='background:{REFERENCE_COLOR}'></i>reference</span>")
    return f"<p class='legend'>{spans}</p>"


def write_html_report(
    estimate: pd.DataFrame,
    reference: pd.DataFrame | None,
    out: str | os.PathLike[str],
    *,
    wheel_radius: float,
    metadata: Mapping[str, str] | None = None,
    title: str | None = None,
) -> Path:
    """Write the interactive report of ``estimate`` as one self-contained HTML file.

    Args:
        estimate: log with ``t`` (s) and estimated channels (spec names: ``vx``, ``fx_fl``,
            ``slip_angle_rr``, …, SI units), optional ``sigma_<name>``, ``valid_*`` and
            ``health_*``; its ``df.attrs`` (Parquet metadata) are listed in the report.
        reference: log with ``t`` and ``ref_`` channels (and the measured ``omega_*``,
            ``ax``, ``ay`` when the estimate lacks them); ``None`` uses the estimate's own
            ``ref_`` columns, if any, and then the report has no scores.
        out: the HTML file to write (parent folders created; replaced atomically).
        wheel_radius: effective rolling radius R in m for the R·ω curves.
        metadata: further key/value pairs to list (e.g. the vehicle, the file names).
        title: page title; default "vestim report".

    Returns:
        ``out`` as a Path. Neither input is modified.

    Raises:
        MissingDependencyError: plotly is not installed (``pip install 'vestim[report]'``).
        LogFormatError: a log has no ``t``, an invalid ``t``, or the logs do not overlap.
        ValueError: ``wheel_radius`` is not a positive finite length.
    """
    _check_radius(wheel_radius)
    _, _, pio = _plotly()
    plotly_js = optional_import("plotly.offline", "report", "vestim report (HTML)").get_plotlyjs()
    logs = Logs(estimate, reference)
    figures = _Builder(logs, wheel_radius).build()
    page_title = title or "vestim report"

    t = logs.t_est
    summary = {
        "samples": f"{t.size}",
        "time span": (f"{t[0]:.3f} … {t[-1]:.3f} s ({t[-1] - t[0]:.1f} s)" if t.size else "empty"),
        "columns besides t": f"{sum(1 for c in estimate.columns if c != ch.T)}",
        "reference": ("given" if reference is not None else
                      ("estimate's own ref_ columns" if logs.scorable() else "none")),
        "wheel radius R": f"{wheel_radius:g} m",
        "written": _dt.datetime.now(_dt.UTC).strftime("%Y-%m-%d %H:%M UTC"),
    }
    parts = [f"<h1>{html.escape(page_title)}</h1>", _legend(), "<nav>"]
    parts += [f"<a href='#{sid}'>{html.escape(head)}</a>" for sid, head, _ in SECTIONS]
    parts += ["<a href='#scores'>Scores</a><a href='#config'>Configuration</a></nav>",
              "<h2 id='summary'>Summary</h2>", _kv_table(summary, "summary-table")]
    missing: list[str] = []
    for sid, head, keys in SECTIONS:
        present = [k for k in keys if k in figures]
        if not present:
            if sid == "validity":
                parts += [f"<h2 id='{sid}'>{html.escape(head)}</h2>",
                          "<p class='note' id='no-validity'>no validity/health channels in this "
                          "estimate (columns named <code>valid_*</code> or <code>health_*</code>)</p>"]
            else:
                missing.append(head)
            continue
        parts.append(f"<h2 id='{sid}'>{html.escape(head)}</h2>")
        for key in present:
            parts.append(pio.to_html(figures[key], full_html=False, include_plotlyjs=False,
                                     div_id=f"plot-{key}", config=_CONFIG))
        skipped = [FIGURES[k] for k in keys if k not in figures]
        if skipped:
            parts.append("<p class='note'>not in this estimate: " +
                         html.escape("; ".join(skipped)) + "</p>")
    if missing:
        parts.append("<p class='note' id='missing-sections'>Sections without channels in this "
                     "estimate: " + html.escape("; ".join(missing)) + ".</p>")
    parts += ["<h2 id='scores'>Scores against the reference</h2>", _score_table(logs)]
    attrs = {str(k): v for k, v in estimate.attrs.items()}
    config = attrs.pop("config", None)
    parts += ["<h2 id='config'>Configuration and metadata</h2>",
              "<h3>Estimate metadata (df.attrs)</h3>",
              _kv_table({k: _readable(v) for k, v in attrs.items()}, "attrs-table")]
    if config is not None:
        parts += ["<h3>Pipeline configuration</h3>", _config_table(config)]
    parts += ["<h3>Report metadata</h3>", _kv_table(dict(metadata or {}), "metadata-table")]
    doc = ("<!DOCTYPE html>\n<html lang='en'><head><meta charset='utf-8'>"
           f"<title>{html.escape(page_title)}</title><style>{_CSS}</style>"
           f"<script type='text/javascript'>{plotly_js}</script></head><body>\n"
           + "\n".join(parts) + "\n</body></html>\n")
    return write_text_atomic(out, doc)
