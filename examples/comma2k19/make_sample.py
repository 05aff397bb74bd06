"""Cut the committed comma2k19 sample (``sample/``) from a raw comma2k19 segment.

comma2k19 (https://github.com/commaai/comma2k19, MIT, comma.ai) is 33 h of commute driving
recorded by comma's EON dongle. A segment is a folder of numpy arrays without extension:
``processed_log/<bus>/<stream>/t`` and ``/value``, and ``global_pose/frame_*``. This script
keeps the streams ``map.toml`` reads, cut to the first ``--seconds`` s of the segment on its
own clock, values unchanged (real data: nothing in the sample is synthetic), and writes them
with the upstream layout plus the upstream licence.

Usage::

    git clone https://github.com/commaai/comma2k19   # the Example_1 chunk has the segment
    python examples/comma2k19/make_sample.py \\
        --raw "comma2k19/Example_1/b0c9d2329ad1606b|2018-08-02--08-34-47/40" --seconds 15

The committed ``sample/`` was made so from segment 40 of that route (Toyota RAV4, upstream
commit 4c7f1a6e1957745beadc1def0e7225f559b09a2a), with ``--seconds 15``.
"""

from __future__ import annotations

import argparse
import shutil
from pathlib import Path

import numpy as np

STREAMS = ("processed_log/CAN/wheel_speed", "processed_log/CAN/steering_angle",
           "processed_log/IMU/accelerometer", "processed_log/IMU/gyro",
           "processed_log/GNSS/live_gnss_ublox")
"""The ``<name>/t`` + ``<name>/value`` streams map.toml reads."""
POSE = ("global_pose/frame_velocities", "global_pose/frame_orientations")
POSE_TIMES = "global_pose/frame_times"


def _load(path: Path) -> np.ndarray:
    return np.asarray(np.load(path, allow_pickle=False))


def _save(path: Path, array: np.ndarray) -> None:
    """An ``.npy`` array under the exact name (no suffix added), as upstream stores them."""
    path.parent.mkdir(parents=True, exist_ok=True)
    with open(path, "wb") as f:
        np.save(f, array, allow_pickle=False)


def cut(raw: Path, out: Path, seconds: float) -> dict[str, int]:
    """Write the streams of :data:`STREAMS` and the pose within ``seconds`` s of the
    segment's first sample into ``out``; returns the samples kept per stream."""
    first = min(float(_load(raw / s / "t")[0]) for s in STREAMS)
    end = first + seconds
    kept: dict[str, int] = {}
    for stream in STREAMS:
        t = _load(raw / stream / "t")
        keep = t <= end
        _save(out / stream / "t", t[keep])
        _save(out / stream / "value", _load(raw / stream / "value")[keep])
        kept[stream] = int(keep.sum())
    t = _load(raw / POSE_TIMES)
    keep = t <= end + 0.1  # one pose frame past the end, so the pose covers every row
    _save(out / POSE_TIMES, t[keep])
    for name in POSE:
        _save(out / name, _load(raw / name)[keep])
    kept["global_pose"] = int(keep.sum())
    licence = raw / "LICENSE"
    if licence.is_file():
        shutil.copyfile(licence, out / "LICENSE")
    return kept


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--raw", type=Path, required=True, help="a raw comma2k19 segment folder")
    parser.add_argument("--seconds", type=float, default=15.0, help="s to keep from the start")
    parser.add_argument("--out", type=Path, default=Path(__file__).parent / "sample")
    args = parser.parse_args()
    kept = cut(args.raw, args.out, args.seconds)
    print(f"wrote {args.out}: " + ", ".join(f"{k} {n}" for k, n in kept.items()))


if __name__ == "__main__":
    main()
