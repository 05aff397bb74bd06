"""LPV observer design speed: `design_lpv` for a vehicle file (issue 5 target: < 30 s on one core).

Run:  .venv/bin/python benchmarks/bench_design.py

Pins the process to one CPU (where the OS allows) and one BLAS thread, then
times the whole `design_lpv()` call — load the vehicle file, synthesise and
verify the longitudinal and lateral schedules — for the built-in vehicles and
for a new vehicle file written on the fly with different tire data. The first
call of the process also pays for importing cvxpy and compiling its problem
machinery; it is reported separately ("cold").
"""

from __future__ import annotations

import os

for _var in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS", "NUMBA_NUM_THREADS"):
    os.environ.setdefault(_var, "1")
if hasattr(os, "sched_setaffinity"):
    os.sched_setaffinity(0, {min(os.sched_getaffinity(0))})

import tempfile  # noqa: E402
import time  # noqa: E402
from importlib import resources  # noqa: E402
from pathlib import Path  # noqa: E402

TARGET_S = 30.0

NEW_TIRE = {"sigma0_x": "520.0", "sigma1_x": "0.9", "kappa_x": "9.5", "sigma0_y": "150.0",
            "sigma1_y": "0.6", "kappa_y": "11.0"}


def _new_vehicle_file(folder: Path) -> Path:
    """The compact car with different LuGre data, as a fresh TOML file."""
    text = (resources.files("vestim") / "data" / "vehicles" / "compact_car.toml").read_text()
    lines = []
    for line in text.splitlines():
        key = line.split("=")[0].strip()
        lines.append(f"{key} = {NEW_TIRE[key]}" if key in NEW_TIRE else line)
    path = folder / "new_car.toml"
    path.write_text("\n".join(lines) + "\n")
    return path


def main() -> None:
    t0 = time.perf_counter()
    from vestim.design import design_lpv

    t_import = time.perf_counter() - t0
    print(f"import vestim.design: {t_import:.2f} s; CPUs: {sorted(os.sched_getaffinity(0))}"
          if hasattr(os, "sched_getaffinity") else f"import vestim.design: {t_import:.2f} s")
    with tempfile.TemporaryDirectory() as tmp:
        cases = [("hashemi_suv (cold)", "hashemi_suv"), ("hashemi_suv", "hashemi_suv"),
                 ("compact_car", "compact_car"), ("new vehicle file", str(_new_vehicle_file(
                     Path(tmp))))]
        print(f"{'vehicle':22s} {'wall s':>7s} {'gamma x':>8s} {'gamma y':>8s} {'verified':>9s}")
        worst = 0.0
        for label, veh in cases:
            t1 = time.perf_counter()
            sched = design_lpv(veh)
            dt = time.perf_counter() - t1
            worst = max(worst, dt)
            cx = sched.directions["longitudinal"].certificate
            cy = sched.directions["lateral"].certificate
            ok = all(c is not None and c.verified and c.schedule_verified for c in (cx, cy))
            print(f"{label:22s} {dt:7.2f} {cx.gamma if cx else float('nan'):8.4f} "
                  f"{cy.gamma if cy else float('nan'):8.4f} {ok!s:>9s}")
    verdict = "PASS" if worst < TARGET_S else "FAIL"
    print(f"slowest design {worst:.2f} s (target < {TARGET_S:.0f} s on one core): {verdict}")


if __name__ == "__main__":
    main()
