"""Atomic file writes: every output vestim writes goes through :func:`atomic_path`.

A temporary file in the target's folder is written and then moved into place
with :func:`os.replace`, so a reader never sees a partial file and a failed
write leaves any previous file untouched. The temporary file's name holds the writer's
process id, so the next write to the same target removes one left by a killed writer
(kill -9 runs no cleanup). The temporary file is created with
mode 0o666 minus the umask (as a plain ``open`` would); ``tempfile.mkstemp``
would leave the final file readable by its owner only.
"""

from __future__ import annotations

import os
import uuid
from collections.abc import Iterable, Iterator, Sequence
from contextlib import contextmanager
from pathlib import Path

from vestim.errors import OutputPathError


@contextmanager
def atomic_path(path: str | os.PathLike[str]) -> Iterator[Path]:
    """Yield a temporary path next to ``path``; on success move it onto ``path``.

    Parent folders are created. On any exception the temporary file is removed
    and the exception propagates.
    """
    target = Path(path)
    target.parent.mkdir(parents=True, exist_ok=True)
    _remove_stale(target)
    tmp = target.parent / f".{target.name}.{os.getpid()}.{uuid.uuid4().hex}.tmp"
    os.close(os.open(tmp, os.O_WRONLY | os.O_CREAT | os.O_EXCL, 0o666))
    try:
        yield tmp
        os.replace(tmp, target)
    except BaseException:
        tmp.unlink(missing_ok=True)
        raise


def _remove_stale(target: Path) -> None:
    """Remove temporary files of ``target`` left by a writer that was killed (kill -9 runs no
    cleanup): those whose writer process no longer exists. A live writer's file is kept."""
    for tmp in target.parent.glob(f".{target.name}.*.tmp"):
        parts = tmp.name[len(target.name) + 2:].split(".")
        if len(parts) != 3 or not parts[0].isdigit():
            continue
        pid = int(parts[0])
        try:
            os.kill(pid, 0)  # signal 0: only asks whether the process exists
        except ProcessLookupError:
            tmp.unlink(missing_ok=True)
        except PermissionError:  # it exists, under another user
            continue


def write_text_atomic(path: str | os.PathLike[str], text: str) -> Path:
    """Write ``text`` (UTF-8) to ``path`` atomically; returns the path."""
    with atomic_path(path) as tmp:
        tmp.write_text(text, encoding="utf-8")
    return Path(path)


def check_output_path(
    out: str | os.PathLike[str],
    *,
    inputs: Iterable[str | os.PathLike[str] | None] = (),
    suffixes: Sequence[str] = (),
) -> Path:
    """Refuse an output path before any work is done; returns it as a Path.

    Args:
        out: the file to write.
        inputs: the files the command reads (``None`` entries are ignored); ``out`` must be
            none of them, also through another spelling or a link.
        suffixes: the extensions the writer knows (lower case, with the dot); empty: any.

    Raises:
        OutputPathError: ``out`` is an input, an existing folder, or has another extension.
    """
    p = Path(out)
    for src in inputs:
        if src is None:
            continue
        s = Path(src)
        same = (s.exists() and p.exists() and os.path.samefile(s, p)) or (
            p.resolve() == s.resolve())
        if same:
            raise OutputPathError(f"--out {str(p)!r} is the input {str(s)!r}; vestim never "
                                  "overwrites its inputs: give another output file")
    if p.is_dir():
        raise OutputPathError(f"--out {str(p)!r} is a folder; give a file name")
    if suffixes and p.suffix.lower() not in suffixes:
        raise OutputPathError(f"--out {str(p)!r}: unsupported extension "
                              f"{p.suffix or '(none)'!r}; use one of {', '.join(suffixes)}")
    return p
