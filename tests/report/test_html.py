"""HTML report: one self-contained file (plotly.js embedded, nothing fetched), every plot
with its data, error traces and scores that match the known offsets of the estimate, one y
range and one colour per corner, sections skipped without their channels, a file size that
does not grow with the log's length, the CLI command, and a real headless browser that
draws every plot without a console error."""

from __future__ import annotations

import json
import re
import sys
from pathlib import Path

import numpy as np
import pandas as pd
import plotly.offline
import pytest
from typer.testing import CliRunner

from tests.report.conftest import OFFSETS, R
from vestim.cli import app
from vestim.constants import CORNERS
from vestim.errors import LogFormatError, MissingDependencyError
from vestim.estimators.validity import REASONS
from vestim.io import write_log
from vestim.metrics import coverage, score, significant
from vestim.report.data import MAX_POINTS
from vestim.report.html import FIGURES, report_figures, write_html_report
from vestim.report.style import CORNER_COLORS, GRID, REASON_COLORS

CHROMIUM = Path("/usr/bin/chromium")
ALL_FIGURES = list(FIGURES)  # the offset estimate has every channel the report draws


def _trace(fig, name: str, row: int | None = None, col: int | None = None):  # type: ignore[no-untyped-def]
    """The one trace called ``name`` (in subplot row/col when given)."""
    found = [tr for tr in fig.select_traces(selector={"name": name}, row=row, col=col)]
    assert len(found) == 1, (name, row, col, [t.name for t in fig.data])
    return found[0]


@pytest.fixture(scope="module")
def report(tmp_path_factory: pytest.TempPathFactory, offset_estimate: pd.DataFrame,
           sim_log: pd.DataFrame) -> Path:
    out = tmp_path_factory.mktemp("html") / "sub" / "report.html"
    est0, ref0 = offset_estimate.copy(), sim_log.copy()
    path = write_html_report(offset_estimate, sim_log, out, wheel_radius=R,
                             metadata={"vehicle": "hashemi_suv", "note": "<b>escaped</b>"},
                             title="step steer")
    pd.testing.assert_frame_equal(offset_estimate, est0)  # inputs never modified
    pd.testing.assert_frame_equal(sim_log, ref0)
    assert offset_estimate.attrs == est0.attrs
    return path


def test_file_is_self_contained(report: Path) -> None:
    """No script or stylesheet is fetched: plotly.js is inlined once, every figure is a div
    drawn by Plotly.newPlot; no temporary file is left next to the report (atomic write)."""
    text = report.read_text(encoding="utf-8")
    assert re.search(r"<script[^>]*\bsrc\s*=", text) is None
    assert re.search(r"<link[^>]*\bhref\s*=\s*['\"]https?:", text) is None
    assert text.count(plotly.offline.get_plotlyjs()) == 1
    for key in ALL_FIGURES:
        assert f'id="plot-{key}"' in text, key
        assert re.search(rf'Plotly\.newPlot\(\s*"plot-{key}"', text), key
    assert [p.name for p in report.parent.iterdir()] == ["report.html"]
    assert "no validity/health channels" not in text  # the estimate has valid_fl, health_vx


def test_every_plot_has_data(offset_estimate: pd.DataFrame, sim_log: pd.DataFrame) -> None:
    figs = report_figures(offset_estimate, sim_log, wheel_radius=R)
    assert list(figs) == ALL_FIGURES
    for key, fig in figs.items():
        assert len(fig.data) > 0, key
        for tr in fig.data:
            assert tr.x is not None and len(tr.x) > 0, (key, tr.name)
            assert np.isfinite(np.asarray(tr.y, dtype=float)).any(), (key, tr.name)


