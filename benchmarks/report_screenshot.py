"""The HTML report in a real browser: the docs screenshot and the size of a 1 h report.

1. Runs the default pipeline on the cross-plant log x07 (brake in a turn, dry, AWD) from its
   measured channels only, writes ``vestim report``'s HTML for it against the full log
   (out/report/x07_report.html), opens it in headless Debian Chromium (playwright) and saves
   the top of the page (summary and speeds) and the F_x grid, one below the other, as
   docs/img/report.png, after checking that the page logged no
   console error and that every plotly div drew its traces.
2. ``--long``: tiles that estimate and log to one hour at 200 Hz (720 000 samples), writes
   its report and prints the file size and the time to write it (min/max envelope, so the
   size does not grow with the log's length).

Usage (from the project root):

    .venv/bin/python benchmarks/report_screenshot.py [--long] [--no-screenshot]
"""

from __future__ import annotations

import argparse
import io
import sys
import time
from pathlib import Path

import numpy as np
import pandas as pd

import vestim
from vestim.io import load_vehicle, read_log
from vestim.io.files import atomic_path
from vestim.report.html import write_html_report

ROOT = Path(__file__).resolve().parents[1]
XP = ROOT.parent / "shared" / "crossplant" / "data"
LOG = XP / "x07_brake_turn_dry_awd.parquet"
VEHICLE = XP / "vehicle3_awd.toml"
OUT = ROOT / "out" / "report"
PNG = ROOT / "docs" / "img" / "report.png"
CHROMIUM = "/usr/bin/chromium"
ARGS = ["--headless", "--no-sandbox", "--disable-gpu", "--disable-quic", "--no-first-run",
        "--disable-background-networking", "--disable-component-update", "--disable-sync"]
VIEWPORT = {"width": 1400, "height": 1000}


def _estimate() -> tuple[pd.DataFrame, pd.DataFrame, float]:
    """The default estimate with the metadata `vestim estimate` writes (vestim.estimate)."""
    veh = load_vehicle(VEHICLE)
    log = read_log(LOG)
    measured = log[[c for c in log.columns if not c.startswith("ref_")]]
    est = vestim.estimate(measured, VEHICLE)
    return est, log, veh.body.wheel_radius


def _screenshot(page_path: Path, png: Path) -> None:
    from playwright.sync_api import sync_playwright

    errors: list[str] = []
    with sync_playwright() as p:
        browser = p.chromium.launch(executable_path=CHROMIUM, args=ARGS)
        try:
            page = browser.new_page(viewport=VIEWPORT)
            page.on("console", lambda m: errors.append(m.text) if m.type == "error" else None)
            page.on("pageerror", lambda e: errors.append(str(e)))
            page.goto(page_path.resolve().as_uri())
            page.wait_for_load_state("load")
            traces = page.evaluate(
                "Array.from(document.querySelectorAll('.plotly-graph-div'))"
                ".map(d => [d.id, d.querySelectorAll('.scatterlayer .trace').length])")
            # the top of the page down to the end of the speed figure, then the F_x grid
            speed = page.locator("#plot-speed").bounding_box()
            forces = page.locator("#plot-force_fx").bounding_box()
            if speed is None or forces is None:
                sys.exit("the report has no speed or F_x figure to show")
            width = VIEWPORT["width"]
            top = page.screenshot(full_page=True, clip={"x": 0, "y": 0, "width": width,
                                                        "height": speed["y"] + speed["height"]})
            grid = page.screenshot(full_page=True, clip={"x": 0, "y": forces["y"], "width": width,
                                                         "height": forces["height"]})
        finally:
            browser.close()
    if errors:
        sys.exit(f"console errors: {errors}")
    _stack([top, grid], png)
    empty = [div for div, n in traces if n == 0]
    if empty:
        sys.exit(f"plots without drawn traces: {empty}")
    print(f"{len(traces)} plotly divs drawn, no console error; wrote {png} "
          f"({png.stat().st_size / 1e3:.0f} kB)")


def _stack(shots: list[bytes], png: Path) -> None:
    """The browser's PNG screenshots one below the other, written atomically to ``png``."""
    from PIL import Image

    images = [Image.open(io.BytesIO(b)).convert("RGB") for b in shots]
    out = Image.new("RGB", (max(i.width for i in images), sum(i.height for i in images)), "white")
    y = 0
    for im in images:
        out.paste(im, (0, y))
        y += im.height
    with atomic_path(png) as tmp:
        out.save(tmp, format="png", optimize=True)


def _long(est: pd.DataFrame, log: pd.DataFrame, wheel_radius: float) -> None:
    dt = float(np.median(np.diff(log["t"].to_numpy())))
    n_tiles = int(np.ceil(3600.0 / (len(log) * dt)))
    span = len(log) * dt

    def tile(df: pd.DataFrame) -> pd.DataFrame:
        out = pd.concat([df] * n_tiles, ignore_index=True)
        out["t"] = np.arange(len(out)) * dt
        out.attrs = dict(df.attrs)
        return out

    est_l, log_l = tile(est), tile(log)
    t0 = time.perf_counter()
    path = write_html_report(est_l, log_l, OUT / "long_1h_report.html", wheel_radius=wheel_radius,
                             title="1 h tiled x07")
    wall = time.perf_counter() - t0
    print(f"1 h report: {len(est_l)} samples ({n_tiles} × {span:.1f} s at {1 / dt:.0f} Hz), "
          f"{path.stat().st_size / 1e6:.2f} MB, written in {wall:.1f} s -> {path}")


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--long", action="store_true", help="also write and size a 1 h report")
    ap.add_argument("--no-screenshot", action="store_true", help="skip the browser step")
    args = ap.parse_args()
    est, log, radius = _estimate()
    t0 = time.perf_counter()
    page = write_html_report(est, log, OUT / "x07_report.html", wheel_radius=radius,
                             metadata={"estimate": "pipeline (default config), measured channels",
                                       "reference": LOG.name},
                             title="vestim report: x07 brake in a turn (cross-plant)")
    print(f"wrote {page} ({page.stat().st_size / 1e6:.2f} MB, {len(est)} samples) in "
          f"{time.perf_counter() - t0:.1f} s")
    if not args.no_screenshot:
        _screenshot(page, PNG)
    if args.long:
        _long(est, log, radius)


if __name__ == "__main__":
    main()
