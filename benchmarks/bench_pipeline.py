"""Pipeline speed (issues 4 and 27): one hour of 200 Hz four-corner data, after JIT warm-up,
as ratios to a bare compiled 1-state UKF over four corners measured in the same process
(:func:`stage_times.bare_ukf`).

Run:  .venv/bin/python benchmarks/bench_pipeline.py [--configs]

``--configs`` also times ``step()`` of every registered configuration (the product of the
stages' methods in :mod:`vestim.estimators.registry`), best of 3 × 1000 samples each.

Issue 27's targets: the default pipeline's hour ≤ 20× the bare kernel (≈ 0.5 s); ``step()``
≤ 10 µs for every registered configuration; peak memory ≤ 1 GiB. Also printed: how much of a
``step()`` is the compiled call (:func:`vestim.pipeline.rows.step_sample`: the health stages
and :func:`~vestim.pipeline.rows.pipeline_rows` over one row) and how long a fresh process's
first ``step()`` takes once the kernels are cached (building the compiled stepper).
"""

from __future__ import annotations

import argparse
import itertools
import resource
import subprocess
import sys
import time

import numpy as np
import pandas as pd

from stage_times import bare_ukf
from vestim.estimators import registry
from vestim.filters.ukf import ukf_weights
from vestim.io import load_vehicle
from vestim.pipeline import Pipeline, PipelineConfig
from vestim.sim import get_maneuver, simulate

FIRST_STEP = """
import time
from vestim.estimators import registry
from vestim.io import load_vehicle
from vestim.pipeline import Pipeline, PipelineConfig
from vestim.sim import get_maneuver, simulate
veh = load_vehicle("hashemi_suv")
row = simulate(get_maneuver("dlc_snow"), veh, seed=1).iloc[0].to_dict()
row = {k: v for k, v in row.items() if not k.startswith("ref_")}
pipe = Pipeline(veh)
t0 = time.perf_counter()
pipe.step(row)
print(time.perf_counter() - t0)
"""


def bare_ns(z: np.ndarray) -> float:
    """The bare kernel's best of 5 over ``z`` (n, 4), ns per corner-step."""
    wm, wc, tau = ukf_weights(1)
    out = np.empty_like(z)
    best = float("inf")
    for _ in range(6):  # the first compiles or loads
        t0 = time.perf_counter()
        bare_ukf(z, 0.1, 0.2, wm, wc, tau, np.zeros(4), np.ones(4), out)
        best = min(best, time.perf_counter() - t0)
    return best / z.size * 1e9


def step_us(pipe: Pipeline, rows: list[dict[str, float]], passes: int = 5) -> float:
    """``pipe.step`` over rows 50 … 1049 after 50 to settle, best of ``passes``, µs per sample."""
    best = float("inf")
    for _ in range(passes):
        pipe.reset()
        for r in rows[:50]:
            pipe.step(r)
        t0 = time.perf_counter()
        for r in rows[50:1050]:
            pipe.step(r)
        best = min(best, (time.perf_counter() - t0) / 1000)
    return best * 1e6


def every_configuration(veh: object, rows: list[dict[str, float]]) -> None:
    """``step()`` of every registered configuration (force × normal × velocity × fusion),
    best of 3 × 1000 samples each: the distribution and the slowest five."""
    stages = {"force": "force", "normal": "normal", "velocity": "velocity", "fusion": "fusion"}
    choices = [registry.names(stage) for stage in stages]
    times = []
    for combo in itertools.product(*choices):
        cfg = PipelineConfig(**dict(zip(stages, combo, strict=True)))
        times.append((step_us(Pipeline(veh, cfg), rows, passes=3), "-".join(combo)))
    times.sort()
    us = np.array([t for t, _ in times])
    print(f"step(), {len(times)} registered configurations: median {np.median(us):.1f} us, "
          f"90th percentile {np.percentile(us, 90):.1f}, fastest {us[0]:.1f} ({times[0][1]}), "
          f"slowest {us[-1]:.1f} ({times[-1][1]}); ≤ 10 us: {int(np.sum(us <= 10))}")
    for t, name in times[-5:]:
        print(f"  {name}: {t:.1f} us")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--configs", action="store_true",
                        help="also time step() of every registered configuration")
    args = parser.parse_args()
    veh = load_vehicle("hashemi_suv")
    log = simulate(get_maneuver("dlc_snow"), veh, seed=1)
    log = log.drop(columns=[c for c in log.columns if c.startswith("ref_")])
    pipe = Pipeline(veh)
    pipe.run(log)
    for n in (72_000, 240_000, 720_000):
        reps = n // len(log) + 1
        big = pd.concat([log] * reps, ignore_index=True).iloc[:n].copy()
        big["t"] = np.arange(n) * 0.005
        z = np.ascontiguousarray(big[[f"omega_{c}" for c in ("fl", "fr", "rl", "rr")]])
        bare = bare_ns(z)
        best = float("inf")
        for _ in range(3):
            t0 = time.perf_counter()
            pipe.run(big)
            best = min(best, time.perf_counter() - t0)
        ns = best / (4 * n) * 1e9
        print(f"{n:8d} samples: {best:6.3f} s ({n * 0.005 / best:5.0f}x real time), {ns:5.0f} ns "
              f"per corner-step = {ns / bare:4.1f}x the bare 1-state UKF ({bare:.0f} ns)")
    peak = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024**2
    print(f"peak resident memory of this process: {peak:.2f} GiB")
    rows = [{str(k): float(v) for k, v in r.items()} for r in log.to_dict("records")]
    fn = None
    spent = [0.0]

    def timed(*args: object) -> None:  # the compiled call, timed
        t0 = time.perf_counter()
        assert fn is not None
        fn(*args)
        spent[0] += time.perf_counter() - t0

    best = best_call = float("inf")
    for _ in range(5):  # best of 5 passes of 1000 samples (the VM's timer noise is large)
        pipe.reset()
        for r in rows[:50]:
            pipe.step(r)
        fn = fn or pipe._step_fn
        t0 = time.perf_counter()
        for r in rows[50:1050]:
            pipe.step(r)
        best = min(best, (time.perf_counter() - t0) / 1000)
        pipe.reset()
        for r in rows[:50]:
            pipe.step(r)
        pipe._step_fn, spent[0] = timed, 0.0
        for r in rows[50:1050]:
            pipe.step(r)
        pipe._step_fn = fn
        best_call = min(best_call, spent[0] / 1000)
    bare = bare_ns(np.ascontiguousarray(log[[f"omega_{c}" for c in ("fl", "fr", "rl", "rr")]]))
    print(f"step(): {best * 1e6:.1f} us per sample (four corners, best of 5 x 1000) = "
          f"{best * 1e9 / (4 * bare):.0f}x the bare UKF's four corner-steps; the compiled call "
          f"{best_call * 1e6:.1f} us of it")
    first = subprocess.run([sys.executable, "-c", FIRST_STEP], capture_output=True, text=True,
                           check=True)
    print(f"a fresh process's first step() (kernels cached): {float(first.stdout):.2f} s")
    if args.configs:
        every_configuration(veh, rows)


if __name__ == "__main__":
    main()
