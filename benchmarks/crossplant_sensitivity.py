"""Sensitivity of the default estimate to the parameters the vehicle file does not give.

Each parameter the default pipeline takes from a vestim default (not from the crossplant
vehicle files) is set to 0.7× and 1.3× its value, one at a time, and the default runs on
every crossplant log (``../shared/crossplant``, no ``ref_`` columns). The table gives, per
parameter and channel, the mean over the 12 logs of the change of the figure that
``targets.py`` scores (vx %, vy RMSE m/s, worst slip-angle RMSE °, Fz pooled %, Fx %,
Fy %, max |μ|), and the change of the real RAV4 log's v_x RMSE (m/s, without its
``gnss_speed``). Writes the Markdown table between markers in docs/results.md.

    .venv/bin/python benchmarks/crossplant_sensitivity.py [--only x05 x06] [--no-write]
"""

from __future__ import annotations

import argparse
import json
import sys
import tempfile
import tomllib
from collections.abc import Callable
from dataclasses import replace
from pathlib import Path

import numpy as np
import pandas as pd

from _docs import write_section
from vestim.estimators.velocity.reference import ReferenceParams
from vestim.io import load_vehicle
from vestim.io.vehicle import Vehicle
from vestim.pipeline import Pipeline, PipelineConfig

ROOT = Path(__file__).resolve().parents[1]
XP = ROOT.parent / "shared" / "crossplant"
RAV4 = ROOT.parent / "shared" / "real" / "comma2k19_rav4"
Setup = tuple[Vehicle, PipelineConfig]
Perturb = Callable[[Vehicle, PipelineConfig, float], Setup]
CHANNELS = ("vx", "vy", "sa", "fz", "fx", "fy", "mu")


def _suspension(key: str) -> Perturb:
    def apply(v: Vehicle, c: PipelineConfig, f: float) -> Setup:
        s = v.suspension
        value = getattr(s, key) * f
        if key == "roll_stiffness_front_share":
            value = min(value, 0.95)
        return replace(v, suspension=replace(s, **{key: value})), c
    return apply


def _tire(keys: tuple[str, ...]) -> Perturb:
    def apply(v: Vehicle, c: PipelineConfig, f: float) -> Setup:
        return replace(v, tire=replace(v.tire, **{k: getattr(v.tire, k) * f for k in keys})), c
    return apply


def _reference(key: str) -> Perturb:
    def apply(v: Vehicle, c: PipelineConfig, f: float) -> Setup:
        ref: ReferenceParams = c.reference
        return v, replace(c, reference=replace(ref, **{key: getattr(ref, key) * f}))
    return apply


PARAMETERS: dict[str, tuple[str, Perturb]] = {
    "roll_inertia": ("[suspension] default 0.2 I_z: the I_x ṗ term of the lateral load "
                     "transfer", _suspension("roll_inertia")),
    "pitch_inertia": ("[suspension] default 0.8 I_z: the I_y q̇ term of the longitudinal "
                      "load transfer", _suspension("pitch_inertia")),
    "roll_stiffness_front_share": ("[suspension] default 0.55: front share of the lateral "
                                   "load transfer", _suspension("roll_stiffness_front_share")),
    "cornering stiffness prior": ("[tire] σ0y/κy = 15/rad (nominal): prior of the online "
                                  "cornering stiffness", _tire(("sigma0_y",))),
    "LuGre longitudinal": ("[tire] σ0x, σ1x, σ2x (nominal): the corner KF of the fused "
                           "default", _tire(("sigma0_x", "sigma1_x", "sigma2_x"))),
    "slip prior": ("reference filter slip_bias = 1/C = 0.05 (not in the file): the expected "
                   "wheel slip μ_x/C removed from each wheel speed", _reference("slip_bias")),
}


