"""Every velocity configuration on the independent data: the crossplant logs and the RAV4 log.

Runs the pipeline in-process with the vehicle files exactly as given (nominal tire values,
no [suspension]) on each log copied without its ``ref_`` columns, scores it with
``../shared/crossplant/targets.py``'s own ``judge`` (the accuracy targets of the cross-plant
issue), scores the naive floor of ``../shared/crossplant/baselines.py`` the same way, and
writes the Markdown tables between the markers in docs/results.md (crossplant and real
first). Usage (from the project root):

    .venv/bin/python benchmarks/crossplant_table.py [--configs fused reference kf ukf lpv]
        [--only x05 x06] [--no-write]
"""

from __future__ import annotations

import argparse
import json
import sys
import tempfile
import tomllib
from pathlib import Path

import numpy as np
import pandas as pd

from _docs import write_section
from vestim.io import load_vehicle
from vestim.pipeline import Pipeline, PipelineConfig

ROOT = Path(__file__).resolve().parents[1]
SHARED = ROOT.parent / "shared"
XP = SHARED / "crossplant"
RAV4 = SHARED / "real" / "comma2k19_rav4"


def _measured(log: pd.DataFrame) -> pd.DataFrame:
    return log[[c for c in log.columns if not c.startswith(("ref_", "_"))]]


def _row(name: str, figs: dict[str, float], probs: list[str]) -> str:
    f = figs
    return (f"| {name} | {f['vx']:.2f} | {f['vx_c']:.2f} | {f['vy']:.3f} / {max(0.04, 0.5 * f['vy0']):.3f}"
            f" | {f['sa']:.2f} / {f['sa_lim']:.2f} | {f['fz']:.2f} / {f['fz_c']:.2f} | {f['fx']:.2f}"
            f" | {f['fy']:.2f} | {f['mu']:.2f} | {len(probs)} |")


def crossplant(configs: list[str], only: list[str]) -> list[str]:
    """Markdown lines: one table per log, a row per configuration and the naive floor."""
    sys.path.insert(0, str(XP))
    import baselines  # type: ignore[import-not-found]
    import targets  # type: ignore[import-not-found]

    man = json.loads((XP / "data" / "manifest.json").read_text())["maneuvers"]
    names = [m for m in sorted(man) if not only or m.startswith(tuple(only))]
    head = ("| configuration | vx % | worst corner vx % | vy RMSE / limit m/s | slip angle ° / limit"
            " | Fz pooled / worst % | Fx % | Fy % | max \\|μ\\| | targets missed |")
    lines = ["Targets: vx ≤ 1 % (mean ≤ 0.4 %), corners ≤ 1.5 %; vy and slip angle ≤ the limit "
             "shown; Fz ≤ 2 % / 3 %; Fx ≤ 4 % (8 % on x01–x04, x07); Fy ≤ 5 %; |μ| ≤ 1.2. "
             "`naive` is the floor of `../shared/crossplant/baselines.py` (vy = 0, static "
             "loads, (T − I_w ω̇)/R), scored the same way.", ""]
    mean_vx: dict[str, list[float]] = {c: [] for c in configs}
    with tempfile.TemporaryDirectory() as tmp:
        for m in names:
            truth = XP / "data" / man[m]["file"]
            vfile = XP / "data" / man[m]["vehicle_file"]
            veh = tomllib.loads(vfile.read_text())["vehicle"]
            log = pd.read_parquet(truth)
            lines += [f"**{m}**", "", head, "|---|---|---|---|---|---|---|---|---|---|"]
            for cfg in configs:
                est = Pipeline(load_vehicle(str(vfile)), PipelineConfig(velocity=cfg)).run(_measured(log))
                path = Path(tmp) / f"{m}.{cfg}.parquet"
                est.to_parquet(path)
                figs, probs = targets.judge(m, truth, path, veh)
                mean_vx[cfg].append(figs["vx"])
                lines.append(_row(cfg, figs, probs))
            naive = baselines.naive(log, veh)
            path = Path(tmp) / f"{m}.naive.parquet"
            naive.to_parquet(path)
            figs, probs = targets.judge(m, truth, path, veh)
            lines += [_row("naive", figs, probs), ""]
            print(m, "done", flush=True)
    lines.append("Mean CG vx NRMS over the logs: " + ", ".join(
        f"{c} {np.mean(v):.2f} %" for c, v in mean_vx.items()) + ".")
    return lines


