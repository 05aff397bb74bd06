"""Every example runs from a clean clone: the commands of each ``examples/*/README.md`` (its
``sh`` blocks, then its ``python`` blocks) run one after the other in a fresh folder holding
only a copy of ``examples/``, with nothing from outside the repository."""

from __future__ import annotations

import re
import shlex
import shutil
import subprocess
import sys
from pathlib import Path

import pytest

REPO = Path(__file__).resolve().parents[1]
EXAMPLES = sorted(p.parent.name for p in (REPO / "examples").glob("*/README.md"))
_BLOCK = re.compile(r"^```(sh|python)\n(.*?)^```", re.M | re.S)


def _blocks(readme: Path, kind: str) -> list[str]:
    return [body for k, body in _BLOCK.findall(readme.read_text(encoding="utf-8")) if k == kind]


def commands(readme: Path) -> list[list[str]]:
    """The shell commands of the README's ``sh`` blocks (continuation lines joined, comment
    lines left out), ``vestim`` and ``python`` run by this interpreter."""
    out: list[list[str]] = []
    for body in _blocks(readme, "sh"):
        for line in body.replace("\\\n", " ").splitlines():
            words = shlex.split(line, comments=True)
            if not words:
                continue
            if words[0] == "vestim":
                words = [sys.executable, "-m", "vestim", *words[1:]]
            elif words[0] == "python":
                words = [sys.executable, *words[1:]]
            out.append(words)
    return out


def test_every_example_is_found_and_has_commands() -> None:
    assert EXAMPLES == ["comma2k19", "mdf4_can", "obd_csv", "ros2_bag"]
    for name in EXAMPLES:
        cmds = commands(REPO / "examples" / name / "README.md")
        assert any("estimate" in c for c in cmds), name  # each estimates from its recording


@pytest.mark.parametrize("name", EXAMPLES)
def test_example_runs_from_a_clean_clone(name: str, tmp_path: Path) -> None:
    """Each command exits 0 in a folder with nothing but a copy of examples/, and an
    estimate is written."""
    shutil.copytree(REPO / "examples", tmp_path / "examples")
    readme = tmp_path / "examples" / name / "README.md"
    for cmd in commands(readme):
        res = subprocess.run(cmd, cwd=tmp_path, capture_output=True, text=True, timeout=300)
        assert res.returncode == 0, f"{shlex.join(cmd[1:])}\n{res.stdout}\n{res.stderr}"
    for code in _blocks(readme, "python"):
        res = subprocess.run([sys.executable, "-c", code], cwd=tmp_path, capture_output=True,
                             text=True, timeout=120)
        assert res.returncode == 0, f"{code}\n{res.stderr}"
    written = {p.name for p in tmp_path.glob("*est*.parquet")}
    assert written, sorted(p.name for p in tmp_path.iterdir())
