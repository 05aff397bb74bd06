"""Make the ROS 2 bag example from a drive log (e.g. one `vestim simulate` wrote).

Writes two ROS 2 bags of the same drive, ``<stem>_bag_db3/`` (sqlite3 storage) and
``<stem>_bag_mcap/`` (MCAP storage; ``<stem>``: the log's file name without its suffix), each a
folder with ``metadata.yaml`` as ``ros2 bag record`` makes it. Topics, SI units, REP-103 axes
(x forward, y left, z up = ISO 8855):

- ``/imu``           sensor_msgs/msg/Imu: linear_acceleration, angular_velocity, header.stamp
- ``/wheel_speeds``  std_msgs/msg/Float64MultiArray: data = [fl, fr, rl, rr] rad/s (no header)
- ``/wheel_torques`` vestim_msgs/msg/WheelTorques: header, fl, fr, rl, rr N·m
- ``/steering``      vestim_msgs/msg/Steering: header, steering_wheel_angle rad
- ``/road_wheel_angles`` vestim_msgs/msg/RoadWheelAngles: header, fl, fr rad

The ``vestim_msgs`` types are stored in the bag with their definitions, as rosbag2 does
for any type. ``map.toml`` (next to this script) reads either bag back into a vestim drive log.

Usage::

    vestim simulate step_steer --out drive.parquet
    python examples/ros2_bag/make_example.py --log drive.parquet [--seconds S] [--out DIR]
        [--latency S]

``--out`` defaults to the current folder; earlier bags of the same name there are replaced.
"""

from __future__ import annotations

import argparse
import shutil
from pathlib import Path

import pandas as pd

from vestim.io.writers import write_ros2_bag


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
    parser.add_argument("--latency", type=float, default=0.0,
                        help="s from each sample to its recording (the bag's receive time)")
    args = parser.parse_args()
    log = pd.read_parquet(args.log) if args.log.suffix != ".csv" else pd.read_csv(args.log)
    log = measured(log, args.seconds)
    for storage, suffix in (("sqlite3", "db3"), ("mcap", "mcap")):
        bag = args.out / f"{args.log.stem}_bag_{suffix}"
        if bag.exists() and (bag / "metadata.yaml").is_file():
            shutil.rmtree(bag)  # an earlier run's bag (never a folder that is not a bag)
        write_ros2_bag(log, bag, storage=storage, receive_latency=args.latency)
        size = sum(p.stat().st_size for p in bag.iterdir()) / 1024
        print(f"wrote {bag}/ ({storage}, {len(log)} samples, {size:.0f} KiB)")


if __name__ == "__main__":
    main()
