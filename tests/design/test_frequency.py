"""Frequency response per frozen wheel speed (004 Fig. 6-7) against scipy.signal."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from scipy import signal

from vestim.design.frequency import frequency_response, frozen_hinf_norm, plot_frequency_response
from vestim.design.lmi import LPVSystem
from vestim.io.vehicle import load_vehicle
from vestim.models import lpv

AX = lpv.longitudinal_axis(load_vehicle("hashemi_suv"))


@pytest.mark.filterwarnings("ignore::scipy.signal.BadCoefficients")
def test_frequency_response_matches_scipy_state_space() -> None:
    # Frozen observer error dynamics at ω = 90 rad/s, every channel, vs scipy's freqresp
    # (independent: it goes through zeros and poles); rounding of that route: 1e-8 relative.
    a0, a1, be = lpv.affine_error_dynamics(0.68, 183.1, AX)
    sys_ = LPVSystem.from_affine(a0, a1, be, None, np.eye(2))
    f = np.logspace(-1, 4, 50)
    g = frequency_response(sys_, np.array([90.0]), f)[0]
    a = a0 + 90.0 * a1
    for i in range(2):
        for j in range(2):
            ss = signal.StateSpace(a, be[:, j:j + 1], np.eye(2)[i:i + 1], np.zeros((1, 1)))
            _, resp = signal.freqresp(ss, f)
            np.testing.assert_allclose(g[:, i, j], resp, rtol=1e-8)


def test_frozen_hinf_norm_of_first_order_lag() -> None:
    # 1/(s + 4): peak |G| = 1/4 at f = 0 (exact).
    sys_ = LPVSystem.from_affine(np.array([[-4.0]]), np.zeros((1, 1)), np.eye(1), None, np.eye(1))
    peak, at = frozen_hinf_norm(sys_, np.array([0.0, 1.0]))
    np.testing.assert_allclose(peak, 0.25, rtol=1e-12)
    assert at[0] == 0.0


def test_plot_writes_a_small_png(tmp_path: Path) -> None:
    a0, a1, be = lpv.affine_error_dynamics(0.68, 183.1, AX)
    sys_ = LPVSystem.from_affine(a0, a1, be, None, np.eye(2))
    p = plot_frequency_response(sys_, [0.0, 90.0, 180.0], tmp_path / "fr.png", title="t")
    assert p.exists() and 0 < p.stat().st_size < 300_000
    with pytest.raises(FileNotFoundError):
        (tmp_path / ".fr.png.tmp").stat()
