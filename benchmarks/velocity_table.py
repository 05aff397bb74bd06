"""Velocity-estimation accuracy table (issue 4): CG and corner NRMS per maneuver and method.

Run:  .venv/bin/python benchmarks/velocity_table.py [--out FILE] [--tires magic,lugre]
      [--drivetrains awd,rwd]

NRMS per 000 (RMS error / max |truth|); for v_y the denominator is
max(max |truth|, 1 m/s). Columns: CG v_x for each velocity method of the
pipeline (the UKF is omitted: it equals the KF to round-off on this linear
model) and the naive mean wheel speed R·ω̄ as the floor, then the default's
worst-corner v_x and CG v_y.
Default parameters, seed 1, default sensor noise.
"""

from __future__ import annotations

import argparse
from pathlib import Path

import numpy as np

from vestim.constants import CORNERS
from vestim.io import load_vehicle
from vestim.pipeline import VELOCITY_METHODS, Pipeline, PipelineConfig
from vestim.sim import get_maneuver, maneuver_names, simulate

SKIP = {"coast", "split_mu_brake", "stiffness_study"}
DEFAULT = PipelineConfig().velocity


def nrms(est: np.ndarray, ref: np.ndarray, floor: float = 0.0) -> float:
    return float(100 * np.sqrt(np.mean((est - ref) ** 2)) / max(np.max(np.abs(ref)), floor))


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--out", type=Path, default=None)
    ap.add_argument("--tires", default="magic,lugre")
    ap.add_argument("--drivetrains", default="awd,rwd")
    args = ap.parse_args()
    veh = load_vehicle("hashemi_suv")
    methods = [m for m in VELOCITY_METHODS if m != "ukf"]  # ukf == kf to round-off (tested)
    header = ["maneuver", "tire", "drive", *[f"vx {m}" for m in methods], "vx R·ω̄",
              f"corner vx {DEFAULT} (worst)", f"vy {DEFAULT}"]
    lines = ["| " + " | ".join(header) + " |", "|" + "---|" * len(header)]
    for tire in args.tires.split(","):
        for drive in args.drivetrains.split(","):
            for name in maneuver_names():
                if name in SKIP:
                    continue
                log = simulate(get_maneuver(name, tire=tire, drivetrain=drive), veh, seed=1)
                ref = log["ref_vx"].to_numpy()
                cells = []
                outs = {}
                for m in methods:
                    outs[m] = Pipeline(veh, PipelineConfig(velocity=m)).run(log)
                    cells.append(nrms(outs[m]["vx"].to_numpy(), ref))
                omega = log[[f"omega_{c}" for c in CORNERS]].to_numpy()
                cells.append(nrms(veh.body.wheel_radius * omega.mean(axis=1), ref))
                d = outs[DEFAULT]
                corner = max(nrms(d[f"vx_{c}"].to_numpy(), log[f"ref_vx_{c}"].to_numpy())
                             for c in CORNERS)
                cells += [corner, nrms(d["vy"].to_numpy(), log["ref_vy"].to_numpy(), 1.0)]
                lines.append("| " + " | ".join([name, tire, drive, *(f"{v:.1f}" for v in cells)])
                             + " |")
                print(lines[-1], flush=True)
    text = "\n".join(lines) + "\n"
    if args.out:
        args.out.write_text(text)


if __name__ == "__main__":
    main()
