"""Estimate figures: which PNG files are written, that they are valid PNGs under 300 kB,
that missing channels skip a figure without error, that inputs are not modified; the
figure conventions (one y range and one colour per corner, error strips with the known
offsets, the score in each panel) and, for the simulation overview, that every panel's
unit is the unit of everything drawn in it."""

from __future__ import annotations

import struct
from pathlib import Path

import matplotlib.pyplot as plt
import numpy as np
import pandas as pd
import pytest
from matplotlib.colors import to_hex

from tests.report.conftest import OFFSETS, R
from vestim.constants import CORNERS
from vestim.errors import LogFormatError
from vestim.io import channels as ch
from vestim.metrics import coverage, score, significant
from vestim.report.data import MAX_POINTS
from vestim.report.data import envelope as _envelope
from vestim.report.figures import FIGURE_FILES, estimate_figure, plot_estimate
from vestim.report.plots import plot_simulation
from vestim.report.style import CG_COLOR, CORNER_COLORS, CORNER_NAMES, REFERENCE_COLOR

PNG_SIGNATURE = b"\x89PNG\r\n\x1a\n"
MAX_BYTES = 300_000  # the size limit per PNG


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


def _value_axes(fig) -> dict[str, plt.Axes]:  # type: ignore[no-untyped-def]
    """Value panel of each corner, found by its title ("front left (fl)")."""
    out = {c: ax for ax in fig.axes for c in CORNERS if ax.get_title() == f"{CORNER_NAMES[c]} ({c})"}
    assert set(out) == set(CORNERS)
    return out


def test_corner_grid_conventions(offset_estimate: pd.DataFrame, sim_log: pd.DataFrame) -> None:
    """F_x grid of the offset estimate (F_x = truth + 100·(k+1) N at corner k, σ = 150 N):
    the four value panels share one y range holding every corner's band and reference; each
    corner's estimate and error are in its colour, the reference black; the error strip
    under a panel holds the offset; the panel text gives metrics.score's NRMS (3 significant
    figures) and RMSE and the σ coverage: the 100 N error of fl is within 1σ everywhere, the
    200 N of fr within 2σ only, the 400 N of rr outside 2σ = 300 N."""
    fig = estimate_figure(offset_estimate, sim_log, "force_fx", wheel_radius=R)
    assert fig is not None
    try:
        values = _value_axes(fig)
        limits = {ax.get_ylim() for ax in values.values()}
        assert len(limits) == 1
        lo, hi = limits.pop()
        for c in CORNERS:
            est = offset_estimate[f"fx_{c}"]
            assert lo <= est.min() - 150.0 and hi >= est.max() + 150.0
            assert lo <= sim_log[f"ref_fx_{c}"].min() and hi >= sim_log[f"ref_fx_{c}"].max()
        table = score(offset_estimate, sim_log).set_index("channel")
        cover = coverage(offset_estimate, sim_log).set_index("channel")
        assert list(cover.loc["fx_fl", ["within_1sigma", "within_2sigma"]]) == [1.0, 1.0]
        assert list(cover.loc["fx_fr", ["within_1sigma", "within_2sigma"]]) == [0.0, 1.0]
        assert list(cover.loc["fx_rr", ["within_1sigma", "within_2sigma"]]) == [0.0, 0.0]
        errors = [ax for ax in fig.axes if ax.get_ylabel() == "error [N]"]
        assert len(errors) == 4
        assert len({ax.get_ylim() for ax in errors}) == 1  # error strips share a range too
        for c, ax in values.items():
            lines = {ln.get_label(): ln for ln in ax.get_lines()}
            assert to_hex(lines["estimate"].get_color()) == CORNER_COLORS[c].lower()
            assert to_hex(lines["reference"].get_color()) == REFERENCE_COLOR
            assert ax.get_ylabel() == "F_x [N]"
            row = table.loc[f"fx_{c}"]
            cov = cover.loc[f"fx_{c}"]
            text = (f"NRMS {significant(row['nrms_pct'])} %, RMSE {row['rmse']:.3g} N, within 1σ "
                    f"{100 * cov['within_1sigma']:.0f} %, 2σ {100 * cov['within_2sigma']:.0f} %")
            assert text in [t.get_text() for t in ax.texts]
            # the strip right below the panel: same column, next row
            strip = next(e for e in errors if e.get_position().x0 == pytest.approx(ax.get_position().x0)
                         and e.get_position().y1 < ax.get_position().y0
                         and ax.get_position().y0 - e.get_position().y1 < 0.1)
            err_line = next(ln for ln in strip.get_lines() if ln.get_xydata().shape[0] > 2)
            assert to_hex(err_line.get_color()) == CORNER_COLORS[c].lower()
            np.testing.assert_allclose(err_line.get_ydata(), OFFSETS[f"fx_{c}"], rtol=1e-9)
    finally:
        plt.close(fig)


