"""Figures of simulated or recorded logs (PNG, written atomically)."""

from __future__ import annotations

from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt
import pandas as pd
from matplotlib.axes import Axes
from matplotlib.figure import Figure

from vestim.constants import CORNERS
from vestim.io.files import atomic_path
from vestim.report.style import CG_COLOR, CORNER_COLORS, REFERENCE_COLOR


def save_figure(fig: Figure, path: str | Path, dpi: int = 110) -> Path:
    """Write ``fig`` as PNG atomically (temporary file, then rename) and close it."""
    path = Path(path)
    try:
        with atomic_path(path) as tmp:
            fig.savefig(tmp, dpi=dpi, format="png")
    finally:
        plt.close(fig)
    return path


def plot_simulation(log: pd.DataFrame, wheel_radius: float, title: str = "") -> Figure:
    """Overview of a simulated log in ten panels, each of one quantity and one unit.

    Left column: CG speed with wheel-periphery speeds R·ω per corner (cf. 000 Fig. 11)
    [m/s]; slip ratios [-]; F_x per corner [N]; F_z per corner [N]; IMU specific force
    a_x, a_y [m/s²]. Right column: CG lateral velocity [m/s]; road friction μ per corner
    [-]; F_y per corner [N]; steering-wheel angle [rad] (road-wheel angles δ when the log
    has no steering-wheel channel); yaw rate [rad/s]. Corner colours are those of
    :data:`vestim.report.style.CORNER_COLORS`. Needs the ``ref_`` channels.

    Args:
        log: simulator log (``t`` in s, ``omega_*`` in rad/s, ``ref_`` channels).
        wheel_radius: effective rolling radius R in m for the R·ω curves.
        title: figure title; empty for none.
    """
    t = log["t"].to_numpy()
    fig, axes = plt.subplots(5, 2, figsize=(12, 12), sharex=True, constrained_layout=True)

    def corners(ax: Axes, prefix: str, ylabel: str, label: str = "") -> None:
        for c in CORNERS:
            ax.plot(t, log[f"{prefix}_{c}"], lw=0.9, color=CORNER_COLORS[c], label=f"{label}{c}")
        ax.set_ylabel(ylabel)
        ax.legend(fontsize=7, ncol=4)

    ax = axes[0, 0]
    for c in CORNERS:
        ax.plot(t, wheel_radius * log[f"omega_{c}"], lw=0.8, color=CORNER_COLORS[c],
                label=f"R·ω {c}")
    ax.plot(t, log["ref_vx"], color=REFERENCE_COLOR, lw=2, label="ref v_x (CG)")
    ax.set_ylabel("speed [m/s]")
    ax.legend(fontsize=7, ncol=2)
    ax = axes[0, 1]
    ax.plot(t, log["ref_vy"], color=REFERENCE_COLOR, lw=1.2, label="ref v_y (CG)")
    ax.set_ylabel("lateral velocity v_y [m/s]")
    ax.legend(fontsize=7)
    corners(axes[1, 0], "ref_slip_ratio", "slip ratio [-]")
    corners(axes[1, 1], "ref_mu", "road friction μ [-]")
    corners(axes[2, 0], "ref_fx", "F_x [N]", "F_x ")
    corners(axes[2, 1], "ref_fy", "F_y [N]", "F_y ")
    corners(axes[3, 0], "ref_fz", "normal load F_z [N]")
    ax = axes[3, 1]
    if "steering_wheel_angle" in log:
        ax.plot(t, log["steering_wheel_angle"], color=REFERENCE_COLOR, lw=0.9,
                label="steering-wheel angle")
        ax.set_ylabel("steering-wheel angle [rad]")
    else:
        for c in ("fl", "fr"):
            if f"delta_{c}" in log:
                ax.plot(t, log[f"delta_{c}"], lw=0.9, color=CORNER_COLORS[c], label=f"δ {c}")
        ax.set_ylabel("road-wheel angle δ [rad]")
    if ax.get_legend_handles_labels()[0]:
        ax.legend(fontsize=7)
    ax = axes[4, 0]
    ax.plot(t, log["ax"], lw=0.7, color=CG_COLOR, label="a_x")
    ax.plot(t, log["ay"], lw=0.7, color="0.35", label="a_y")
    ax.set_ylabel("specific force [m/s²]")
    ax.legend(fontsize=7, ncol=2)
    ax = axes[4, 1]
    ax.plot(t, log["yaw_rate"], lw=0.8, color=CG_COLOR, label="yaw rate")
    ax.set_ylabel("yaw rate [rad/s]")
    ax.legend(fontsize=7)
    for a in axes[-1, :]:
        a.set_xlabel("t [s]")
    for a in axes.flat:
        a.grid(alpha=0.3)
    if title:
        fig.suptitle(title)
    return fig
