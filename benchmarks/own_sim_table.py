"""The default pipeline on vestim's own simulator: per-run figures, and their change against
a baseline run of an earlier version (the regression check of the cross-plant issue).

    .venv/bin/python benchmarks/own_sim_table.py --out now.json
    .venv/bin/python benchmarks/own_sim_table.py --compare benchmarks/own_sim_baseline_6e6584c.json now.json

``own_sim_baseline_6e6584c.json`` holds the figures of commit 6e6584c, before the
cross-plant issue (made with this script on that checkout).

Per maneuver × tire × drivetrain (seed 1, default sensors, no ``ref_`` columns): CG v_x
NRMS %, CG v_y NRMS % (denominator max(|v_y|, 1 m/s)), worst-corner v_x %, worst-corner
F_x and F_y % (500 N floor), worst-corner F_z %. ``--compare`` prints the runs where a
channel got worse by more than 0.3 point and the worst change per channel (Markdown).
"""

from __future__ import annotations

import argparse
import json
from pathlib import Path

import numpy as np
import pandas as pd

from vestim.io import load_vehicle
from vestim.pipeline import Pipeline
from vestim.sim import get_maneuver, maneuver_names, simulate

CORNERS = ("fl", "fr", "rl", "rr")
SKIP = {"coast", "split_mu_brake", "stiffness_study"}


def _nrms(est: np.ndarray, ref: np.ndarray, floor: float = 0.0) -> float:
    return float(100 * np.sqrt(np.mean((est - ref) ** 2)) / max(np.abs(ref).max(), floor))


def _worst(e: pd.DataFrame, log: pd.DataFrame, q: str, floor: float = 0.0) -> float:
    """Worst corner's NRMS % of channel ``q``."""
    return max(_nrms(e[f"{q}_{c}"].to_numpy(), log[f"ref_{q}_{c}"].to_numpy(), floor)
               for c in CORNERS)


def run_all() -> dict[str, dict[str, float]]:
    veh = load_vehicle("hashemi_suv")
    out: dict[str, dict[str, float]] = {}
    for name in maneuver_names():
        if name in SKIP:
            continue
        for tire in ("magic", "lugre"):
            for drive in ("awd", "rwd"):
                log = simulate(get_maneuver(name, tire=tire, drivetrain=drive), veh, seed=1)
                e = Pipeline(veh).run(log[[c for c in log.columns if not c.startswith("ref_")]])

                out[f"{name}/{tire}/{drive}"] = {
                    "vx": _nrms(e["vx"].to_numpy(), log["ref_vx"].to_numpy()),
                    "vy": _nrms(e["vy"].to_numpy(), log["ref_vy"].to_numpy(), 1.0),
                    "vx_corner": _worst(e, log, "vx"), "fx": _worst(e, log, "fx", 500.0),
                    "fy": _worst(e, log, "fy", 500.0), "fz": _worst(e, log, "fz")}
    return out


def compare(base: dict[str, dict[str, float]], now: dict[str, dict[str, float]]) -> str:
    rows = ["| run | channel | before % | now % |", "|---|---|---|---|"]
    worst: dict[str, float] = {}
    for run, figs in base.items():
        for ch, b in figs.items():
            d = now[run][ch] - b
            worst[ch] = max(worst.get(ch, -np.inf), d)
            if d > 0.3:
                rows.append(f"| {run} | {ch} | {b:.2f} | {now[run][ch]:.2f} |")
    better = sum(now[r][c] < base[r][c] - 0.3 for r in base for c in base[r])
    return "\n".join([*rows, "", "Worst change per channel (points): " + ", ".join(
        f"{c} {v:+.2f}" for c, v in worst.items()) + f"; {better} run-channels improved by "
        "more than 0.3 point."])


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__)
    ap.add_argument("--out", type=Path)
    ap.add_argument("--compare", nargs=2, type=Path, metavar=("BASE", "NOW"))
    args = ap.parse_args()
    if args.compare:
        base, now = (json.loads(p.read_text()) for p in args.compare)
        print(compare(base, now))
        return
    res = run_all()
    text = json.dumps(res, indent=1)
    if args.out:
        args.out.write_text(text)
    else:
        print(text)


if __name__ == "__main__":
    main()
