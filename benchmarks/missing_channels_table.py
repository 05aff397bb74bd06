"""Accuracy cost of missing channels (issue 4): no wheel torques, no roll/pitch rates and az.

Run:  .venv/bin/python benchmarks/missing_channels_table.py [--out docs/results_missing_channels.md]

With --out, an existing file keeps its text and only the table between the
``<!-- table -->`` and ``<!-- /table -->`` markers is replaced; a new file gets the table.

Each simulated log (Magic Formula tire, seed 1, default sensor noise) is estimated
four times with the default pipeline: with every channel ("all"), without the four
``torque_*`` columns ("−T": F_x from the chassis equation, vestim.models.chassis),
without ``roll_rate``, ``pitch_rate`` and ``az`` ("−rpa": quasi-static attitude,
level-road a_z), and without both ("−T−rpa": what a conventional car's CAN log often
has). Cells are NRMS in % per 000 Sec. IV (RMS error / max |truth|): F_x and F_z the
worst of the four corners, F_x with the issue's 500 N floor; v_x the CG speed.
"F_x −T axle" is the worst axle's NRMS of the left + right sum (1000 N floor): the chassis
path splits each axle's torque equally left/right (an open differential), so where
individually controlled motors cut one wheel's torque the corner figure suffers and the
axle figure shows what is left. F_z does not depend on the torques, so its "−T" column
equals "all" and is left out.
The estimator is given the maneuver's drivetrain (``Vehicle.with_drivetrain``), as a
user gives the vehicle file of the car that was logged.
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

import numpy as np
import pandas as pd

from vestim.constants import CORNERS
from vestim.io import load_vehicle
from vestim.pipeline import Pipeline
from vestim.sim import get_maneuver, simulate

MANEUVERS = ("accel_brake", "ait_dry", "launch_split_mu", "dlc_snow")
DRIVETRAINS = ("awd", "rwd")
TORQUES = [f"torque_{c}" for c in CORNERS]
ATTITUDE = ["roll_rate", "pitch_rate", "az"]
BEGIN, END = "<!-- table -->", "<!-- /table -->"
VARIANTS: dict[str, list[str]] = {"all": [], "−T": TORQUES, "−rpa": ATTITUDE,
                                  "−T−rpa": TORQUES + ATTITUDE}


def nrms(est: np.ndarray, ref: np.ndarray, floor: float = 0.0) -> float:
    """NRMS in % (000 Sec. IV), denominator max(max |ref|, floor)."""
    return float(100 * np.sqrt(np.mean((est - ref) ** 2)) / max(np.max(np.abs(ref)), floor))


def worst(out: pd.DataFrame, log: pd.DataFrame, name: str, floor: float = 0.0) -> float:
    return max(nrms(out[f"{name}_{c}"].to_numpy(), log[f"ref_{name}_{c}"].to_numpy(), floor)
               for c in CORNERS)


def row(maneuver: str, drive: str) -> list[float]:
    veh = load_vehicle("hashemi_suv").with_drivetrain(drive)
    log = simulate(get_maneuver(maneuver, tire="magic", drivetrain=drive), veh, seed=1)
    measured = log.drop(columns=[c for c in log.columns if c.startswith("ref_")])
    outs = {k: Pipeline(veh).run(measured.drop(columns=drop)) for k, drop in VARIANTS.items()}
    fx = [worst(outs[k], log, "fx", 500.0) for k in VARIANTS]
    axle = max(nrms(outs["−T"][[f"fx_{c}" for c in pair]].to_numpy().sum(axis=1),
                    log[[f"ref_fx_{c}" for c in pair]].to_numpy().sum(axis=1), 1000.0)
               for pair in (CORNERS[:2], CORNERS[2:]))
    fz = [worst(outs[k], log, "fz") for k in ("all", "−rpa")]
    vx = [nrms(outs[k]["vx"].to_numpy(), log["ref_vx"].to_numpy()) for k in VARIANTS]
    return [*fx, axle, *fz, *vx]


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--out", type=Path, default=None)
    args = ap.parse_args()
    header = ["maneuver", "drive", *[f"F_x {k}" for k in VARIANTS], "F_x −T axle", "F_z all",
              "F_z −rpa",
              *[f"v_x {k}" for k in VARIANTS]]
    lines = ["| " + " | ".join(header) + " |", "|" + "---|" * len(header)]
    for maneuver in MANEUVERS:
        for drive in DRIVETRAINS:
            cells = row(maneuver, drive)
            fmt = [f"{v:.1f}" for v in cells[:7]] + [f"{v:.2f}" for v in cells[7:]]
            lines.append("| " + " | ".join([maneuver, drive, *fmt]) + " |")
            print(lines[-1], flush=True)
    text = "\n".join(lines) + "\n"
    if args.out:
        old = args.out.read_text(encoding="utf-8") if args.out.exists() else ""
        if BEGIN in old and END in old:
            head, rest = old.split(BEGIN, 1)
            text = f"{head}{BEGIN}\n{text}{END}{rest.split(END, 1)[1]}"
        args.out.write_text(text, encoding="utf-8")
    else:
        sys.stdout.write(text)


if __name__ == "__main__":
    main()
