"""The CLI prints user text verbatim (Rich markup would delete "[tyre]"), and `estimate` runs
the cross-channel input checks: errors exit 2 naming the channel, warnings are printed and
stored in the output's metadata (issue 14)."""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

import pandas as pd
import pyarrow.parquet as pq
import typer
from typer.testing import CliRunner

from vestim.cli import app
from vestim.constants import CORNERS
from vestim.io import load_vehicle, write_log
from vestim.sim import get_maneuver, simulate

runner = CliRunner()


def _flat(text: str) -> str:
    """Whitespace collapsed: Rich and click wrap long lines at the terminal width."""
    return " ".join(text.split())


def test_bracketed_error_message_survives(tmp_path: Path) -> None:
    """A vehicle file with an unknown table: the message names [tyre] and lists the allowed
    tables in brackets; before escaping it read "unknown table(s) ; allowed: , , ,"."""
    bad = tmp_path / "car.toml"
    bad.write_text("[vehicle]\nmass = 1500.0\n[tyre]\nmu = 1.0\n", encoding="utf-8")
    res = runner.invoke(app, ["estimate", str(tmp_path / "log.parquet"), "--out",
                              str(tmp_path / "est.parquet"), "--vehicle", str(bad)])
    assert res.exit_code == 2
    out = _flat(res.output)
    assert "unknown table(s) [tyre]; allowed: [vehicle], [tire], [stiffness]" in out
    assert "Traceback" not in out


def test_config_help_keeps_its_brackets() -> None:
    res = runner.invoke(app, ["estimate", "--help"])
    assert res.exit_code == 0
    assert "TOML file with a [pipeline] table" in _flat(res.output)


def _commands(cmd: Any, path: tuple[str, ...] = ()) -> list[tuple[tuple[str, ...], Any]]:
    """Every command of the tree with its argv path (typer ships its own click, so by duck
    typing: a group has ``commands``)."""
    found = [(path, cmd)]
    for name, sub in getattr(cmd, "commands", {}).items():
        found += _commands(sub, (*path, name))
    return found


def test_every_bracketed_help_text_survives() -> None:
    """Every option and command help that holds a '[' appears in its --help as written, in
    every command of the tree (a guard for help texts added later)."""
    checked = 0
    for path, cmd in _commands(typer.main.get_command(app)):
        texts = [p.help for p in cmd.params if getattr(p, "help", None)]
        texts += [cmd.help] if cmd.help else []
        texts = [t for t in texts if "[" in t]
        if not texts:
            continue
        res = runner.invoke(app, [*path, "--help"])
        assert res.exit_code == 0, res.output
        for t in texts:
            assert _flat(t) in _flat(res.output), (path, t)
            checked += 1
    assert checked >= 1  # at least estimate --config


def _sim_log(tmp_path: Path, name: str) -> tuple[Path, pd.DataFrame]:
    veh = load_vehicle("hashemi_suv")
    return tmp_path / f"{name}.parquet", simulate(get_maneuver(name), veh, seed=0)


def test_estimate_stops_on_a_flipped_yaw_rate(tmp_path: Path) -> None:
    """dlc_snow with yaw_rate negated: exit 2, one line naming yaw_rate and the fix, and no
    output file (the estimate would be garbage: 99 % v_x error in the issue's table)."""
    path, log = _sim_log(tmp_path, "dlc_snow")
    log["yaw_rate"] = -log["yaw_rate"]
    write_log(log, path)
    out = tmp_path / "est.parquet"
    res = runner.invoke(app, ["estimate", "--vehicle", "hashemi_suv", str(path), "--out", str(out)])
    assert res.exit_code == 2, res.output
    text = _flat(res.output)
    assert "column 'yaw_rate' has the wrong sign" in text and "negate yaw_rate" in text
    assert "Traceback" not in text
    assert not out.exists()


def test_estimate_stores_warnings_in_the_metadata(tmp_path: Path) -> None:
    """dlc_snow with km/h wheel speeds (ω × 3.6·R = ×1.188): weak evidence, so the estimate is
    written, a warning is printed, and the metadata's ``vestim.warnings`` holds it as JSON;
    a clean log stores an empty list."""
    path, log = _sim_log(tmp_path, "dlc_snow")
    write_log(log, tmp_path / "clean.parquet")
    for c in CORNERS:
        log[f"omega_{c}"] = log[f"omega_{c}"] * 3.6 * 0.33
    write_log(log, path)
    out = tmp_path / "est.parquet"
    res = runner.invoke(app, ["estimate", "--vehicle", "hashemi_suv", str(path), "--out", str(out)])
    assert res.exit_code == 0, res.output
    assert "warning: columns omega_fl, omega_fr, omega_rl, omega_rr may be in km/h" in _flat(
        res.output)
    meta = pq.read_schema(out).metadata
    warnings = json.loads(meta[b"vestim.warnings"])
    assert [w["channel"] for w in warnings] == ["omega_fl, omega_fr, omega_rl, omega_rr"]
    assert warnings[0]["severity"] == "warning" and "km/h" in warnings[0]["message"]
    res = runner.invoke(app, ["estimate", "--vehicle", "hashemi_suv",
                              str(tmp_path / "clean.parquet"), "--out",
                              str(tmp_path / "clean_est.parquet")])
    assert res.exit_code == 0, res.output
    assert "warning:" not in res.output
    meta = pq.read_schema(tmp_path / "clean_est.parquet").metadata
    assert json.loads(meta[b"vestim.warnings"]) == []
