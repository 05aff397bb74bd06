"""Force-estimation accuracy table (issue 3): NRMS per corner on every maneuver, both tire plants.

Run:  .venv/bin/python benchmarks/force_table.py [--out docs/results_force.md]

NRMS is 000's definition (RMS error / max |truth|). For channels whose truth
stays near zero (F_x at constant speed, F_y when driving straight) the
denominator is max(max |truth|, 500 N), as the issue asks. Each cell is the
worst of the four corners. Columns:
  Fx ukf / ukf_rw / pid / uio / naive — longitudinal methods; naive is the
      finite-difference floor (T − I_w Δω/Δt)/R on the noisy log;
  Fx FD-true — the same finite difference on the noise-free log (true ω and T):
      the floor where TC/ABS chop the torque faster than the sampling;
  Fy — lateral UKF; Fz dyn / static / paper — our load transfer with the
      suspension states, quasi-static, and 001 eq. (14)–(17) as printed.
Default parameters for every run, seed 1, default sensor noise.
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

import numpy as np

from vestim.constants import CORNERS
from vestim.estimators.force import ForceConfig, ForceEstimator
from vestim.estimators.force import normal as nrm
from vestim.io import load_vehicle
from vestim.io.inputs import inputs_from_log
from vestim.sim import SensorModel, get_maneuver, maneuver_names, simulate

SKIP = {"coast", "split_mu_brake"}


def nrms(est: np.ndarray, ref: np.ndarray, floor: float = 0.0) -> float:
    return float(np.sqrt(np.mean((est - ref) ** 2)) / max(np.max(np.abs(ref)), floor))


def worst(out, log, prefix: str, floor: float = 0.0) -> float:
    return 100 * max(nrms(out[f"{prefix}_{c}"].to_numpy(), log[f"ref_{prefix}_{c}"].to_numpy(), floor)
                     for c in CORNERS)


def row(name: str, tire: str, veh) -> list[str]:
    m = get_maneuver(name, tire=tire)
    log = simulate(m, veh, seed=1)
    clean = simulate(m, veh, sensors=SensorModel.ideal())
    cells = []
    for method in ("ukf", "ukf_rw", "pid", "uio", "naive"):
        out = ForceEstimator(veh, ForceConfig(longitudinal=method)).run(log)
        cells.append(worst(out, log, "fx", 500.0))
        if method == "ukf":
            fy = worst(out, log, "fy", 500.0)
            fz_dyn = worst(out, log, "fz")
    fd_true = ForceEstimator(veh, ForceConfig(longitudinal="naive")).run(clean)
    cells.append(worst(fd_true, clean, "fx", 500.0))
    fz_static = worst(ForceEstimator(veh, ForceConfig(normal="static")).run(log), log, "fz")
    # 001 eq. (14)-(17) as printed, fed with our attitude estimate.
    out = ForceEstimator(veh).run(log)
    u = inputs_from_log(log, veh)
    paper = nrm.normal_loads_paper(u.ax, u.ay, u.az, out["roll"].to_numpy(),
                                   out["pitch"].to_numpy(), veh)
    fz_paper = 100 * max(nrms(paper[:, i], log[f"ref_fz_{c}"].to_numpy())
                         for i, c in enumerate(CORNERS))
    flags = ",".join(f for f, on in (("TC", m.tc), ("ABS", m.abs_)) if on) or "-"
    return [name, tire, flags, *(f"{v:.1f}" for v in cells), f"{fy:.1f}", f"{fz_dyn:.1f}",
            f"{fz_static:.1f}", f"{fz_paper:.1f}"]


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--out", type=Path, default=None)
    args = ap.parse_args()
    veh = load_vehicle("hashemi_suv")
    header = ["maneuver", "tire", "ctrl", "Fx ukf", "Fx ukf_rw", "Fx pid", "Fx uio", "Fx naive",
              "Fx FD-true", "Fy ukf", "Fz dyn", "Fz static", "Fz paper"]
    lines = ["| " + " | ".join(header) + " |", "|" + "---|" * len(header)]
    for tire in ("magic", "lugre"):
        for name in maneuver_names():
            if name in SKIP:
                continue
            lines.append("| " + " | ".join(row(name, tire, veh)) + " |")
            print(lines[-1], flush=True)
    text = "\n".join(lines) + "\n"
    if args.out:
        args.out.write_text(text)
    else:
        sys.stdout.write(text)


if __name__ == "__main__":
    main()