def test_traces_carry_the_right_numbers(offset_estimate: pd.DataFrame, sim_log: pd.DataFrame) -> None:
    """1601 samples < MAX_POINTS, so lines are the samples themselves (float32): R·ω is
    0.33·ω, each error strip holds the estimate's known offset (F_x: 100·(k+1) N at corner
    k), and the μ circle points of the estimate are F_x/F_z against F_y/F_z."""
    assert len(sim_log) < MAX_POINTS
    figs = report_figures(offset_estimate, sim_log, wheel_radius=R)
    speed = figs["speed"]
    for c in CORNERS:
        np.testing.assert_allclose(_trace(speed, f"R·ω {c}").y, R * sim_log[f"omega_{c}"], rtol=1e-6)
    np.testing.assert_allclose(_trace(speed, "error v_x (CG)").y, OFFSETS["vx"], atol=1e-5)
    for prefix in ("fx", "fy", "fz", "vx", "vy", "slip_ratio", "slip_angle"):
        fig = figs[{"fx": "force_fx", "fy": "force_fy", "fz": "force_fz", "vx": "velocity_vx",
                    "vy": "velocity_vy"}.get(prefix, prefix)]
        for c in CORNERS:
            off = OFFSETS[f"{prefix}_{c}"]
            np.testing.assert_allclose(_trace(fig, f"error {c}").y, off, atol=1e-4 * max(1.0, abs(off)))
            np.testing.assert_allclose(_trace(fig, f"estimate {c}").y,
                                       offset_estimate[f"{prefix}_{c}"], rtol=1e-6, atol=1e-7)
    fl = _trace(figs["friction_corners"], "estimate fl")
    np.testing.assert_allclose(fl.y, offset_estimate["fx_fl"] / offset_estimate["fz_fl"], rtol=1e-6)
    np.testing.assert_allclose(fl.x, offset_estimate["fy_fl"] / offset_estimate["fz_fl"], rtol=1e-6)
    gg = _trace(figs["friction_gg"], "measured a_x, a_y")
    np.testing.assert_allclose(gg.y, sim_log["ax"], rtol=1e-6, atol=1e-6)


def test_corner_panels_share_range_and_colour(offset_estimate: pd.DataFrame,
                                              sim_log: pd.DataFrame) -> None:
    """The four F_x panels have one y range holding every corner's estimate ± σ and
    reference (padded by at most 5 % of the span), zoom-linked to the fl panel; each
    corner's estimate and error trace are drawn in that corner's colour."""
    fig = report_figures(offset_estimate, sim_log, wheel_radius=R)["force_fx"]
    values = np.concatenate([np.r_[offset_estimate[f"fx_{c}"] - 150.0, offset_estimate[f"fx_{c}"] + 150.0,
                                   sim_log[f"ref_fx_{c}"]] for c in CORNERS])
    lo_all, hi_all = values.min(), values.max()
    ranges, matches = [], []
    for c in CORNERS:
        r, col = GRID[c]
        sub = fig.get_subplot(2 * r + 1, col + 1)
        ranges.append(tuple(sub.yaxis.range))
        matches.append(sub.yaxis.matches)
        assert _trace(fig, f"estimate {c}", 2 * r + 1, col + 1).line.color == CORNER_COLORS[c]
        assert _trace(fig, f"error {c}", 2 * r + 2, col + 1).line.color == CORNER_COLORS[c]
    assert len(set(ranges)) == 1
    lo, hi = ranges[0]
    span = hi_all - lo_all
    assert lo <= lo_all and hi >= hi_all
    assert lo_all - lo <= 0.051 * span and hi - hi_all <= 0.051 * span
    assert matches[0] is None and set(matches[1:]) == {"y"}


def test_score_table_matches_metrics(report: Path, offset_estimate: pd.DataFrame,
                                     sim_log: pd.DataFrame) -> None:
    """One row per channel of vestim.metrics.score: its NRMS (3 significant figures, * when
    floored) and RMSE (4 significant digits); F_x fl's RMSE is the 100 N offset. Panel titles
    carry the same score."""
    text = report.read_text(encoding="utf-8")
    assert "id='score-table'" in text
    table = score(offset_estimate, sim_log)
    rows = {m[0]: (m[1], m[2]) for m in re.findall(
        r"<tr><td>([a-z_]+)</td><td>[^<]*</td><td>([^<]+)</td><td>([^<]+)</td>", text)}
    assert set(rows) == set(table["channel"])
    for r in table.to_dict(orient="records"):
        pct, rmse = rows[r["channel"]]
        assert pct.rstrip("*") == significant(r["nrms_pct"]), r["channel"]
        assert pct.endswith("*") == bool(r["floored"])
        assert rmse == ("–" if r["samples"] == 0 else f"{r['rmse']:.4g}"), r["channel"]
    rmse_fx_fl = re.search(r"<tr><td>fx_fl</td><td>N</td><td>[^<]+</td><td>([^<]+)</td>", text)
    assert rmse_fx_fl is not None and float(rmse_fx_fl.group(1)) == pytest.approx(100.0, rel=1e-4)
    assert "RMSE 100 N" in text  # the fl title of the F_x grid
    # the v_x title: 0.2 m/s over max|ref| (about 20 m/s): 1 %, printed with 3 figures, not "1.0"
    vx = table.set_index("channel").loc["vx", "nrms_pct"]
    assert f"NRMS {significant(vx)} %" in text and len(significant(vx).replace(".", "")) >= 3


