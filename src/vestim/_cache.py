"""Where Numba keeps vestim's compiled kernels: a user cache directory, not the package.

Numba writes its on-disk cache next to each source file by default, so a read-only
install (a system site-packages, a container layer) recompiles every kernel in every
process. vestim points Numba at ``$NUMBA_CACHE_DIR`` when the user set it, else at
``$XDG_CACHE_HOME/vestim/numba/<code>`` (``~/.cache/vestim/numba/<code>``).

``<code>`` is a fingerprint of vestim's source files (:func:`code_fingerprint`). Numba keys
each cached kernel by its own source file's path and modification time only, not by the
files of the functions it calls: once ``pipeline/rows.py`` is cached, a change in
``estimators/force/longitudinal.py`` alone (an upgrade, an edit) would still run the old,
inlined longitudinal filter. Every version of the code gets its own directory instead (a
user-set ``$NUMBA_CACHE_DIR`` has that hazard; clear it after changing the code).
"""

from __future__ import annotations

import functools
import hashlib
import os
import sys
import threading
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from pathlib import Path
from typing import Any

ENV = "NUMBA_CACHE_DIR"
NOTICE_AFTER_S = 1.0
"""A compilation still running after this many seconds is announced (:func:`compile_notice`)."""


@functools.cache
def code_fingerprint() -> str:
    """SHA-256 (16 hex digits) of the path and bytes of every ``.py`` file of the installed
    vestim package: the same for the same code, different after any change."""
    root = Path(__file__).resolve().parent
    digest = hashlib.sha256()
    for path in sorted(root.rglob("*.py")):
        digest.update(path.relative_to(root).as_posix().encode())
        digest.update(path.read_bytes())
    return digest.hexdigest()[:16]


def cache_dir() -> Path:
    """The directory Numba caches vestim's kernels in (it may not exist yet)."""
    if os.environ.get(ENV):
        return Path(os.environ[ENV])
    base = os.environ.get("XDG_CACHE_HOME") or str(Path.home() / ".cache")
    return Path(base) / "vestim" / "numba" / code_fingerprint()


def configure() -> Path:
    """Point Numba at :func:`cache_dir`; a value the user set is kept as it is."""
    path = cache_dir()
    os.environ.setdefault(ENV, str(path))
    numba = sys.modules.get("numba")
    if numba is not None:  # imported before vestim: its config has already read the environment
        numba.config.CACHE_DIR = os.environ[ENV]
    return path


def notice_text() -> str:
    """What :func:`compile_notice` says."""
    return ("compiling vestim's kernels for this code path (once per machine and code path, "
            f"about 1-3 min the first time); later runs load them from {cache_dir()}")


class _CompileWatch:
    """Numba compile-event listener: a compilation that is still running ``after_s`` after
    it started calls ``say`` (once). Nested compilations (a kernel compiling the functions
    it calls) count as one; loading a kernel from the cache is no compilation."""

    def __init__(self, say: Callable[[str], None], after_s: float) -> None:
        self._say, self._after_s = say, after_s
        self._lock = threading.Lock()
        self._depth = 0
        self._timer: threading.Timer | None = None
        self.said = False

    def on_start(self, event: Any) -> None:
        with self._lock:
            self._depth += 1
            if self._depth == 1 and not self.said:
                self._timer = threading.Timer(self._after_s, self._fire)
                self._timer.daemon = True
                self._timer.start()

    def on_end(self, event: Any) -> None:
        with self._lock:
            self._depth = max(self._depth - 1, 0)
            if self._depth == 0:
                self.cancel()

    def cancel(self) -> None:
        if self._timer is not None:
            self._timer.cancel()
            self._timer = None

    def _fire(self) -> None:
        with self._lock:
            if self._depth == 0 or self.said:
                return
            self.said = True
        self._say(notice_text())


@contextmanager
def compile_notice(say: Callable[[str], None], after_s: float = NOTICE_AFTER_S) -> Iterator[None]:
    """Within the block, call ``say(notice_text())`` once when a Numba compilation has run
    for ``after_s`` s: every code path's first run on a machine (a new kernel, a new
    argument type, a new vestim or Numba) is announced, and a run that loads every kernel
    from the cache says nothing. ``say`` runs on a timer thread."""
    from numba.core import event

    class Listener(event.Listener):
        def __init__(self, watch: _CompileWatch) -> None:
            self.watch = watch

        def on_start(self, ev: event.Event) -> None:
            self.watch.on_start(ev)

        def on_end(self, ev: event.Event) -> None:
            self.watch.on_end(ev)

    watch = _CompileWatch(say, after_s)
    try:
        with event.install_listener("numba:compile", Listener(watch)):
            yield
    finally:
        watch.cancel()
