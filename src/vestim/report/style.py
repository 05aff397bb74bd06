"""Figure conventions shared by the PNG figures and the HTML report, defined once.

- One colour per corner everywhere (:data:`CORNER_COLORS`, the Okabe–Ito colour-blind safe
  palette): the estimate of a corner quantity, its error trace and its ±σ band, the R·ω curve
  of that wheel and its friction-use points all use the corner's colour.
- The reference (ground truth) is always black (:data:`REFERENCE_COLOR`), CG quantities of
  the estimate are always :data:`CG_COLOR`.
- A per-corner quantity is drawn as a 2×2 grid, front row on top and left column on the
  left (:data:`GRID`), with one y range shared by the four panels (:func:`shared_range`).
- Axis labels name the quantity and the unit of what is plotted (:func:`axis_label`).
"""

from __future__ import annotations

from collections.abc import Iterable

import numpy as np

__all__ = [
    "CG_COLOR",
    "CORNER_COLORS",
    "CORNER_NAMES",
    "ERROR_ALPHA",
    "GRID",
    "INVALID_ALPHA",
    "QUANTITY_LABELS",
    "REASON_COLORS",
    "REFERENCE_COLOR",
    "SIGMA_ALPHA",
    "axis_label",
    "rgba",
    "shared_range",
]

CORNER_COLORS: dict[str, str] = {
    "fl": "#0072B2",  # blue
    "fr": "#D55E00",  # vermillion
    "rl": "#009E73",  # bluish green
    "rr": "#CC79A7",  # reddish purple
}
"""Colour of each corner (hex RGB), the same in every PNG figure and the HTML report."""

CG_COLOR = "#E69F00"
"""Colour of estimated CG quantities (v_x, v_y) and of the a_x–a_y diagram (orange)."""

REFERENCE_COLOR = "#000000"
"""Colour of the reference (ground truth): black, drawn on top of the estimate."""

SIGMA_ALPHA = 0.22
"""Opacity of a ±1σ band (in its corner's colour)."""

ERROR_ALPHA = 0.9
"""Opacity of an error trace (estimate − reference, in its corner's colour)."""

REASON_COLORS: dict[str, str] = {
    "not converged": "#9E9E9E",   # grey
    "standstill": "#F0E442",      # yellow
    "reverse": "#56B4E9",         # sky blue
    "high slip": "#E41A1C",       # red
    "unobservable": "#8E7CC3",    # violet
    "input faulty": "#6B4226",    # brown
    "v_y unverified": "#FF7F00",  # orange
    "inconsistent": "#E7298A",    # magenta
}
"""Colour of a shaded "not valid" band, by the first of its reasons
(:data:`vestim.estimators.validity.REASONS` names)."""

INVALID_ALPHA = 0.16
"""Opacity of a "not valid" band behind a time plot."""

CORNER_NAMES: dict[str, str] = {"fl": "front left", "fr": "front right",
                                "rl": "rear left", "rr": "rear right"}
"""Panel title of each corner."""

GRID: dict[str, tuple[int, int]] = {"fl": (0, 0), "fr": (0, 1), "rl": (1, 0), "rr": (1, 1)}
"""(row, column) of each corner in a 2×2 grid: front row on top, left column on the left."""

QUANTITY_LABELS: dict[str, str] = {
    "vx": "v_x", "vy": "v_y", "fx": "F_x", "fy": "F_y", "fz": "F_z",
    "slip_ratio": "slip ratio", "slip_angle": "slip angle", "mu_x": "μ_x = F_x/F_z",
    "mu_y": "μ_y = F_y/F_z", "mu": "road μ",
}
"""Readable name of each channel family (a channel name without its corner suffix)."""

def axis_label(quantity: str, unit: str | None) -> str:
    """``"F_x [N]"`` for family ``"fx"`` and unit ``"N"``; "-" or no unit gives ``"[-]"``."""
    name = QUANTITY_LABELS.get(quantity, quantity)
    return f"{name} [{unit or '-'}]"


def rgba(color: str, alpha: float) -> str:
    """CSS ``rgba(r,g,b,alpha)`` of a ``#rrggbb`` colour (for plotly fills)."""
    h = color.lstrip("#")
    r, g, b = (int(h[i:i + 2], 16) for i in (0, 2, 4))
    return f"rgba({r},{g},{b},{alpha:g})"


def shared_range(arrays: Iterable[np.ndarray | None], pad: float = 0.05) -> tuple[float, float] | None:
    """One (low, high) range holding every finite value of ``arrays``, padded by ``pad`` of
    the span on each side; ``None`` when there is no finite value. A constant signal gets a
    span of ±max(1 % of |value|, 1e-9) so the axis is not degenerate."""
    lo, hi = np.inf, -np.inf
    for a in arrays:
        if a is None or a.size == 0:
            continue
        finite = a[np.isfinite(a)]
        if finite.size:
            lo = min(lo, float(finite.min()))
            hi = max(hi, float(finite.max()))
    if not np.isfinite(lo):
        return None
    span = hi - lo
    if span <= 0.0:
        half = max(0.01 * abs(lo), 1e-9)
        return lo - half, hi + half
    return lo - pad * span, hi + pad * span
