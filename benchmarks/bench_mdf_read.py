"""MDF4 + CAN read speed (issue 14): one hour of raw CAN frames decoded with a DBC.

Run:  .venv/bin/python benchmarks/bench_mdf_read.py [--rate 100] [--hours 1] [--out DIR]

Builds a synthetic spec log at ``--rate`` Hz (wheel speeds, wheel torques, steering and
road-wheel angles, IMU accelerations and rates; gnss_speed at 10 Hz), writes it with
:func:`vestim.io.writers.write_mdf_can` as one CAN bus-logging group (six messages per
row plus the GNSS message at 10 Hz: 2.2 M frames for 1 h at 100 Hz) and times
:func:`vestim.io.readers.mdf.read_streams` for all 18 signals, best of 3 after one
warm-up. Target: ≤ 5 s for a 1 h log at 100–1000 Hz.

It also times asammdf's own decoding of the same file, ``MDF.extract_bus_logging`` with the
DBC (canmatrix) and the 18 signals taken out of its result, and checks that both give the
same samples bit for bit: vestim keeps its NumPy decoder only while it is the faster one
(issue 28). Measured (1 h at 100 Hz, 2.2 M frames, one core): see docs/channel-map.md.
"""

from __future__ import annotations

import argparse
import tempfile
import time
from pathlib import Path

import numpy as np
import pandas as pd

from _timing import best_of
from vestim.io.readers.mdf import read_streams
from vestim.io.writers import CAN_SIGNALS, write_mdf_can


def synthetic_log(rate: float, hours: float) -> pd.DataFrame:
    """A spec log of smooth signals within the DBC ranges, ``rate`` Hz for ``hours`` h."""
    n = round(hours * 3600 * rate)
    t = np.arange(n) / rate
    rng = np.random.default_rng(1)
    slow = np.sin(2 * np.pi * t / 60.0)
    cols: dict[str, np.ndarray] = {"t": t}
    for k, c in enumerate(("fl", "fr", "rl", "rr")):
        cols[f"omega_{c}"] = 40.0 + 20.0 * slow + 0.1 * k + 0.01 * rng.standard_normal(n)
        cols[f"torque_{c}"] = 300.0 * np.sin(2 * np.pi * t / 17.0 + k)
    cols["steering_wheel_angle"] = 1.5 * np.sin(2 * np.pi * t / 7.0)
    cols["delta_fl"] = cols["delta_fr"] = cols["steering_wheel_angle"] / 16.0
    cols["ax"] = 2.0 * np.sin(2 * np.pi * t / 11.0)
    cols["ay"] = 4.0 * np.sin(2 * np.pi * t / 7.0)
    cols["az"] = 9.81 + 0.2 * rng.standard_normal(n)
    cols["yaw_rate"] = 0.3 * np.sin(2 * np.pi * t / 7.0)
    cols["roll_rate"] = 0.05 * np.sin(2 * np.pi * t / 3.0)
    cols["pitch_rate"] = 0.02 * np.sin(2 * np.pi * t / 5.0)
    gnss = np.full(n, np.nan)
    step = max(1, round(rate / 10.0))
    gnss[::step] = 13.0 + 6.5 * slow[::step]
    cols["gnss_speed"] = gnss
    return pd.DataFrame(cols)


def read_with_asammdf(mf4: Path, dbc: Path, addresses: list[str]) -> dict[str, tuple[np.ndarray, np.ndarray]]:
    """``{address: (t, value)}`` decoded by asammdf's ``extract_bus_logging`` (bus 1)."""
    import asammdf

    with asammdf.MDF(str(mf4)) as raw:
        decoded = raw.extract_bus_logging({"CAN": [(str(dbc), 0)]})
        try:
            out = {}
            for a in addresses:
                sig = decoded.get(f"CAN1.{a}")
                out[a] = (np.asarray(sig.timestamps), np.asarray(sig.samples, dtype=np.float64))
        finally:
            decoded.close()
    return out


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--rate", type=float, default=100.0, help="CAN message rate, Hz (default 100)")
    ap.add_argument("--hours", type=float, default=1.0, help="log length, h (default 1)")
    ap.add_argument("--out", type=Path, default=None, help="folder for the MDF4 file (default: a temp dir)")
    args = ap.parse_args()
    with tempfile.TemporaryDirectory() as tmp:
        folder = args.out or Path(tmp)
        mf4, dbc = folder / "bench.mf4", folder / "bench.dbc"
        log = synthetic_log(args.rate, args.hours)
        t0 = time.perf_counter()
        write_mdf_can(log, mf4, dbc)
        write_s = time.perf_counter() - t0
        del log
        addresses = [s.address for s in CAN_SIGNALS.values()]
        streams = read_streams(mf4, addresses, dbc=[dbc])  # warm-up (page cache, imports)
        frames = sum(len(streams[a].t) for a in {s.address.split(".")[0]: s.address
                                                   for s in CAN_SIGNALS.values()}.values())
        wall, cpu = best_of(lambda: read_streams(mf4, addresses, dbc=[dbc]), repeats=3)
        lib = read_with_asammdf(mf4, dbc, addresses)
        same = all(np.array_equal(lib[a][0], streams[a].t) and np.array_equal(lib[a][1], streams[a].value)
                   for a in addresses)
        lib_wall, lib_cpu = best_of(lambda: read_with_asammdf(mf4, dbc, addresses), repeats=3)
        size = mf4.stat().st_size / 1024**2
        print(f"{args.hours:g} h at {args.rate:g} Hz: {frames:,} CAN frames, {size:.0f} MiB MDF4 "
              f"(written in {write_s:.1f} s)")
        print(f"read_streams, {len(addresses)} signals: {wall:.2f} s wall, {cpu:.2f} s CPU "
              f"(best of 3; target <= 5 s)")
        print(f"asammdf extract_bus_logging, same signals: {lib_wall:.2f} s wall, {lib_cpu:.2f} s CPU "
              f"(best of 3); vestim's decoder is {lib_wall / wall:.1f}x faster; samples "
              f"{'bit-identical' if same else 'DIFFER'}")


if __name__ == "__main__":
    main()
