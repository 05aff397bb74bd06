"""Where an hour of ``vestim estimate`` goes (issue 27: ≤ 2 s end to end, warm; output ≤ 100 MB;
peak ≤ 1 GiB), phase by phase in one process, each against a bare compiled 1-state UKF over
four corners (:func:`stage_times.bare_ukf`) on the same hour.

Writes the hour (the simulator's dlc_snow tiled, 65 536-row groups, as
:func:`bench_memory.write_long_log`) to a temporary folder, then times what the CLI does with
it: reading it in pieces (:func:`vestim.io.iter_log`), the input gate on its first
:data:`~vestim.io.sanity.GATE_ROWS` rows (an hour: all of them), the pipeline over the pieces
(:meth:`~vestim.pipeline.Pipeline.run_pieces`) and writing the estimates
(:class:`vestim.io.LogWriter`, float32); best of 3 after a warm-up. The end-to-end figure
with the interpreter's start and imports, and the peak memory, come from
``bench_memory.py --hours 1`` (the CLI in a child process).

Run:  .venv/bin/python benchmarks/bench_estimate.py
"""

from __future__ import annotations

import tempfile
import time
from pathlib import Path

import numpy as np
import pandas as pd

from bench_memory import write_long_log
from bench_pipeline import bare_ns
from vestim.io import LogWriter, iter_log, load_vehicle
from vestim.io.sanity import GATE_ROWS, gate
from vestim.pipeline import Pipeline


def main() -> None:
    veh = load_vehicle("hashemi_suv")
    with tempfile.TemporaryDirectory() as tmp:
        src, out = Path(tmp) / "hour.parquet", Path(tmp) / "hour_est.parquet"
        n = write_long_log(src, 1.0)
        times: dict[str, float] = {}
        pieces: list[pd.DataFrame] = []
        frames: list[pd.DataFrame] = []
        pipe = Pipeline(veh)

        def read() -> None:
            pieces[:] = iter_log(src, require=["measured"], wheel_radius=veh.body.wheel_radius)

        def check() -> None:
            gate(pd.concat(pieces, ignore_index=True).iloc[:GATE_ROWS], veh, source=str(src))

        def estimate() -> None:
            frames[:] = pipe.run_pieces(pieces)

        def write() -> None:
            with LogWriter(out, float32=True) as w:
                for f in frames:
                    w.write(f)

        for rep in range(4):  # the first compiles or loads the kernels
            for name, fn in (("read", read), ("gate", check), ("estimate", estimate),
                             ("write", write)):
                t0 = time.perf_counter()
                fn()
                if rep:
                    times[name] = min(times.get(name, np.inf), time.perf_counter() - t0)
        z = np.ascontiguousarray(pd.concat(pieces)[[f"omega_{c}" for c in ("fl", "fr", "rl",
                                                                         "rr")]])
        bare = bare_ns(z) * z.size / 1e9
        total = sum(times.values())
        print(f"{n} samples; the bare 1-state UKF over four corners: {bare:.3f} s")
        for name, s in times.items():
            print(f"{name:9s} {s:6.2f} s = {s / bare:5.1f}x the bare kernel")
        print(f"{'total':9s} {total:6.2f} s = {total / bare:5.1f}x; output "
              f"{out.stat().st_size / 1e6:.1f} MB")


if __name__ == "__main__":
    main()
