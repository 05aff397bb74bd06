"""Peak memory and wall time of `vestim estimate` on a long log (issue 15: ≤ 2 GiB for 10 h).

Writes a log of ``--hours`` hours at 200 Hz (the simulator's dlc_snow tiled, t continuous) as a
Parquet file of 65 536-row groups, then runs ``vestim estimate`` on it in a child process (the
default vehicle and pipeline; the Parquet log streams through in pieces) and reports the
child's peak resident memory (``ru_maxrss``), its wall time and the output's size. The files go
to a temporary folder, removed after (``--keep DIR`` keeps them there).

Run:  .venv/bin/python benchmarks/bench_memory.py --hours 10
"""

from __future__ import annotations

import argparse
import resource
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np
import pandas as pd

from vestim.io import LogWriter, load_vehicle
from vestim.sim import get_maneuver, simulate

RATE = 200.0
GROUP = 65_536


def write_long_log(path: Path, hours: float) -> int:
    """The tiled log, written group by group (never whole in memory); returns its rows."""
    veh = load_vehicle("hashemi_suv")
    one = simulate(get_maneuver("dlc_snow"), veh, seed=1)
    one = one.drop(columns=[c for c in one.columns if c.startswith("ref_")])
    n = int(hours * 3600 * RATE)
    reps = GROUP // len(one) + 2
    block = pd.concat([one] * reps, ignore_index=True)
    with LogWriter(path) as w:
        for a in range(0, n, GROUP):
            m = min(GROUP, n - a)
            piece = block.iloc[(a % len(one)):(a % len(one)) + m].copy()
            piece["t"] = (a + np.arange(m)) / RATE
            w.write(piece.reset_index(drop=True))
    return n


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__)
    ap.add_argument("--hours", type=float, default=10.0)
    ap.add_argument("--keep", type=Path, default=None)
    args = ap.parse_args()
    with tempfile.TemporaryDirectory() as tmp:
        folder = args.keep or Path(tmp)
        folder.mkdir(parents=True, exist_ok=True)
        src, out = folder / "long.parquet", folder / "long_est.parquet"
        t0 = time.perf_counter()
        n = write_long_log(src, args.hours)
        print(f"input: {n} samples ({args.hours:g} h), {src.stat().st_size / 2**20:.0f} MiB, "
              f"written in {time.perf_counter() - t0:.1f} s")
        t0 = time.perf_counter()
        subprocess.run([sys.executable, "-m", "vestim", "estimate", str(src), "--vehicle", "hashemi_suv",
                        "--out", str(out)],
                       check=True)
        wall = time.perf_counter() - t0
        peak = resource.getrusage(resource.RUSAGE_CHILDREN).ru_maxrss / 2**20  # kB -> GiB
        print(f"vestim estimate: {wall:.1f} s wall, peak resident memory {peak:.2f} GiB, "
              f"output {out.stat().st_size / 2**20:.0f} MiB")


if __name__ == "__main__":
    main()
