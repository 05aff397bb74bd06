"""Writing a benchmark's Markdown section into docs/results.md (never part of the tests)."""

from __future__ import annotations

import argparse
from collections.abc import Callable
from pathlib import Path

RESULTS = Path(__file__).resolve().parents[1] / "docs" / "results.md"


def write_section(name: str, text: str, after: str | None = None, path: Path = RESULTS) -> None:
    """Replace the text between ``<!-- name:begin -->`` and ``<!-- name:end -->`` in ``path``
    by ``text``, atomically (temporary file, then rename). Without the markers the section
    goes after the first line holding ``after`` (the title line if None)."""
    begin, end = f"<!-- {name}:begin -->", f"<!-- {name}:end -->"
    doc = path.read_text(encoding="utf-8")
    if begin in doc and end in doc:
        pre, rest = doc.split(begin, 1)
        post = rest.split(end, 1)[1]
    else:
        key = after if after is not None and after in doc else doc.partition("\n")[0]
        head, _, tail = doc.partition(key)
        pre, post = head + key + "\n\n", "\n" + tail.lstrip("\n")
    write_page(path, f"{pre}{begin}\n{text}\n{end}{post}")


def write_page(path: Path, text: str) -> None:
    """Write a whole Markdown page atomically (temporary file, then rename)."""
    tmp = path.with_suffix(".md.tmp")
    tmp.write_text(text, encoding="utf-8")
    tmp.replace(path)


def page_main(doc: str, build: Callable[[], str], out: Path) -> None:
    """The command line of a script that generates one docs page: ``--out`` (default
    ``out``), the page from ``build()``, written atomically."""
    ap = argparse.ArgumentParser(description=doc.split("\n\n")[0])
    ap.add_argument("--out", type=Path, default=out)
    args = ap.parse_args()
    write_page(args.out, build())
    print(f"wrote {args.out}")
