"""Writing a benchmark's Markdown section into docs/results.md (never part of the tests)."""

from __future__ import annotations

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
    tmp = path.with_suffix(".md.tmp")
    tmp.write_text(f"{pre}{begin}\n{text}\n{end}{post}", encoding="utf-8")
    tmp.replace(path)
