"""Figures of simulated or recorded logs (PNG, written atomically)."""

from __future__ import annotations

from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt
import numpy as np
import pandas as pd
from matplotlib.figure import Figure

from vestim.constants import CORNERS
from vestim.io.files import atomic_path


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
    """Overview of a simulated log: speeds, slip, forces, loads, IMU and steering.

    Panels: CG speed with wheel-periphery speeds R·ω per corner (cf. 000 Fig. 11);
    slip ratios; longitudinal and lateral tire forces; normal loads; specific
    force and yaw rate; steering-wheel angle. Needs the ``ref_`` channels.
    """
    t = log["t"].to_numpy()
    fig, axes = plt.subplots(3, 2, figsize=(12, 9), sharex=True, constrained_layout=True)
    ax = axes[0, 0]
    ax.plot(t, log["ref_vx"], "k", lw=2, label="ref vx (CG)")
    for c in CORNERS:
        ax.plot(t, wheel_radius * log[f"omega_{c}"], lw=0.8, label=f"R·ω {c}")
    ax.set_ylabel("speed [m/s]")
    ax.legend(fontsize=7, ncol=2)
    ax = axes[0, 1]
    for c in CORNERS:
        ax.plot(t, log[f"ref_slip_ratio_{c}"], lw=0.9, label=c)
    ax.set_ylabel("slip ratio [-]")
    ax.legend(fontsize=7, ncol=4)
    ax = axes[1, 0]
    for c in CORNERS:
        ax.plot(t, log[f"ref_fx_{c}"], lw=0.9, label=f"Fx {c}")
        ax.plot(t, log[f"ref_fy_{c}"], lw=0.9, ls="--", label=f"Fy {c}")
    ax.set_ylabel("tire force [N]")
    ax.legend(fontsize=7, ncol=2)
    ax = axes[1, 1]
    for c in CORNERS:
        ax.plot(t, log[f"ref_fz_{c}"], lw=0.9, label=c)
    ax.set_ylabel("normal load [N]")
    ax.legend(fontsize=7, ncol=4)
    ax = axes[2, 0]
    ax.plot(t, log["ax"], lw=0.7, label="ax")
    ax.plot(t, log["ay"], lw=0.7, label="ay")
    ax.plot(t, log["ref_vy"], lw=1.2, label="ref vy [m/s]")
    ax.plot(t, 10 * log["yaw_rate"], lw=0.7, label="10·yaw rate [rad/s]")
    ax.set_ylabel("IMU [m/s²]")
    ax.set_xlabel("t [s]")
    ax.legend(fontsize=7, ncol=2)
    ax = axes[2, 1]
    if "steering_wheel_angle" in log:
        ax.plot(t, log["steering_wheel_angle"], label="steering wheel [rad]")
    mu = log[[f"ref_mu_{c}" for c in CORNERS]].to_numpy()
    ax.plot(t, np.min(mu, axis=1), label="min μ")
    ax.plot(t, np.max(mu, axis=1), ls="--", label="max μ")
    ax.set_xlabel("t [s]")
    ax.legend(fontsize=7)
    for a in axes.flat:
        a.grid(alpha=0.3)
    if title:
        fig.suptitle(title)
    return fig
