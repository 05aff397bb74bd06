"""Velocity accuracy on independent data, in-process: the real logs, the crossplant x01-x12 and
the crossplant campaign, scored with ``../shared``'s own definitions (``targets.py``,
``campaign_score.judge``).

usage: python benchmarks/lateral_study.py [--tag NAME] [--only revs x06 s1_0 ...] [--jobs 2]
                                         [--set reference.k_rel=0.3 ...]

Prints one line per log (v_x, v_y, β, slip angle, with * for a miss and ! for worse than the
naive floor) and a summary per data set. The estimates go to /tmp/vestim-study/<tag>/ so that
two versions can be compared channel by channel. Not part of the test run.
"""
from __future__ import annotations

import argparse
import json
import sys
import tomllib
import warnings
from concurrent.futures import ProcessPoolExecutor
from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd

SHARED = Path(__file__).resolve().parents[2] / "shared"
CROSS = SHARED / "crossplant"
REAL = SHARED / "real"
sys.path.insert(0, str(CROSS))
LAT = ("vx", "vy", "beta", "alpha")
LIMITED = ("x01", "x02", "x03", "x04", "x07")


def _cases() -> list[tuple[str, str, Path, Path, tuple[str, ...]]]:
    """(set, id, log, vehicle file, dropped columns)."""
    out = [("real", "rav4", REAL / "comma2k19_rav4/seg40.parquet",
            REAL / "comma2k19_rav4/vehicle.toml", ("gnss_speed",)),
           ("real", "rav4_gnss", REAL / "comma2k19_rav4/seg40.parquet",
            REAL / "comma2k19_rav4/vehicle.toml", ()),
           ("real", "revs", REAL / "revs_250lm/20140222_01_01_03.parquet",
            REAL / "revs_250lm/vehicle.toml", ())]
    for name, data in (("cross", CROSS / "data"), ("campaign", CROSS / "data_campaign")):
        man = json.loads((data / "manifest.json").read_text())["maneuvers"]
        for sid in sorted(man):
            out.append((name, sid, data / man[sid]["file"], data / man[sid]["vehicle_file"], ()))
    return out


def _real_score(truth: pd.DataFrame, est: pd.DataFrame) -> dict[str, dict[str, float | None]]:
    d = truth[truth.t >= 0.5]
    vx = np.interp(d.t, est.t, est.vx)
    vy = np.interp(d.t, est.t, est.vy)
    m = d.ref_vx.to_numpy() > 3
    bt = np.degrees(np.arctan2(d.ref_vy, d.ref_vx))[m]
    b = np.degrees(np.arctan2(vy, np.maximum(vx, 0.1)))[m]

    def rmse(a: np.ndarray) -> float:
        return float(np.sqrt(np.mean(np.square(a))))

    return {"vx": {"value": rmse(vx - d.ref_vx), "floor": None},
            "vy": {"value": rmse(vy - d.ref_vy), "floor": rmse(d.ref_vy)},
            "beta": {"value": rmse(b - bt), "floor": rmse(bt)},
            "alpha": {"value": None, "floor": None}}


def _config(sets: list[str]) -> object:
    """A PipelineConfig with ``table.field=value`` overrides (a study's variants; nested
    tables as ``force.load_filter.kind=-1``)."""
    from dataclasses import replace

    from vestim.pipeline import PipelineConfig

    def put(obj: Any, path: list[str], value: str) -> Any:
        old = getattr(obj, path[0])
        new = type(old)(value) if len(path) == 1 else put(old, path[1:], value)
        return replace(obj, **{path[0]: new})

    cfg = PipelineConfig()
    for item in sets:
        key, value = item.split("=")
        cfg = put(cfg, key.split("."), value)
    return cfg


def _one(args: tuple[str, list[str], str, str, Path, Path, tuple[str, ...]]
         ) -> tuple[str, str, dict]:
    tag, sets, kind, sid, log, vfile, drop = args
    warnings.filterwarnings("ignore")
    import campaign_score as cs

    from vestim.io import load_vehicle
    from vestim.pipeline import Pipeline

    truth = pd.read_parquet(log)
    cols = [c for c in truth.columns if not c.startswith(("ref_", "_")) and c not in drop]
    out = Path("/tmp/vestim-study") / tag / f"{sid}.parquet"
    out.parent.mkdir(parents=True, exist_ok=True)
    try:
        est = Pipeline(load_vehicle(vfile), _config(sets)).run(truth[cols].copy())
    except Exception as exc:
        return kind, sid, {"error": f"{type(exc).__name__}: {exc}"}
    est.to_parquet(out)
    if kind == "real":
        return kind, sid, _real_score(truth, est)
    veh = tomllib.loads(vfile.read_text())["vehicle"]
    res = cs.judge(log, out, veh, sid[:3] in LIMITED, None)
    return kind, sid, {ch: res[ch] for ch in (*LAT, "fz", "fy")}


def _cell(r: dict) -> str:
    v = r.get("value")
    if v is None:
        return "   -   "
    mark = ("*" if r.get("limit") is not None and v > r["limit"] else " ") + (
        "!" if r.get("floor") is not None and v > r["floor"] else " ")
    return f"{v:6.3f}{mark}"


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser()
    ap.add_argument("--tag", default="now")
    ap.add_argument("--only", nargs="*")
    ap.add_argument("--jobs", type=int, default=2)
    ap.add_argument("--set", nargs="*", default=[])
    a = ap.parse_args(argv)
    cases = [(a.tag, a.set, *c) for c in _cases()
             if not a.only or c[1].startswith(tuple(a.only)) or c[0] in a.only]
    with ProcessPoolExecutor(a.jobs) as pool:
        results = list(pool.map(_one, cases))
    scores = Path("/tmp/vestim-study") / a.tag / "scores.json"
    scores.write_text(json.dumps({sid: res for _, sid, res in results}, indent=1, default=str))
    summary: dict[str, dict[str, list[float]]] = {}
    print(f"{'log':34s}" + "".join(f"{c:>10s}" for c in (*LAT, "fz", "fy")))
    for kind, sid, res in results:
        if "error" in res:
            print(f"{sid:34s} {res['error'][:90]}")
            continue
        print(f"{sid:34s}" + "".join(f"{_cell(res[c]):>10s}" for c in (*LAT, "fz", "fy")
                                     if c in res) )
        s = summary.setdefault(kind, {})
        for c, r in res.items():
            if r.get("value") is None:
                continue
            s.setdefault(c, []).append(r["value"])
            s.setdefault(c + "_miss", []).append(
                float(r.get("limit") is not None and r["value"] > r["limit"]))
            s.setdefault(c + "_worse", []).append(
                float(r.get("floor") is not None and r["value"] > r["floor"]))
    for kind, s in summary.items():
        print(f"== {kind}")
        for c in (*LAT, "fz", "fy"):
            if c not in s:
                continue
            v = np.array(s[c])
            print(f"   {c:6s} median {np.median(v):8.3f}  p90 {np.quantile(v, 0.9):8.3f}  "
                  f"worst {v.max():8.3f}  miss {int(sum(s[c + '_miss']))}/{v.size}  "
                  f"worse than floor {int(sum(s[c + '_worse']))}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