def _score_cells(text: str) -> dict[str, list[str]]:
    """The cells of each row of the score table, by channel."""
    body = text[text.index("id='score-table'"):]
    body = body[:body.index("</table>")]
    return {cells[0]: cells[1:] for cells in
            (re.findall(r"<td[^>]*>([^<]*)</td>", row) for row in body.split("<tr>")[2:])}


def test_coverage_column(report: Path, offset_estimate: pd.DataFrame, sim_log: pd.DataFrame) -> None:
    """Beside every score, the share of samples within 1σ and 2σ (metrics.coverage): F_x's
    error is 100·(k+1) N against σ = 150 N, so fl is within 1σ on every sample (100.0/100.0),
    fr within 2σ only (0.0/100.0), rr outside 2σ (0.0/0.0); F_y has no σ ("–")."""
    cells = _score_cells(report.read_text(encoding="utf-8"))
    header = ["unit", "NRMS [%]", "RMSE", "max error", "max |ref|", "floor", "within 1σ [%]",
              "within 2σ [%]", "samples"]
    assert "<th>within 1σ [%]</th><th>within 2σ [%]</th>" in report.read_text(encoding="utf-8")
    one, two = header.index("within 1σ [%]"), header.index("within 2σ [%]")
    assert (cells["fx_fl"][one], cells["fx_fl"][two]) == ("100.0", "100.0")
    assert (cells["fx_fr"][one], cells["fx_fr"][two]) == ("0.0", "100.0")
    assert (cells["fx_rr"][one], cells["fx_rr"][two]) == ("0.0", "0.0")
    assert (cells["fy_fl"][one], cells["fy_fl"][two]) == ("–", "–")
    table = coverage(offset_estimate, sim_log).set_index("channel")
    for name, row in table.iterrows():
        assert cells[str(name)][one] == f"{100 * row['within_1sigma']:.1f}", name


def test_mu_not_excited(report: Path) -> None:
    """A road friction μ that is NaN on every row reads "not excited" (not "0 (1601 NaN
    skipped)"); one NaN on its first 800 rows gives "801 (800 not excited)"."""
    cells = _score_cells(report.read_text(encoding="utf-8"))
    assert cells["mu_fl"][-1] == "not excited" and cells["mu_fl"][1] == "–"
    assert cells["mu_fr"][-1] == "801 (800 not excited)"


def test_validity_bands(offset_estimate: pd.DataFrame, sim_log: pd.DataFrame) -> None:
    """valid_velocity is 0 for t < 2 s (reason 1) and 5 ≤ t < 5.5 s (reason 10 = 2 + 8): the
    speed and velocity plots shade exactly those spans (to the next sample), named by the
    decoded reasons (validity.reason_names), coloured by the first reason, labelled in
    place where the label fits (2 s of 8 s: 290 px for 15 characters; 0.5 s: 72 px, too
    narrow for 23); the force plots have no valid_force, so none."""
    figs = report_figures(offset_estimate, sim_log, wheel_radius=R)
    t = offset_estimate["t"].to_numpy()
    dt = t[1] - t[0]
    shapes = figs["speed"].layout.shapes
    assert [s.name for s in shapes] == ["velocity not valid: not converged",
                                        "velocity not valid: standstill, high slip"]
    first, second = shapes
    assert (first.x0, first.x1) == (0.0, pytest.approx(2.0, abs=1e-9))
    assert (second.x0, second.x1) == (pytest.approx(5.0, abs=1e-9), pytest.approx(5.5, abs=1e-9))
    assert first.fillcolor == REASON_COLORS["not converged"]
    assert second.fillcolor == REASON_COLORS["standstill"]
    assert first.label.text == "not converged" and not second.label.text
    assert first.showlegend and second.showlegend and first.yref == "paper"
    # a corner grid shades both columns; the legend names each span once
    vx = figs["velocity_vx"].layout.shapes
    assert sorted({s.xref for s in vx}) == ["x", "x2"] and sum(bool(s.showlegend) for s in vx) == 2
    assert not figs["force_fx"].layout.shapes
    # the validity timeline shades its valid_velocity row only
    rows = [s for s in figs["validity"].layout.shapes]
    assert len(rows) == 2 and all(s.yref.endswith(" domain") for s in rows)
    assert set(REASON_COLORS) == set(REASONS.values())
    assert dt > 0


