"""vestim: corner-based estimation of tire forces and vehicle velocities robust to road friction.

Layers (imports go one way, checked by import-linter in CI): ``io`` → ``models`` (physics)
→ ``filters`` → ``estimators`` → ``pipeline``; ``sim``, ``metrics`` and ``report`` use
the layers below the pipeline, ``design`` (offline analysis) may run the pipeline, and
``batch`` and ``cli`` sit on top.

The main API is importable from the package itself; the heavy modules load on first use,
so ``import vestim`` stays fast::

    import vestim
    est = vestim.estimate("drive.parquet", "car.toml")
"""

from __future__ import annotations

from importlib import import_module
from importlib.metadata import PackageNotFoundError, version
from typing import Any

from vestim import _cache

_cache.configure()  # before any submodule imports numba

try:
    __version__ = version("vestim")
except PackageNotFoundError:  # pragma: no cover - running from a source tree without install
    __version__ = "0.0.0+unknown"

_API = {
    "estimate": "vestim.pipeline",
    "Pipeline": "vestim.pipeline",
    "PipelineConfig": "vestim.pipeline",
    "load_vehicle": "vestim.io",
    "read_log": "vestim.io",
    "write_log": "vestim.io",
    "score": "vestim.metrics",
    "calibrate": "vestim.design.calibrate",
    "VestimError": "vestim.errors",
}

__all__ = ["__version__", *_API]


def __getattr__(name: str) -> Any:
    if name in _API:
        value = getattr(import_module(_API[name]), name)
        globals()[name] = value
        return value
    raise AttributeError(f"module 'vestim' has no attribute {name!r}")


def __dir__() -> list[str]:
    return sorted(__all__)