def rav4(configs: list[str]) -> list[str]:
    """Markdown lines: the RAV4 log (no torques), v_x and v_y RMSE against the pose reference,
    with and without its sparse ``gnss_speed``."""
    log = pd.read_parquet(RAV4 / "seg40.parquet")
    veh = load_vehicle(str(RAV4 / "vehicle.toml"))
    ref_vx, ref_vy = log["ref_vx"].to_numpy(), log["ref_vy"].to_numpy()
    omega = log[[f"omega_{c}" for c in ("fl", "fr", "rl", "rr")]].to_numpy()
    wheel = veh.body.wheel_radius * omega.mean(axis=1)

    def rmse(a: np.ndarray) -> float:
        return float(np.sqrt(np.mean(a * a)))

    lines = ["| configuration | vx RMSE m/s, no gnss_speed | vx RMSE m/s, with gnss_speed "
             "| vy RMSE m/s |", "|---|---|---|---|",
             f"| mean wheel speed, vy = 0 | {rmse(wheel - ref_vx):.3f} | — | "
             f"{rmse(ref_vy):.3f} |"]
    measured = _measured(log)
    for cfg in configs:
        cells = []
        for data in (measured.drop(columns=["gnss_speed"]), measured):
            est = Pipeline(veh, PipelineConfig(velocity=cfg)).run(data)
            cells.append((rmse(est["vx"].to_numpy() - ref_vx), rmse(est["vy"].to_numpy() - ref_vy)))
        lines.append(f"| {cfg} | {cells[0][0]:.3f} | {cells[1][0]:.3f} | {cells[1][1]:.3f} |")
    return [*lines, "", "Targets: vx ≤ 0.155 m/s without `gnss_speed`, ≤ 0.06 m/s with it; "
            "vy ≤ 0.03 m/s."]


def summary(only: list[str]) -> list[str]:
    """Markdown lines: the default against every target, one row per crossplant log."""
    sys.path.insert(0, str(XP))
    import targets  # type: ignore[import-not-found]

    man = json.loads((XP / "data" / "manifest.json").read_text())["maneuvers"]
    lines = ["| log | vx % | corner vx % | vy m/s (limit) | slip angle ° (limit) | Fz % pooled / "
             "worst | Fx % (limit) | Fy % | max \\|μ\\| | misses |",
             "|---|---|---|---|---|---|---|---|---|---|"]
    misses = 0
    with tempfile.TemporaryDirectory() as tmp:
        for m in sorted(man):
            if only and not m.startswith(tuple(only)):
                continue
            truth = XP / "data" / man[m]["file"]
            vfile = XP / "data" / man[m]["vehicle_file"]
            path = Path(tmp) / f"{m}.parquet"
            Pipeline(load_vehicle(str(vfile))).run(_measured(pd.read_parquet(truth))).to_parquet(path)
            f, probs = targets.judge(m, truth, path, tomllib.loads(vfile.read_text())["vehicle"])
            misses += len(probs)
            lim = 8 if m.startswith(targets.LIMITED) else 4
            lines.append(
                f"| {m} | {f['vx']:.2f} | {f['vx_c']:.2f} | {f['vy']:.3f} ({max(0.04, 0.5 * f['vy0']):.3f})"
                f" | {f['sa']:.2f} ({f['sa_lim']:.2f}) | {f['fz']:.2f} / {f['fz_c']:.2f} | {f['fx']:.2f} "
                f"({lim}) | {f['fy']:.2f} | {f['mu']:.2f} | {'; '.join(probs) or '—'} |")
    return [*lines, "", f"{misses} targets missed (`../shared/crossplant/targets.py` checks the same)."]


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__)
    ap.add_argument("--configs", nargs="+", default=["fused", "reference", "kf", "ukf", "lpv"])
    ap.add_argument("--only", nargs="*", default=[])
    ap.add_argument("--no-write", action="store_true")
    args = ap.parse_args()
    body = ["## Independent data (first): crossplant and the real RAV4 log", "",
            "Made by `benchmarks/crossplant_table.py` (vehicle files as given; one parameter "
            "set for every log).", "", "### The default against the targets", "",
            *summary(args.only), "", "### RAV4 (comma2k19 seg40, real)", "",
            *rav4(args.configs), "", "### Crossplant x01–x12 (CommonRoad MB + PAC2002)", "",
            *crossplant(args.configs, args.only)]
    text = "\n".join(body)
    print(text)
    if args.no_write:
        return
    write_section("crossplant", text)


if __name__ == "__main__":
    main()
