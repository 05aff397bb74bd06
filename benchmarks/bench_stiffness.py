"""Cost per time step of Algorithm 1 (002) against the particle count, like 002 Fig. 14.

Run:  .venv/bin/python benchmarks/bench_stiffness.py [--repeats 3] [--filters alg1,augpf]

Times :class:`vestim.estimators.stiffness.NoiseAdaptivePF` (and, for comparison,
the AUGPF) on the 60 s ``stiffness_study`` log at 200 Hz (12 001 steps), after a
warm-up run that compiles / loads the Numba cache. The workload is fixed: the
bias filter on and model-error noise on all three states (0.2 m/s², 0.2 m/s²,
0.1 rad/s², the heaviest configuration: seven normals per particle and step),
so that versions of the kernel compare on the same work. Reports process CPU
time (one thread) and wall time per step, the best of ``--repeats`` runs, and
the cost per particle-step, which is flat if the cost is O(N) (002 Fig. 14).
Issue target: at least 10 000 steps/s with 500 particles on one core. On a
machine shared with other jobs the CPU time still varies by ±10 %.
"""

from __future__ import annotations

import argparse
import os
import platform
import time

os.environ.setdefault("NUMBA_NUM_THREADS", "1")

import numpy as np

from vestim.estimators.stiffness import (
    AugmentedPF,
    NoiseAdaptivePF,
    StiffnessConfig,
    prepare_inputs,
)
from vestim.io import load_vehicle
from vestim.sim import SensorModel, get_maneuver, simulate

COUNTS = (100, 250, 500, 1000, 2000)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--repeats", type=int, default=3)
    ap.add_argument("--filters", default="alg1,augpf", help="comma-separated: alg1, augpf")
    args = ap.parse_args()
    vehicle = load_vehicle("hashemi_suv").with_drivetrain("fwd")
    log = simulate(get_maneuver("stiffness_study"), vehicle, seed=0,
                   sensors=SensorModel(accel_bias=0.0, gyro_bias=0.0))
    log = log[[c for c in log.columns if not c.startswith("ref_")]]
    cfg = StiffnessConfig(model_error=(0.2, 0.2, 0.1))
    inputs = prepare_inputs(log, vehicle, cfg)
    steps = inputs.t.shape[0]
    print(f"{steps} steps of {inputs.u[0, 3] * 1e3:.1f} ms; best of {args.repeats}; "
          f"{platform.processor() or platform.machine()}, {os.cpu_count()} CPUs")
    print(f"{'filter':8s} {'N':>5s} {'CPU us/step':>12s} {'wall us/step':>13s} {'steps/s':>9s} "
          f"{'ns/(particle step)':>19s}")
    filters: dict[str, type[NoiseAdaptivePF] | type[AugmentedPF]] = {"alg1": NoiseAdaptivePF,
                                                                      "augpf": AugmentedPF}
    for name in args.filters.split(","):
        cls = filters[name]
        cls(vehicle, None, cfg, 100).run(inputs, np.random.default_rng(0))  # compile / cache
        for n in COUNTS:
            filt = cls(vehicle, None, cfg, n)
            cpu = wall = float("inf")
            for r in range(args.repeats):
                rng = np.random.default_rng(r)
                w0, c0 = time.perf_counter(), time.process_time()
                filt.run(inputs, rng)
                cpu = min(cpu, time.process_time() - c0)
                wall = min(wall, time.perf_counter() - w0)
            print(f"{name:8s} {n:5d} {1e6 * cpu / steps:12.1f} {1e6 * wall / steps:13.1f} "
                  f"{steps / cpu:9.0f} {1e9 * cpu / steps / n:19.1f}", flush=True)


if __name__ == "__main__":
    main()
