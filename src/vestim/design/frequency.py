"""Frequency response of observer error dynamics per frozen wheel speed (004 Fig. 6–7).

For each frozen parameter ρ the error dynamics are LTI,
G_ρ(jf) = C (jf I − A(ρ))⁻¹ B + D (f in rad/s). The peak over f of σ_max(G_ρ)
is the frozen H∞ norm, a lower bound on the LPV γ of
:func:`vestim.design.analysis.hinf_performance` (which also covers ρ varying
at rate |ρ̇| ≤ ρ̇_max).
"""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path

import numpy as np
from numpy.typing import NDArray

from vestim.design.lmi import FArray, LPVSystem

__all__ = ["frequency_response", "frozen_hinf_norm", "plot_frequency_response"]


def frequency_response(system: LPVSystem, rho: FArray, freqs: FArray) -> NDArray[np.complex128]:
    """G(jf) for every ρ and frequency f: shape (R, F, p, m).

    Args:
        system: error dynamics (:class:`~vestim.design.lmi.LPVSystem`).
        rho: frozen parameter values (R,), e.g. wheel speeds in rad/s.
        freqs: angular frequencies (F,), rad/s.
    """
    r = np.atleast_1d(np.asarray(rho, float))
    f = np.atleast_1d(np.asarray(freqs, float))
    a, b, c, d = system.matrices(r)
    n = a.shape[-1]
    jw = 1j * f[None, :, None, None] * np.eye(n)
    x = np.linalg.solve(jw - a[:, None], np.broadcast_to(b[:, None], (r.size, f.size,
                                                                     *b.shape[-2:])))
    return np.asarray(c[:, None] @ x + d[:, None], np.complex128)


def frozen_hinf_norm(system: LPVSystem, rho: FArray, freqs: FArray | None = None
                     ) -> tuple[FArray, FArray]:
    """(peak σ_max over the sweep, frequency of the peak) for each frozen ρ.

    The default sweep is 2000 log-spaced points over 1e-3 … 1e5 rad/s plus f = 0.
    """
    f = np.concatenate([[0.0], np.logspace(-3, 5, 2000)]) if freqs is None else np.asarray(freqs)
    g = frequency_response(system, rho, f)
    s = np.linalg.svd(g, compute_uv=False)[..., 0]
    i = np.argmax(s, axis=1)
    return s[np.arange(s.shape[0]), i], f[i]


def plot_frequency_response(system: LPVSystem, rho: Sequence[float], path: str | Path, *,
                            title: str = "", input_names: Sequence[str] = ("Omega_z", "Omega_a"),
                            output_names: Sequence[str] = ("e_z", "e_vr"),
                            freqs: FArray | None = None) -> Path:
    """Magnitude of every channel of G_ρ(jf) for several wheel speeds (cf. 004 Fig. 6–7).

    Writes a PNG atomically and returns its path.
    """
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    from vestim.report.plots import save_figure

    f = np.logspace(-1, 4, 400) if freqs is None else np.asarray(freqs, float)
    g = np.abs(frequency_response(system, np.asarray(rho, float), f))
    p, m = g.shape[-2:]
    fig, axes = plt.subplots(p, m, figsize=(4.2 * m, 2.8 * p), sharex=True, squeeze=False,
                             constrained_layout=True)
    for i in range(p):
        for j in range(m):
            ax = axes[i, j]
            for k, r in enumerate(rho):
                ax.loglog(f, g[k, :, i, j], lw=1.1, label=f"|omega| = {r:g} rad/s")
            ax.set_title(f"{input_names[j] if j < len(input_names) else j} -> "
                         f"{output_names[i] if i < len(output_names) else i}", fontsize=9)
            ax.grid(True, which="both", lw=0.3)
    for ax in axes[-1]:
        ax.set_xlabel("frequency [rad/s]")
    axes[0, 0].legend(fontsize=7)
    if title:
        fig.suptitle(title)
    return save_figure(fig, path, dpi=90)
