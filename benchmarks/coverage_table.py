"""Is the default's σ honest? Share of samples within 1σ and 2σ of the truth, per channel
family and log, on the crossplant logs and the RAV4 log (``vestim score --coverage``).

A Gaussian error with the stated σ gives 68 % / 95 %; issue 15's band is 60–80 % / 90–98 %.
Writes the ``coverage`` section of docs/results.md (``--write``). About 20 s.
"""

from __future__ import annotations

import argparse
import json
from pathlib import Path

import pandas as pd

from vestim.io import load_vehicle, read_log
from vestim.metrics import coverage
from vestim.pipeline import Pipeline

SHARED = Path(__file__).resolve().parents[1] / ".." / "shared"


def _run(log_path: Path, vehicle: Path, name: str) -> pd.DataFrame:
    log = read_log(log_path)
    est = Pipeline(load_vehicle(vehicle)).run(log[[c for c in log.columns
                                                   if not c.startswith("ref_")]])
    table = coverage(est, log)
    table["log"] = name
    return table


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__)
    ap.add_argument("--write", action="store_true", help="update docs/results.md")
    args = ap.parse_args()
    data = SHARED / "crossplant" / "data"
    manifest = json.loads((data / "manifest.json").read_text())["maneuvers"]
    tables = [_run(data / m["file"], data / m["vehicle_file"], name[:3])
              for name, m in manifest.items()]
    real = SHARED / "real" / "comma2k19_rav4"
    tables.append(_run(real / "seg40.parquet", real / "vehicle.toml", "RAV4"))
    t = pd.concat(tables)
    t["family"] = t["channel"].str.replace(r"_(fl|fr|rl|rr)$", "_*", regex=True)
    g = t.groupby(["log", "family"], sort=False)[["within_1sigma", "within_2sigma"]].mean()
    families = list(dict.fromkeys(t["family"]))
    logs = ["RAV4", *[n for n in dict.fromkeys(t["log"]) if n != "RAV4"]]
    head = "| log | " + " | ".join(f"{f} 1σ / 2σ %" for f in families) + " |"
    lines = ["### σ coverage of the default (issue 15)", "",
             "Share of samples whose error lies within 1σ / 2σ of the truth (Gaussian: 68 / 95;"
             " a calibrated σ: 60–80 / 90–98). `benchmarks/coverage_table.py`.", "",
             head, "|---|" + "---:|" * len(families)]
    for log in logs:
        cells = []
        for f in families:
            a, b = g.loc[(log, f)] if (log, f) in g.index else (float("nan"), float("nan"))
            if a == a:  # not NaN: the log has samples of that family with a σ
                cells.append(f"{100 * a:.0f} / {100 * b:.0f}")
            else:
                cells.append("–")
        lines.append(f"| {log} | " + " | ".join(cells) + " |")
    text = "\n".join(lines)
    print(text)
    if args.write:
        import _docs

        _docs.write_section("coverage", text, after="<!-- corner-observers:end -->")


if __name__ == "__main__":
    main()
