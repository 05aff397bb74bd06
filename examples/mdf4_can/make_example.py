"""Make the MDF4 + CAN example from a drive log (e.g. one `vestim simulate` wrote).

Writes ``<stem>_can.mf4`` (``<stem>``: the log's file name without its suffix): what a CAN
logger (Vector, CSS, Kvaser, …) records, the raw CAN frames of the bus as an ASAM MDF4
bus-logging group (``CAN_DataFrame``: ID, DLC, data bytes, timestamp), six frames (one per
message) at every sample; and ``vehicle.dbc``, the bus's database (wheel speeds in rpm, wheel
torques in N·m, steering angles in degrees, IMU accelerations in m/s² and rates in °/s,
scaled 16-bit integers, IMU messages in Motorola byte order). ``map.toml`` (next to this
script) decodes and reads it back into a vestim drive log.

Usage::

    vestim simulate step_steer --out drive.parquet
    python examples/mdf4_can/make_example.py --log drive.parquet [--seconds S] [--out DIR]

``--out`` defaults to the current folder; ``vehicle.dbc`` there equals the committed
``examples/mdf4_can/vehicle.dbc`` (``vestim.io.writers.VEHICLE_DBC``).
"""

from __future__ import annotations

import argparse
from pathlib import Path

import pandas as pd

from vestim.io.writers import write_mdf_can


def measured(log: pd.DataFrame, seconds: float | None = None) -> pd.DataFrame:
    """The log's measured channels (no ``ref_*``), the first ``seconds`` s if given."""
    if seconds is not None:
        log = log.loc[log["t"] - log["t"].iloc[0] <= seconds + 1e-9]
    return log[[c for c in log.columns if not c.startswith("ref_")]].reset_index(drop=True)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--log", type=Path, required=True,
                        help="spec log (.parquet/.csv), e.g. from `vestim simulate`")
    parser.add_argument("--seconds", type=float, default=None, help="keep the first S seconds")
    parser.add_argument("--out", type=Path, default=Path("."), help="output folder")
    args = parser.parse_args()
    log = pd.read_parquet(args.log) if args.log.suffix != ".csv" else pd.read_csv(args.log)
    log = measured(log, args.seconds)
    mf4 = write_mdf_can(log, args.out / f"{args.log.stem}_can.mf4", args.out / "vehicle.dbc")
    print(f"wrote {mf4} ({len(log)} samples, {mf4.stat().st_size / 1024:.0f} KiB) "
          f"and {args.out / 'vehicle.dbc'}")


if __name__ == "__main__":
    main()