def test_speed_figure_colours_and_error(offset_estimate: pd.DataFrame, sim_log: pd.DataFrame) -> None:
    """R·ω per corner in the corner colours (the same as in the grids), the CG estimate in
    CG_COLOR, and an error strip of v_x holding its 0.2 m/s offset."""
    fig = estimate_figure(offset_estimate, sim_log, "speed", wheel_radius=R)
    assert fig is not None
    try:
        main, strip = fig.axes
        lines = {ln.get_label(): ln for ln in main.get_lines()}
        for c in CORNERS:
            assert to_hex(lines[f"R·ω {c}"].get_color()) == CORNER_COLORS[c].lower()
            np.testing.assert_allclose(lines[f"R·ω {c}"].get_ydata(), R * sim_log[f"omega_{c}"])
        assert to_hex(lines["estimate v_x (CG)"].get_color()) == CG_COLOR.lower()
        assert main.get_ylabel() == "speed [m/s]" and strip.get_ylabel() == "error v_x [m/s]"
        err = next(ln for ln in strip.get_lines() if ln.get_xydata().shape[0] > 2)
        np.testing.assert_allclose(err.get_ydata(), OFFSETS["vx"], rtol=1e-9)
    finally:
        plt.close(fig)


def test_simulation_panels_have_one_unit(sim_log: pd.DataFrame) -> None:
    """Every line of the overview is one log column (or R·ω), and that column's unit is the
    unit in its panel's y label: no panel mixes m/s², m/s and rad/s any more. Lines of one
    corner have that corner's colour."""
    fig = plot_simulation(sim_log, R, title="step steer")
    try:
        columns = {c: sim_log[c].to_numpy(dtype=float) for c in sim_log.columns}
        columns.update({f"R·omega_{c}": R * sim_log[f"omega_{c}"].to_numpy() for c in CORNERS})
        labelled = 0
        for ax in fig.axes:
            label = ax.get_ylabel()
            assert label.endswith("]"), label
            unit = label[label.rindex("[") + 1:-1]
            for ln in ax.get_lines():
                y = np.asarray(ln.get_ydata(), dtype=float)
                match = [n for n, v in columns.items() if v.shape == y.shape and np.array_equal(v, y)]
                assert match, (label, ln.get_label())
                units = {"m/s" if n.startswith("R·omega_") else ch.unit_of(n) for n in match}
                assert units == {unit}, (label, match)
                corners = {n[-2:] for n in match}
                if corners <= set(CORNERS):  # equal arrays (μ = 1 at every corner): any of them
                    colours = {CORNER_COLORS[c].lower() for c in corners}
                    assert to_hex(ln.get_color()) in colours, match
                labelled += 1
        assert labelled >= 30  # 4 R·ω + v_x, v_y, 4 × (slip, μ, F_x, F_y, F_z), a_x, a_y, ψ̇, steering
    finally:
        plt.close(fig)
