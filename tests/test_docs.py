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


def _rows(text: str) -> list[list[str]]:
    """The cells of every Markdown table row of ``text``."""
    return [[c.strip() for c in line.strip().strip("|").split("|")]
            for line in text.splitlines() if line.startswith("| ")]


def test_every_output_column_is_documented_with_its_unit():
    """Each column `vestim estimate` writes (default pipeline; corners as `_fl`) has a row
    in docs/format.md's table of estimated channels whose unit is the one the Parquet
    schema carries (vestim.io.channels.unit_of; "–" for "-"); σ columns are listed in the
    `sigma_<name>` row."""
    import vestim
    from vestim.sim import simulate

    est = vestim.estimate(simulate("step_steer", "hashemi_suv", seed=0).iloc[:200], "hashemi_suv")
    text = _text()
    section = text[text.index("### Estimated channels"):text.index("**Validity flags.**")]
    rows = _rows(section)
    sigma_row = next(r for r in rows if r[0] == "`sigma_<name>`")
    missing: list[str] = []
    for col in est.columns:
        name = re.sub(r"_(fr|rl|rr)(?=_|$)", "_fl", col)
        if name.startswith("sigma_"):
            ok = f"`{name[len('sigma_'):]}`" in sigma_row[2]
        else:
            unit = (ch.unit_of(col) or "?").replace("-", "–")
            ok = any(f"`{name}`" in r[0] and r[1] == unit for r in rows)
        if not ok:
            missing.append(f"{col} [{ch.unit_of(col)}]")
    assert not missing, f"estimate columns without their row (or unit) in docs/format.md: {missing}"


def test_every_reason_bit_is_documented():
    """The bit table of docs/format.md is validity.REASONS: each bit with its name."""
    from vestim.estimators.validity import REASONS

    bits = {r[0]: r[1] for r in _rows(_text()) if r[0].isdigit()}
    assert bits == {str(b): n for b, n in REASONS.items()}


REPO = Path(__file__).resolve().parents[1]
OUTSIDE = re.compile(r"\.\./shared|shared/spec|/work/shared|\.\./spec/|shared/papers|/ \"shared\"")
"""A path outside the repository (the project's data folder beside it)."""


def test_no_user_facing_text_names_a_path_outside_the_repo():
    """Error messages, docstrings and CLI help (src/), the docs, the README and the examples
    name only paths inside the repository (docs/format.md is the format reference); tests
    and benchmarks may read data from outside."""
    files = [*sorted((REPO / "src" / "vestim").rglob("*.py")), *sorted((REPO / "docs").glob("*.md")),
             REPO / "README.md", *sorted(p for p in (REPO / "examples").rglob("*")
                                          if p.suffix in (".md", ".py", ".toml", ".dbc"))]
    found = [f"{p.relative_to(REPO)}:{i}: {line.strip()}"
             for p in files for i, line in enumerate(p.read_text(encoding="utf-8").splitlines(), 1)
             if OUTSIDE.search(line)]
    assert not found, "\n".join(found)