def test_configuration_is_a_table(tmp_path: Path, offset_estimate: pd.DataFrame,
                                  sim_log: pd.DataFrame) -> None:
    """The estimate's config metadata (JSON) is one table row per parameter, grouped by its
    table, not a JSON blob; a JSON list (warnings) is one item per line, "none" when empty."""
    est = offset_estimate.copy()
    est.attrs = {"vehicle": "hashemi_suv",
                 "config": json.dumps({"force": "ukf", "force_params": {"ukf": {"r_omega": 0.18}}}),
                 "warnings": json.dumps([{"check": "a", "message": "one"},
                                         {"check": "b", "message": "two"}]),
                 "gaps": "[]"}
    text = write_html_report(est, sim_log, tmp_path / "r.html", wheel_radius=R).read_text(
        encoding="utf-8")
    assert "id='config-table'" in text
    assert "<tr><td>pipeline</td><td>force</td><td>ukf</td></tr>" in text
    assert "<tr><td>force_params.ukf</td><td>r_omega</td><td>0.18</td></tr>" in text
    assert "{&quot;force" not in text and '{"force' not in text
    assert "<td>warnings</td><td>check: a; message: one<br>check: b; message: two</td>" in text
    assert "<td>gaps</td><td>none</td>" in text


def test_metadata_and_validity_sections(report: Path) -> None:
    text = report.read_text(encoding="utf-8")
    assert "<td>velocity</td><td>fused</td>" in text  # df.attrs
    assert "<td>note</td><td>&lt;b&gt;escaped&lt;/b&gt;</td>" in text  # caller's metadata, escaped
    assert "<title>step steer</title>" in text


def test_sections_skipped_without_channels(tmp_path: Path) -> None:
    """Only v_y, no reference, no flags: just the CG velocity plot, a note for the missing
    sections, the validity note, and no score table (nothing to score against)."""
    t = np.linspace(0.0, 2.0, 201)
    est = pd.DataFrame({"t": t, "vy": 0.1 * np.sin(t)})
    path = write_html_report(est, None, tmp_path / "r.html", wheel_radius=R)
    text = path.read_text(encoding="utf-8")
    assert re.findall(r'id="plot-([a-z_]+)"', text) == ["velocity_cg"]
    assert "no validity/health channels in this estimate" in text
    assert "id='missing-sections'" in text and "Tire forces per corner" in text
    assert "id='score-table'" not in text and "No reference channels" in text
    assert list(report_figures(est, None, wheel_radius=R)) == ["velocity_cg"]


def test_long_log_size_does_not_grow(tmp_path: Path) -> None:
    """Beyond MAX_POINTS every line is a min/max envelope of MAX_POINTS points, so a 200 000
    and a 400 000 sample log of the same channels give reports within 1 % of each other
    (noise in the last base64 digits only), and only a few hundred kB above plotly.js."""
    rng = np.random.default_rng(1)

    def log(n: int) -> pd.DataFrame:
        cols: dict[str, np.ndarray] = {"t": np.arange(n) / 200.0}
        for name in ("vx", *(f"fx_{c}" for c in CORNERS)):
            cols[name] = rng.standard_normal(n)
            cols["ref_" + name] = rng.standard_normal(n)
            cols["sigma_" + name] = rng.random(n)
        for c in CORNERS:
            cols[f"omega_{c}"] = 50.0 + rng.standard_normal(n)
        return pd.DataFrame(cols)

    small = write_html_report(log(200_000), None, tmp_path / "a.html", wheel_radius=R).stat().st_size
    large = write_html_report(log(400_000), None, tmp_path / "b.html", wheel_radius=R).stat().st_size
    js = len(plotly.offline.get_plotlyjs())
    assert abs(large - small) < 0.01 * small
    # speed (4 R·ω + band + estimate + reference + error) and F_x (4 × the same but R·ω)
    # ≈ 30 lines × 2 axes × 2000 points × 5.3 B (float32 base64) ≈ 0.7 MB of data
    assert small - js < 1.2e6