def figures(vehicle: Vehicle, config: PipelineConfig, name: str, truth: Path,
            table: dict[str, float], tmp: Path) -> dict[str, float]:
    """targets.py's figures of the default on one crossplant log (``table``: the log's
    vehicle file's [vehicle] table, which targets.py reads for its kinematic floor)."""
    sys.path.insert(0, str(XP))
    import targets  # type: ignore[import-not-found]

    log = pd.read_parquet(truth)
    measured = log[[c for c in log.columns if not c.startswith(("ref_", "_"))]]
    path = tmp / f"{name}.parquet"
    Pipeline(vehicle, config).run(measured).to_parquet(path)
    figs, _ = targets.judge(name, truth, path, table)
    return {c: float(figs[c]) for c in CHANNELS}


def rav4_vx(vehicle: Vehicle, config: PipelineConfig) -> float:
    """v_x RMSE (m/s) of the RAV4 log without its ``gnss_speed``."""
    log = pd.read_parquet(RAV4 / "seg40.parquet")
    measured = log[[c for c in log.columns if not c.startswith(("ref_", "_"))]]
    est = Pipeline(vehicle, config).run(measured.drop(columns=["gnss_speed"]))
    return float(np.sqrt(np.mean((est["vx"].to_numpy() - log["ref_vx"].to_numpy()) ** 2)))


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__)
    ap.add_argument("--only", nargs="*", default=[])
    ap.add_argument("--no-write", action="store_true")
    args = ap.parse_args()
    man = json.loads((XP / "data" / "manifest.json").read_text())["maneuvers"]
    names = [m for m in sorted(man) if not args.only or m.startswith(tuple(args.only))]
    lines = ["| parameter (what it sets) | factor | " + " | ".join(
        ("Δ vx %", "Δ vy m/s", "Δ slip angle °", "Δ Fz %", "Δ Fx %", "Δ Fy %", "Δ max|μ|",
         "Δ RAV4 vx m/s")) + " |", "|---|---|" + "---|" * (len(CHANNELS) + 1)]
    with tempfile.TemporaryDirectory() as tmpdir:
        tmp = Path(tmpdir)

        def setup(vfile: Path, perturb: Perturb | None, f: float) -> Setup:
            veh, cfg = load_vehicle(str(vfile)), PipelineConfig()
            return (veh, cfg) if perturb is None else perturb(veh, cfg, f)

        def run(perturb: Perturb | None, f: float) -> dict[str, np.ndarray]:
            per_log: dict[str, list[float]] = {c: [] for c in CHANNELS}
            for m in names:
                vfile = XP / "data" / man[m]["vehicle_file"]
                table = tomllib.loads(vfile.read_text())["vehicle"]
                figs = figures(*setup(vfile, perturb, f), m, XP / "data" / man[m]["file"],
                               table, tmp)
                for c in CHANNELS:
                    per_log[c].append(figs[c])
            out = {c: np.array(v) for c, v in per_log.items()}
            out["rav4"] = np.array([rav4_vx(*setup(RAV4 / "vehicle.toml", perturb, f))])
            return out

        base = run(None, 1.0)
        cols = (*CHANNELS, "rav4")
        lines.append("| (vehicle files as given) | 1 | " + " | ".join(
            f"{base[c].mean():.3f}" for c in cols) + " |")
        for pname, (what, perturb) in PARAMETERS.items():
            for f in (0.7, 1.3):
                res = run(perturb, f)
                lines.append(f"| {pname} ({what}) | {f:g} | " + " | ".join(
                    f"{(res[c] - base[c]).mean():+.3f}" for c in cols) + " |")
                print(pname, f, "done", flush=True)
    text = "\n".join(["## Sensitivity to the parameters the vehicle file does not give", "",
                      f"Made by `benchmarks/crossplant_sensitivity.py` on {len(names)} crossplant "
                      "logs: the first row is the mean figure over the logs, the others the "
                      "mean change with one parameter at 0.7× or 1.3×.", "", *lines])
    print(text)
    if args.no_write:
        return
    write_section("sensitivity", text, after="<!-- crossplant:end -->")


if __name__ == "__main__":
    main()
