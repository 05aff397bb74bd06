"""docs/format.md is the repository's own statement of the log and vehicle-file format:
it must name every channel the reader knows and every key the vehicle loader accepts."""

from __future__ import annotations

import re
from dataclasses import fields
from pathlib import Path

import pytest

from vestim.io import channels as ch
from vestim.io import vehicle as veh

FORMAT = Path(__file__).resolve().parents[1] / "docs" / "format.md"
TABLES = {"vehicle": veh.VehicleBody, "tire": veh.LuGreTire, "stiffness": veh.Stiffness,
          "suspension": veh.Suspension, "aerodynamics": veh.Aerodynamics,
          "powertrain": veh.Powertrain, "magic_formula": veh.MagicFormula}


def _text() -> str:
    return FORMAT.read_text(encoding="utf-8")


def test_tables_are_the_loaders_tables():
    """The loader accepts exactly these tables (and [calibration], whose keys are checked
    below); a new one must be documented here first."""
    assert {*TABLES, "calibration"} == set(veh._TABLES)


def test_every_calibration_key_is_documented():
    from vestim.io.calibration import KEYS

    text = _text()
    for group, keys in KEYS.items():
        assert f"[calibration.{group}]" in text
        missing = [k for k in keys if f"`{k}`" not in text]
        assert not missing, f"[calibration.{group}] keys not in docs/format.md: {missing}"


@pytest.mark.parametrize("table", sorted(TABLES))
def test_every_vehicle_key_is_documented(table: str):
    text = _text()
    assert f"[{table}]" in text
    missing = [f.name for f in fields(TABLES[table]) if f"`{f.name}`" not in text]
    assert not missing, f"[{table}] keys not in docs/format.md: {missing}"


def test_every_measured_and_reference_channel_is_documented():
    text = _text()
    named = set(re.findall(r"`([a-z_]+)`", text))
    # Per-corner channels are written once as `name_fl` … `name_rr`.
    wanted = {c for c in (*ch.MEASURED, *ch.REFERENCE)
              if not c.endswith(("_fr", "_rl", "_rr"))}
    assert wanted - named == set()
