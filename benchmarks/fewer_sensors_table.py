"""Accuracy with fewer sensors on the crossplant logs (issue 14): no wheel speeds, no ax, no rates.

Run:  .venv/bin/python benchmarks/fewer_sensors_table.py [--out docs/fewer-sensors.md]

With --out, the table between the ``<!-- table -->`` and ``<!-- /table -->`` markers of the
file is replaced (the rest of its text is kept); without, the table goes to stdout.

Each crossplant log (``../shared/crossplant/data``, the vehicle file its manifest names, as
given) is estimated by the default pipeline on its measured channels with:

* "all": every channel;
* "gnss": no ``omega_*``, and the issue's ``gnss_speed``: |(ref_vx, ref_vy)| + N(0, 0.05 m/s)
  at 10 Hz (seed 0), NaN between fixes;
* "CAN": no ``omega_*``, and a dense ``vehicle_speed``: the true speed quantised to 0.1 km/h;
* "−ax": no ``ax`` (a_x from the free-rolling wheel speed);
* "−rates": no ``roll_rate``, ``pitch_rate`` (quasi-static attitude);
* "gnss −ax": "gnss" without ``ax`` as well (a_x from the fixes).

Cells: sideslip β = atan2(v_y, v_x) RMS error in degrees over the samples with a true speed
≥ 3 m/s, and the CG v_x RMSE in m/s. "turning" marks the logs with max |a_y| > 1 m/s², those
the issue's β ≤ 0.3° (gnss) applies to.
"""

from __future__ import annotations

import argparse
import json
import sys
from collections.abc import Callable
from pathlib import Path

import numpy as np
import pandas as pd

from vestim.io import load_vehicle, read_log
from vestim.io.channels import WHEEL_SPEEDS
from vestim.pipeline import Pipeline

ROOT = Path(__file__).resolve().parents[1]
DATA = ROOT / ".." / "shared" / "crossplant" / "data"
BEGIN, END = "<!-- table -->", "<!-- /table -->"


def measured(log: pd.DataFrame, drop: tuple[str, ...] = ()) -> pd.DataFrame:
    return log.drop(columns=[c for c in log.columns if c.startswith("ref_") or c in drop])


def true_speed(log: pd.DataFrame) -> np.ndarray:
    return np.asarray(np.hypot(log["ref_vx"], log["ref_vy"]))


def gnss_only(log: pd.DataFrame, seed: int = 0) -> pd.DataFrame:
    """No wheel speeds; gnss_speed = true speed + N(0, 0.05 m/s) at 10 Hz, NaN between."""
    rng = np.random.default_rng(seed)
    t = log["t"].to_numpy()
    rows = np.unique(np.searchsorted(t, np.arange(t[0], t[-1] + 1e-9, 0.1)).clip(0, len(t) - 1))
    gnss = np.full(len(t), np.nan)
    gnss[rows] = np.maximum(true_speed(log)[rows] + rng.normal(0.0, 0.05, rows.size), 0.0)
    out = measured(log, WHEEL_SPEEDS)
    out["gnss_speed"] = gnss
    return out


def can_only(log: pd.DataFrame) -> pd.DataFrame:
    """No wheel speeds; vehicle_speed = the true speed at 0.1 km/h resolution."""
    out = measured(log, WHEEL_SPEEDS)
    out["vehicle_speed"] = np.round(true_speed(log) * 36.0) / 36.0
    return out


VARIANTS: dict[str, Callable[[pd.DataFrame], pd.DataFrame]] = {
    "all": measured,
    "gnss": gnss_only,
    "CAN": can_only,
    "−ax": lambda log: measured(log, ("ax",)),
    "−rates": lambda log: measured(log, ("roll_rate", "pitch_rate")),
    "gnss −ax": lambda log: gnss_only(log).drop(columns=["ax"]),
}


def beta_rms_deg(est: pd.DataFrame, log: pd.DataFrame) -> float:
    moving = true_speed(log) >= 3.0
    err = np.arctan2(est["vy"], est["vx"]) - np.arctan2(log["ref_vy"], log["ref_vx"])
    return float(np.degrees(np.sqrt(np.mean(np.asarray(err)[moving] ** 2))))


def rmse(a: pd.Series, b: pd.Series) -> float:
    return float(np.sqrt(np.mean((np.asarray(a) - np.asarray(b)) ** 2)))


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--out", type=Path, default=None)
    args = ap.parse_args()
    manifest = json.loads((DATA / "manifest.json").read_text())["maneuvers"]
    header = ["log", "turning", *[f"β {k} °" for k in VARIANTS], *[f"v_x {k} m/s" for k in VARIANTS]]
    lines = ["| " + " | ".join(header) + " |", "|" + "---|" * len(header)]
    for name, m in manifest.items():
        log = read_log(DATA / m["file"], require=["measured"])
        veh = load_vehicle(DATA / m["vehicle_file"])
        outs = {k: Pipeline(veh).run(make(log)) for k, make in VARIANTS.items()}
        turning = "yes" if float(np.abs(log["ay"]).max()) > 1.0 else "no"
        cells = [f"{beta_rms_deg(o, log):.3f}" for o in outs.values()]
        cells += [f"{rmse(o['vx'], log['ref_vx']):.3f}" for o in outs.values()]
        lines.append("| " + " | ".join([name, turning, *cells]) + " |")
        print(lines[-1], flush=True)
    text = "\n".join(lines) + "\n"
    if args.out:
        old = args.out.read_text(encoding="utf-8") if args.out.exists() else ""
        if BEGIN in old and END in old:
            head, rest = old.split(BEGIN, 1)
            text = f"{head}{BEGIN}\n{text}{END}{rest.split(END, 1)[1]}"
        import _docs

        _docs.write_page(args.out, text)
    else:
        sys.stdout.write(text)


if __name__ == "__main__":
    main()
