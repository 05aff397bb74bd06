"""Make the OBD-style CSV example from a crossplant log.

Writes ``obd.csv``: what a CAN/OBD logger exports, with its own column names and units —
time in ms, wheel speeds in km/h (wheel circumferential speed R·ω), steering-wheel angle in
degrees, yaw rate in deg/s, lateral acceleration in g — and no longitudinal acceleration.
``map.toml`` (next to this script) reads it back into a vestim drive log.

Usage::

    python examples/obd_csv/make_example.py --log X.parquet [--radius R] [--out DIR]

The committed ``obd.csv`` was made from the crossplant data set's log
``x05_sine_steer_dry_rwd.parquet`` (sine steer on dry asphalt, its ``vehicle2.toml``, committed
here as ``vehicle.toml``, R = 0.344 m), every second sample (100 Hz). Any drive log works,
e.g. ``vestim simulate step_steer --out drive.parquet`` and ``--radius 0.33`` (hashemi_suv)
with the map's radius changed to match.
"""

from __future__ import annotations

import argparse
from pathlib import Path

import numpy as np
import pandas as pd

DEFAULT_RADIUS = 0.344
"""m; vehicle2.toml's wheel_radius, the radius the map's wheel-speed expression divides by."""
STANDARD_GRAVITY = 9.80665
"""m/s²; the "g" of a logger's acceleration columns (and of the map's unit = "g")."""
SI_COLUMNS = ("t", "omega_fl", "omega_fr", "omega_rl", "omega_rr", "steering_wheel_angle",
              "yaw_rate", "ay")
"""The spec channels the OBD file carries (plus ``ax`` with ``with_ax``)."""
WHEEL_COLUMNS = {"omega_fl": "WheelSpeed_FL_kph", "omega_fr": "WheelSpeed_FR_kph",
                 "omega_rl": "WheelSpeed_RL_kph", "omega_rr": "WheelSpeed_RR_kph"}


def si_copy(log: pd.DataFrame, *, step: int = 2, with_ax: bool = False) -> pd.DataFrame:
    """The SI channels the OBD file holds, every ``step``-th row of ``log``."""
    cols = [*SI_COLUMNS, *(["ax"] if with_ax else [])]
    return log.loc[::step, cols].reset_index(drop=True)


def make_obd_frame(si: pd.DataFrame, *, wheel_radius: float = DEFAULT_RADIUS) -> pd.DataFrame:
    """The OBD-style table of an SI copy (see :func:`si_copy`): ms, km/h, deg, deg/s, g."""
    out = {"time_ms": si["t"].to_numpy() * 1e3}
    for col, name in WHEEL_COLUMNS.items():
        out[name] = si[col].to_numpy() * wheel_radius * 3.6
    out["SteeringWheelAngle_deg"] = np.degrees(si["steering_wheel_angle"].to_numpy())
    out["YawRate_dps"] = np.degrees(si["yaw_rate"].to_numpy())
    out["LatAccel_g"] = si["ay"].to_numpy() / STANDARD_GRAVITY
    if "ax" in si.columns:
        out["LongAccel_g"] = si["ax"].to_numpy() / STANDARD_GRAVITY
    return pd.DataFrame(out)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--log", type=Path, required=True, help="spec log (.parquet)")
    parser.add_argument("--radius", type=float, default=DEFAULT_RADIUS, help="m")
    parser.add_argument("--out", type=Path, default=Path("."), help="output folder")
    args = parser.parse_args()
    frame = make_obd_frame(si_copy(pd.read_parquet(args.log)), wheel_radius=args.radius)
    args.out.mkdir(parents=True, exist_ok=True)
    path = args.out / "obd.csv"
    frame.to_csv(path, index=False)  # floats in shortest round-trip form
    print(f"wrote {path} ({len(frame)} rows)")


if __name__ == "__main__":
    main()
