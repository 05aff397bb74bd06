"""Where Numba keeps vestim's compiled kernels: a user cache directory, not the package.

Numba writes its on-disk cache next to each source file by default, so a read-only
install (a system site-packages, a container layer) recompiles every kernel in every
process. vestim points Numba at ``$NUMBA_CACHE_DIR`` when the user set it, else at
``$XDG_CACHE_HOME/vestim/numba`` (``~/.cache/vestim/numba``). Numba keys each entry by the
source file's path and modification time, so several installs can share the directory.
"""

from __future__ import annotations

import os
import sys
from pathlib import Path

ENV = "NUMBA_CACHE_DIR"


def cache_dir() -> Path:
    """The directory Numba caches vestim's kernels in (it may not exist yet)."""
    if os.environ.get(ENV):
        return Path(os.environ[ENV])
    base = os.environ.get("XDG_CACHE_HOME") or str(Path.home() / ".cache")
    return Path(base) / "vestim" / "numba"


def configure() -> Path:
    """Point Numba at :func:`cache_dir`; a value the user set is kept as it is."""
    path = cache_dir()
    os.environ.setdefault(ENV, str(path))
    numba = sys.modules.get("numba")
    if numba is not None:  # imported before vestim: its config has already read the environment
        numba.config.CACHE_DIR = os.environ[ENV]
    return path


def is_cold() -> bool:
    """True when no vestim kernel is in the cache yet, i.e. the next run compiles them."""
    path = cache_dir()
    return not path.is_dir() or next(path.rglob("*.nbi"), None) is None
