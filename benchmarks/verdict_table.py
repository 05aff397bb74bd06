"""The papers' velocity methods against the reference filter on independent data (issue 31's
verdict table): CG v_x NRMS (%) per crossplant log and per campaign maneuver family, for the
default (the reference filter, ``reference``), the fused filter (``fused``), the corner
observers of 000/001 (``kf``, ``ukf``, ``lpv``, fused to the CG by 001's axle weights) and
the corner KF with the other fusions (``adaptive``, 003's ``opinion``).

usage: python benchmarks/verdict_table.py [--jobs 2] [--rerun]

Each configuration is one ``benchmarks/lateral_study.py`` run (tag ``verdict_<name>``, scores in
/tmp/vestim-study/); existing scores are reused unless ``--rerun``. Prints Markdown: the table
and, per log, the default's gap to the best single configuration (issue 31: ≤ 0.1 point).
Not part of the test run.
"""
from __future__ import annotations

import argparse
import json
from pathlib import Path

import numpy as np

import lateral_study

CONFIGS: dict[str, list[str]] = {
    "reference": [],
    "fused": ["velocity=fused"],
    "kf": ["velocity=kf"],
    "ukf": ["velocity=ukf"],
    "lpv": ["velocity=lpv"],
    "kf/adaptive": ["velocity=kf", "fusion=adaptive"],
    "kf/opinion": ["velocity=kf", "fusion=opinion"],
}
"""Column → the study's ``--set`` overrides (the default first)."""

STUDY = Path("/tmp/vestim-study")


def _tag(name: str) -> str:
    return "verdict_" + name.replace("/", "_")


def _scores(name: str, jobs: int, rerun: bool) -> dict[str, dict]:
    path = STUDY / _tag(name) / "scores.json"
    if rerun or not path.is_file():
        args = ["--tag", _tag(name), "--jobs", str(jobs), "--only", "cross", "campaign"]
        lateral_study.main(args + (["--set", *CONFIGS[name]] if CONFIGS[name] else []))
    return json.loads(path.read_text())


def _vx(res: dict) -> float:
    r = res.get("vx", {}) if "error" not in res else {}
    v = r.get("value")
    return float("nan") if v is None else float(v)


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser()
    ap.add_argument("--jobs", type=int, default=2)
    ap.add_argument("--rerun", action="store_true")
    a = ap.parse_args(argv)
    scores = {name: _scores(name, a.jobs, a.rerun) for name in CONFIGS}
    logs = sorted(s for s in scores["reference"] if s.startswith(("x", "s")))
    groups: dict[str, list[str]] = {}
    for sid in logs:
        family = sid if sid.startswith("x") else "campaign " + sid.split("_", 2)[2]
        groups.setdefault(family, []).append(sid)
    names = list(CONFIGS)
    print("| log / family (n) | " + " | ".join(names) + " | best single | default − best |")
    print("|---" * (len(names) + 3) + "|")
    worst_gap = []
    for family, sids in groups.items():
        table = np.array([[_vx(scores[n][s]) for n in names] for s in sids])
        # Only scenarios with wheel speeds compare the corner observers (without them every
        # method is the reference filter on the speed measurements).
        med = np.nanmedian(table, axis=0)
        gaps = table[:, 0] - np.nanmin(table, axis=1)
        worst_gap.extend(gaps.tolist())
        best = names[int(np.nanargmin(med))]
        cells = " | ".join(f"{v:.3f}" for v in med)
        label = f"{family} ({len(sids)})" if len(sids) > 1 else family
        print(f"| {label} | {cells} | {best} | {np.nanmax(gaps):+.3f} |")
    g = np.array(worst_gap)
    print(f"\nDefault − best single configuration per log: ≤ 0.1 point on {int((g <= 0.1).sum())} of "
          f"{g.size}; worst {g.max():+.3f}.")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