def test_bad_arguments(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    est = pd.DataFrame({"t": [0.0, 1.0], "vx": [1.0, 2.0]})
    with pytest.raises(ValueError, match="wheel_radius must be a positive length"):
        write_html_report(est, None, tmp_path / "r.html", wheel_radius=0.0)
    with pytest.raises(LogFormatError, match="estimate: no time column 't'"):
        write_html_report(est.drop(columns="t"), None, tmp_path / "r.html", wheel_radius=R)
    monkeypatch.setitem(sys.modules, "plotly.graph_objects", None)  # plotly not installed
    with pytest.raises(MissingDependencyError, match=r"vestim\[report\]"):
        write_html_report(est, None, tmp_path / "r.html", wheel_radius=R)
    assert not (tmp_path / "r.html").exists()


def test_cli_report(tmp_path: Path, offset_estimate: pd.DataFrame, sim_log: pd.DataFrame,
                    monkeypatch: pytest.MonkeyPatch) -> None:
    """`vestim report EST REF --out` prints the file; the Parquet metadata of the estimate
    and the vehicle appear in it. A missing plotly is one error line with exit status 2."""
    est = write_log(offset_estimate, tmp_path / "est.parquet",
                    metadata={"force": "ukf", "vehicle": "hashemi_suv"})
    ref = write_log(sim_log, tmp_path / "sim.parquet")
    runner = CliRunner()
    res = runner.invoke(app, ["report", "--vehicle", "hashemi_suv",
                              str(est), str(ref), "--out", str(tmp_path / "r.html")])
    assert res.exit_code == 0, res.output
    assert res.stdout.strip() == str(tmp_path / "r.html")
    text = (tmp_path / "r.html").read_text(encoding="utf-8")
    assert "<td>force</td><td>ukf</td>" in text and "<td>vehicle</td><td>hashemi_suv</td>" in text
    assert "id='score-table'" in text
    monkeypatch.setitem(sys.modules, "plotly.graph_objects", None)
    res = runner.invoke(app, ["report", "--vehicle", "hashemi_suv",
                              str(est), "--out", str(tmp_path / "x.html")])
    assert res.exit_code == 2
    assert "vestim[report]" in res.output and "Traceback" not in res.output
    assert not (tmp_path / "x.html").exists()


@pytest.mark.skipif(not CHROMIUM.exists(), reason="needs Debian Chromium at /usr/bin/chromium "
                    "(apt-get install chromium)")
def test_real_browser_draws_every_plot(report: Path) -> None:
    """Headless Chromium loads the file:// page with every network request refused: no
    request leaves the file, no console error, and every plotly div drew as many SVG
    traces as it has traces, each with data points (plotly's own count of the points it
    decoded from the page, ``_fullData[i]._length``). The validity bands are drawn: the
    speed plot's two "not valid" spans as two shaded rectangles with a width on screen,
    labelled "not converged" in the page and named in the legend; the score table shows
    the coverage columns with fx_fl's 100.0 % within 1σ."""
    from playwright.sync_api import sync_playwright

    args = ["--headless", "--no-sandbox", "--disable-gpu", "--disable-quic", "--no-first-run",
            "--disable-background-networking", "--disable-component-update", "--disable-sync"]
    errors: list[str] = []
    requests: list[str] = []
    with sync_playwright() as p:
        browser = p.chromium.launch(executable_path=str(CHROMIUM), args=args)
        try:
            page = browser.new_page(viewport={"width": 1400, "height": 900})
            page.on("console", lambda m: errors.append(m.text) if m.type == "error" else None)
            page.on("pageerror", lambda e: errors.append(str(e)))

            def route(r) -> None:  # type: ignore[no-untyped-def]
                if r.request.url.startswith("file:"):
                    r.continue_()
                else:
                    requests.append(r.request.url)
                    r.abort()

            page.route("**/*", route)
            page.goto(report.resolve().as_uri())
            page.wait_for_load_state("load")
            divs = page.evaluate("""() => Array.from(document.querySelectorAll('.plotly-graph-div'))
                .map(d => ({id: d.id, traces: d.data.length,
                            points: d._fullData.map(t => t._length || 0),
                            drawn: d.querySelectorAll('.scatterlayer .trace').length}))""")
            bands = page.evaluate("""() => {
                const d = document.getElementById('plot-speed');
                const rects = Array.from(d.querySelectorAll('.shapelayer path'))
                    .map(p => p.getBoundingClientRect().width);
                const texts = Array.from(d.querySelectorAll('.shapelayer text, .legendtext'))
                    .map(t => t.textContent);
                return {rects, texts};
            }""")
            table = page.evaluate("""() => {
                const t = document.getElementById('score-table');
                const head = Array.from(t.querySelectorAll('th')).map(h => h.textContent);
                const row = Array.from(t.querySelectorAll('tr')).find(
                    r => r.cells[0].textContent === 'fx_fl');
                const col = head.indexOf('within 1σ [%]');
                const cell = row.cells[col];
                return {head, value: cell.textContent,
                        visible: cell.getBoundingClientRect().width > 0};
            }""")
        finally:
            browser.close()
    assert errors == []
    assert requests == []
    assert [d["id"] for d in divs] == [f"plot-{k}" for k in ALL_FIGURES]
    for d in divs:
        assert d["traces"] > 0 and min(d["points"]) > 0, d["id"]
        assert d["drawn"] == d["traces"], d
    assert len(bands["rects"]) == 2 and min(bands["rects"]) > 5, bands  # px on screen
    assert "not converged" in bands["texts"], bands  # the label drawn in the band
    assert "velocity not valid: standstill, high slip" in bands["texts"], bands
    assert "within 1σ [%]" in table["head"] and "within 2σ [%]" in table["head"]
    assert table["value"] == "100.0" and table["visible"], table


def test_cli_report_takes_the_vehicle_from_the_metadata(tmp_path: Path, offset_estimate: pd.DataFrame,
                                                        sim_log: pd.DataFrame) -> None:
    """Without --vehicle the report uses the vehicle file the estimate's metadata names
    (vehicle_file, as `vestim estimate` writes it): compact_car's R = 0.31 m, not the
    hashemi_suv default's 0.33 m. An estimate that names none is one error line asking for
    --vehicle; --vehicle still overrides."""
    from importlib import resources

    car = tmp_path / "my_car.toml"
    car.write_bytes((resources.files("vestim") / "data" / "vehicles" / "compact_car.toml").read_bytes())
    est = offset_estimate.copy()
    est.attrs = {"vehicle": "my_car", "vehicle_file": str(car)}
    path = write_log(est, tmp_path / "est.parquet", metadata=est.attrs)
    res = runner_invoke(["report", str(path), "--out", str(tmp_path / "r.html")])
    assert res.exit_code == 0, res.output
    text = (tmp_path / "r.html").read_text(encoding="utf-8")
    assert "<td>wheel_radius</td><td>0.31 m</td>" in text
    assert "<td>vehicle</td><td>my_car (from the estimate&#x27;s metadata)</td>" in text
    res = runner_invoke(["report", str(path), "--vehicle", "hashemi_suv", "--out",
                         str(tmp_path / "r2.html")])
    assert "<td>wheel_radius</td><td>0.33 m</td>" in (tmp_path / "r2.html").read_text(encoding="utf-8")
    est.attrs = {"vehicle": "my_car"}
    bare = write_log(est, tmp_path / "bare.parquet", metadata=est.attrs)
    res = runner_invoke(["report", str(bare), "--out", str(tmp_path / "r3.html")])
    assert res.exit_code == 2 and "names no vehicle file (vehicle 'my_car')" in res.output
    assert "pass --vehicle FILE" in res.output and "Traceback" not in res.output
    car.unlink()
    res = runner_invoke(["report", str(path), "--out", str(tmp_path / "r4.html")])
    assert res.exit_code == 2 and "which is not found" in res.output


def runner_invoke(args: list[str]):  # type: ignore[no-untyped-def]
    return CliRunner().invoke(app, args)


def test_invalid_spans_of_a_long_or_flickering_flag() -> None:
    """Beyond MAX_POINTS rows a span is a time bucket holding at least one invalid row (its
    reasons OR-ed), so no invalid row is lost; a flag that flickers more often than
    MAX_SPANS times is drawn with MAX_SPANS buckets."""
    from vestim.report.data import MAX_SPANS, invalid_spans

    t = np.arange(100_000) * 0.01
    valid = np.ones(t.size)
    reason = np.zeros(t.size)
    valid[50_000], reason[50_000] = 0.0, 8.0  # one row of high slip
    valid[50_001], reason[50_001] = 0.0, 2.0  # the next row: standstill
    (span,) = invalid_spans(t, valid, reason)
    assert span[0] <= t[50_000] and span[1] > t[50_001] and span[2] == 10
    flicker = (np.arange(t.size) % 50 == 0).astype(float)  # invalid every 0.5 s: 2000 spans
    spans = invalid_spans(t, 1.0 - flicker, flicker)
    assert len(spans) <= MAX_SPANS and all(m == 1 for _, _, m in spans)
    assert invalid_spans(t[:10], np.ones(10), np.zeros(10)) == []
