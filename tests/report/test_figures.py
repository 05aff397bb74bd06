"""Estimate figures: which PNG files are written, that they are valid PNGs under 300 kB,
that missing channels skip a figure without error, and that inputs are not modified."""

from __future__ import annotations

import struct
from pathlib import Path

import matplotlib.pyplot as plt
import numpy as np
import pandas as pd
import pytest

from vestim.constants import CORNERS
from vestim.errors import LogFormatError
from vestim.report.figures import FIGURE_FILES, MAX_POINTS, _envelope, plot_estimate
from vestim.sim import simulate

PNG_SIGNATURE = b"\x89PNG\r\n\x1a\n"
MAX_BYTES = 300_000  # the size limit per PNG
R = 0.33  # m, hashemi_suv wheel_radius


def _png_size(path: Path) -> tuple[int, int]:
    """(width, height) in px from the IHDR chunk, after checking the PNG signature."""
    data = path.read_bytes()
    assert data[:8] == PNG_SIGNATURE, path
    assert data[12:16] == b"IHDR", path
    width, height = struct.unpack(">II", data[16:24])
    return width, height


def _check_pngs(paths: list[Path]) -> None:
    for p in paths:
        assert p.is_file()
        size = p.stat().st_size
        assert 0 < size < MAX_BYTES, (p.name, size)
        width, height = _png_size(p)
        assert width > 500 and height > 300


@pytest.fixture(scope="module")
def sim_log() -> pd.DataFrame:
    return simulate("step_steer", "hashemi_suv", seed=0)


@pytest.fixture(scope="module")
def estimate(sim_log: pd.DataFrame) -> pd.DataFrame:
    """A noisy fabricated estimate of every plotted channel with a σ on the forces."""
    rng = np.random.default_rng(0)
    n = len(sim_log)
    cols: dict[str, np.ndarray] = {"t": sim_log["t"].to_numpy()}
    cols["vx"] = sim_log["ref_vx"].to_numpy() + 0.2
    cols["vy"] = sim_log["ref_vy"].to_numpy() - 0.05
    for c in CORNERS:
        cols[f"vx_{c}"] = sim_log[f"ref_vx_{c}"].to_numpy() + 0.05 * rng.standard_normal(n)
        for f in ("fx", "fy", "fz"):
            # noisy estimates are the worst case for PNG compression
            cols[f"{f}_{c}"] = sim_log[f"ref_{f}_{c}"].to_numpy() + 100.0 * rng.standard_normal(n)
            cols[f"sigma_{f}_{c}"] = np.full(n, 150.0)
    return pd.DataFrame(cols)


def test_all_figures_written_as_valid_pngs(sim_log: pd.DataFrame, estimate: pd.DataFrame,
                                           tmp_path: Path) -> None:
    est0, ref0 = estimate.copy(), sim_log.copy()
    paths = plot_estimate(estimate, sim_log, wheel_radius=R, out_dir=tmp_path / "figs")
    assert [p.name for p in paths] == list(FIGURE_FILES.values())
    assert all(p.parent == tmp_path / "figs" for p in paths)
    _check_pngs(paths)
    assert sorted(p.name for p in (tmp_path / "figs").iterdir()) == sorted(FIGURE_FILES.values())
    pd.testing.assert_frame_equal(estimate, est0)
    pd.testing.assert_frame_equal(sim_log, ref0)
    assert plt.get_fignums() == []  # every figure closed


def test_reference_defaults_to_estimate_frame(sim_log: pd.DataFrame, tmp_path: Path) -> None:
    """A simulator log that also carries estimates is drawn against its own ref_ columns;
    omega_* comes from the same frame for the R·ω curves."""
    log = sim_log.copy()
    log["vx"] = log["ref_vx"] + 0.1
    log["fz_fl"] = log["ref_fz_fl"] - 200.0
    paths = plot_estimate(log, wheel_radius=R, out_dir=tmp_path)
    assert [p.name for p in paths] == [FIGURE_FILES[k] for k in ("speed", "velocity_cg", "force_fz")]
    _check_pngs(paths)


