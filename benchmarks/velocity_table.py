"""Velocity-estimation accuracy table (issue 4): CG and corner NRMS per maneuver and method.

Run:  .venv/bin/python benchmarks/velocity_table.py [--out FILE] [--tires magic,lugre]
      [--drivetrains awd,rwd] [--jobs N]

NRMS per 000 (RMS error / max |truth|, in %); for v_y the denominator is
max(max |truth|, 1 m/s). Columns: CG v_x for each velocity method of the pipeline
(the UKF is omitted: it equals the KF to round-off on this linear model; the corner
observers are mapped to the CG with the fixed axle weights η1 = η2 = 0.5), the naive
mean wheel speed R·ω̄ as the floor, then the default's worst-corner v_x and CG v_y,
and the reference filter's v_y. Default parameters, seed 1, default sensor noise; the
estimators see the log with every ``ref_`` column removed.
"""

from __future__ import annotations

import argparse
from concurrent.futures import ProcessPoolExecutor
from pathlib import Path

import numpy as np

from vestim.constants import CORNERS
from vestim.io import load_vehicle
from vestim.metrics import nrms
from vestim.pipeline import VELOCITY_METHODS, Pipeline, PipelineConfig
from vestim.sim import get_maneuver, maneuver_names, simulate

SKIP = {"coast", "split_mu_brake", "stiffness_study"}
DEFAULT = PipelineConfig().velocity
METHODS = [m for m in VELOCITY_METHODS if m != "ukf"]  # ukf == kf to round-off (tested)


def one_run(case: tuple[str, str, str]) -> list[float]:
    """The table cells (%) of one maneuver × tire × drivetrain."""
    name, tire, drive = case
    veh = load_vehicle("hashemi_suv")
    log = simulate(get_maneuver(name, tire=tire, drivetrain=drive), veh, seed=1)
    measured = log[[c for c in log.columns if not c.startswith("ref_")]]
    ref = log["ref_vx"].to_numpy()
    outs = {m: Pipeline(veh, PipelineConfig(velocity=m)).run(measured) for m in METHODS}
    cells = [100 * nrms(outs[m]["vx"], ref) for m in METHODS]
    omega = log[[f"omega_{c}" for c in CORNERS]].to_numpy()
    cells.append(100 * nrms(veh.body.wheel_radius * omega.mean(axis=1), ref))
    d = outs[DEFAULT]
    cells.append(max(100 * nrms(d[f"vx_{c}"], log[f"ref_vx_{c}"]) for c in CORNERS))
    cells.append(100 * nrms(d["vy"], log["ref_vy"], 1.0))
    cells.append(100 * nrms(outs["reference"]["vy"], log["ref_vy"], 1.0))
    return cells


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--out", type=Path, default=None)
    ap.add_argument("--tires", default="magic,lugre")
    ap.add_argument("--drivetrains", default="awd,rwd")
    ap.add_argument("--jobs", type=int, default=1)
    args = ap.parse_args()
    cases = [(name, tire, drive) for tire in args.tires.split(",")
             for drive in args.drivetrains.split(",")
             for name in maneuver_names() if name not in SKIP]
    header = ["maneuver", "tire", "drive", *[f"vx {m}" for m in METHODS], "vx R·ω̄",
              f"corner vx {DEFAULT} (worst)", f"vy {DEFAULT}", "vy reference"]
    lines = ["| " + " | ".join(header) + " |", "|" + "---|" * len(header)]
    with ProcessPoolExecutor(args.jobs) as pool:
        results = list(pool.map(one_run, cases))
    for case, cells in zip(cases, results, strict=True):
        lines.append("| " + " | ".join([*case, *(f"{v:.1f}" for v in cells)]) + " |")
        print(lines[-1], flush=True)
    table = np.array(results)
    k = METHODS.index(DEFAULT)
    summary = (f"\n{DEFAULT}: CG vx ≤ 1 % on {int(np.sum(table[:, k] <= 1.0))}/{len(cases)} runs "
               f"(worst {table[:, k].max():.1f} %), every corner ≤ 2 % on "
               f"{int(np.sum(table[:, -3] <= 2.0))}/{len(cases)}, CG vy ≤ 5 % on "
               f"{int(np.sum(table[:, -2] <= 5.0))}/{len(cases)} (worst {table[:, -2].max():.1f} %)\n")
    print(summary)
    if args.out:
        args.out.write_text("\n".join(lines) + "\n" + summary)


if __name__ == "__main__":
    main()