def test_missing_channels_skip_figures(tmp_path: Path) -> None:
    """Only vy estimated, no reference, no wheel speeds: just the CG velocity figure."""
    t = np.linspace(0.0, 2.0, 201)
    estimate = pd.DataFrame({"t": t, "vy": 0.1 * np.sin(t), "confidence_fl": 1.0})
    paths = plot_estimate(estimate, out_dir=tmp_path)
    assert [p.name for p in paths] == [FIGURE_FILES["velocity_cg"]]
    _check_pngs(paths)


def test_nothing_to_plot_returns_empty_list(tmp_path: Path) -> None:
    estimate = pd.DataFrame({"t": [0.0, 1.0], "ax": [0.0, 0.1]})
    assert plot_estimate(estimate, out_dir=tmp_path / "none") == []
    assert not (tmp_path / "none").exists()


def test_partial_corners_and_no_wheel_radius(sim_log: pd.DataFrame, tmp_path: Path) -> None:
    """fx for one corner only draws the grid with 'no estimate' panels; without a wheel
    radius the speed figure is still drawn (without R·ω)."""
    estimate = pd.DataFrame({"t": sim_log["t"], "vx": sim_log["ref_vx"],
                             "fx_rr": sim_log["ref_fx_rr"]})
    paths = plot_estimate(estimate, sim_log, out_dir=tmp_path)
    assert [p.name for p in paths] == [FIGURE_FILES[k] for k in ("speed", "velocity_cg", "force_fx")]
    _check_pngs(paths)


def test_long_noisy_log_stays_small(tmp_path: Path) -> None:
    """200 000 samples (1000 s at 200 Hz) of pure noise, the worst case for PNG size,
    is drawn as a min/max envelope and stays under 300 kB."""
    rng = np.random.default_rng(1)
    n = 200_000
    cols: dict[str, np.ndarray] = {"t": np.arange(n) / 200.0}
    for name in ("vx", "fx_fl", "fx_fr", "fx_rl", "fx_rr"):
        cols[name] = rng.standard_normal(n)
        cols["ref_" + name] = rng.standard_normal(n)
        cols["sigma_" + name] = rng.random(n)
    for c in CORNERS:
        cols[f"omega_{c}"] = 50.0 + rng.standard_normal(n)
    paths = plot_estimate(pd.DataFrame(cols), wheel_radius=R, out_dir=tmp_path)
    assert len(paths) == 3
    _check_pngs(paths)


def test_envelope_keeps_extremes_and_bounds_points() -> None:
    """The envelope draws at most MAX_POINTS points and keeps every bucket's min and max,
    so the global extremes (a spike at one sample) survive. 50 000 samples in 1000 buckets
    of 50: NaN is ignored inside a bucket, and an all-NaN bucket stays a gap (2 NaN points)."""
    n = 50_000
    t = np.arange(n, dtype=float)
    y = np.zeros(n)
    y[12_345] = 7.0
    y[40_000] = -3.0
    y[100:120] = np.nan  # part of bucket 2
    y[1000:1100] = np.nan  # buckets 20 and 21 entirely
    tt, yy = _envelope(t, y)
    assert tt.size == yy.size <= MAX_POINTS
    assert np.nanmax(yy) == 7.0 and np.nanmin(yy) == -3.0
    assert np.flatnonzero(np.isnan(yy)).tolist() == [40, 41, 42, 43]
    assert np.all(np.diff(tt) >= 0)
    short_t, short_y = _envelope(t[:100], y[:100])
    assert short_t.size == 100 and np.array_equal(short_y, y[:100])


def test_bad_arguments(tmp_path: Path) -> None:
    estimate = pd.DataFrame({"t": [0.0, 1.0], "vx": [1.0, 2.0]})
    with pytest.raises(ValueError, match="wheel_radius must be a positive length"):
        plot_estimate(estimate, wheel_radius=0.0, out_dir=tmp_path)
    with pytest.raises(LogFormatError, match="estimate: no time column 't'"):
        plot_estimate(estimate.drop(columns="t"), out_dir=tmp_path)
